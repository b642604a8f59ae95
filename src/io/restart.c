/* Restart from the last complete frame of a drape HDF5 file.
 *
 * The file is checked on rank 0 with plain HDF5 calls first (so that a missing,
 * truncated, foreign or damaged file gets one clear sentence naming it instead of an
 * HDF5 error stack): datasets, shapes, the stored options, and the times and step of
 * the frames (finite, in order). Then the frame is read collectively through
 * PetscViewerHDF5, in natural lattice order, so the restart may use any number of
 * ranks, and checked to be finite. */
#include <output.h>
#include <drape.h>
#include <petscviewerhdf5.h>
#include <stdlib.h>
#include <strings.h>

/* What rank 0 found in the file; why is set when it is unusable. */
typedef struct {
  PetscInt    nframes, Mx, My;
  PetscReal   step;  /* of the last complete frame          */
  PetscReal  *times; /* of the complete frames (caller frees) */
  char       *options;
  const char *why;
  /* the cloth the run had, as its start-up numbers in the file say (old files: unset) */
  double values[6]; /* size_warp, size_weft, density, shear, stretch_warp, stretch_weft */
  int    has_value[6];
  char   model[32];
} RestartInfo;

static const char *const value_names[] = {"size_warp", "size_weft", "density", "shear", "stretch_warp", "stretch_weft"};

/* Rank of dataset `name` and its dimensions (at most 4); -1 if it is missing or not
 * a dataset of floating-point numbers. */
static int DatasetShape(hid_t fid, const char *name, hsize_t dims[4])
{
  hid_t did, sid, tid;
  int   ndims = -1;

  if (H5Lexists(fid, name, H5P_DEFAULT) <= 0 || (did = H5Dopen2(fid, name, H5P_DEFAULT)) < 0) return -1;
  if ((tid = H5Dget_type(did)) >= 0) {
    if (H5Tget_class(tid) == H5T_FLOAT && (sid = H5Dget_space(did)) >= 0) {
      ndims = H5Sget_simple_extent_ndims(sid);
      if (ndims < 0 || ndims > 4 || H5Sget_simple_extent_dims(sid, dims, NULL) < 0) ndims = -1;
      H5Sclose(sid);
    }
    H5Tclose(tid);
  }
  H5Dclose(did);
  return ndims;
}

/* Read rows [first, first + n) of a [frames][1] dataset. */
static herr_t ReadColumn(hid_t fid, const char *name, hsize_t first, hsize_t n, double *buf)
{
  hsize_t start[2] = {first, 0}, count[2] = {n, 1};
  hid_t   did, fs, ms;
  herr_t  status = -1;

  if ((did = H5Dopen2(fid, name, H5P_DEFAULT)) < 0) return -1;
  if ((fs = H5Dget_space(did)) >= 0) {
    if ((ms = H5Screate_simple(2, count, NULL)) >= 0) {
      if (H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL) >= 0) status = H5Dread(did, H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT, buf);
      H5Sclose(ms);
    }
    H5Sclose(fs);
  }
  H5Dclose(did);
  return status;
}

static PetscErrorCode RestartInspectFile(hid_t fid, RestartInfo *r)
{
  const char *const sets[] = {"time", "step", "position", "velocity"};
  hsize_t           dims[4][4];
  hid_t             aid, tid;

  PetscFunctionBeginUser;
  if (H5Aexists(fid, "drape_version") <= 0 || H5Aexists(fid, "options") <= 0) {
    r->why = "it was not written by drape (no drape_version or options attribute)";
    PetscFunctionReturn(0);
  }
  r->nframes = PETSC_MAX_INT;
  for (PetscInt k = 0; k < 4; k++) {
    int ndims = DatasetShape(fid, sets[k], dims[k]);
    if (ndims < 0) {
      r->why     = "it has no frames (a dataset is missing or not numbers)";
      r->nframes = 0;
      PetscFunctionReturn(0);
    }
    if (ndims != (k < 2 ? 2 : 4) || (k < 2 && dims[k][1] != 1) || (k >= 2 && (dims[k][3] != 3 || dims[k][1] < 2 || dims[k][2] < 2 || dims[k][1] > PETSC_MAX_INT || dims[k][2] > PETSC_MAX_INT))) {
      r->why = k < 2 ? "its /time or /step dataset is not [frames][1]" : "its /position or /velocity dataset is not [frames][My][Mx][3]";
      PetscFunctionReturn(0);
    }
    r->nframes = PetscMin(r->nframes, (PetscInt) PetscMin(dims[k][0], (hsize_t) PETSC_MAX_INT));
  }
  if (dims[2][1] != dims[3][1] || dims[2][2] != dims[3][2]) {
    r->why = "its /position and /velocity datasets differ in shape";
    PetscFunctionReturn(0);
  }
  r->My = (PetscInt) dims[2][1];
  r->Mx = (PetscInt) dims[2][2];
  if (r->nframes < 1) {
    r->why = "it holds no complete frame";
    PetscFunctionReturn(0);
  }
  /* the options the run was made with: a fixed-length string, read into the buffer */
  if ((aid = H5Aopen(fid, "options", H5P_DEFAULT)) < 0 || (tid = H5Aget_type(aid)) < 0) {
    r->why = "its options attribute cannot be read";
    if (aid >= 0) H5Aclose(aid);
    PetscFunctionReturn(0);
  }
  if (H5Tget_class(tid) != H5T_STRING || H5Tis_variable_str(tid) != 0 || H5Tget_size(tid) > (1 << 20))
    r->why = "its options attribute is not a string of drape's options";
  else {
    PetscCall(PetscCalloc1(H5Tget_size(tid) + 1, &r->options));
    if (H5Aread(aid, tid, r->options) < 0)
      r->why = "its options attribute cannot be read";
    else if (strstr(r->options, "-options_file") || strstr(r->options, "_yaml"))
      r->why = "its stored options name an options file, which drape does not follow";
  }
  H5Tclose(tid);
  H5Aclose(aid);
  if (r->why) PetscFunctionReturn(0);
  for (int k = 0; k < 6; k++) {
    if (H5Aexists(fid, value_names[k]) <= 0 || (aid = H5Aopen(fid, value_names[k], H5P_DEFAULT)) < 0) continue;
    r->has_value[k] = H5Aread(aid, H5T_NATIVE_DOUBLE, &r->values[k]) >= 0;
    H5Aclose(aid);
  }
  if (H5Aexists(fid, "model") > 0 && (aid = H5Aopen(fid, "model", H5P_DEFAULT)) >= 0) {
    if ((tid = H5Aget_type(aid)) >= 0) {
      if (H5Tget_class(tid) == H5T_STRING && H5Tis_variable_str(tid) == 0 && H5Tget_size(tid) < sizeof r->model && H5Aread(aid, tid, r->model) < 0) r->model[0] = 0;
      H5Tclose(tid);
    }
    H5Aclose(aid);
  }
  /* times and step of the frames: finite, in order (a restart from t = inf never ends) */
  PetscCall(PetscMalloc1(r->nframes, &r->times));
  if (ReadColumn(fid, "time", 0, (hsize_t) r->nframes, r->times) < 0) {
    r->why = "its /time or /step dataset cannot be read (the file is damaged)";
    PetscFunctionReturn(0);
  }
  /* a run killed inside a frame's write can leave /time one longer than what was
   * written (HDF5 extends the dataset before it writes the value, which stays at the
   * fill value 0): that frame is not complete */
  while (r->nframes > 1 && r->times[r->nframes - 1] == 0 && r->times[r->nframes - 2] > 0) r->nframes--;
  if (ReadColumn(fid, "step", (hsize_t) r->nframes - 1, 1, &r->step) < 0) {
    r->why = "its /time or /step dataset cannot be read (the file is damaged)";
    PetscFunctionReturn(0);
  }
  for (PetscInt k = 0; k < r->nframes; k++) {
    if (!(r->times[k] >= 0 && r->times[k] <= 1e12) || (k && r->times[k] < r->times[k - 1])) {
      r->why = "the times of its frames are not finite, in order, from 0 to 1e12 s (the file is damaged or not drape's)";
      PetscFunctionReturn(0);
    }
  }
  if (!(r->step >= 0 && r->step <= PETSC_MAX_INT && r->step == PetscFloorReal(r->step))) r->why = "the step of its last frame is not a whole number from 0 to the largest PetscInt (the file is damaged or not drape's)";
  PetscFunctionReturn(0);
}

/* Rank 0 only. */
static PetscErrorCode RestartInspect(const char file[], RestartInfo *r)
{
  hid_t          fid;
  PetscBool      isdir;
  PetscErrorCode ierr;

  PetscFunctionBeginUser;
  PetscCall(PetscMemzero(r, sizeof *r));
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  PetscCall(PetscTestDirectory(file, 'r', &isdir));
  if (isdir) {
    r->why = "it is a directory";
    PetscFunctionReturn(0);
  }
  {
    FILE *fp = fopen(file, "rb");
    if (!fp) {
      r->why = "it does not exist or cannot be read";
      PetscFunctionReturn(0);
    }
    fclose(fp);
  }
  if (H5Fis_hdf5(file) <= 0) {
    r->why = "it is not an HDF5 file";
    PetscFunctionReturn(0);
  }
  fid = H5Fopen(file, H5F_ACC_RDONLY, H5P_DEFAULT);
  if (fid < 0) {
    r->why = "it is damaged or truncated (HDF5 cannot open it)";
    PetscFunctionReturn(0);
  }
  ierr = RestartInspectFile(fid, r);
  H5Fclose(fid);
  PetscCall(ierr);
  PetscFunctionReturn(0);
}

static PetscErrorCode RestartInfoDestroy(RestartInfo *r)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree(r->options));
  PetscCall(PetscFree(r->times));
  PetscFunctionReturn(0);
}

/* Rank 0 inspects the file; every rank learns the verdict and raises it together. */
static PetscErrorCode RestartCheck(MPI_Comm comm, const char file[], RestartInfo *r)
{
  PetscMPIInt rank;
  char        reason[256] = "";

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(PetscMemzero(r, sizeof *r));
  if (!rank) {
    PetscCall(RestartInspect(file, r));
    if (r->why) PetscCall(PetscStrncpy(reason, r->why, sizeof reason));
  }
  PetscCallMPI(MPI_Bcast(reason, sizeof reason, MPI_CHAR, 0, comm));
  if (reason[0]) PetscCall(RestartInfoDestroy(r));
  PetscCheck(!reason[0], comm, PETSC_ERR_FILE_UNEXPECTED, "Cannot restart from %s: %s", file, reason);
  PetscFunctionReturn(0);
}

/* options PETSc 3.18 acts on in PetscInitialize() (some again in PetscFinalize(),
 * where a stored one would dump or log what this run never traced) */
static const char *const startup_only[] = {"-malloc_debug",
                                           "-malloc_dump",
                                           "-malloc_test",
                                           "-malloc_view",
                                           "-malloc_view_threshold",
                                           "-malloc_coalesce",
                                           "-malloc_requested_size",
                                           "-malloc_hbw",
                                           "-malloc_info",
                                           "-memory_view",
                                           "-log_view",
                                           "-log_view_memory",
                                           "-log_summary",
                                           "-log_all",
                                           "-log",
                                           "-log_mpe",
                                           "-log_sync",
                                           "-log_threshold",
                                           "-log_trace",
                                           "-info",
                                           "-history",
                                           "-objects_dump",
                                           "-no_signal_handler",
                                           "-on_error_abort",
                                           "-on_error_attach_debugger",
                                           "-on_error_emacs",
                                           "-on_error_mpiabort",
                                           "-start_in_debugger",
                                           "-stop_for_debugger",
                                           "-debugger_ranks",
                                           "-debugger_nodes",
                                           "-debug_terminal",
                                           "-fp_trap"};

/* The cloth's material and geometry: its frames hold that cloth, so a restart takes
 * them from the file (-cloth_size 2 on a 1 m cloth's restart ran at 20 % strain). The
 * lattice is compared in RestartReadLastFrame. */
static const char *const model_options[] = {"-cloth_size", "-cloth_shape", "-cloth_outline", "-cloth_fabric", "-cloth_model", "-cloth_density", "-cloth_stretch", "-cloth_shear", "-cloth_bend", "-cloth_bend_table", "-cloth_bend_table_samples", NULL};

/* One value of an option: a boolean's spellings as one, numbers by value. */
static PetscBool SameValue(const char a[], const char b[])
{
  static const char *const yes[] = {"", "1", "true", "yes", "on"}, *const no[] = {"0", "false", "no", "off"};
  int ya = 0, yb = 0, na = 0, nb = 0;

  for (size_t k = 0; k < sizeof yes / sizeof yes[0]; k++) ya |= !strcasecmp(a, yes[k]), yb |= !strcasecmp(b, yes[k]);
  for (size_t k = 0; k < sizeof no / sizeof no[0]; k++) na |= !strcasecmp(a, no[k]), nb |= !strcasecmp(b, no[k]);
  if ((ya && yb) || (na && nb)) return PETSC_TRUE;
  while (*a || *b) { /* comma-separated lists, value by value */
    char  *ea, *eb;
    size_t la = strcspn(a, ","), lb = strcspn(b, ",");
    double x = strtod(a, &ea), y = strtod(b, &eb);
    if (ea == a + la && eb == b + lb && la && lb) {
      if (!(x == y || PetscAbsReal((PetscReal) (x - y)) <= 1e-12 * PetscMax(PetscAbsReal((PetscReal) x), PetscAbsReal((PetscReal) y)))) return PETSC_FALSE;
    } else if (la != lb || strncasecmp(a, b, la))
      return PETSC_FALSE;
    a += la + (a[la] == ',');
    b += lb + (b[lb] == ',');
  }
  return PETSC_TRUE;
}

/* Is a value given now the one the file's run had by default, as its start-up numbers
 * say? (-cloth_size 1 restates a default 1 m square.) */
static PetscBool SameAsFileDefault(const char name[], const char now[], const RestartInfo *r)
{
  static const struct {
    const char *name;
    int         first, count;
  } numbers[] = {{"-cloth_size", 0, 2}, {"-cloth_density", 2, 1}, {"-cloth_shear", 3, 1}, {"-cloth_stretch", 4, 2}};

  if (!strcmp(name, "-cloth_model")) return (PetscBool) (r->model[0] && !strcasecmp(now, r->model));
  for (size_t k = 0; k < sizeof numbers / sizeof numbers[0]; k++) {
    double      given[2];
    int         n = 0;
    const char *p = now;
    char       *end;
    if (strcmp(name, numbers[k].name)) continue;
    while (n < 2) {
      given[n++] = strtod(p, &end);
      if (end == p || (*end && *end != ',')) return PETSC_FALSE;
      if (!*end) break;
      p = end + 1;
    }
    if (*end) return PETSC_FALSE; /* more values than the option takes */
    for (int i = 0; i < numbers[k].count; i++) {
      const int    j = numbers[k].first + i;
      const double g = given[n == 1 ? 0 : i];
      if (!r->has_value[j] || !(PetscAbsReal((PetscReal) (g - r->values[j])) <= 1e-12 * PetscAbsReal((PetscReal) r->values[j]))) return PETSC_FALSE;
    }
    return (PetscBool) (n <= numbers[k].count);
  }
  return PETSC_FALSE;
}

/* Refuse a command line that gives the restarted cloth another material or geometry. */
static PetscErrorCode RestartCheckModel(MPI_Comm comm, const char file[], const char stored_options[], const RestartInfo *r)
{
  PetscOptions stored;

  PetscFunctionBeginUser;
  PetscCall(PetscOptionsCreate(&stored));
  PetscCall(PetscOptionsInsertString(stored, stored_options));
  for (const char *const *name = model_options; *name; name++) {
    char      was[1024] = "", now[1024] = "", why[1200] = "";
    PetscBool was_set, now_set;
    /* raw: the values as given, stored and now, are compared before any component reads them */
    PetscCall(PetscOptionsGetString(stored, NULL, *name, was, sizeof was, &was_set));
    PetscCall(PetscOptionsGetString(NULL, NULL, *name, now, sizeof now, &now_set));
    if (!now_set || (was_set && SameValue(was, now)) || (!was_set && SameAsFileDefault(*name, now, r))) continue;
    if (was_set)
      PetscCall(PetscSNPrintf(why, sizeof why, "its run had %s %s", *name, was));
    else {
      char value[128] = "";
      for (int k = 0; k < 6; k++) /* the default's value, where the file's start-up numbers give it */
        if (r->has_value[k] && !strncmp(value_names[k], *name + 7, 4)) (void) snprintf(value + strlen(value), sizeof value - strlen(value), "%s%g", value[0] ? "," : " ", r->values[k]);
      if (!strcmp(*name, "-cloth_model") && r->model[0]) (void) snprintf(value, sizeof value, " %s", r->model);
      PetscCall(PetscSNPrintf(why, sizeof why, "its run had the default%s%s", value[0] ? ", " : "", value[0] ? *name : ""));
      if (value[0]) PetscCall(PetscStrlcat(why, value, sizeof why));
    }
    PetscCall(PetscOptionsDestroy(&stored));
    SETERRQ(comm, PETSC_ERR_USER_INPUT, "Cannot restart from %s with %s %s: %s, and its frames hold that cloth (a restart keeps the cloth's material and geometry: leave %s out, or start a new run)", file, *name, now, why, *name);
  }
  PetscCall(PetscOptionsDestroy(&stored));
  PetscFunctionReturn(0);
}

/* The options stored in the file into the options database under the command
 * line's own (the command line wins). */
static PetscErrorCode RestartInsertOptions(MPI_Comm comm, const char file[])
{
  PetscMPIInt rank;
  PetscInt    len = 0;
  RestartInfo r;
  int         argc;
  char      **argv;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(DrapeRegisterInput(file, "restart file"));
  PetscCall(RestartCheck(comm, file, &r));
  if (!rank) {
    size_t n;
    PetscCall(PetscStrlen(r.options, &n));
    len = (PetscInt) n;
  }
  PetscCallMPI(MPI_Bcast(&len, 1, MPIU_INT, 0, comm));
  if (rank) PetscCall(PetscCalloc1(len + 1, &r.options));
  PetscCallMPI(MPI_Bcast(r.options, (PetscMPIInt) len + 1, MPI_CHAR, 0, comm));
  /* the stored run's options, less those PETSc acts on as it starts (memory
   * tracing, logging, debugging: too late now, and -options_left would call them
   * unused) and its -output_file (the frames go on in the file restarted from, the
   * output's default: a copy's options name the original, which a new run would
   * truncate), then the command line again: it wins. The database is written here
   * because the stored options are every component's, read by their SetFromOptions. */
  PetscCall(PetscOptionsInsertString(NULL, r.options));
  for (size_t k = 0; k < sizeof(startup_only) / sizeof(startup_only[0]); k++) PetscCall(PetscOptionsClearValue(NULL, startup_only[k]));
  PetscCall(PetscOptionsClearValue(NULL, "-output_file"));
  PetscCall(PetscGetArgs(&argc, &argv));
  PetscCall(PetscOptionsInsert(NULL, &argc, &argv, NULL));
  for (size_t k = 0; k < sizeof(startup_only) / sizeof(startup_only[0]); k++) { /* raw: marks those given now used (PetscInitialize() used them; no component reads them) */
    PetscBool given;
    PetscCall(PetscOptionsHasName(NULL, NULL, startup_only[k], &given));
  }
  {
    PetscErrorCode ierr;
    PetscCallMPI(MPI_Bcast(r.values, 6, MPI_DOUBLE, 0, comm));
    PetscCallMPI(MPI_Bcast(r.has_value, 6, MPI_INT, 0, comm));
    PetscCallMPI(MPI_Bcast(r.model, sizeof r.model, MPI_CHAR, 0, comm));
    ierr = RestartCheckModel(comm, file, r.options, &r);
    if (ierr) PetscCall(RestartInfoDestroy(&r));
    PetscCall(ierr);
  }
  PetscCall(RestartInfoDestroy(&r));
  PetscFunctionReturn(0);
}

typedef struct {
  const char  *file;
  Cloth        cloth;
  PetscScalar *x, *v;
  PetscInt     frame;
} RestartFrame;

static PetscErrorCode RestartReadFrame(void *ctx)
{
  RestartFrame *f = (RestartFrame *) ctx;
  PetscViewer   viewer;
  DM            da;
  Vec           X;

  PetscFunctionBeginUser;
  PetscCall(ClothGetDM(f->cloth, &da));
  PetscCall(DMCreateGlobalVector(da, &X));
  PetscCall(PetscViewerHDF5Open(PetscObjectComm((PetscObject) da), f->file, FILE_MODE_READ, &viewer));
  PetscCall(PetscViewerHDF5PushTimestepping(viewer));
  PetscCall(PetscViewerHDF5SetTimestep(viewer, f->frame));
  for (PetscInt k = 0; k < 2; k++) {
    PetscCall(PetscObjectSetName((PetscObject) X, k ? "velocity" : "position"));
    PetscCall(VecLoad(X, viewer));
    PetscCall(ClothFromDMDA(f->cloth, X, k ? f->v : f->x));
  }
  PetscCall(PetscViewerHDF5PopTimestepping(viewer));
  PetscCall(PetscViewerDestroy(&viewer));
  PetscCall(VecDestroy(&X));
  PetscFunctionReturn(0);
}

/* The last complete frame into x, v (owned order), with its time and step, and the
 * times of all complete frames (caller frees). */
static PetscErrorCode RestartReadLastFrame(MPI_Comm comm, const char file[], Cloth cloth, PetscScalar *x, PetscScalar *v, PetscReal *t, PetscInt *step, PetscInt *nframes, PetscReal **times)
{
  PetscMPIInt  rank;
  PetscInt     sizes[3];
  ClothInfo    info;
  RestartInfo  r;
  RestartFrame frame = {.file = file, .cloth = cloth, .x = x, .v = v};
  char         what[PETSC_MAX_PATH_LEN + 64];
  PetscBool    finite = PETSC_TRUE;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(ClothGetInfo(cloth, &info));
  PetscCall(RestartCheck(comm, file, &r));
  sizes[0] = r.nframes;
  sizes[1] = r.Mx;
  sizes[2] = r.My;
  PetscCallMPI(MPI_Bcast(sizes, 3, MPIU_INT, 0, comm));
  PetscCallMPI(MPI_Bcast(&r.step, 1, MPIU_REAL, 0, comm));
  if (sizes[1] != info.Mx || sizes[2] != info.My) PetscCall(RestartInfoDestroy(&r));
  PetscCheck(sizes[1] == info.Mx && sizes[2] == info.My, comm, PETSC_ERR_USER_INPUT, "Cannot restart from %s: its lattice is %" PetscInt_FMT " x %" PetscInt_FMT ", this run's is %" PetscInt_FMT " x %" PetscInt_FMT, file, sizes[1], sizes[2], info.Mx,
             info.My);
  if (rank) PetscCall(PetscMalloc1(sizes[0], &r.times));
  PetscCallMPI(MPI_Bcast(r.times, (PetscMPIInt) sizes[0], MPIU_REAL, 0, comm));
  frame.frame = sizes[0] - 1;
  PetscCall(PetscSNPrintf(what, sizeof what, "Cannot restart from %s: its last frame cannot be read", file));
  PetscCall(DrapeCollectiveRead(comm, RestartReadFrame, &frame, what));
  for (PetscInt k = 0; k < 3 * info.nowned; k++) finite = (PetscBool) (finite && !PetscIsInfOrNanScalar(x[k]) && !PetscIsInfOrNanScalar(v[k]));
  PetscCall(MPIU_Allreduce(MPI_IN_PLACE, &finite, 1, MPIU_BOOL, MPI_LAND, comm));
  if (!finite) PetscCall(RestartInfoDestroy(&r));
  PetscCheck(finite, comm, PETSC_ERR_FILE_UNEXPECTED, "Cannot restart from %s: its last frame holds positions or velocities that are not finite", file);
  *nframes = sizes[0];
  *t       = r.times[sizes[0] - 1];
  *step    = (PetscInt) r.step;
  *times   = r.times; /* the caller's now */
  r.times  = NULL;
  PetscCall(RestartInfoDestroy(&r));
  PetscFunctionReturn(0);
}

struct _p_Restart {
  MPI_Comm  comm;
  char      file[PETSC_MAX_PATH_LEN]; /* -restart, as PETSc's viewer opens it */
  PetscBool enabled;
  PetscReal t;    /* time of the frame restarted from */
  PetscInt  step; /* its step */
};

PetscErrorCode RestartCreate(MPI_Comm comm, Restart *restart)
{
  PetscFunctionBeginUser;
  PetscCall(PetscNew(restart));
  (*restart)->comm = comm;
  PetscFunctionReturn(0);
}

PetscErrorCode RestartDestroy(Restart *restart)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree(*restart));
  PetscFunctionReturn(0);
}

PetscErrorCode RestartSetFromOptions(Restart r, Output output)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(r->comm, NULL, "Restart", "Restart");
  PetscCall(PetscOptionsString("-restart", "Continue the run stored in this drape HDF5 file from its last complete frame (its options apply; the command line overrides them)", "RestartLoad", r->file, r->file, sizeof r->file, &r->enabled));
  PetscOptionsEnd();
  if (!r->enabled) PetscFunctionReturn(0);
  PetscCall(DrapeCheckPathLength(r->comm, "-restart", r->file, sizeof r->file));
  PetscCheck(r->file[0], r->comm, PETSC_ERR_USER_INPUT, "-restart needs a file name");
  PetscCall(DrapeFileName("-restart", r->file, r->file, sizeof r->file)); /* the file PETSc's viewer reads */
  PetscCall(DrapeCheckInputPath(r->comm, "-restart", r->file, "restart file"));
  PetscCall(RestartInsertOptions(r->comm, r->file));
  PetscCall(OutputSetDefaultFile(output, r->file));
  PetscFunctionReturn(0);
}

PetscErrorCode RestartEnabled(Restart r, PetscBool *enabled)
{
  PetscFunctionBeginUser;
  *enabled = r->enabled;
  PetscFunctionReturn(0);
}

PetscErrorCode RestartSupported(Cloth cloth, PetscBool *supported)
{
  ClothInfo info;

  PetscFunctionBeginUser;
  PetscCall(ClothGetInfo(cloth, &info));
  *supported = (PetscBool) !(info.hysteresis[0] > 0 || info.hysteresis[1] > 0);
  PetscFunctionReturn(0);
}

PetscErrorCode RestartLoad(Restart r, Cloth cloth, Output output, PetscScalar *x, PetscScalar *v)
{
  PetscInt   nframes;
  PetscReal *times;
  PetscBool  supported;

  PetscFunctionBeginUser;
  if (!r->enabled) PetscFunctionReturn(0);
  PetscCall(RestartSupported(cloth, &supported));
  PetscCheck(supported, r->comm, PETSC_ERR_USER_INPUT, "-restart cannot continue a run with -cloth_bend_hysteresis: the frames hold positions and velocities, not the plastic curvature that the bending friction remembers; run it from the start");
  PetscCall(RestartReadLastFrame(r->comm, r->file, cloth, x, v, &r->t, &r->step, &nframes, &times));
  PetscCall(OutputSetAppend(output, r->file, nframes, times));
  PetscCall(PetscFree(times));
  PetscFunctionReturn(0);
}

PetscErrorCode RestartGetStart(Restart r, PetscReal *t, PetscInt *step)
{
  PetscFunctionBeginUser;
  if (t) *t = r->t;
  if (step) *step = r->step;
  PetscFunctionReturn(0);
}

PetscErrorCode RestartViewStop(Restart r, Cloth cloth, Output output, PetscViewer viewer, const char signal[], PetscInt step, PetscReal t)
{
  const char *file;
  PetscBool   supported;

  PetscFunctionBeginUser;
  PetscCall(OutputGetFileName(output, &file));
  PetscCall(RestartSupported(cloth, &supported));
  PetscCall(PetscViewerASCIIPrintf(viewer, "Stopped by %s after step %" PetscInt_FMT " at t = %g s; ", signal, step, (double) t));
  if (file && !supported)
    PetscCall(PetscViewerASCIIPrintf(viewer, "the frames so far are in %s, but -restart cannot continue a run with -cloth_bend_hysteresis (the frames do not hold the bending friction's plastic curvature): run it again from the start\n", file));
  else if (file)
    PetscCall(PetscViewerASCIIPrintf(viewer, "the state is the last frame of %s: continue with -restart %s\n", file, file));
  else
    PetscCall(PetscViewerASCIIPrintf(viewer, "without -output_file there is nothing to restart from\n"));
  PetscFunctionReturn(0);
}
