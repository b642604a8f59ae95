/* A simulation: the cloth, its state U = [x; v], a PETSc TS and the monitors.
 *
 * State layout: on every rank U holds the owned particles' positions (3 per
 * particle) followed by their velocities, so the "position" and "momentum" splits
 * of TSBASICSYMPLECTIC are contiguous views and no copy is made. */
#pragma once

#include <petscts.h>
#include <cloth.h>
#include <solid.h>
#include <contactsolve.h>
#include <selfcontact.h>

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

/* drapebe.c: drape's backward Euler in the paper's form (scheme 4: A dv = b, SNES +
 * KSP CG on an assembled matrix, contact as constraints of the step), the TS type
 * "drapebe". DrapeTSRegister() registers it; TSDrapeBESetCloth() gives it the cloth
 * (required) and TSDrapeBESetContact() the contact with the solid as constraints of
 * the step (include/contactsolve.h; none: no contact), which its TSSetUp sets up. The setters and getters do nothing on TS of other types (the impulse and
 * statistics are then zero). */
#define TSDRAPEBE "drapebe"
PETSC_EXTERN PetscErrorCode DrapeTSRegister(void);
PETSC_EXTERN PetscErrorCode TSDrapeBESetCloth(TS, Cloth);
PETSC_EXTERN PetscErrorCode TSDrapeBESetContact(TS, ContactSolve);
/* Self-contact's close pairs in the step's solve (include/selfcontact.h); NULL: none. */
PETSC_EXTERN PetscErrorCode TSDrapeBESetSelfContact(TS, SelfContact);
/* Omega_max of the cloth at the start (rad/s): with (h Omega_max)^2 the default
 * preconditioner is chosen (block Jacobi/ICC or algebraic multigrid); without it
 * the TS estimates Omega_max itself. */
PETSC_EXTERN PetscErrorCode TSDrapeBESetStiffness(TS, PetscReal);
/* The state was changed after the last step by more than the landing on the solid
 * (the self-contact filter): the energy check of the next step starts from it. */
PETSC_EXTERN PetscErrorCode TSDrapeBEStateChanged(TS);
/* Impulse (N s) the contact constraints gave this rank's particles in the last step. */
PETSC_EXTERN PetscErrorCode TSDrapeBEGetContactImpulse(TS, PetscReal[3]);
/* Solves made and steps rejected so far, and the last failed solve in words. */
PETSC_EXTERN PetscErrorCode TSDrapeBEGetStatistics(TS, PetscInt *solves, PetscInt *rejected, const char **failure);

/* stability.c: Omega_max^2 = lambda_max(M^-1 H) by the Lanczos process (at most
 * `iterations` steps, fewer once it has converged), and the step limits it implies
 * for the explicit schemes. Collective. */
typedef struct {
  PetscBool reference;  /* in: exactly `iterations` steps, each product through the elements' full matrices (tests) */
  PetscReal omega;      /* rad/s                                          */
  PetscReal symplectic; /* largest stable step of symplectic Euler, s     */
  PetscReal euler;      /* largest stable step of explicit Euler (0: none) */
  PetscInt  iterations; /* Lanczos steps taken                            */
} StabilityLimits;
PETSC_EXTERN PetscErrorCode StabilityEstimate(Cloth, const PetscScalar *x, PetscInt iterations, StabilityLimits *);
