/* The rest test (src/integrate/rest.c), private to src/integrate/: a draping run
 * ends by itself once the kinetic energy per unit mass has stayed below
 * -drape_rest_tol for -drape_rest_time of simulated time. Before that, once it has
 * stayed below -drape_settle_tol as long, the cloth is settling: drapebe's step may
 * grow (TSAdaptDrapeSetSettled). */
#pragma once

#include <cloth.h>
#include <report.h>

typedef struct _p_RestTest *RestTest;

/* Not collective. */
PETSC_EXTERN PetscErrorCode RestTestCreate(MPI_Comm, RestTest *);
/* -drape_rest_tol, -drape_rest_time, -drape_settle_tol. Collective. */
PETSC_EXTERN PetscErrorCode RestTestSetFromOptions(RestTest);
/* After the step to time t, with the owned particles' velocities v: has the cloth
 * now been at rest long enough? Has it been settling long enough (settled; NULL: not
 * asked)? (Both always false with -drape_rest_tol 0.) Collective. */
PETSC_EXTERN PetscErrorCode RestTestUpdate(RestTest, Cloth, const PetscScalar *v, PetscReal t, PetscBool *at_rest, PetscBool *settled);
/* Did the run end at rest? Not collective. */
PETSC_EXTERN PetscErrorCode RestTestAtRest(RestTest, PetscBool *);
/* When it came to rest, on viewer (NULL: not printed), and at_rest in the report.
 * Collective on the viewer. */
PETSC_EXTERN PetscErrorCode RestTestView(RestTest, Report, PetscViewer);
/* Not collective. */
PETSC_EXTERN PetscErrorCode RestTestDestroy(RestTest *);
