/* The explicit schemes' stability (src/integrate/stability.c): Omega_max^2 =
 * lambda_max(M^-1 H) by the Lanczos process, and the step limits it implies. */
#pragma once

#include <cloth.h>
#include <report.h>

typedef struct {
  PetscBool reference;  /* in: exactly `iterations` steps, each product through the elements' full matrices (tests) */
  PetscReal omega;      /* rad/s                                          */
  PetscReal symplectic; /* largest stable step of symplectic Euler, s     */
  PetscReal euler;      /* largest stable step of explicit Euler (0: none) */
  PetscInt  iterations; /* Lanczos steps taken                            */
} StabilityLimits;

/* Omega_max of the cloth at x (owned order) by at most `iterations` Lanczos steps
 * (fewer once it has converged), and the step limits it implies. Collective on the
 * cloth's communicator. */
PETSC_EXTERN PetscErrorCode StabilityEstimate(Cloth, const PetscScalar *x, PetscInt iterations, StabilityLimits *);
/* The estimate's lines on viewer (NULL: none) and its numbers in the report
 * (omega_max, symplectic_limit, euler_limit), from the same values; damping in 1/s.
 * Collective on the viewer. */
PETSC_EXTERN PetscErrorCode StabilityView(const StabilityLimits *, PetscReal damping, Report, PetscViewer);
