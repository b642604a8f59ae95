/* A simulation: the cloth, its state U = [x; v], a PETSc TS and the monitors
 * (src/integrate/simulation.c). The TS type drapebe is in drapebe.h, the stability
 * estimate in stability.h.
 *
 * State layout: on every rank U holds the owned particles' positions (3 per
 * particle) followed by their velocities, so the "position" and "momentum" splits
 * of TSBASICSYMPLECTIC are contiguous views and no copy is made. */
#pragma once

#include <petscsys.h>

typedef struct _p_Simulation *Simulation;

/* Create; read and check every option (and the input files they name) before any
 * output file is opened; set up cloth, solid, state and TS; run to the end; destroy.
 * Collective. */
PETSC_EXTERN PetscErrorCode SimulationCreate(MPI_Comm, Simulation *);
PETSC_EXTERN PetscErrorCode SimulationSetFromOptions(Simulation);
PETSC_EXTERN PetscErrorCode SimulationSetUp(Simulation);
PETSC_EXTERN PetscErrorCode SimulationRun(Simulation);
PETSC_EXTERN PetscErrorCode SimulationDestroy(Simulation *);
/* Was the run stopped by SIGTERM, SIGINT, SIGHUP or SIGPIPE (after writing its last
 * frame), and can -restart continue it from that frame (not with bending friction,
 * whose plastic state the frames do not hold)? Not collective. */
PETSC_EXTERN PetscErrorCode SimulationInterrupted(Simulation, PetscBool *interrupted, PetscBool *restartable);
