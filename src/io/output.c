/* HDF5 frames through PetscViewerHDF5, in natural lattice order whatever the
 * number of ranks, and an XDMF index beside the file for ParaView.
 *
 * File layout (t = frame index):
 *   /position, /velocity   [t][My][Mx][3]   (m, m/s)
 *   /time, /step, /energy_kinetic, /energy_gravity, /energy_stretch,
 *   /energy_shear, /energy_bend, /contact_depth, /contact_count   [t][1]
 *                                           (s, -, J, m, -)
 *   /contact_force   [t][3]  mean force of the solid on the cloth since the
 *                            previous frame (N; 0 in the first frame)
 *   /strain_max      [t][1]  largest stretch of a lattice edge, (l - L)/L
 *   /solid_triangles  [9 x triangles]       (m) the solid's mesh, for pictures
 *   /active          [My x Mx]  1 for the particles of the cloth, 0 for the lattice
 *                    points outside its outline (they never move), natural order
 *   attributes of /: options (as given) and the run's report (report.h): the
 *                    start-up numbers when the file is opened (drape_version,
 *                    lattice, material, limits), the summary at the end.
 * /time is written last in each frame, so its length counts the complete frames
 * (but for a last entry a killed run extended and never wrote: 0 after a later
 * time; the readers drop it);
 * every frame is flushed, so a run killed later leaves them readable. The XDMF
 * index lists every frame at the end of the run; while it runs, it is made again at
 * most once a second of wall time (OutputRefreshXDMF), so a run killed leaves an
 * index of the frames of all but its last second (the HDF5 file has them all). */
#include <output.h>
#include <drape.h>
#include <petscviewerhdf5.h>
#include <errno.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#define NSCALARS 11
/* Seconds of wall time between rewrites of the XDMF index while frames are written (OutputRefreshXDMF) */
#define OUTPUT_XDMF_WAIT 1.0
static const char *const scalar_names[NSCALARS] = {"step", "energy_kinetic", "energy_gravity", "energy_stretch", "energy_shear", "energy_bend", "contact_depth", "contact_count", "contact_force", "strain_max", "time"};
static const PetscInt    scalar_sizes[NSCALARS] = {1, 1, 1, 1, 1, 1, 1, 1, 3, 1, 1};

struct _p_Output {
  MPI_Comm       comm;
  char           given[PETSC_MAX_PATH_LEN];                          /* -output_file as typed              */
  char           file[PETSC_MAX_PATH_LEN], xdmf[PETSC_MAX_PATH_LEN]; /* the files written (DrapeFileName) */
  PetscBool      enabled;
  PetscReal      interval, next_time;
  PetscInt       every, nframes, last_step, Mx, My, nalloc;
  PetscInt       xdmf_frames; /* frames the XDMF index on disk lists */
  PetscLogDouble xdmf_wall;   /* when it was written (PetscTime) */
  PetscReal     *times;
  PetscBool      append; /* continue an existing file (restart) */
  PetscViewer    viewer;
  Vec            X, V, scalars[NSCALARS];
};

PetscErrorCode OutputCreate(MPI_Comm comm, Output *out)
{
  Output o;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&o));
  o->comm      = comm;
  o->interval  = 1.0 / 30;
  o->last_step = -1;
  *out         = o;
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL); /* a failed call is reported in one sentence, not HDF5's error stack */
  PetscFunctionReturn(0);
}

/* Can this rank write -output_file and its XDMF index, without overwriting anything
 * the run reads? A directory that exists and takes a new file (a probe file is made
 * and removed: read-only and pseudo file systems refuse it), an output that is a
 * regular file if it exists, a name MPI-IO can extend, files compared by identity. */
static PetscErrorCode OutputCheckFile(void *ctx)
{
  Output      o = (Output) ctx;
  char        dir[PETSC_MAX_PATH_LEN], probe[PETSC_MAX_PATH_LEN + 64], tmp[PETSC_MAX_PATH_LEN + 8];
  const char *base = strrchr(o->file, '/') ? strrchr(o->file, '/') + 1 : o->file;
  size_t      len;
  PetscBool   isdir, same;
  PetscMPIInt rank;
  FILE       *fp;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(o->comm, &rank));
  PetscCall(PetscStrlen(base, &len));
  PetscCheck(len > 0, PETSC_COMM_SELF, PETSC_ERR_USER_INPUT, "-output_file %s names a directory, not a file", o->file);
  PetscCheck(len <= 200, PETSC_COMM_SELF, PETSC_ERR_USER_INPUT, "The name of -output_file, %s, is longer than 200 characters (not counting its directory): MPI-IO names files after it and would go beyond the 255 a file system takes", base);
  PetscCall(PetscStrncpy(dir, o->file, sizeof dir));
  if (base == o->file)
    PetscCall(PetscStrcpy(dir, "."));
  else
    dir[base - o->file - 1] = 0;
  if (!dir[0]) PetscCall(PetscStrcpy(dir, "/"));
  PetscCall(PetscTestDirectory(dir, 'x', &isdir));
  PetscCheck(isdir, PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write -output_file %s: directory %s does not exist or is not writable", o->file, dir);
  PetscCall(PetscTestDirectory(o->file, 'r', &isdir));
  PetscCheck(!isdir, PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write -output_file %s: it is a directory", o->file);
  {
    struct stat st;
    if (!stat(o->file, &st)) {
      PetscCheck(S_ISREG(st.st_mode), PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write -output_file %s: it exists and is not a regular file (a device, pipe or socket)", o->file);
      PetscCheck(!access(o->file, W_OK), PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write -output_file %s: it exists and is not writable", o->file);
    }
  }
  {
    PetscLogDouble now; /* a name no other run on any node picks at this moment */
    PetscCall(PetscTime(&now));
    PetscCall(PetscSNPrintf(probe, sizeof probe, "%s/.drape-probe-%d-%d-%.0f", dir, (int) getpid(), (int) rank, 1e6 * now));
  }
  fp = fopen(probe, "wbx");
  PetscCheck(fp, PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write -output_file %s: directory %s does not exist or is not writable (%s)", o->file, dir, strerror(errno));
  {
    int failed = fputc('\n', fp) == EOF;
    failed     = fclose(fp) || failed;
    (void) remove(probe);
    PetscCheck(!failed, PETSC_COMM_SELF, PETSC_ERR_FILE_WRITE, "Cannot write -output_file %s: the file system of %s takes no data (full?)", o->file, dir);
  }
  PetscCall(DrapeCheckOutputPath("-output_file", o->file)); /* /dev is writable to root */
  /* the XDMF index, written to a temporary file renamed over it after each frame: a
   * directory (or a device) of either name would fail only after the HDF5 file had
   * been truncated and its first frame written */
  PetscCall(PetscSNPrintf(tmp, sizeof tmp, "%s.tmp", o->xdmf));
  for (int k = 0; k < 2; k++) {
    const char *path = k ? tmp : o->xdmf, *what = k ? "the temporary file of its XDMF index" : "its XDMF index";
    struct stat st;
    if (stat(path, &st)) continue;
    PetscCheck(!S_ISDIR(st.st_mode), PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write -output_file %s: %s, %s, is a directory; remove it, or choose another -output_file", o->file, what, path);
    PetscCheck(S_ISREG(st.st_mode), PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write -output_file %s: %s, %s, exists and is not a regular file (a device, pipe or socket); remove it, or choose another -output_file", o->file, what, path);
    PetscCheck(!k || !access(path, W_OK), PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write -output_file %s: %s, %s, exists and is not writable; remove it, or choose another -output_file", o->file, what, path);
  }
  /* nothing the run reads may be overwritten (a restart continues its own file) */
  PetscCall(DrapeSameFile(o->file, o->xdmf, &same));
  PetscCheck(!same, PETSC_COMM_SELF, PETSC_ERR_USER_INPUT, "-output_file %s would be overwritten by its own XDMF index %s: give the HDF5 file another extension, e.g. .h5", o->file, o->xdmf);
  PetscCall(DrapeSameFile(o->file, tmp, &same));
  PetscCheck(!same, PETSC_COMM_SELF, PETSC_ERR_USER_INPUT, "-output_file %s would be overwritten by the temporary file of its XDMF index: give the HDF5 file another name, e.g. run.h5", o->file);
  {
    char option[2 * PETSC_MAX_PATH_LEN + 64] = "-output_file";
    if (strcmp(o->given, o->file)) PetscCall(PetscSNPrintf(option, sizeof option, "-output_file %s, which PETSc writes as %s,", o->given, o->file));
    PetscCall(DrapeCheckNotInput(option, o->file, "restart file"));
  }
  PetscCall(DrapeCheckNotInput("The XDMF index of -output_file", o->xdmf, NULL));
  PetscCall(DrapeCheckNotInput("The XDMF index of -output_file", tmp, NULL));
  PetscFunctionReturn(0);
}

PetscErrorCode OutputSetFromOptions(Output o)
{
  PetscBool flg;

  PetscFunctionBeginUser;
  PetscOptionsBegin(o->comm, NULL, "Output", "Output");
  PetscCall(PetscOptionsString("-output_file", "HDF5 file for the frames (nothing is written without it)", "OutputSetFromOptions", o->file, o->file, sizeof o->file, &flg));
  o->enabled = (PetscBool) (o->enabled || flg); /* or OutputSetDefaultFile's */
  PetscCall(PetscOptionsReal("-output_interval", "Simulated time between frames (s); 0: use -output_steps", "OutputSetFromOptions", o->interval, &o->interval, NULL));
  PetscCall(PetscOptionsInt("-output_steps", "Steps between frames (0: use -output_interval)", "OutputSetFromOptions", o->every, &o->every, &flg));
  PetscOptionsEnd();
  if (flg && o->every > 0) o->interval = 0;
  PetscCall(DrapeCheckReal(o->comm, "-output_interval", 1, &o->interval, 0, 1e6, "s"));
  PetscCall(DrapeCheckInt(o->comm, "-output_steps", o->every, 0, PETSC_MAX_INT));
  if (o->enabled) {
    char *slash, *dot;
    PetscCheck(o->file[0], o->comm, PETSC_ERR_USER_INPUT, "-output_file needs a file name, e.g. -output_file run.h5");
    PetscCall(DrapeCheckPathLength(o->comm, "-output_file", o->file, sizeof o->file - 16));
    /* PETSc's viewer opens the name with ${HOSTNAME}, ${USERNAME}, ... replaced: every
     * check below, and the XDMF index, are on the file it opens */
    PetscCall(PetscStrncpy(o->given, o->file, sizeof o->given));
    PetscCall(DrapeFileName("-output_file", o->given, o->file, sizeof o->file));
    PetscCall(DrapeCheckPathLength(o->comm, "-output_file", o->file, sizeof o->file - 16));
    PetscCall(PetscStrncpy(o->xdmf, o->file, sizeof o->xdmf));
    dot   = strrchr(o->xdmf, '.');
    slash = strrchr(o->xdmf, '/');
    if (dot && (!slash || dot > slash)) *dot = 0;
    PetscCall(PetscStrlcat(o->xdmf, ".xmf", sizeof o->xdmf));
    /* on every rank: a node-local directory missing on one rank would hang MPI-IO */
    PetscCall(DrapeCollective(o->comm, OutputCheckFile, o));
  }
  PetscFunctionReturn(0);
}

/* The next frame time after a frame at t: the first multiple of the interval beyond
 * it, computed, not counted up to (a tiny interval or a huge t would never end). */
static PetscErrorCode OutputScheduleAfter(Output o, PetscReal t)
{
  PetscFunctionBeginUser;
  o->next_time = 0;
  if (o->interval > 0) o->next_time = (PetscFloorReal(t / o->interval + 1e-9) + 1) * o->interval;
  PetscFunctionReturn(0);
}

PetscErrorCode OutputSetAppend(Output o, const char file[], PetscInt nframes, const PetscReal times[])
{
  PetscBool same;

  PetscFunctionBeginUser;
  if (!o->enabled) PetscFunctionReturn(0);
  PetscCall(DrapeSameFile(file, o->file, &same)); /* by identity: ./r.h5 is r.h5 */
  if (!same) PetscFunctionReturn(0);
  o->append  = PETSC_TRUE;
  o->nalloc  = nframes + 64;
  o->nframes = nframes;
  PetscCall(PetscFree(o->times));
  PetscCall(PetscMalloc1(o->nalloc, &o->times));
  PetscCall(PetscArraycpy(o->times, times, nframes));
  PetscCall(OutputScheduleAfter(o, times[nframes - 1]));
  PetscFunctionReturn(0);
}

PetscErrorCode OutputSetDefaultFile(Output o, const char file[])
{
  PetscFunctionBeginUser;
  PetscCall(PetscStrncpy(o->file, file, sizeof o->file));
  o->enabled = PETSC_TRUE;
  PetscFunctionReturn(0);
}

PetscErrorCode OutputGetFileName(Output o, const char **file)
{
  PetscFunctionBeginUser;
  *file = o->enabled ? o->given : NULL;
  PetscFunctionReturn(0);
}

PetscErrorCode OutputEnabled(Output o, PetscBool *enabled)
{
  PetscFunctionBeginUser;
  *enabled = o->enabled;
  PetscFunctionReturn(0);
}

PetscErrorCode OutputLastStep(Output o, PetscInt *step)
{
  PetscFunctionBeginUser;
  *step = o->last_step;
  PetscFunctionReturn(0);
}

typedef struct {
  Output    o;
  ClothInfo info;
  Cloth     cloth;
  Solid     solid;
} OutputOpenContext;

/* Create (or, for a restart, reopen) the file and write what describes the run. */
static PetscErrorCode OutputCreateFile(void *ctx)
{
  OutputOpenContext *c = (OutputOpenContext *) ctx;
  Output             o = c->o;
  char              *given;
  PetscMPIInt        rank;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(o->comm, &rank));
  if (o->append) {
    /* a restart continues its own file: frames and attributes are already there */
    PetscCall(PetscViewerHDF5Open(o->comm, o->file, FILE_MODE_APPEND, &o->viewer));
    PetscCall(PetscViewerHDF5SetCollective(o->viewer, PETSC_TRUE));
    PetscCall(PetscViewerHDF5PushTimestepping(o->viewer));
    PetscFunctionReturn(0);
  }
  PetscCall(PetscViewerHDF5Open(o->comm, o->file, FILE_MODE_WRITE, &o->viewer));
  PetscCall(PetscViewerHDF5SetCollective(o->viewer, PETSC_TRUE)); /* collective MPI-IO */
  PetscCall(PetscOptionsGetAll(NULL, &given));
  PetscCall(PetscViewerHDF5WriteAttribute(o->viewer, "/", "options", PETSC_STRING, given));
  PetscCall(PetscFree(given));
  {
    PetscInt   ntri;
    PetscReal *xyz;
    PetscCall(SolidGetTriangles(c->solid, &ntri, &xyz));
    if (ntri) {
      Vec          T;
      PetscScalar *a;
      PetscCall(VecCreateMPI(o->comm, rank ? 0 : 9 * ntri, 9 * ntri, &T));
      PetscCall(PetscObjectSetName((PetscObject) T, "solid_triangles"));
      PetscCall(VecGetArray(T, &a));
      if (!rank) PetscCall(PetscArraycpy(a, xyz, 9 * ntri));
      PetscCall(VecRestoreArray(T, &a));
      PetscCall(VecView(T, o->viewer));
      PetscCall(VecDestroy(&T));
    }
    PetscCall(PetscFree(xyz));
  }
  {
    /* the cloth's own particles, so that a reader need not redo the cut of the outline:
     * each rank fills a contiguous range of the natural order (PETSc's split), so no
     * rank holds the whole lattice's flags */
    Vec          A;
    PetscScalar *a;
    PetscInt     lo, hi;
    PetscCall(VecCreateMPI(o->comm, PETSC_DECIDE, o->Mx * o->My, &A));
    PetscCall(PetscObjectSetName((PetscObject) A, "active"));
    PetscCall(VecGetOwnershipRange(A, &lo, &hi));
    PetscCall(VecGetArray(A, &a));
    for (PetscInt n = lo; n < hi; n++) a[n - lo] = ClothIsActive(c->cloth, n % o->Mx, n / o->Mx) ? 1.0 : 0.0;
    PetscCall(VecRestoreArray(A, &a));
    PetscCall(VecView(A, o->viewer));
    PetscCall(VecDestroy(&A));
  }
  PetscCall(PetscViewerHDF5PushTimestepping(o->viewer));
  PetscFunctionReturn(0);
}

PetscErrorCode OutputOpen(Output o, Cloth cloth, Solid solid)
{
  DM                da;
  PetscMPIInt       rank;
  OutputOpenContext ctx = {.o = o, .cloth = cloth, .solid = solid};
  char              what[PETSC_MAX_PATH_LEN + 64];

  PetscFunctionBeginUser;
  if (!o->enabled) PetscFunctionReturn(0);
  PetscCall(ClothGetDM(cloth, &da));
  PetscCall(ClothGetInfo(cloth, &ctx.info));
  o->Mx = ctx.info.Mx;
  o->My = ctx.info.My;
  PetscCall(DMCreateGlobalVector(da, &o->X));
  PetscCall(DMCreateGlobalVector(da, &o->V));
  PetscCall(PetscObjectSetName((PetscObject) o->X, "position"));
  PetscCall(PetscObjectSetName((PetscObject) o->V, "velocity"));
  PetscCallMPI(MPI_Comm_rank(o->comm, &rank));
  for (PetscInt k = 0; k < NSCALARS; k++) {
    PetscCall(VecCreateMPI(o->comm, rank ? 0 : scalar_sizes[k], scalar_sizes[k], &o->scalars[k]));
    PetscCall(PetscObjectSetName((PetscObject) o->scalars[k], scalar_names[k]));
  }
  PetscCall(PetscSNPrintf(what, sizeof what, "Cannot %s -output_file %s", o->append ? "reopen" : "create", o->file));
  PetscCall(DrapeCollectiveWrite(o->comm, OutputCreateFile, &ctx, what));
  PetscFunctionReturn(0);
}

PetscErrorCode OutputFrameDue(Output o, PetscInt step, PetscReal t, PetscBool *due)
{
  PetscFunctionBeginUser;
  *due = PETSC_FALSE;
  if (!o->enabled) PetscFunctionReturn(0);
  if (o->nframes == 0)
    *due = PETSC_TRUE;
  else if (o->every > 0)
    *due = (PetscBool) (step % o->every == 0);
  else if (o->interval > 0)
    *due = (PetscBool) (t >= o->next_time - 1e-9 * o->interval);
  PetscFunctionReturn(0);
}

/* Rewrite the XDMF index (rank 0, through a temporary file and a rename, so a
 * reader never sees half of it). */
static PetscErrorCode OutputWriteXDMF(Output o)
{
  char        tmp[PETSC_MAX_PATH_LEN + 8];
  const char *h5 = strrchr(o->file, '/') ? strrchr(o->file, '/') + 1 : o->file;
  FILE       *fp;
  PetscMPIInt rank;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(o->comm, &rank));
  if (rank) PetscFunctionReturn(0);
  PetscCall(PetscSNPrintf(tmp, sizeof tmp, "%s.tmp", o->xdmf));
  fp = fopen(tmp, "w"); /* not PetscFOpen: it would replace ${...} and '\\' in the name again */
  PetscCheck(fp, PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot open %s: %s", tmp, strerror(errno));
  PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"2.0\">\n <Domain>\n  <Grid Name=\"cloth\" GridType=\"Collection\" CollectionType=\"Temporal\">\n"));
  for (PetscInt k = 0; k < o->nframes; k++) {
    PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, "   <Grid Name=\"frame %" PetscInt_FMT "\" GridType=\"Uniform\">\n    <Time Value=\"%.10g\"/>\n", k, (double) o->times[k]));
    PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, "    <Topology TopologyType=\"2DSMesh\" Dimensions=\"%" PetscInt_FMT " %" PetscInt_FMT "\"/>\n", o->My, o->Mx));
    for (PetscInt f = 0; f < 2; f++) {
      const char *name = f ? "velocity" : "position";
      PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, f ? "    <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">\n" : "    <Geometry GeometryType=\"XYZ\">\n"));
      PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, "     <DataItem ItemType=\"HyperSlab\" Dimensions=\"%" PetscInt_FMT " %" PetscInt_FMT " 3\" Type=\"HyperSlab\">\n", o->My, o->Mx));
      PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, "      <DataItem Dimensions=\"3 4\" Format=\"XML\">%" PetscInt_FMT " 0 0 0 1 1 1 1 1 %" PetscInt_FMT " %" PetscInt_FMT " 3</DataItem>\n", k, o->My, o->Mx));
      PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, "      <DataItem Dimensions=\"%" PetscInt_FMT " %" PetscInt_FMT " %" PetscInt_FMT " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">%s:/%s</DataItem>\n", o->nframes, o->My, o->Mx, h5, name));
      PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, f ? "     </DataItem>\n    </Attribute>\n" : "     </DataItem>\n    </Geometry>\n"));
    }
    PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, "   </Grid>\n"));
  }
  PetscCall(PetscFPrintf(PETSC_COMM_SELF, fp, "  </Grid>\n </Domain>\n</Xdmf>\n"));
  PetscCheck(!fclose(fp), PETSC_COMM_SELF, PETSC_ERR_FILE_WRITE, "Cannot write %s: %s", tmp, strerror(errno));
  PetscCheck(rename(tmp, o->xdmf) == 0, PETSC_COMM_SELF, PETSC_ERR_FILE_WRITE, "Cannot rename %s to %s", tmp, o->xdmf);
  PetscFunctionReturn(0);
}

/* The XDMF index rewritten for the frames written since it was last, if any: now
 * (force), or when it is the first frame or a second of wall time has passed. The
 * index lists every frame and names the whole dataset's shape in each (a frame
 * changes every entry): made again at every frame it cost O(frames) a frame, 15 % of
 * a 21^2 drapebe run writing 250 frames (tests/test_self_contact.py's crease) and
 * more the longer the run. Not collective (rank 0 writes it). */
static PetscErrorCode OutputRefreshXDMF(Output o, PetscBool force)
{
  PetscLogDouble now;

  PetscFunctionBeginUser;
  if (o->xdmf_frames == o->nframes) PetscFunctionReturn(0);
  PetscCall(PetscTime(&now));
  if (!force && o->xdmf_frames > 0 && now - o->xdmf_wall < OUTPUT_XDMF_WAIT) PetscFunctionReturn(0);
  PetscCall(OutputWriteXDMF(o));
  o->xdmf_frames = o->nframes;
  o->xdmf_wall   = now;
  PetscFunctionReturn(0);
}

typedef struct {
  Output    o;
  PetscInt  step;
  PetscReal t, values[NSCALARS][3];
} OutputFrameContext;

/* Is there room for one more frame? A write that fails half-way leaves HDF5's
 * metadata in memory ahead of the file: when the library closes the file (at
 * MPI_Finalize at the latest) it writes them, and every frame is lost. So a frame
 * that would pass the process's file-size limit (ulimit -f; SIGXFSZ is ignored, so
 * a write that passes it anyway fails with EFBIG instead of killing drape) or not
 * fit on the file system is refused before it is written, while the file still
 * holds only complete, flushed frames. Room asked for: the frame's data twice
 * (chunks and their index) and 256 KiB for HDF5's metadata. */
static PetscErrorCode OutputCheckRoom(void *ctx)
{
  OutputFrameContext *c    = (OutputFrameContext *) ctx;
  Output              o    = c->o;
  const double        need = 2.0 * 48.0 * (double) o->Mx * (double) o->My + 262144.0;
  struct rlimit       limit;
  struct stat         st;
  struct statvfs      fs;
  char                dir[PETSC_MAX_PATH_LEN];
  const char         *slash = strrchr(o->file, '/');

  PetscFunctionBeginUser;
  if (stat(o->file, &st)) PetscFunctionReturn(0); /* the write's own error says why */
  if (!getrlimit(RLIMIT_FSIZE, &limit) && limit.rlim_cur != RLIM_INFINITY) {
    const double room = (double) limit.rlim_cur;
    PetscCheck((double) st.st_size + need <= room, PETSC_COMM_SELF, PETSC_ERR_FILE_WRITE,
               "the file would pass this process's file-size limit (ulimit -f: %.0f bytes; the file has %.0f and a frame needs up to %.0f more); the %" PetscInt_FMT
               " frames written are complete; raise the limit (ulimit -f unlimited), or write fewer frames (-output_interval, -output_steps)",
               room, (double) st.st_size, need, o->nframes);
    PetscCheck(1024.0 * (double) (o->nframes + 2) <= room, PETSC_COMM_SELF, PETSC_ERR_FILE_WRITE,
               "its XDMF index %s would pass this process's file-size limit (ulimit -f: %.0f bytes); the %" PetscInt_FMT " frames written are complete; raise the limit", o->xdmf, room, o->nframes);
  }
  PetscCall(PetscStrncpy(dir, o->file, sizeof dir));
  if (!slash)
    PetscCall(PetscStrcpy(dir, "."));
  else
    dir[slash == o->file ? 1 : slash - o->file] = 0;
  if (!statvfs(dir, &fs)) {
    const double avail = (double) fs.f_bavail * (double) fs.f_frsize;
    PetscCheck(avail >= need, PETSC_COMM_SELF, PETSC_ERR_FILE_WRITE,
               "the disk is full: the file system of %s has %.0f bytes free and a frame needs up to %.0f; the %" PetscInt_FMT " frames written are complete; free some space, or write fewer frames", dir, avail, need, o->nframes);
  }
  PetscFunctionReturn(0);
}

/* One frame into the file, flushed, and the XDMF index that lists it. */
static PetscErrorCode OutputWriteFrameFile(void *ctx)
{
  OutputFrameContext *c = (OutputFrameContext *) ctx;
  Output              o = c->o;
  PetscScalar        *a;
  hid_t               fid;

  PetscFunctionBeginUser;
  PetscCall(PetscViewerHDF5SetTimestep(o->viewer, o->nframes));
  PetscCall(VecView(o->X, o->viewer));
  PetscCall(VecView(o->V, o->viewer));
  for (PetscInt k = 0; k < NSCALARS; k++) {
    PetscInt nl;
    PetscCall(VecGetLocalSize(o->scalars[k], &nl));
    if (nl) {
      PetscCall(VecGetArray(o->scalars[k], &a));
      for (PetscInt d = 0; d < nl; d++) a[d] = c->values[k][d];
      PetscCall(VecRestoreArray(o->scalars[k], &a));
    }
    PetscCall(VecView(o->scalars[k], o->viewer));
  }
  PetscCall(PetscViewerHDF5GetFileId(o->viewer, &fid));
  PetscCheck(H5Fflush(fid, H5F_SCOPE_GLOBAL) >= 0, PETSC_COMM_SELF, PETSC_ERR_FILE_WRITE, "HDF5 cannot flush the frame to the file");
  if (o->nframes >= o->nalloc) {
    PetscReal *times;
    o->nalloc = 2 * o->nalloc + 64;
    PetscCall(PetscMalloc1(o->nalloc, &times));
    if (o->nframes) PetscCall(PetscArraycpy(times, o->times, o->nframes));
    PetscCall(PetscFree(o->times));
    o->times = times;
  }
  o->times[o->nframes++] = c->t;
  o->last_step           = c->step;
  PetscCall(OutputScheduleAfter(o, c->t));
  PetscCall(OutputRefreshXDMF(o, PETSC_FALSE));
  PetscFunctionReturn(0);
}

PetscErrorCode OutputWriteFrame(Output o, Cloth cloth, PetscInt step, PetscReal t, const PetscScalar *x, const PetscScalar *v, const ClothEnergies *en)
{
  OutputFrameContext ctx = {.o = o, .step = step, .t = t};
  char               what[PETSC_MAX_PATH_LEN + 64];

  PetscFunctionBeginUser;
  if (!o->enabled) PetscFunctionReturn(0);
  ctx.values[0][0] = (PetscReal) step;
  ctx.values[1][0] = en->kinetic;
  ctx.values[2][0] = en->gravity;
  ctx.values[3][0] = en->stretch;
  ctx.values[4][0] = en->shear;
  ctx.values[5][0] = en->bend;
  ctx.values[6][0] = en->contact_depth;
  ctx.values[7][0] = (PetscReal) en->contact_count;
  for (PetscInt d = 0; d < 3; d++) ctx.values[8][d] = en->contact_force[d];
  ctx.values[9][0]  = en->strain_max;
  ctx.values[10][0] = t;
  PetscCall(ClothToDMDA(cloth, x, o->X));
  PetscCall(ClothToDMDA(cloth, v, o->V));
  PetscCall(PetscSNPrintf(what, sizeof what, "Cannot write frame %" PetscInt_FMT " to -output_file %s", o->nframes, o->file));
  PetscCall(DrapeCollectiveWrite(o->comm, OutputCheckRoom, &ctx, what));
  PetscCall(PetscSNPrintf(what, sizeof what, "Cannot write frame %" PetscInt_FMT " to -output_file %s (is the disk full?)", o->nframes, o->file));
  PetscCall(DrapeCollectiveWrite(o->comm, OutputWriteFrameFile, &ctx, what));
  PetscFunctionReturn(0);
}

typedef struct {
  Output o;
  Report report;
} OutputReportContext;

static PetscErrorCode OutputWriteReportFile(void *ctx)
{
  OutputReportContext *c = (OutputReportContext *) ctx;
  PetscInt             n;
  hid_t                fid;

  PetscFunctionBeginUser;
  PetscCall(ReportGetSize(c->report, &n));
  for (PetscInt k = 0; k < n; k++) {
    const char   *name, *s;
    PetscDataType type;
    PetscReal     r;
    PetscInt      i;
    PetscBool     b;
    PetscCall(ReportGetEntry(c->report, k, &name, &type, &r, &i, &s));
    b = (PetscBool) (i != 0);
    if (type == PETSC_REAL && PetscAbsReal(r) >= PETSC_INFINITY) r = r > 0 ? (PetscReal) INFINITY : (PetscReal) -INFINITY; /* PETSc's infinity is finite */
    PetscCall(PetscViewerHDF5WriteAttribute(c->o->viewer, "/", name, type, type == PETSC_REAL ? (const void *) &r : type == PETSC_INT ? (const void *) &i : type == PETSC_BOOL ? (const void *) &b : (const void *) s));
  }
  PetscCall(PetscViewerHDF5GetFileId(c->o->viewer, &fid));
  PetscCheck(H5Fflush(fid, H5F_SCOPE_GLOBAL) >= 0, PETSC_COMM_SELF, PETSC_ERR_FILE_WRITE, "HDF5 cannot flush the file");
  PetscCall(OutputRefreshXDMF(c->o, PETSC_TRUE)); /* at the run's end every frame listed; at a restart's start the frames it continues (a killed run's index may lack its last second) */
  PetscFunctionReturn(0);
}

PetscErrorCode OutputWriteReport(Output o, Report report)
{
  OutputReportContext ctx = {.o = o, .report = report};
  char                what[PETSC_MAX_PATH_LEN + 64];

  PetscFunctionBeginUser;
  if (!o->enabled) PetscFunctionReturn(0);
  PetscCall(PetscSNPrintf(what, sizeof what, "Cannot write the run's report to -output_file %s", o->file));
  PetscCall(DrapeCollectiveWrite(o->comm, OutputWriteReportFile, &ctx, what));
  PetscFunctionReturn(0);
}

PetscErrorCode OutputDestroy(Output *out)
{
  Output o = *out;

  PetscFunctionBeginUser;
  if (!o) PetscFunctionReturn(0);
  PetscCall(PetscViewerDestroy(&o->viewer));
  PetscCall(VecDestroy(&o->X));
  PetscCall(VecDestroy(&o->V));
  for (PetscInt k = 0; k < NSCALARS; k++) PetscCall(VecDestroy(&o->scalars[k]));
  PetscCall(PetscFree(o->times));
  PetscCall(PetscFree(*out));
  PetscFunctionReturn(0);
}
