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

static PetscBool error_is_user = PETSC_FALSE;

static PetscErrorCode DrapeErrorHandler(MPI_Comm comm, int line, const char *fun, const char *file, PetscErrorCode n, PetscErrorType p, const char *mess, void *ctx)
{
  PetscMPIInt rank = 0;

  if (p == PETSC_ERROR_INITIAL) error_is_user = IsUserError(n);
  if (!error_is_user) return PetscTraceBackErrorHandler(comm, line, fun, file, n, p, mess, ctx);
  if (p == PETSC_ERROR_INITIAL) {
    if (comm != MPI_COMM_NULL) MPI_Comm_rank(comm, &rank);
    if (!rank) (void) PetscFPrintf(PETSC_COMM_SELF, PETSC_STDERR, "drape: error: %s\n", mess ? mess : "(no message)");
  }
  return n;
}

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
