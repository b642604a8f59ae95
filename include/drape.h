/* drape: fabric simulation by the particle method (Landovsky), on PETSc.
 * Program-wide pieces: version, log events, the error handler, option checks, and
 * the identity of the files a run reads and writes. */
#pragma once

#include <petscsys.h>

#define DRAPE_VERSION "0.1.0"

/* A kernel compiled three times, for x86-64-v4 (AVX-512), v3 (AVX2) and the baseline,
 * the version the CPU takes chosen when the program starts (GCC's function
 * multi-versioning); _FLATTEN also inlines every call inside it, so that the kernels
 * it calls are compiled for its instruction set. In the files the Makefile compiles
 * with -ffp-contract=off (no multiply-add contracted; no sum is reordered without
 * -ffast-math) every version gives the same bits; elsewhere they agree to round-off.
 * Other compilers, or -DDRAPE_NO_TARGET_CLONES: the baseline only. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__INTEL_COMPILER) && !defined(DRAPE_NO_TARGET_CLONES)
#define DRAPE_TARGET_CLONES         __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#define DRAPE_TARGET_CLONES_FLATTEN __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"), flatten))
#else
#define DRAPE_TARGET_CLONES
#define DRAPE_TARGET_CLONES_FLATTEN
#endif

/* Log events and stages, registered once by DrapeInitialize(); -log_view shows them. */
typedef struct {
  PetscClassId  classid;
  PetscLogEvent forces, energies, jacobian, linear_solve, output, stability, contact, self_contact, self_broad, cloth_setup, partition;
  PetscLogStage setup, timeloop;
} DrapeLog;

PETSC_EXTERN DrapeLog drape_log;

/* Register log events and install drape's error handler (user errors are kept for
 * one sentence at the end, DrapeEndWithError(); internal errors keep PETSc's
 * traceback). Collective on PETSC_COMM_WORLD. */
PETSC_EXTERN PetscErrorCode DrapeInitialize(void);
/* Undo DrapeInitialize(). Collective on PETSC_COMM_WORLD. */
PETSC_EXTERN PetscErrorCode DrapeFinalize(void);
/* End a run that failed on this rank with error ierr. If every rank failed (a bad
 * input all ranks find), rank 0 prints the one `drape: error:` sentence and the job
 * ends normally; if some rank did not fail within a few seconds (it waits in a
 * collective operation and would hang), this rank prints its sentence and ends the
 * job with MPI_Abort. Collective on PETSC_COMM_WORLD when every rank failed. */
PETSC_EXTERN PetscErrorCode DrapeEndWithError(PetscErrorCode ierr);
/* Run fn(ctx) on every rank of comm where each rank does the same local work
 * (reading a small input file, testing a directory): a failure is raised once,
 * collectively on comm, with the message of the lowest failing rank, not printed by
 * every rank. Collective. */
PETSC_EXTERN PetscErrorCode DrapeCollective(MPI_Comm, PetscErrorCode (*)(void *), void *);
/* DrapeCollective for writing or reading a file: a failure (a full disk, a file system
 * gone, a damaged file; HDF5 says so in its own words) is raised as one sentence
 * "what: HDF5's words". A rank whose peers stay inside a collective library call
 * (MPI-IO) ends the job with MPI_Abort after a few seconds. Collective. */
PETSC_EXTERN PetscErrorCode DrapeCollectiveWrite(MPI_Comm, PetscErrorCode (*)(void *), void *, const char what[]);
PETSC_EXTERN PetscErrorCode DrapeCollectiveRead(MPI_Comm, PetscErrorCode (*)(void *), void *, const char what[]);
/* Refuse options in drape's own namespaces (-cloth_, -output_, -drape_, ...) that
 * no component read: a misspelt drape option is an error, not a silent default.
 * Collective. */
PETSC_EXTERN PetscErrorCode DrapeCheckUnusedOptions(MPI_Comm);

/* Refuse a job whose ranks disagree (an MPMD launch with different options, node-local
 * input files that differ): a digest of the options database, of the files of
 * -solid_file, -cloth_outline and -restart, and of the name -output_file has once
 * PETSc replaced its ${...}, is compared with rank 0's, at start-up, before any rank
 * builds its model. Collective. */
PETSC_EXTERN PetscErrorCode DrapeCheckRanksAgree(MPI_Comm);
/* Refuse a name of -output_file or -restart (the files MPI-IO opens, as PETSc names
 * them) longer than DRAPE_MPIIO_NAME_MAX characters, directory included: Open MPI's
 * MPI-IO names a lock file after it in a buffer of 256 bytes, and a longer name
 * ended in "buffer overflow detected" (SIGABRT) before a frame was written.
 * Collective. */
#define DRAPE_MPIIO_NAME_MAX 230
PETSC_EXTERN PetscErrorCode DrapeCheckMPIIONames(MPI_Comm);
/* -log_view [type]:FILE[:format[:mode]]: PETSc opens FILE only in PetscFinalize,
 * after the run, and one it cannot open ended there in its traceback: a name too
 * long for PETSc (PETSC_MAX_PATH_LEN) or the file system (255 characters between
 * slashes), or a directory that is not there (on rank 0, which writes the log), is
 * refused before the run. Collective. */
PETSC_EXTERN PetscErrorCode DrapeCheckLogView(MPI_Comm);
/* Refuse an input file option (-solid_file, -restart, -cloth_outline) whose file is
 * not a regular file (a FIFO, /dev/zero, a socket), before anything opens it; what
 * names it in the sentence. Missing files and directories are left to the reader.
 * Collective. */
PETSC_EXTERN PetscErrorCode DrapeCheckInputFile(MPI_Comm, const char option[], const char what[]);
/* The same check on a file name drape has already read from `option` (and, for a
 * file that PETSc's viewers open, passed through DrapeFileName). Collective. */
PETSC_EXTERN PetscErrorCode DrapeCheckInputPath(MPI_Comm, const char option[], const char path[], const char what[]);
/* The file PETSc's viewers open for a name: they replace ${HOSTNAME}, ${USERNAME},
 * ${PETSC_ARCH}, ... and any ${VAR} of the environment (PetscStrreplace); drape
 * compares and writes the names so replaced, so that its checks see the file PETSc
 * writes; a ${VAR} not set is refused naming `option`. Not collective. */
PETSC_EXTERN PetscErrorCode DrapeFileName(const char option[], const char given[], char actual[], size_t size);
/* Refuse an output name in /dev or /proc, directly or through symbolic links
 * (/dev/stdout is the file stdout goes to). Not collective. */
PETSC_EXTERN PetscErrorCode DrapeCheckOutputPath(const char option[], const char path[]);

/* Before PetscInitialize, after MPI_Init: read, with PETSc's rules, every options
 * file PETSc is about to read (-options_file, the files they name, the petscrc files,
 * PETSC_OPTIONS) on every rank, and record them as inputs. Returns 1 when all are
 * sound; otherwise 0, and the caller starts PETSc without them so that
 * DrapeReportOptionsFiles() says what is wrong in one sentence (PETSc's own reader
 * would end with a traceback, a crash or a hang). Not a PETSc function (PETSc is not
 * running yet). Collective on MPI_COMM_WORLD. */
PETSC_EXTERN int DrapeCheckOptionsFiles(int argc, char **argv);
/* Raise the problem DrapeCheckOptionsFiles() found, if any. Collective. */
PETSC_EXTERN PetscErrorCode DrapeReportOptionsFiles(MPI_Comm);

/* Values read from options, where they are read. DrapeCheckReal: n values finite
 * and in [lo, hi] (unit for the message). DrapeCheckIntOption: the integer option
 * `name` as typed fits PetscInt (PETSc keeps the low bits of a larger one:
 * 4294967302 becomes 6). DrapeCheckInt: both, and v in [lo, hi].
 * DrapeCheckPathLength: a file name option read into a buffer of `size` bytes was not
 * cut short. Each ends with one sentence naming the option. Collective. */
/* v in the fewest digits (6 to 17, C's %g) that read back as v: a refused value
 * printed as given. Returns buf. Not collective. */
PETSC_EXTERN const char    *DrapeFormatReal(PetscReal v, char buf[], size_t size);
PETSC_EXTERN PetscErrorCode DrapeCheckReal(MPI_Comm, const char name[], PetscInt n, const PetscReal v[], PetscReal lo, PetscReal hi, const char unit[]);
PETSC_EXTERN PetscErrorCode DrapeCheckIntOption(MPI_Comm, const char name[]);
PETSC_EXTERN PetscErrorCode DrapeCheckInt(MPI_Comm, const char name[], PetscInt v, PetscInt lo, PetscInt hi);
PETSC_EXTERN PetscErrorCode DrapeCheckPathLength(MPI_Comm, const char name[], const char value[], size_t size);

/* Memory this rank's node has (physical, or a container's limit) and one process may
 * use (RLIMIT_AS), bytes; PETSC_MAX_REAL when unknown. Not collective. */
PETSC_EXTERN PetscErrorCode DrapeMemoryAvailable(PetscLogDouble *node, PetscLogDouble *process);

/* Files by identity, not by name (device and inode; for a file that does not exist
 * yet, its directory's and its own name): "run.h5", "./run.h5" and a link to it are
 * one file. DrapeRegisterInput records a file this rank read (`what`: "cloth
 * outline", ...); DrapeCheckNotInput refuses an output path that is one of them
 * (except those registered as `except`, may be NULL), with one sentence naming
 * `option`. Not collective (on the rank's own view of the file system). */
PETSC_EXTERN PetscErrorCode DrapeSameFile(const char a[], const char b[], PetscBool *same);
PETSC_EXTERN PetscErrorCode DrapeRegisterInput(const char path[], const char what[]);
PETSC_EXTERN PetscErrorCode DrapeCheckNotInput(const char option[], const char path[], const char except[]);
