/* The Hessian of the internal energy applied to a vector, matrix-free (element by
 * element): the stability estimate's operator (src/integrate/stability.c). */
#include "clothimpl.h"
#include <drape.h>

PetscErrorCode ClothApplyHessian(Cloth c, const PetscScalar *x, const PetscScalar *z, PetscScalar *y)
{
  const PetscScalar *xl;
  PetscScalar       *zl, *yl;
  Vec                Zl;
  PetscReal          H[225];

  PetscFunctionBeginUser;
  Zl = c->Zl;
  PetscCall(VecPlaceArray(c->Xg, z));
  PetscCall(VecScatterBegin(c->ghost, c->Xg, Zl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(c->ghost, c->Xg, Zl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecResetArray(c->Xg));
  PetscCall(ClothScatterPositions(c, x, &xl));
  PetscCall(VecGetArray(Zl, &zl));
  PetscCall(VecGetArray(c->Yl, &yl));
  PetscCall(PetscArrayzero(yl, 3 * c->nlocal));
  for (PetscInt l = 0; l < c->nlocal; l++)
    if (c->pinned_local[l]) zl[3 * l] = zl[3 * l + 1] = zl[3 * l + 2] = 0;
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt n = KindSize(kind), m = 3 * n;
    for (PetscInt e = 0; e < KindCount(c, kind); e++) {
      const PetscInt *p = KindParticles(c, kind, e);
      ElementHessian(c, PETSC_FALSE, kind, e, xl, H);
      for (PetscInt i = 0; i < m; i++) {
        PetscReal s = 0;
        for (PetscInt j = 0; j < m; j++) s += H[m * i + j] * zl[3 * p[j / 3] + j % 3];
        yl[3 * p[i / 3] + i % 3] += s;
      }
    }
  }
  for (PetscInt k = 0; k < c->nowned; k++)
    for (PetscInt d = 0; d < 3; d++) y[3 * k + d] = c->pinned[k] ? 0 : yl[3 * c->owned_local[k] + d];
  PetscCall(VecRestoreArray(c->Yl, &yl));
  PetscCall(VecRestoreArray(Zl, &zl));
  PetscCall(ClothEndScatter(c, &xl));
  PetscFunctionReturn(0);
}

