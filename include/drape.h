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
/* Run fn(ctx) on every rank of comm where each rank does the same local work
 * (reading a small input file): a failure is raised once, collectively on comm,
 * with the message of the lowest failing rank, not printed by every rank. */
PETSC_EXTERN PetscErrorCode DrapeCollective(MPI_Comm, PetscErrorCode (*)(void *), void *);
/* Was the last error a user error raised on a communicator of all ranks (so every
 * rank returns it and the job can end without MPI_Abort)? */
PETSC_EXTERN PetscBool DrapeErrorIsCollective(void);
/* Refuse options in drape's own namespaces (-cloth_, -output_, -drape_, ...) that
 * no component read: a misspelt drape option is an error, not a silent default. */
PETSC_EXTERN PetscErrorCode DrapeCheckUnusedOptions(MPI_Comm);
