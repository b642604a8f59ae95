/* The rest test: kinetic energy per unit mass of the free particles below
 * -drape_rest_tol for -drape_rest_time ends a draping run (rest.h). */
#include "rest.h"
#include <drape.h>

struct _p_RestTest {
  MPI_Comm  comm;
  PetscReal tol, time; /* J/kg (0: never at rest); s */
  PetscReal since;     /* below tol since this time (-1: not below) */
  PetscReal t;         /* when it came to rest */
  PetscBool at_rest;
};

PetscErrorCode RestTestCreate(MPI_Comm comm, RestTest *rest)
{
  PetscFunctionBeginUser;
  PetscCall(PetscNew(rest));
  (*rest)->comm  = comm;
  (*rest)->time  = 0.2;
  (*rest)->since = -1;
  PetscFunctionReturn(0);
}

PetscErrorCode RestTestDestroy(RestTest *rest)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree(*rest));
  PetscFunctionReturn(0);
}

PetscErrorCode RestTestSetFromOptions(RestTest r)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(r->comm, NULL, "Rest test: the run ends when the cloth comes to rest", "RestTest");
  PetscCall(PetscOptionsReal("-drape_rest_tol", "Stop when the kinetic energy per unit mass (J/kg) stays below this for -drape_rest_time (0: never)", "RestTestUpdate", r->tol, &r->tol, NULL));
  PetscCall(PetscOptionsReal("-drape_rest_time", "Simulated time the cloth must stay below -drape_rest_tol to count as at rest (s)", "RestTestUpdate", r->time, &r->time, NULL));
  PetscOptionsEnd();
  PetscCall(DrapeCheckReal(r->comm, "-drape_rest_tol", 1, &r->tol, 0, 1e6, "J/kg"));
  PetscCall(DrapeCheckReal(r->comm, "-drape_rest_time", 1, &r->time, 0, 1e6, "s"));
  PetscFunctionReturn(0);
}

PetscErrorCode RestTestUpdate(RestTest r, Cloth cloth, const PetscScalar *v, PetscReal t, PetscBool *at_rest)
{
  PetscReal        loc[2] = {0, 0}, sum[2];
  const PetscReal *mass;
  const PetscBool *pinned;
  ClothInfo        info;

  PetscFunctionBeginUser;
  *at_rest = PETSC_FALSE;
  if (r->tol <= 0) PetscFunctionReturn(0);
  PetscCall(ClothGetInfo(cloth, &info));
  PetscCall(ClothGetMasses(cloth, &mass, &pinned));
  for (PetscInt k = 0; k < info.nowned; k++) {
    if (pinned[k]) continue; /* pinned and inactive particles never move */
    for (PetscInt d = 0; d < 3; d++) loc[0] += 0.5 * mass[k] * v[3 * k + d] * v[3 * k + d];
    loc[1] += mass[k];
  }
  PetscCall(MPIU_Allreduce(loc, sum, 2, MPIU_REAL, MPI_SUM, r->comm));
  if (sum[0] / sum[1] >= r->tol)
    r->since = -1;
  else if (r->since < 0)
    r->since = t;
  else if (t - r->since >= r->time) {
    r->t       = t;
    r->at_rest = *at_rest = PETSC_TRUE;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode RestTestAtRest(RestTest r, PetscBool *at_rest)
{
  PetscFunctionBeginUser;
  *at_rest = r->at_rest;
  PetscFunctionReturn(0);
}

PetscErrorCode RestTestView(RestTest r, Report report, PetscViewer viewer)
{
  PetscFunctionBeginUser;
  PetscCall(ReportSetBool(report, "at_rest", r->at_rest));
  if (viewer && r->at_rest) PetscCall(PetscViewerASCIIPrintf(viewer, "At rest at t = %g s: kinetic energy below -drape_rest_tol %g J/kg since t = %g s\n", (double) r->t, (double) r->tol, (double) r->since));
  PetscFunctionReturn(0);
}
