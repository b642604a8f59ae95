/* Restart from the last complete frame of a drape HDF5 file.
 *
 * The file is checked on rank 0 with plain HDF5 calls first (so that a missing,
 * truncated or foreign file gets one clear sentence instead of an HDF5 error
 * stack), then the frame is read collectively through PetscViewerHDF5, in natural
 * lattice order, so the restart may use any number of ranks. */
#include <output.h>
#include <drape.h>
#include <petscviewerhdf5.h>

/* Number of complete frames (the shortest of the per-frame datasets) and the
 * stored options; rank 0 only. *why is set when the file is unusable. */
static PetscErrorCode RestartInspect(const char file[], PetscInt *nframes, char **options, const char **why)
{
  const char *const sets[] = {"time", "step", "position", "velocity"};
  hid_t             fid, aid, tid;
  htri_t            ok;

  PetscFunctionBeginUser;
  *nframes = 0;
  *options = NULL;
  *why     = NULL;
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  {
    FILE *fp = fopen(file, "rb");
    if (!fp) {
      *why = "it does not exist or cannot be read";
      PetscFunctionReturn(0);
    }
    fclose(fp);
  }
  ok = H5Fis_hdf5(file);
  if (ok <= 0) {
    *why = "it is not an HDF5 file";
    PetscFunctionReturn(0);
  }
  fid = H5Fopen(file, H5F_ACC_RDONLY, H5P_DEFAULT);
  if (fid < 0) {
    *why = "it is damaged or truncated (HDF5 cannot open it)";
    PetscFunctionReturn(0);
  }
  if (H5Aexists(fid, "drape_version") <= 0 || H5Aexists(fid, "options") <= 0) {
    *why = "it was not written by drape (no drape_version or options attribute)";
    H5Fclose(fid);
    PetscFunctionReturn(0);
  }
  *nframes = PETSC_MAX_INT;
  for (PetscInt k = 0; k < 4; k++) {
    hid_t   did, sid;
    hsize_t dims[4];
    if (H5Lexists(fid, sets[k], H5P_DEFAULT) <= 0 || (did = H5Dopen2(fid, sets[k], H5P_DEFAULT)) < 0) {
      *why     = "it has no frames (a dataset is missing)";
      *nframes = 0;
      H5Fclose(fid);
      PetscFunctionReturn(0);
    }
    sid = H5Dget_space(did);
    if (H5Sget_simple_extent_dims(sid, dims, NULL) < 1) dims[0] = 0;
    *nframes = PetscMin(*nframes, (PetscInt) dims[0]);
    H5Sclose(sid);
    H5Dclose(did);
  }
  if (*nframes < 1) *why = "it holds no complete frame";
  aid = H5Aopen(fid, "options", H5P_DEFAULT);
  tid = H5Aget_type(aid);
  {
    size_t n = H5Tget_size(tid);
    PetscCall(PetscCalloc1(n + 1, options));
    if (H5Aread(aid, tid, *options) < 0) *why = "its options attribute cannot be read";
  }
  H5Tclose(tid);
  H5Aclose(aid);
  H5Fclose(fid);
  PetscFunctionReturn(0);
}

PetscErrorCode RestartInsertOptions(MPI_Comm comm, const char file[])
{
  PetscMPIInt rank;
  PetscInt    nframes = 0, len = 0;
  char       *options = NULL, reason[256] = "";
  const char *why = NULL;
  int         argc;
  char      **argv;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  if (!rank) {
    PetscCall(RestartInspect(file, &nframes, &options, &why));
    if (why) PetscCall(PetscStrncpy(reason, why, sizeof reason));
    if (options) {
      size_t n;
      PetscCall(PetscStrlen(options, &n));
      len = (PetscInt) n;
    }
  }
  PetscCallMPI(MPI_Bcast(reason, sizeof reason, MPI_CHAR, 0, comm));
  PetscCheck(!reason[0], comm, PETSC_ERR_FILE_UNEXPECTED, "Cannot restart from %s: %s", file, reason);
  PetscCallMPI(MPI_Bcast(&len, 1, MPIU_INT, 0, comm));
  if (rank) PetscCall(PetscCalloc1(len + 1, &options));
  PetscCallMPI(MPI_Bcast(options, (PetscMPIInt) len + 1, MPI_CHAR, 0, comm));
  /* the stored run's options, then the command line again: it wins */
  PetscCall(PetscOptionsInsertString(NULL, options));
  PetscCall(PetscGetArgs(&argc, &argv));
  PetscCall(PetscOptionsInsert(NULL, &argc, &argv, NULL));
  PetscCall(PetscFree(options));
  PetscFunctionReturn(0);
}

/* an HDF5 call on the (already inspected) restart file; a negative return stops
 * the run with the file's name (only rank 0 reads: main aborts the job) */
#define H5Check(call)                                                                                                                                                                                                                                    \
  do {                                                                                                                                                                                                                                                   \
    if ((call) < 0) SETERRQ(PETSC_COMM_SELF, PETSC_ERR_FILE_READ, "Cannot read the restart file %s: %s failed", file, #call);                                                                                                                            \
  } while (0)

PetscErrorCode RestartLoad(MPI_Comm comm, const char file[], Cloth cloth, PetscScalar *x, PetscScalar *v, PetscReal *t, PetscInt *step, PetscInt *nframes, PetscReal **times)
{
  PetscMPIInt rank;
  PetscInt    n = 0, dims[2] = {0, 0};
  char       *options = NULL;
  const char *why;
  PetscViewer viewer;
  DM          da;
  Vec         X;
  ClothInfo   info;
  PetscReal   stepv = 0;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(ClothGetInfo(cloth, &info));
  if (!rank) {
    hid_t fid, did, sid;
    PetscCall(RestartInspect(file, &n, &options, &why));
    PetscCall(PetscFree(options));
    PetscCall(PetscMalloc1(n, times));
    H5Check(fid = H5Fopen(file, H5F_ACC_RDONLY, H5P_DEFAULT));
    H5Check(did = H5Dopen2(fid, "position", H5P_DEFAULT));
    H5Check(sid = H5Dget_space(did));
    {
      hsize_t d[4];
      PetscCheck(H5Sget_simple_extent_ndims(sid) == 4, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "Cannot restart from %s: its /position dataset is not [frames][My][Mx][3]", file);
      H5Check(H5Sget_simple_extent_dims(sid, d, NULL));
      dims[0] = (PetscInt) d[2];
      dims[1] = (PetscInt) d[1];
    }
    H5Check(H5Sclose(sid));
    H5Check(H5Dclose(did));
    {
      /* /time and /step: [frames][1]; read all times, the last step */
      PetscReal *buf;
      PetscCall(PetscMalloc1(PetscMax(n, 1), &buf));
      H5Check(did = H5Dopen2(fid, "time", H5P_DEFAULT));
      {
        hsize_t start[2] = {0, 0}, count[2] = {(hsize_t) n, 1};
        hid_t   fs, ms;
        H5Check(fs = H5Dget_space(did));
        H5Check(ms = H5Screate_simple(2, count, NULL));
        H5Check(H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL));
        H5Check(H5Dread(did, H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT, *times));
        H5Check(H5Sclose(ms));
        H5Check(H5Sclose(fs));
      }
      H5Check(H5Dclose(did));
      H5Check(did = H5Dopen2(fid, "step", H5P_DEFAULT));
      {
        hsize_t start[2] = {(hsize_t) (n - 1), 0}, count[2] = {1, 1};
        hid_t   fs, ms;
        H5Check(fs = H5Dget_space(did));
        H5Check(ms = H5Screate_simple(2, count, NULL));
        H5Check(H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL));
        H5Check(H5Dread(did, H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT, buf));
        stepv = buf[0];
        H5Check(H5Sclose(ms));
        H5Check(H5Sclose(fs));
      }
      H5Check(H5Dclose(did));
      PetscCall(PetscFree(buf));
    }
    H5Check(H5Fclose(fid));
  }
  PetscCallMPI(MPI_Bcast(&n, 1, MPIU_INT, 0, comm));
  PetscCallMPI(MPI_Bcast(dims, 2, MPIU_INT, 0, comm));
  PetscCallMPI(MPI_Bcast(&stepv, 1, MPIU_REAL, 0, comm));
  PetscCheck(dims[0] == info.Mx && dims[1] == info.My, comm, PETSC_ERR_USER_INPUT, "Cannot restart from %s: its lattice is %" PetscInt_FMT " x %" PetscInt_FMT ", this run's is %" PetscInt_FMT " x %" PetscInt_FMT, file, dims[0], dims[1], info.Mx,
             info.My);
  if (rank) PetscCall(PetscMalloc1(n, times));
  PetscCallMPI(MPI_Bcast(*times, (PetscMPIInt) n, MPIU_REAL, 0, comm));
  *nframes = n;
  *t       = (*times)[n - 1];
  *step    = (PetscInt) stepv;

  PetscCall(ClothGetDM(cloth, &da));
  PetscCall(DMCreateGlobalVector(da, &X));
  PetscCall(PetscViewerHDF5Open(comm, file, FILE_MODE_READ, &viewer));
  PetscCall(PetscViewerHDF5PushTimestepping(viewer));
  PetscCall(PetscViewerHDF5SetTimestep(viewer, n - 1));
  for (PetscInt f = 0; f < 2; f++) {
    PetscCall(PetscObjectSetName((PetscObject) X, f ? "velocity" : "position"));
    PetscCall(VecLoad(X, viewer));
    PetscCall(ClothFromDMDA(cloth, X, f ? v : x));
  }
  PetscCall(PetscViewerHDF5PopTimestepping(viewer));
  PetscCall(PetscViewerDestroy(&viewer));
  PetscCall(VecDestroy(&X));
  PetscFunctionReturn(0);
}
