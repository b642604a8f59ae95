/* drape: fabric simulation by the particle method (Landovsky), on PETSc.
 * Program-wide pieces: version, log events, the error handler and option checks. */
#pragma once

#include <petscsys.h>

#define DRAPE_VERSION "0.1.0"

/* Log events and stages, registered once by DrapeInitialize(); -log_view shows them. */
typedef struct {
  PetscClassId  classid;
  PetscLogEvent forces, energies, jacobian, linear_solve, output, stability, contact;
  PetscLogStage setup, timeloop;
} DrapeLog;

PETSC_EXTERN DrapeLog drape_log;

/* Register log events and install drape's error handler (user errors print one
 * sentence; internal errors keep PETSc's traceback). */
PETSC_EXTERN PetscErrorCode DrapeInitialize(void);
/* Undo DrapeInitialize() (the error handler). */
PETSC_EXTERN PetscErrorCode DrapeFinalize(void);
/* Refuse options in drape's own namespaces (-cloth_, -output_, -drape_, ...) that
 * no component read: a misspelt drape option is an error, not a silent default. */
PETSC_EXTERN PetscErrorCode DrapeCheckUnusedOptions(MPI_Comm);
