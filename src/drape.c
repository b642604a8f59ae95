/* Program-wide set-up: log events and stages, the error handler, option checks. */
#include <drape.h>

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
    return PETSC_TRUE;
  default:
    return PETSC_FALSE;
  }
}

static PetscBool error_is_user = PETSC_FALSE, error_on_all = PETSC_FALSE;

static PetscErrorCode DrapeErrorHandler(MPI_Comm comm, int line, const char *fun, const char *file, PetscErrorCode n, PetscErrorType p, const char *mess, void *ctx)
{
  PetscMPIInt rank = 0;

  if (p == PETSC_ERROR_INITIAL) {
    PetscMPIInt size = 0, world = 1;
    error_is_user = IsUserError(n);
    if (comm != MPI_COMM_NULL) MPI_Comm_size(comm, &size);
    MPI_Comm_size(PETSC_COMM_WORLD, &world);
    error_on_all = (PetscBool) (size == world);
  }
  if (!error_is_user) return PetscTraceBackErrorHandler(comm, line, fun, file, n, p, mess, ctx);
  if (p == PETSC_ERROR_INITIAL) {
    if (comm != MPI_COMM_NULL) MPI_Comm_rank(comm, &rank);
    if (!rank) (void) PetscFPrintf(PETSC_COMM_SELF, PETSC_STDERR, "drape: error: %s\n", mess ? mess : "(no message)");
  }
  return n;
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

PetscErrorCode DrapeCollective(MPI_Comm comm, PetscErrorCode (*fn)(void *), void *ctx)
{
  PetscErrorCode ierr;
  PetscMPIInt    rank, size, failed, first;
  PetscInt       code;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(PetscPushErrorHandler(CaptureErrorHandler, NULL));
  ierr = (*fn)(ctx);
  PetscCall(PetscPopErrorHandler());
  failed = ierr ? rank : size;
  PetscCallMPI(MPI_Allreduce(&failed, &first, 1, MPI_INT, MPI_MIN, comm));
  if (first == size) PetscFunctionReturn(0);
  code = ierr ? (PetscInt) captured_code : 0;
  PetscCallMPI(MPI_Bcast(&code, 1, MPIU_INT, first, comm));
  PetscCallMPI(MPI_Bcast(captured_message, sizeof captured_message, MPI_CHAR, first, comm));
  SETERRQ(comm, (PetscErrorCode) code, "%s", captured_message);
}

PetscBool DrapeErrorIsCollective(void) { return (PetscBool) (error_is_user && error_on_all); }

PetscErrorCode DrapeInitialize(void)
{
  PetscFunctionBeginUser;
  PetscCall(PetscPushErrorHandler(DrapeErrorHandler, NULL));
  PetscCall(PetscClassIdRegister("drape", &drape_log.classid));
  PetscCall(PetscLogEventRegister("DrapeForces", drape_log.classid, &drape_log.forces));
  PetscCall(PetscLogEventRegister("DrapeEnergies", drape_log.classid, &drape_log.energies));
  PetscCall(PetscLogEventRegister("DrapeJacobian", drape_log.classid, &drape_log.jacobian));
  PetscCall(PetscLogEventRegister("DrapeLinSolve", drape_log.classid, &drape_log.linear_solve));
  PetscCall(PetscLogEventRegister("DrapeOutput", drape_log.classid, &drape_log.output));
  PetscCall(PetscLogEventRegister("DrapeStability", drape_log.classid, &drape_log.stability));
  PetscCall(PetscLogEventRegister("DrapeContact", drape_log.classid, &drape_log.contact));
  PetscCall(PetscLogStageRegister("Setup", &drape_log.setup));
  PetscCall(PetscLogStageRegister("Time loop", &drape_log.timeloop));
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeFinalize(void)
{
  PetscFunctionBeginUser;
  PetscCall(PetscPopErrorHandler());
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeCheckUnusedOptions(MPI_Comm comm)
{
  static const char *const prefixes[] = {"cloth_", "output_", "drape_", "gravity", "solid_", "contact_", "cusick_", NULL};
  PetscInt                 n;
  char                   **names, **values;

  PetscFunctionBeginUser;
  PetscCall(PetscOptionsLeftGet(NULL, &n, &names, &values));
  for (PetscInt i = 0; i < n; i++) {
    for (const char *const *p = prefixes; *p; p++) {
      PetscBool match;
      PetscCall(PetscStrbeginswith(names[i], *p, &match));
      if (match) {
        char name[256];
        PetscCall(PetscStrncpy(name, names[i], sizeof name));
        PetscCall(PetscOptionsLeftRestore(NULL, &n, &names, &values));
        SETERRQ(comm, PETSC_ERR_USER_INPUT, "Unknown option -%s: drape has no such option, or it does not apply to this run (run with -help for the list)", name);
      }
    }
  }
  PetscCall(PetscOptionsLeftRestore(NULL, &n, &names, &values));
  PetscFunctionReturn(0);
}
