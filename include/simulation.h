/* A simulation: the cloth, its state U = [x; v], a PETSc TS and the monitors.
 *
 * State layout: on every rank U holds the owned particles' positions (3 per
 * particle) followed by their velocities, so the "position" and "momentum" splits
 * of TSBASICSYMPLECTIC are contiguous views and no copy is made. */
#pragma once

#include <petscts.h>
#include <cloth.h>

typedef struct _p_Simulation *Simulation;

/* Create; read and check every option (and the input files they name) before any
 * output file is opened; set up cloth, solid, state and TS; run to the end; destroy.
 * Collective. */
PETSC_EXTERN PetscErrorCode SimulationCreate(MPI_Comm, Simulation *);
PETSC_EXTERN PetscErrorCode SimulationSetFromOptions(Simulation);
PETSC_EXTERN PetscErrorCode SimulationSetUp(Simulation);
PETSC_EXTERN PetscErrorCode SimulationRun(Simulation);
PETSC_EXTERN PetscErrorCode SimulationDestroy(Simulation *);
/* Was the run stopped by SIGTERM/SIGINT (after writing its last frame)? Not
 * collective. */
PETSC_EXTERN PetscErrorCode SimulationInterrupted(Simulation, PetscBool *);

/* beuler.c: drape's backward Euler in the paper's form (A dv = b, SNES + KSP CG on
 * an assembled MATAIJ), registered as TS type "beuler". The Cloth must be composed
 * on the TS as a PetscContainer named "drape_cloth". */
PETSC_EXTERN PetscErrorCode DrapeTSRegisterBEuler(void);
PETSC_EXTERN PetscErrorCode TSDrapeGetContactImpulse(TS, PetscReal[3]);

/* stability.c: Omega_max^2 = lambda_max(M^-1 H) by power iteration, and the step
 * limits it implies for the explicit schemes. Collective. */
typedef struct {
  PetscReal omega;      /* rad/s                                          */
  PetscReal symplectic; /* largest stable step of symplectic Euler, s     */
  PetscReal euler;      /* largest stable step of explicit Euler (0: none) */
  PetscInt  iterations;
} StabilityLimits;
PETSC_EXTERN PetscErrorCode StabilityEstimate(Cloth, const PetscScalar *x, PetscInt iterations, StabilityLimits *);
