/* Stability limits of the explicit schemes from Omega_max (paper section 4).
 *
 * Omega_max^2 = lambda_max(M^-1 H), H the Hessian of the internal energy with pins
 * removed, by power iteration on the symmetric M^-1/2 H M^-1/2 (matrix-free: no
 * matrix is built for an explicit run). For the top mode x'' = -Omega^2 x - c x':
 *   symplectic Euler  h <= (sqrt(c^2 + 4 Omega^2) - c) / Omega^2   (2/Omega at c = 0)
 *   explicit Euler    h <= c / Omega^2 if the top mode is underdamped (c < 2 Omega),
 *                     h <= 2 / (c/2 + sqrt(c^2/4 - Omega^2)) otherwise; no step at c = 0.
 */
#include <simulation.h>
#include <drape.h>

PetscErrorCode StabilityEstimate(Cloth cloth, const PetscScalar *x, PetscInt iterations, StabilityLimits *lim)
{
  ClothInfo        info;
  const PetscReal *mass;
  const PetscBool *pinned;
  PetscScalar     *z, *w;
  const PetscInt  *natural;
  PetscReal        lambda = 0, c, Om2, loc[2], sum[2];
  PetscInt         n;
  DM               da;
  MPI_Comm         comm;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.stability, 0, 0, 0, 0));
  PetscCall(ClothGetInfo(cloth, &info));
  PetscCall(ClothGetMasses(cloth, &mass, &pinned));
  PetscCall(ClothGetDM(cloth, &da));
  comm = PetscObjectComm((PetscObject) da);
  n    = 3 * info.nowned;
  PetscCall(PetscMalloc2(n, &z, n, &w));
  /* start vector from each particle's lattice index: the same on any number of ranks */
  PetscCall(ClothGetNatural(cloth, &natural));
  for (PetscInt i = 0; i < n; i++) {
    PetscReal h = PetscSinReal(12.9898 * (3 * natural[i / 3] + i % 3) + 78.233) * 43758.5453;
    z[i]        = h - PetscFloorReal(h);
  }
  for (PetscInt it = 0; it < iterations; it++) {
    /* w = M^-1/2 H M^-1/2 z, lambda = (z.w)/(z.z) */
    for (PetscInt i = 0; i < n; i++) z[i] /= PetscSqrtReal(mass[i / 3]);
    PetscCall(ClothApplyHessian(cloth, x, z, w));
    loc[0] = loc[1] = 0;
    for (PetscInt i = 0; i < n; i++) {
      z[i] *= PetscSqrtReal(mass[i / 3]);
      w[i] /= PetscSqrtReal(mass[i / 3]);
      loc[0] += z[i] * w[i];
      loc[1] += w[i] * w[i];
    }
    PetscCall(MPIU_Allreduce(loc, sum, 2, MPIU_REAL, MPI_SUM, comm));
    loc[0] = 0;
    for (PetscInt i = 0; i < n; i++) loc[0] += z[i] * z[i];
    PetscCall(MPIU_Allreduce(loc, &c, 1, MPIU_REAL, MPI_SUM, comm));
    lambda = c > 0 ? sum[0] / c : 0;
    if (sum[1] <= 0) break;
    for (PetscInt i = 0; i < n; i++) z[i] = w[i] / PetscSqrtReal(sum[1]);
  }
  PetscCall(PetscFree2(z, w));
  c               = info.damping;
  Om2             = PetscMax(lambda, 0);
  lim->omega      = PetscSqrtReal(Om2);
  lim->iterations = iterations;
  if (Om2 > 0) {
    lim->symplectic = (PetscSqrtReal(c * c + 4 * Om2) - c) / Om2;
    if (c <= 0)
      lim->euler = 0;
    else if (c < 2 * lim->omega)
      lim->euler = c / Om2;
    else
      lim->euler = 2 / (0.5 * c + PetscSqrtReal(0.25 * c * c - Om2));
  } else {
    lim->symplectic = PETSC_INFINITY;
    lim->euler      = c > 0 ? 2 / c : PETSC_INFINITY;
  }
  PetscCall(PetscLogEventEnd(drape_log.stability, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}
