#define _XOPEN_SOURCE 700 /* lstat, readlink, realpath */
/* Program-wide set-up: log events and stages, the error handler, option checks,
 * options files, and the identity of the files drape reads and writes. */
#include <drape.h>
#include <ctype.h>
#include <errno.h>
#include <stdlib.h>
#include <strings.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

DrapeLog drape_log;

/* PETSc error classes that report a problem with the user's input or run (one
 * sentence is enough); anything else is a bug and keeps PETSc's traceback. */
static PetscBool IsUserError(PetscErrorCode n)
{
  switch (n) {
  case PETSC_ERR_USER_INPUT:
  case PETSC_ERR_USER:
  case PETSC_ERR_ARG_OUTOFRANGE:
  case PETSC_ERR_ARG_UNKNOWN_TYPE:
  case PETSC_ERR_ARG_WRONG:
  case PETSC_ERR_ARG_INCOMP:
  case PETSC_ERR_FILE_OPEN:
  case PETSC_ERR_FILE_READ:
  case PETSC_ERR_FILE_WRITE:
  case PETSC_ERR_FILE_UNEXPECTED:
  case PETSC_ERR_NOT_CONVERGED:
  case PETSC_ERR_SUP:
  case PETSC_ERR_MEM:
    return PETSC_TRUE;
  default:
    return PETSC_FALSE;
  }
}

/* The last error raised on this rank: printed by DrapeEndWithError, once per job. */
static PetscBool       error_is_user = PETSC_FALSE;
static char            error_message[1024];
static MPI_Comm        error_comm = MPI_COMM_NULL; /* the end-of-run agreement, apart from every other message */
static const PetscReal error_wait = 5;             /* s: how long failed ranks wait for the others to fail too   */

static PetscErrorCode DrapeErrorHandler(MPI_Comm comm, int line, const char *fun, const char *file, PetscErrorCode n, PetscErrorType p, const char *mess, void *ctx)
{
  if (p == PETSC_ERROR_INITIAL) {
    /* PETSc 3.18's PetscMallocAlign raises a failed allocation with its caller's line
     * as the error code and the caller's name as the message: known by where it is raised */
    const PetscBool memory = (PetscBool) (n == PETSC_ERR_MEM || (fun && (!strcmp(fun, "PetscMallocAlign") || !strcmp(fun, "PetscReallocAlign") || !strcmp(fun, "PetscTrMallocDefault") || !strcmp(fun, "PetscTrReallocDefault"))));
    error_is_user          = (PetscBool) (memory || IsUserError(n));
    if (n == PETSC_ERR_MISSING_FACTOR) { /* MatGetFactor: a preconditioner the matrix type does not have */
      size_t len    = mess ? strlen(mess) : 0;
      error_is_user = PETSC_TRUE;
      (void) PetscSNPrintf(error_message, sizeof error_message, "%.*s: the preconditioner (-pc_type, or -sub_pc_type in blocks) needs a factorization that this matrix type (-drape_mat_type) does not have; choose another -pc_type or -drape_mat_type",
                           (int) (len && mess[len - 1] == '.' ? len - 1 : len), mess ? mess : "");
    } else if (memory && mess && !strncmp(mess, "Out of memory", 13)) /* drape's own sentence (a C++ std::bad_alloc caught) */
      (void) PetscStrncpy(error_message, mess, sizeof error_message);
    else if (memory)
      (void) PetscSNPrintf(error_message, sizeof error_message, "Out of memory (an allocation in %s failed): this run needs more memory than the machine gives it; use a smaller lattice, or more nodes",
                           mess && strncmp(mess, "Memory requested", 16) ? mess : "PETSc");
    else
      (void) PetscStrncpy(error_message, mess ? mess : "(no message)", sizeof error_message);
  }
  if (!error_is_user) return PetscTraceBackErrorHandler(comm, line, fun, file, n, p, mess, ctx);
  return n;
}

/* Wait for a request, at most error_wait seconds; done says whether it completed. */
static PetscErrorCode WaitFor(MPI_Request *request, int *done)
{
  PetscLogDouble t0, t;

  PetscFunctionBeginUser;
  PetscCall(PetscTime(&t0));
  for (*done = 0;;) {
    PetscCallMPI(MPI_Test(request, done, MPI_STATUS_IGNORE));
    PetscCall(PetscTime(&t));
    if (*done || t - t0 > error_wait) break;
    PetscCall(PetscSleep(0.01));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeEndWithError(PetscErrorCode ierr)
{
  PetscMPIInt size, rank;
  int         all = 1;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(PETSC_COMM_WORLD, &size));
  PetscCallMPI(MPI_Comm_rank(PETSC_COMM_WORLD, &rank));
  if (size > 1 && error_comm != MPI_COMM_NULL) {
    /* ranks that failed together (a bad input every rank finds) meet here at once;
     * a rank that did not fail waits in some collective operation and never comes */
    MPI_Request request;
    PetscCallMPI(MPI_Ibarrier(error_comm, &request));
    PetscCall(WaitFor(&request, &all));
  }
  if (error_is_user && (!all || !rank)) PetscCall(PetscFPrintf(PETSC_COMM_SELF, PETSC_STDERR, "drape: error: %s\n", error_message));
  if (!all) PETSCABORT(PETSC_COMM_WORLD, ierr); /* the frames written so far stay readable */
  PetscFunctionReturn(0);
}

/* While DrapeCollective runs its function: keep the first error's message, print nothing. */
static char           captured_message[1024];
static PetscErrorCode captured_code;

static PetscErrorCode CaptureErrorHandler(MPI_Comm comm, int line, const char *fun, const char *file, PetscErrorCode n, PetscErrorType p, const char *mess, void *ctx)
{
  if (p == PETSC_ERROR_INITIAL) {
    captured_code = n;
    (void) PetscStrncpy(captured_message, mess ? mess : "(no message)", sizeof captured_message);
  }
  return n;
}

/* DrapeCollective, raising the error as `code` with `prefix` when code is not 0 */
static PetscErrorCode Collective(MPI_Comm comm, PetscErrorCode (*fn)(void *), void *ctx, PetscErrorCode as, const char prefix[])
{
  PetscErrorCode ierr;
  PetscMPIInt    rank, size, failed, first;
  PetscInt       code;
  char           where[32] = "";

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(PetscPushErrorHandler(CaptureErrorHandler, NULL));
  ierr = (*fn)(ctx);
  PetscCall(PetscPopErrorHandler());
  failed = ierr ? rank : size;
  {
    /* a rank that failed inside a collective library call (MPI-IO on a full disk) can
     * leave the others inside it: this rank then ends the job rather than wait */
    MPI_Request request;
    int         done = 0;
    PetscCallMPI(MPI_Iallreduce(&failed, &first, 1, MPI_INT, MPI_MIN, comm, &request));
    if (ierr)
      PetscCall(WaitFor(&request, &done));
    else
      PetscCallMPI(MPI_Wait(&request, MPI_STATUS_IGNORE));
    if (ierr && !done) {
      PetscCall(PetscFPrintf(PETSC_COMM_SELF, PETSC_STDERR, "drape: error: %s%s%s\n", prefix ? prefix : "", prefix ? ": " : "", captured_message));
      PETSCABORT(PETSC_COMM_WORLD, ierr);
    }
  }
  if (first == size) PetscFunctionReturn(0);
  code = ierr ? (PetscInt) captured_code : 0;
  PetscCallMPI(MPI_Bcast(&code, 1, MPIU_INT, first, comm));
  PetscCallMPI(MPI_Bcast(captured_message, sizeof captured_message, MPI_CHAR, first, comm));
  if (first > 0) PetscCall(PetscSNPrintf(where, sizeof where, " (on rank %d)", first)); /* a rank-local file system */
  if (as) SETERRQ(comm, as, "%s: %s%s", prefix, captured_message, where);
  SETERRQ(comm, (PetscErrorCode) code, "%s%s", captured_message, where);
}

PetscErrorCode DrapeCollective(MPI_Comm comm, PetscErrorCode (*fn)(void *), void *ctx)
{
  PetscFunctionBeginUser;
  PetscCall(Collective(comm, fn, ctx, 0, NULL));
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCollectiveWrite(MPI_Comm comm, PetscErrorCode (*fn)(void *), void *ctx, const char what[])
{
  PetscFunctionBeginUser;
  PetscCall(Collective(comm, fn, ctx, PETSC_ERR_FILE_WRITE, what));
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCollectiveRead(MPI_Comm comm, PetscErrorCode (*fn)(void *), void *ctx, const char what[])
{
  PetscFunctionBeginUser;
  PetscCall(Collective(comm, fn, ctx, PETSC_ERR_FILE_READ, what));
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeInitialize(void)
{
  PetscFunctionBeginUser;
  PetscCall(PetscPushErrorHandler(DrapeErrorHandler, NULL));
  PetscCallMPI(MPI_Comm_dup(PETSC_COMM_WORLD, &error_comm));
  PetscCall(PetscClassIdRegister("drape", &drape_log.classid));
  PetscCall(PetscLogEventRegister("DrapeForces", drape_log.classid, &drape_log.forces));
  PetscCall(PetscLogEventRegister("DrapeEnergies", drape_log.classid, &drape_log.energies));
  PetscCall(PetscLogEventRegister("DrapeJacobian", drape_log.classid, &drape_log.jacobian));
  PetscCall(PetscLogEventRegister("DrapeLinSolve", drape_log.classid, &drape_log.linear_solve));
  PetscCall(PetscLogEventRegister("DrapeOutput", drape_log.classid, &drape_log.output));
  PetscCall(PetscLogEventRegister("DrapeStability", drape_log.classid, &drape_log.stability));
  PetscCall(PetscLogEventRegister("DrapeContact", drape_log.classid, &drape_log.contact));
  PetscCall(PetscLogEventRegister("DrapeSelfContact", drape_log.classid, &drape_log.self_contact));
  PetscCall(PetscLogEventRegister("DrapeSelfBroad", drape_log.classid, &drape_log.self_broad));
  PetscCall(PetscLogEventRegister("DrapeClothSetUp", drape_log.classid, &drape_log.cloth_setup));
  PetscCall(PetscLogEventRegister("DrapePartition", drape_log.classid, &drape_log.partition));
  PetscCall(PetscLogStageRegister("Setup", &drape_log.setup));
  PetscCall(PetscLogStageRegister("Time loop", &drape_log.timeloop));
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeFinalize(void)
{
  PetscFunctionBeginUser;
  PetscCall(PetscPopErrorHandler());
  if (error_comm != MPI_COMM_NULL) PetscCallMPI(MPI_Comm_free(&error_comm));
  PetscFunctionReturn(0);
}

/* Does an option name PETSc left unused belong to drape, as typed or misspelt? PETSc
 * keeps a name without its leading '-' ("--x" is kept as "-x") and compares names
 * without regard to case: -outputfile, -output-file, -CLOTH_DENSTY and --cloth_density
 * are all near-misses of drape's names. Copies a hint on the name's form into hint. */
static PetscBool DrapeNamespace(const char name[], char hint[], size_t size)
{
  static const char *const prefixes[] = {"cloth_", "output_", "drape_", "gravity", "solid_", "contact_", "cusick_", "restart", NULL};
  char                     canon[256], squeezed[256];
  size_t                   k = 0, m = 0;
  PetscBool                dashes = PETSC_FALSE, upper = PETSC_FALSE;
  const char              *p = name;

  hint[0] = 0;
  while (*p == '-') {
    dashes = PETSC_TRUE;
    p++;
  }
  for (; *p && k + 1 < sizeof canon; p++) {
    char c = (char) tolower((unsigned char) *p);
    if (c != *p) upper = PETSC_TRUE;
    if (c == '-') {
      dashes = PETSC_TRUE;
      c      = '_';
    }
    canon[k++] = c;
    if (c != '_') squeezed[m++] = c;
  }
  canon[k] = squeezed[m] = 0;
  if (dashes || upper) (void) snprintf(hint, size, " (drape's options are written in lower case with one leading '-' and '_' between words: -%s)", canon);
  for (const char *const *q = prefixes; *q; q++) {
    char   word[16];
    size_t n = 0;
    for (const char *c = *q; *c; c++)
      if (*c != '_') word[n++] = *c;
    word[n] = 0;
    if (!strncmp(canon, *q, strlen(*q)) || !strncmp(squeezed, word, n)) return PETSC_TRUE;
  }
  return PETSC_FALSE;
}

PetscErrorCode DrapeCheckUnusedOptions(MPI_Comm comm)
{
  PetscInt n;
  char   **names, **values;

  PetscFunctionBeginUser;
  PetscCall(PetscOptionsLeftGet(NULL, &n, &names, &values));
  for (PetscInt i = 0; i < n; i++) {
    char hint[400];
    if (DrapeNamespace(names[i], hint, sizeof hint)) {
      char name[256];
      PetscCall(PetscStrncpy(name, names[i], sizeof name));
      PetscCall(PetscOptionsLeftRestore(NULL, &n, &names, &values));
      SETERRQ(comm, PETSC_ERR_USER_INPUT, "Unknown option -%s: drape has no such option, or it does not apply to this run%s; run with -help for the list", name, hint);
    }
  }
  PetscCall(PetscOptionsLeftRestore(NULL, &n, &names, &values));
  PetscFunctionReturn(0);
}

/* ---- Values of options ---- */

const char *DrapeFormatReal(PetscReal v, char buf[], size_t size)
{
  /* C's %g: PETSc's printf turns 100 into "100." and inf into "inf."; the fewest
   * digits that read back as v, so that 1.000001e6 is not printed as 1e+06 */
  for (int digits = 6; digits <= 17; digits++) {
    (void) snprintf(buf, size, "%.*g", digits, (double) v);
    if (strtod(buf, NULL) == (double) v || v != v) break;
  }
  return buf;
}

PetscErrorCode DrapeCheckReal(MPI_Comm comm, const char name[], PetscInt n, const PetscReal v[], PetscReal lo, PetscReal hi, const char unit[])
{
  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < n; i++) {
    char slo[32], shi[32], got[32];
    if (v[i] >= lo && v[i] <= hi) continue; /* false for NaN */
    (void) DrapeFormatReal(lo, slo, sizeof slo);
    (void) DrapeFormatReal(hi, shi, sizeof shi);
    (void) DrapeFormatReal(v[i], got, sizeof got);
    if (lo > 0) SETERRQ(comm, PETSC_ERR_USER_INPUT, "%s must be positive and finite, from %s to %s%s%s; got %s", name, slo, shi, unit[0] ? " " : "", unit, got);
    if (lo == 0) SETERRQ(comm, PETSC_ERR_USER_INPUT, "%s must be zero or positive and finite, at most %s%s%s; got %s", name, shi, unit[0] ? " " : "", unit, got);
    SETERRQ(comm, PETSC_ERR_USER_INPUT, "%s must be finite, from %s to %s%s%s; got %s", name, slo, shi, unit[0] ? " " : "", unit, got);
  }
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCheckIntOption(MPI_Comm comm, const char name[])
{
  char      raw[4096];
  PetscBool set;

  PetscFunctionBeginUser;
  PetscCall(PetscOptionsGetString(NULL, NULL, name, raw, sizeof raw, &set));
  /* every run of digits (one value, a list, a range a-b) */
  for (char *p = raw; set && *p;) {
    char     *end;
    long long value;
    if (!isdigit((unsigned char) *p)) {
      p++;
      continue;
    }
    errno = 0;
    value = strtoll(p, &end, 10);
    PetscCheck(errno != ERANGE && value <= PETSC_MAX_INT, comm, PETSC_ERR_USER_INPUT, "%s %s is beyond the integers this PETSc build holds (%d-bit PetscInt: at most %" PetscInt_FMT ")", name, raw, (int) (8 * sizeof(PetscInt)), PETSC_MAX_INT);
    for (p = end; isdigit((unsigned char) *p);) p++;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCheckInt(MPI_Comm comm, const char name[], PetscInt v, PetscInt lo, PetscInt hi)
{
  PetscFunctionBeginUser;
  PetscCall(DrapeCheckIntOption(comm, name));
  if (v >= lo && v <= hi) PetscFunctionReturn(0);
  if (lo == 0) SETERRQ(comm, PETSC_ERR_USER_INPUT, "%s must be zero or positive, an integer of at most %" PetscInt_FMT "; got %" PetscInt_FMT, name, hi, v);
  SETERRQ(comm, PETSC_ERR_USER_INPUT, "%s must be an integer from %" PetscInt_FMT " to %" PetscInt_FMT "; got %" PetscInt_FMT, name, lo, hi, v);
}

PetscErrorCode DrapeCheckPathLength(MPI_Comm comm, const char name[], const char value[], size_t size)
{
  size_t len;

  PetscFunctionBeginUser;
  PetscCall(PetscStrlen(value, &len));
  PetscCheck(len + 1 < size, comm, PETSC_ERR_USER_INPUT, "The file name of %s is too long: at most %d characters", name, (int) size - 2);
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeMemoryAvailable(PetscLogDouble *node, PetscLogDouble *process)
{
  struct rlimit limit;
  long          pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  FILE         *fp;

  PetscFunctionBeginUser;
  *node    = pages > 0 && page > 0 ? (PetscLogDouble) pages * (PetscLogDouble) page : PETSC_MAX_REAL;
  *process = PETSC_MAX_REAL;
  if ((fp = fopen("/sys/fs/cgroup/memory.max", "r"))) { /* a container's limit (cgroup v2) */
    double bytes;
    if (fscanf(fp, "%lf", &bytes) == 1 && bytes > 0) *node = PetscMin(*node, (PetscLogDouble) bytes);
    (void) fclose(fp);
  }
  if (!getrlimit(RLIMIT_AS, &limit) && limit.rlim_cur != RLIM_INFINITY) *process = (PetscLogDouble) limit.rlim_cur;
  PetscFunctionReturn(0);
}

/* ---- Files by identity ---- */

/* Identity of a path: device and inode of the file when it exists, else of its
 * directory with the file's own name (two names of one file that does not exist yet
 * are still the same: "run.h5" and "./run.h5"). */
typedef struct {
  int   exists;
  dev_t dev;
  ino_t ino;
  char  base[256];
} FileId;

/* The directory of path, whose last '/' is slash (NULL: none), into dir. */
static void DirectoryOf(const char path[], const char *slash, char dir[], size_t size)
{
  if (!slash)
    (void) snprintf(dir, size, ".");
  else if (slash == path)
    (void) snprintf(dir, size, "/");
  else
    (void) snprintf(dir, size, "%.*s", (int) (slash - path), path);
}

static int GetFileId(const char path[], FileId *id)
{
  struct stat st;
  char        dir[PETSC_MAX_PATH_LEN];
  const char *slash = strrchr(path, '/');

  memset(id, 0, sizeof *id);
  if (!stat(path, &st)) {
    id->exists = 1;
    id->dev    = st.st_dev;
    id->ino    = st.st_ino;
    return 0;
  }
  DirectoryOf(path, slash, dir, sizeof dir);
  (void) snprintf(id->base, sizeof id->base, "%s", slash ? slash + 1 : path);
  if (stat(dir, &st)) return -1;
  id->dev = st.st_dev;
  id->ino = st.st_ino;
  return 0;
}

static int SameFileId(const FileId *a, const FileId *b) { return a->exists == b->exists && a->dev == b->dev && a->ino == b->ino && !strcmp(a->base, b->base); }

PetscErrorCode DrapeSameFile(const char a[], const char b[], PetscBool *same)
{
  FileId ia, ib;

  PetscFunctionBeginUser;
  *same = (PetscBool) (!GetFileId(a, &ia) && !GetFileId(b, &ib) && SameFileId(&ia, &ib));
  PetscFunctionReturn(0);
}

/* Is path, or a symbolic link it goes through, in /dev or /proc: a device or a
 * process's descriptor? (/dev/stdout with stdout redirected is, to stat(), the
 * regular file stdout goes to.) */
static int InPseudoFileSystem(const char path[])
{
  char p[2 * PETSC_MAX_PATH_LEN + 2], dir[sizeof p], real[PETSC_MAX_PATH_LEN + 4096]; /* realpath writes at most PATH_MAX */

  (void) snprintf(p, sizeof p, "%s", path);
  for (int hop = 0; hop < 40; hop++) {
    const char *slash = strrchr(p, '/');
    char        target[PETSC_MAX_PATH_LEN];
    struct stat st;
    ssize_t     n;
    DirectoryOf(p, slash, dir, sizeof dir);
    if (!realpath(dir, real)) return 0; /* a missing directory: refused elsewhere in its own words */
    if (!strcmp(real, "/dev") || !strncmp(real, "/dev/", 5) || !strcmp(real, "/proc") || !strncmp(real, "/proc/", 6)) return 1;
    if (lstat(p, &st) || !S_ISLNK(st.st_mode)) return 0;
    if ((n = readlink(p, target, sizeof target - 1)) < 0) return 0;
    target[n] = 0;
    if (target[0] == '/')
      (void) snprintf(p, sizeof p, "%s", target);
    else
      (void) snprintf(p, sizeof p, "%.4096s/%.4096s", real, target);
  }
  return 1; /* a loop of links */
}

PetscErrorCode DrapeCheckOutputPath(const char option[], const char path[])
{
  PetscFunctionBeginUser;
  PetscCheck(!InPseudoFileSystem(path), PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot write %s %s: it is a device or a process's file descriptor (in /dev or /proc), not a file in a directory; name a file, e.g. run.h5", option, path);
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCheckInputFile(MPI_Comm comm, const char option[], const char what[])
{
  char      path[PETSC_MAX_PATH_LEN] = "";
  PetscBool set;

  PetscFunctionBeginUser;
  PetscCall(PetscOptionsGetString(NULL, NULL, option, path, sizeof path, &set));
  if (!set) path[0] = 0;
  PetscCall(DrapeCheckInputPath(comm, option, path, what));
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCheckInputPath(MPI_Comm comm, const char option[], const char path[], const char what[])
{
  struct stat st;
  PetscMPIInt bad, any;

  PetscFunctionBeginUser;
  if (!path[0]) PetscFunctionReturn(0);
  /* stat() does not open: a FIFO would block open(), /dev/zero would never end */
  bad = !stat(path, &st) && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode); /* missing files and directories: the reader's own sentence */
  PetscCallMPI(MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, comm));
  PetscCheck(!any, comm, PETSC_ERR_FILE_OPEN, "Cannot read the %s %s (%s): it is not a regular file but a device, pipe or socket%s", what, path, option, bad ? "" : " on another rank");
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeFileName(const char option[], const char given[], char actual[], size_t size)
{
  static const char *const petsc_names[] = {"PETSC_ARCH", "PETSC_DIR", "PETSC_LIB_DIR", "DISPLAY", "HOMEDIRECTORY", "WORKINGDIRECTORY", "USERNAME", "HOSTNAME", "PETSC_MAKE", NULL};

  PetscFunctionBeginUser;
  /* PetscStrreplace's own error for an unset variable does not name the option */
  for (const char *p = strstr(given, "${"); p; p = strstr(p + 2, "${")) {
    const char *end = strchr(p, '}');
    char        name[256];
    PetscBool   known = PETSC_FALSE;
    if (!end || (size_t) (end - p - 2) >= sizeof name) break;
    (void) snprintf(name, sizeof name, "%.*s", (int) (end - p - 2), p + 2);
    for (const char *const *q = petsc_names; *q; q++)
      if (!strcmp(name, *q)) known = PETSC_TRUE;
    PetscCheck(known || getenv(name), PETSC_COMM_SELF, PETSC_ERR_USER_INPUT, "%s %s holds ${%s}, which PETSc replaces by the environment variable %s, and it is not set: set it, or name the file without ${...}", option, given, name, name);
  }
  PetscCall(PetscStrreplace(PETSC_COMM_SELF, given, actual, size));
  PetscFunctionReturn(0);
}

/* Every file drape read (options files, outline, mesh, restart file) on this rank. */
#define DRAPE_MAX_INPUTS 64
typedef struct {
  char   name[PETSC_MAX_PATH_LEN];
  char   what[32];
  FileId id;
} Input;
static Input inputs[DRAPE_MAX_INPUTS];
static int   ninputs;

static void RegisterInput(const char path[], const char what[])
{
  FileId id;

  if (ninputs == DRAPE_MAX_INPUTS || GetFileId(path, &id) || !id.exists) return;
  for (int i = 0; i < ninputs; i++)
    if (SameFileId(&inputs[i].id, &id)) return;
  (void) snprintf(inputs[ninputs].name, sizeof inputs[ninputs].name, "%s", path);
  (void) snprintf(inputs[ninputs].what, sizeof inputs[ninputs].what, "%s", what);
  inputs[ninputs++].id = id;
}

PetscErrorCode DrapeRegisterInput(const char path[], const char what[])
{
  PetscFunctionBeginUser;
  RegisterInput(path, what);
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCheckNotInput(const char option[], const char path[], const char except[])
{
  FileId id;

  PetscFunctionBeginUser;
  if (GetFileId(path, &id)) PetscFunctionReturn(0);
  for (int i = 0; i < ninputs; i++) {
    if (except && !strcmp(inputs[i].what, except)) continue;
    PetscCheck(!SameFileId(&inputs[i].id, &id), PETSC_COMM_SELF, PETSC_ERR_USER_INPUT, "%s would overwrite %s, the %s this run reads: choose another output name", option, path, inputs[i].what);
  }
  PetscFunctionReturn(0);
}

/* ---- Ranks that agree ---- */

/* FNV-1a, 64 bits: enough to tell two files or option sets apart (not a defence
 * against a forger) */
static unsigned long long Fnv1a(unsigned long long h, const void *data, size_t n)
{
  const unsigned char *p = (const unsigned char *) data;
  for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 1099511628211ULL;
  return h;
}

/* The digest of a file's contents (its size and first 64 MiB: a restart file may be
 * large), 1 for a file that does not exist, 2 for one that is not a regular file
 * (never opened: a FIFO would block). */
static unsigned long long FileDigest(const char path[])
{
  unsigned long long h = 14695981039346656037ULL;
  struct stat        st;
  FILE              *fp;
  char               buf[65536];
  size_t             n, total = 0;

  if (stat(path, &st)) return 1;
  if (!S_ISREG(st.st_mode)) return 2;
  if (!(fp = fopen(path, "rb"))) return 1;
  h = Fnv1a(h, &st.st_size, sizeof st.st_size);
  while (total < ((size_t) 64 << 20) && (n = fread(buf, 1, sizeof buf, fp)) > 0) {
    h = Fnv1a(h, buf, n);
    total += n;
  }
  (void) fclose(fp);
  return h;
}

PetscErrorCode DrapeCheckMPIIONames(MPI_Comm comm)
{
  static const char *const options[] = {"-output_file", "-restart"};

  PetscFunctionBeginUser;
  for (int k = 0; k < 2; k++) {
    char        given[PETSC_MAX_PATH_LEN] = "", name[PETSC_MAX_PATH_LEN] = "";
    const char *base;
    PetscBool   set;
    PetscMPIInt bad, any;
    size_t      len;
    PetscCall(PetscOptionsGetString(NULL, NULL, options[k], given, sizeof given, &set));
    if (!set || !given[0]) continue;
    PetscCall(DrapeFileName(options[k], given, name, sizeof name));
    base = strrchr(name, '/') ? strrchr(name, '/') + 1 : name;
    len  = strlen(name);
    bad  = len > DRAPE_MPIIO_NAME_MAX && strlen(base) <= 200; /* a longer last part has its own sentence (the output's checks) */
    PetscCallMPI(MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, comm));
    PetscCheck(!any, comm, PETSC_ERR_USER_INPUT,
               "%s names a file of %zu characters, directory included (%.40s...): MPI-IO, which %s it, takes names of at most %d characters; give a shorter path (a relative one, or through a symbolic link to the directory)%s", options[k], len, name,
               k ? "appends to" : "writes", DRAPE_MPIIO_NAME_MAX, bad ? "" : " (on another rank)");
  }
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCheckLogView(MPI_Comm comm)
{
  static char  value[2 * PETSC_MAX_PATH_LEN]; /* type:FILE:format:mode */
  char         given[PETSC_MAX_PATH_LEN], name[PETSC_MAX_PATH_LEN], dir[PETSC_MAX_PATH_LEN], why[2 * PETSC_MAX_PATH_LEN + 300] = "";
  const char  *file, *end, *part = NULL;
  size_t       len, longest = 0;
  PetscBool    set;
  PetscMPIInt  rank, missing = 0;
  const size_t name_max = 255; /* NAME_MAX of Linux's file systems (ext4, xfs, tmpfs, Lustre, GPFS) */

  PetscFunctionBeginUser;
  PetscCall(PetscOptionsGetString(NULL, NULL, "-log_view", value, sizeof value, &set));
  if (!set || !(file = strchr(value, ':'))) PetscFunctionReturn(0); /* no FILE: the log goes to stdout */
  file++;
  end = strchr(file, ':');
  len = end ? (size_t) (end - file) : strlen(file);
  if (!len) PetscFunctionReturn(0);
  if (len >= sizeof given)
    (void) snprintf(why, sizeof why, "-log_view names a file of %zu characters or more (%.40s...): PETSc takes file names of at most %d characters; give a shorter path", len, file, (int) sizeof given - 2);
  else {
    (void) snprintf(given, sizeof given, "%.*s", (int) len, file);
    PetscCall(DrapeFileName("-log_view", given, name, sizeof name));
    PetscCall(PetscStrlen(name, &len));
    for (const char *p = name; *p; p = end + (*end == '/')) { /* each part between slashes */
      end = strchr(p, '/');
      if (!end) end = p + strlen(p);
      if ((size_t) (end - p) > longest) {
        longest = (size_t) (end - p);
        part    = p;
      }
    }
    if (len + 1 >= sizeof name)
      (void) snprintf(why, sizeof why, "-log_view names a file of %zu characters or more (%.40s...): PETSc takes file names of at most %d characters; give a shorter path", len, name, (int) sizeof name - 2);
    else if (longest > name_max)
      (void) snprintf(why, sizeof why, "-log_view names a file with a part of %zu characters between slashes (%.40s...): a file system takes at most %zu; give a shorter name", longest, part, name_max);
    else {
      /* rank 0 writes the log: its directory must be there */
      PetscCallMPI(MPI_Comm_rank(comm, &rank));
      if (!rank) {
        struct stat st;
        DirectoryOf(name, strrchr(name, '/'), dir, sizeof dir);
        missing = stat(dir, &st) || !S_ISDIR(st.st_mode);
      }
      PetscCallMPI(MPI_Bcast(&missing, 1, MPI_INT, 0, comm));
      if (missing)
        (void) snprintf(why, sizeof why, "-log_view names the file %s in %s, which is not a directory (or not there): PETSc writes the log into it at the end of the run; create it or name another", name, rank ? "a directory of rank 0" : dir);
    }
  }
  if (why[0]) {
    /* the run stops here, and PetscFinalize would still open the file for the log
     * (and end in PETSc's traceback): the option goes */
    PetscCall(PetscOptionsClearValue(NULL, "-log_view"));
    SETERRQ(comm, PETSC_ERR_USER_INPUT, "%s", why);
  }
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCheckRanksAgree(MPI_Comm comm)
{
  static const char *const options[] = {NULL, "-solid_file", "-cloth_outline", "-restart", "-output_file"};
  static const char *const whats[]   = {"options", "solid mesh", "cloth outline", "restart file", "output file"};
  enum {
    N = 5
  };
  unsigned long long mine[N], first[N];
  char               names[N][PETSC_MAX_PATH_LEN];
  PetscMPIInt        rank, size, bad, worst;
  char              *all;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  if (size == 1) PetscFunctionReturn(0);
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(PetscOptionsGetAll(NULL, &all));
  mine[0] = Fnv1a(14695981039346656037ULL, all, strlen(all));
  PetscCall(PetscFree(all));
  for (int k = 1; k < N; k++) {
    PetscBool set;
    names[k][0] = 0;
    PetscCall(PetscOptionsGetString(NULL, NULL, options[k], names[k], sizeof names[k], &set));
    if (set && names[k][0] && k >= 3) PetscCall(DrapeFileName(options[k], names[k], names[k], sizeof names[k])); /* as PETSc's viewer opens them */
    if (k == 4)                                                                                                  /* the name, which may differ by node through ${HOSTNAME} */
      mine[k] = set ? Fnv1a(14695981039346656037ULL, names[k], strlen(names[k])) : 0;
    else
      mine[k] = set && names[k][0] ? FileDigest(names[k]) : 0;
  }
  PetscCall(PetscArraycpy(first, mine, N));
  PetscCallMPI(MPI_Bcast(first, N, MPI_UNSIGNED_LONG_LONG, 0, comm));
  bad = size * N; /* the first (rank, item) that differs from rank 0 */
  for (int k = N - 1; k >= 0; k--)
    if (mine[k] != first[k]) bad = rank * N + k;
  PetscCallMPI(MPI_Allreduce(&bad, &worst, 1, MPI_INT, MPI_MIN, comm));
  if (worst == size * N) PetscFunctionReturn(0);
  PetscCheck(worst % N != 0, comm, PETSC_ERR_USER_INPUT,
             "Rank %d was started with other options than rank 0 (an MPMD launch with different options, or another PETSC_OPTIONS, petscrc or options file on its node): every rank must run the same model; give them all the same options", worst / N);
  {
    char theirs[PETSC_MAX_PATH_LEN];
    PetscCall(PetscArraycpy(theirs, names[worst % N], sizeof theirs));
    PetscCallMPI(MPI_Bcast(theirs, sizeof theirs, MPI_CHAR, worst / N, comm));
    PetscCheck(worst % N != 4, comm, PETSC_ERR_USER_INPUT,
               "Rank %d writes -output_file %s, another file than rank 0's %s (PETSc replaces ${HOSTNAME}, ${USERNAME} and ${VAR} of the environment on each node): every rank must write the same file; name it without them", worst / N, theirs,
               names[4]);
  }
  {
    const int k = worst % N;
    SETERRQ(comm, PETSC_ERR_USER_INPUT,
            "Rank %d reads another %s %s (%s) than rank 0 (node-local files that differ, or one that is missing on some nodes): every rank must read the same file; copy the same file to every node, or put it on a shared file system", worst / N,
            whats[k], names[k], options[k]);
  }
}

/* ---- Options files, checked before PETSc reads them ----
 *
 * PETSc reads the options files (-options_file on the command line, the files they
 * name, the petscrc files, PETSC_OPTIONS) inside PetscInitialize, before drape can
 * install its error handler: a missing, binary or malformed file ends there with a
 * traceback, a file that includes itself with a crash, and a file only rank 0 fails
 * to read with a hang. So drape reads them first, with PETSc's rules, on every rank.
 * It cannot hand them to PETSc's reader instead: PetscOptionsInsertFile needs an
 * initialised PETSc, whose error handler is the one that fails. This pass inserts
 * nothing (PETSc still reads every file itself); it only refuses what PETSc 3.18's
 * PetscOptionsInsertFile (src/sys/objects/options.c) would fail on or misread: a
 * missing, unreadable or non-text file, one over 1 MiB, -options_file nesting past 8
 * or in a cycle, a line that is neither "alias -a -b" nor an option and its value
 * ('#' starts a comment), an unbalanced -prefix_push/-prefix_pop, and YAML. At a
 * PETSc upgrade, compare that function's grammar with CheckOptionsFile below. */
#define OPTIONS_FILE_MAX_BYTES (1 << 20)
#define OPTIONS_FILE_MAX_DEPTH 8
#define OPTIONS_PREFIX_MAX     25

typedef struct {
  char name[PETSC_MAX_PATH_LEN];
  int  depth;
} QueuedFile;

static QueuedFile options_queue[DRAPE_MAX_INPUTS];
static int        options_nqueued;
static int        options_prefix_depth;
static char       options_text[OPTIONS_FILE_MAX_BYTES + 1];
static char       options_problem[1024];

/* PetscOptionsValidKey, without PETSc */
static int ValidKey(const char *key)
{
  char *end;

  if (!key || key[0] != '-') return 0;
  if (key[1] == '-') key++;
  if (!isalpha((unsigned char) key[1])) return 0;
  (void) strtod(key, &end);
  if (end != key && !(*end == '_' || isalnum((unsigned char) *end))) return 0;
  return 1;
}

/* PetscTokenFind with blanks as separators and "quoted" tokens */
static char *NextToken(char **s)
{
  char *p   = *s, *token;
  char  sep = ' ';

  if (!p) return NULL;
  while (*p == ' ') p++;
  if (!*p) {
    *s = NULL;
    return NULL;
  }
  token = p;
  if (*p == '"') {
    sep = '"';
    token++;
    p++;
  }
  while (*p && *p != sep) p++;
  if (*p) *p++ = 0;
  *s = p;
  return token;
}

static int Problem(const char *fmt, const char *a, const char *b, long line)
{
  if (line > 0) {
    char where[PETSC_MAX_PATH_LEN + 64];
    (void) snprintf(where, sizeof where, "Line %ld of the options file %s", line, a);
    (void) snprintf(options_problem, sizeof options_problem, fmt, where, b);
  } else
    (void) snprintf(options_problem, sizeof options_problem, fmt, a, b);
  return 0;
}

static int QueueOptionsFile(const char *name, int depth, const char *from)
{
  if (!name || !name[0] || name[0] == '-') return Problem("-options_file needs a file name%s%s", from ? " in " : "", from ? from : "", 0);
  if (depth > OPTIONS_FILE_MAX_DEPTH) return Problem("The options file %s is nested more than 8 deep (does an options file name itself?)%s", name, "", 0);
  if (options_nqueued == DRAPE_MAX_INPUTS) return Problem("More than 64 options files are named (from %s)%s", from ? from : "the command line", "", 0);
  if (strlen(name) >= sizeof options_queue[0].name) return Problem("An options file name is too long (%s...)%s", "", "", 0);
  (void) snprintf(options_queue[options_nqueued].name, sizeof options_queue[0].name, "%s", name);
  options_queue[options_nqueued++].depth = depth;
  return 1;
}

/* One option of a file, the command line or PETSC_OPTIONS: the keys PETSc treats specially. */
static int CheckSpecialKey(const char *key, const char *value, int depth, const char *from)
{
  if (!strcasecmp(key, "-options_file")) return QueueOptionsFile(value, depth + 1, from);
  if (!strcasecmp(key, "-options_file_yaml") || !strcasecmp(key, "-options_string_yaml")) return Problem("%s: drape reads options files in PETSc's plain format (one -name value per line), not YAML%s", key, "", 0);
  if (!strcasecmp(key, "-prefix_push")) {
    if (!value || value[0] == '-') return Problem("-prefix_push needs a prefix%s%s", from ? " in " : "", from ? from : "", 0);
    if (++options_prefix_depth > OPTIONS_PREFIX_MAX) return Problem("More than 25 nested -prefix_push%s%s", from ? " in " : "", from ? from : "", 0);
  }
  if (!strcasecmp(key, "-prefix_pop") && --options_prefix_depth < 0) return Problem("-prefix_pop without a -prefix_push%s%s", from ? " in " : "", from ? from : "", 0);
  return 1;
}

/* A word PETSc would skip without a word: neither an option nor the value after one. */
static int StrayWord(const char *word, const char *from)
{
  const unsigned char *u = (const unsigned char *) word;

  if (u[0] == 0xe2 && ((u[1] == 0x80 && u[2] >= 0x90 && u[2] <= 0x95) || (u[1] == 0x88 && u[2] == 0x92))) return Problem("'%s' %s starts with a typographic dash, not '-' (a word processor's en dash?): type the option with '-'", word, from, 0);
  if (word[0] == '-') return Problem("'%s' %s is not an option name: an option is '-' and a letter, then letters, digits or '_'", word, from, 0);
  if (!word[0]) return Problem("An empty word%s%s stands where an option should be", " ", from, 0);
  return Problem("'%s' %s is neither an option nor the value of one: drape takes options, each -name or -name value (an options file is read with -options_file FILE)", word, from, 0);
}

/* Options as PetscOptionsInsertArgs reads them (command line, PETSC_OPTIONS). */
static int CheckArgs(int argc, char **argv, const char *from)
{
  const char *where = from ? "in PETSC_OPTIONS" : "on the command line";

  for (int i = 0; i < argc; i++) {
    const char *value = i + 1 < argc ? argv[i + 1] : NULL;
    if (!ValidKey(argv[i])) return StrayWord(argv[i], where);
    if (value && !value[0]) return Problem("%s is given an empty value %s: give it a value, or leave the option out", argv[i], where, 0);
    if (!strcasecmp(argv[i], "-options_file") || !strcasecmp(argv[i], "-prefix_push") || !strcasecmp(argv[i], "-options_file_yaml") || !strcasecmp(argv[i], "-options_string_yaml")) {
      if (!CheckSpecialKey(argv[i], value, 0, from)) return 0;
      i++;
    } else if (!CheckSpecialKey(argv[i], NULL, 0, from))
      return 0;
    else if (value && !ValidKey(value))
      i++;
  }
  return 1;
}

/* One options file, as PetscOptionsInsertFilePetsc and PetscOptionsInsertString read it. */
static int CheckOptionsFile(const char *name, int depth, int required)
{
  struct stat st;
  FILE       *fp;
  size_t      len;
  const char *dot = strrchr(name, '.');
  char       *line, *next;
  long        lineno = 0;

  if (stat(name, &st)) return required ? Problem("Cannot read the options file %s: it does not exist%s", name, "", 0) : 1;
  if (S_ISDIR(st.st_mode)) return required ? Problem("Cannot read the options file %s: it is a directory%s", name, "", 0) : 1;
  if (!S_ISREG(st.st_mode)) return Problem("Cannot read the options file %s: it is not a regular file%s", name, "", 0);
  if (st.st_size > OPTIONS_FILE_MAX_BYTES) return Problem("The options file %s is larger than 1 MB: not an options file%s", name, "", 0);
  if ((len = strlen(name)) > 5 && (!strcmp(name + len - 5, ":yaml") || (dot && (!strcmp(dot, ".yaml") || !strcmp(dot, ".yml") || !strcmp(dot, ".json")))))
    return Problem("The options file %s is YAML: drape reads options files in PETSc's plain format (one -name value per line)%s", name, "", 0);
  fp = fopen(name, "rb");
  if (!fp) return required ? Problem("Cannot read the options file %s: %s", name, strerror(errno), 0) : 1;
  len = fread(options_text, 1, OPTIONS_FILE_MAX_BYTES, fp);
  (void) fclose(fp);
  options_text[len] = 0;
  RegisterInput(name, "options file");
  if (!strncmp(options_text, "%YAML ", 6) || !strncmp(options_text, "---", 3)) return Problem("The options file %s is YAML: drape reads options files in PETSc's plain format (one -name value per line)%s", name, "", 0);
  for (size_t i = 0; i < len; i++) {
    unsigned char ch = (unsigned char) options_text[i];
    if (ch < 32 && ch != '\n' && ch != '\r' && ch != '\t' && ch != '\f' && ch != '\v') return Problem("The options file %s is not a text file (it holds control characters)%s", name, "", 0);
  }
  for (line = options_text; line; line = next) {
    char *token[4], *hash, *cursor = line;
    int   ntoken = 0;
    lineno++;
    next = strpbrk(line, "\n\r");
    if (next) *next++ = 0;
    if ((hash = strchr(line, '#'))) *hash = 0;
    for (char *p = line; *p; p++)
      if (*p == '\t' || *p == '\f' || *p == '\v') *p = ' ';
    while (ntoken < 4 && (token[ntoken] = NextToken(&cursor))) ntoken++;
    if (!ntoken) continue;
    if (token[0][0] == '-') {
      if (!ValidKey(token[0])) return Problem("%s: %s is not an option name", name, token[0], lineno);
      if (ntoken > 1 && ValidKey(token[1])) return Problem("%s: two options on one line (%s ...); write one -name value per line", name, token[0], lineno);
      if (ntoken > 2) return Problem("%s: more than one value after %s", name, token[0], lineno);
      if (!CheckSpecialKey(token[0], ntoken > 1 ? token[1] : NULL, depth, name)) return 0;
    } else if (!strcasecmp(token[0], "alias")) {
      if (ntoken != 3 || !ValidKey(token[1]) || !ValidKey(token[2])) return Problem("%s: an alias line needs two option names%s", name, "", lineno);
    } else
      return Problem("%s: '%s' is not an option (write one -name value per line; # starts a comment)", name, token[0], lineno);
  }
  return 1;
}

static int CheckAllOptionsFiles(int argc, char **argv)
{
  const char *env = getenv("PETSC_OPTIONS"), *home = getenv("HOME");
  int         skip_petscrc = 0;

  for (int i = 1; i < argc; i++)
    if (!strcasecmp(argv[i], "-skip_petscrc")) skip_petscrc = !(i + 1 < argc && (!strcasecmp(argv[i + 1], "0") || !strcasecmp(argv[i + 1], "false") || !strcasecmp(argv[i + 1], "no")));
  if (!skip_petscrc) {
    char rc[PETSC_MAX_PATH_LEN];
    if (home && home[0]) {
      (void) snprintf(rc, sizeof rc, "%s/.petscrc", home);
      if (!CheckOptionsFile(rc, 1, 0)) return 0;
    }
    if (!CheckOptionsFile(".petscrc", 1, 0) || !CheckOptionsFile("petscrc", 1, 0)) return 0;
  }
  if (env && env[0]) {
    static char copy[16384];
    char       *cursor = copy, *words[1024];
    int         n      = 0;
    if (strlen(env) >= sizeof copy) return Problem("The environment variable PETSC_OPTIONS is longer than 16 kB%s%s", "", "", 0);
    (void) snprintf(copy, sizeof copy, "%s", env);
    while (n < 1024 && (words[n] = NextToken(&cursor))) n++;
    if (!CheckArgs(n, words, "PETSC_OPTIONS")) return 0;
  }
  if (!CheckArgs(argc - 1, argv + 1, NULL)) return 0;
  for (int q = 0; q < options_nqueued; q++)
    if (!CheckOptionsFile(options_queue[q].name, options_queue[q].depth, 1)) return 0;
  return 1;
}

int DrapeCheckOptionsFiles(int argc, char **argv)
{
  int rank = 0, size = 1, ok, failed, first;

  if (MPI_Comm_rank(MPI_COMM_WORLD, &rank) || MPI_Comm_size(MPI_COMM_WORLD, &size)) return 0;
  ok     = CheckAllOptionsFiles(argc, argv);
  failed = ok ? size : rank;
  if (MPI_Allreduce(&failed, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD)) return 0;
  if (first == size) return 1;
  if (rank == first && first > 0) {
    char seen[sizeof options_problem + 32];
    (void) snprintf(seen, sizeof seen, "%s (on rank %d)", options_problem, first);
    (void) snprintf(options_problem, sizeof options_problem, "%.1000s", seen);
  }
  if (MPI_Bcast(options_problem, sizeof options_problem, MPI_CHAR, first, MPI_COMM_WORLD)) return 0;
  return 0;
}

PetscErrorCode DrapeReportOptionsFiles(MPI_Comm comm)
{
  PetscFunctionBeginUser;
  PetscCheck(!options_problem[0], comm, PETSC_ERR_FILE_READ, "%s", options_problem);
  PetscFunctionReturn(0);
}
