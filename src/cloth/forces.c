/* Loops of the element kernels over the local element lists: forces, energies,
 * Hessian products and the assembled implicit matrix. Nothing here knows how the
 * particles were distributed: only local arrays, element lists and index maps. */
#include "clothimpl.h"
#include "kernels.h"
#include <drape.h>

/* Ghosted local copy of the owned positions x (owned-particle order). */
PetscErrorCode ClothScatterPositions(Cloth c, const PetscScalar *x, const PetscScalar **xl)
{
  PetscFunctionBeginUser;
  PetscCall(VecPlaceArray(c->Xg, x));
  PetscCall(DMGlobalToLocalBegin(c->da, c->Xg, INSERT_VALUES, c->Xl));
  PetscCall(DMGlobalToLocalEnd(c->da, c->Xg, INSERT_VALUES, c->Xl));
  PetscCall(VecResetArray(c->Xg));
  PetscCall(VecGetArrayRead(c->Xl, xl));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothEndScatter(Cloth c, const PetscScalar **xl)
{
  PetscFunctionBeginUser;
  PetscCall(VecRestoreArrayRead(c->Xl, xl));
  PetscFunctionReturn(0);
}

/* fl (ghosted, zeroed by the caller) -= gradient of the internal energy at xl. */
static void AccumulateInternalForce(Cloth c, const PetscReal *xl, PetscReal *fl)
{
  const ClothElements *st = &c->stretch_el, *sh = &c->shear_el, *be = &c->bend_el;
  PetscReal            g[9];

  for (PetscInt e = 0; e < st->n; e++) {
    const PetscInt a = st->p[2 * e], b = st->p[2 * e + 1];
    KernelStretch(xl + 3 * a, xl + 3 * b, st->coef[e], st->rest[e], g, NULL, PETSC_FALSE);
    for (PetscInt d = 0; d < 3; d++) {
      fl[3 * a + d] -= g[d];
      fl[3 * b + d] -= g[3 + d];
    }
  }
  for (PetscInt pass = 0; pass < 2; pass++) {
    const ClothElements *el   = pass ? be : sh;
    KernelAngleKind      kind = pass ? KERNEL_BEND : KERNEL_SHEAR;
    for (PetscInt e = 0; e < el->n; e++) {
      const PetscInt a = el->p[3 * e], b = el->p[3 * e + 1], v = el->p[3 * e + 2];
      KernelAngle(kind, xl + 3 * a, xl + 3 * b, xl + 3 * v, el->coef[e], g, NULL, PETSC_FALSE);
      for (PetscInt d = 0; d < 3; d++) {
        fl[3 * a + d] -= g[d];
        fl[3 * b + d] -= g[3 + d];
        fl[3 * v + d] -= g[6 + d];
      }
    }
  }
}

PetscErrorCode ClothComputeInternalForce(Cloth c, const PetscScalar *x, PetscScalar *f)
{
  const PetscScalar *xl;
  PetscScalar       *fl;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.forces, 0, 0, 0, 0));
  PetscCall(ClothScatterPositions(c, x, &xl));
  PetscCall(VecGetArray(c->Yl, &fl));
  PetscCall(PetscArrayzero(fl, 3 * c->nlocal));
  AccumulateInternalForce(c, xl, fl);
  for (PetscInt k = 0; k < c->nowned; k++)
    for (PetscInt d = 0; d < 3; d++) f[3 * k + d] = fl[3 * c->owned_local[k] + d];
  PetscCall(VecRestoreArray(c->Yl, &fl));
  PetscCall(ClothEndScatter(c, &xl));
  PetscCall(PetscLogEventEnd(drape_log.forces, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothComputeAcceleration(Cloth c, const PetscScalar *x, const PetscScalar *v, PetscScalar *a)
{
  const PetscScalar *xl;
  PetscScalar       *fl;
  const PetscReal    cd = c->damping;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.forces, 0, 0, 0, 0));
  PetscCall(ClothScatterPositions(c, x, &xl));
  PetscCall(VecGetArray(c->Yl, &fl));
  PetscCall(PetscArrayzero(fl, 3 * c->nlocal));
  AccumulateInternalForce(c, xl, fl);
  for (PetscInt k = 0; k < c->nowned; k++) {
    const PetscInt l = c->owned_local[k];
    if (c->pinned[k]) {
      a[3 * k] = a[3 * k + 1] = a[3 * k + 2] = 0;
      continue;
    }
    for (PetscInt d = 0; d < 3; d++) a[3 * k + d] = fl[3 * l + d] / c->mass[k] + c->gravity[d] - cd * v[3 * k + d];
  }
  PetscCall(VecRestoreArray(c->Yl, &fl));
  PetscCall(ClothEndScatter(c, &xl));
  PetscCall(PetscLogEventEnd(drape_log.forces, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothComputeEnergies(Cloth c, const PetscScalar *x, const PetscScalar *v, ClothEnergies *en)
{
  const ClothElements *st = &c->stretch_el, *sh = &c->shear_el, *be = &c->bend_el;
  const PetscScalar   *xl;
  PetscReal            local[5] = {0, 0, 0, 0, 0}, sum[5];

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.energies, 0, 0, 0, 0));
  for (PetscInt k = 0; k < c->nowned; k++) {
    for (PetscInt d = 0; d < 3; d++) {
      local[0] += 0.5 * c->mass[k] * v[3 * k + d] * v[3 * k + d];
      local[1] -= c->mass[k] * c->gravity[d] * x[3 * k + d];
    }
  }
  PetscCall(ClothScatterPositions(c, x, &xl));
  for (PetscInt e = 0; e < st->n; e++)
    if (st->own[e]) local[2] += KernelStretch(xl + 3 * st->p[2 * e], xl + 3 * st->p[2 * e + 1], st->coef[e], st->rest[e], NULL, NULL, PETSC_FALSE);
  for (PetscInt e = 0; e < sh->n; e++)
    if (sh->own[e]) local[3] += KernelAngle(KERNEL_SHEAR, xl + 3 * sh->p[3 * e], xl + 3 * sh->p[3 * e + 1], xl + 3 * sh->p[3 * e + 2], sh->coef[e], NULL, NULL, PETSC_FALSE);
  for (PetscInt e = 0; e < be->n; e++)
    if (be->own[e]) local[4] += KernelAngle(KERNEL_BEND, xl + 3 * be->p[3 * e], xl + 3 * be->p[3 * e + 1], xl + 3 * be->p[3 * e + 2], be->coef[e], NULL, NULL, PETSC_FALSE);
  PetscCall(ClothEndScatter(c, &xl));
  PetscCall(MPIU_Allreduce(local, sum, 5, MPIU_REAL, MPI_SUM, c->comm));
  en->kinetic = sum[0];
  en->gravity = sum[1];
  en->stretch = sum[2];
  en->shear   = sum[3];
  en->bend    = sum[4];
  PetscCall(PetscLogEventEnd(drape_log.energies, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

/* Element Hessian (particles p[0..n-1]); H is (3n x 3n) row-major. */
static inline void ElementHessian(Cloth c, PetscInt kind, const PetscReal *xl, const PetscInt *p, PetscReal coef, PetscReal rest, PetscReal *H)
{
  PetscBool project = (PetscBool)!c->exact_hessian;
  if (kind == 0) KernelStretch(xl + 3 * p[0], xl + 3 * p[1], coef, rest, NULL, H, project);
  else KernelAngle(kind == 1 ? KERNEL_SHEAR : KERNEL_BEND, xl + 3 * p[0], xl + 3 * p[1], xl + 3 * p[2], coef, NULL, H, project);
}

PetscErrorCode ClothApplyHessian(Cloth c, const PetscScalar *x, const PetscScalar *z, PetscScalar *y)
{
  const ClothElements *lists[3] = {&c->stretch_el, &c->shear_el, &c->bend_el};
  const PetscScalar   *xl;
  PetscScalar         *zl, *yl;
  Vec                  Zl;
  PetscReal            H[81];

  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(c->da, &Zl));
  PetscCall(VecPlaceArray(c->Xg, z));
  PetscCall(DMGlobalToLocal(c->da, c->Xg, INSERT_VALUES, Zl));
  PetscCall(VecResetArray(c->Xg));
  PetscCall(ClothScatterPositions(c, x, &xl));
  PetscCall(VecGetArray(Zl, &zl));
  PetscCall(VecGetArray(c->Yl, &yl));
  PetscCall(PetscArrayzero(yl, 3 * c->nlocal));
  for (PetscInt l = 0; l < c->nlocal; l++)
    if (c->pinned_local[l]) zl[3 * l] = zl[3 * l + 1] = zl[3 * l + 2] = 0;
  for (PetscInt kind = 0; kind < 3; kind++) {
    const ClothElements *el = lists[kind];
    const PetscInt       n  = kind ? 3 : 2, m = 3 * n;
    for (PetscInt e = 0; e < el->n; e++) {
      const PetscInt *p = el->p + n * e;
      ElementHessian(c, kind, xl, p, el->coef[e], el->rest ? el->rest[e] : 0, H);
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
  PetscCall(DMRestoreLocalVector(c->da, &Zl));
  PetscFunctionReturn(0);
}

/* Add b*H(xl) + a*M into J; xl == NULL inserts the pattern only (preallocation). */
static PetscErrorCode ClothAddToMatrix(Cloth c, const PetscReal *xl, PetscReal a, PetscReal b, Mat J)
{
  const ClothElements *lists[3] = {&c->stretch_el, &c->shear_el, &c->bend_el};
  PetscReal            H[81], D[9];

  PetscFunctionBeginUser;
  PetscCall(PetscArrayzero(H, 81));
  for (PetscInt kind = 0; kind < 3; kind++) {
    const ClothElements *el = lists[kind];
    const PetscInt       n  = kind ? 3 : 2;
    for (PetscInt e = 0; e < el->n; e++) {
      const PetscInt *p = el->p + n * e;
      PetscInt        rows[3], cols[3];
      for (PetscInt i = 0; i < n; i++) {
        rows[i] = c->row_map[p[i]];
        cols[i] = c->col_map[p[i]];
      }
      if (xl) {
        ElementHessian(c, kind, xl, p, el->coef[e], el->rest ? el->rest[e] : 0, H);
        for (PetscInt i = 0; i < 9 * n * n; i++) H[i] *= b;
      }
      PetscCall(MatSetValuesBlocked(J, n, rows, n, cols, H, ADD_VALUES));
    }
  }
  for (PetscInt k = 0; k < c->nowned; k++) {
    PetscInt g = c->global[c->owned_local[k]];
    PetscCall(PetscArrayzero(D, 9));
    D[0] = D[4] = D[8] = a * c->mass[k];
    PetscCall(MatSetValuesBlocked(J, 1, &g, 1, &g, D, ADD_VALUES));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ClothCreateMatrix(Cloth c, Mat *J)
{
  Mat      P;
  PetscInt n = 3 * c->nowned;

  PetscFunctionBeginUser;
  PetscCall(MatCreate(c->comm, &P));
  PetscCall(MatSetSizes(P, n, n, PETSC_DETERMINE, PETSC_DETERMINE));
  PetscCall(MatSetBlockSize(P, 3));
  PetscCall(MatSetType(P, MATPREALLOCATOR));
  PetscCall(MatSetUp(P));
  PetscCall(ClothAddToMatrix(c, NULL, 0, 0, P));
  PetscCall(MatAssemblyBegin(P, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(P, MAT_FINAL_ASSEMBLY));
  PetscCall(MatCreate(c->comm, J));
  PetscCall(MatSetSizes(*J, n, n, PETSC_DETERMINE, PETSC_DETERMINE));
  PetscCall(MatSetBlockSize(*J, 3));
  PetscCall(MatSetType(*J, MATAIJ));
  PetscCall(MatSetOptionsPrefix(*J, "drape_"));
  PetscCall(MatSetFromOptions(*J));
  PetscCall(MatPreallocatorPreallocate(P, PETSC_TRUE, *J));
  PetscCall(MatDestroy(&P));
  PetscCall(MatSetOption(*J, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
  PetscCall(MatSetOption(*J, MAT_NO_OFF_PROC_ENTRIES, PETSC_TRUE));
  PetscCall(MatSetOption(*J, MAT_SYMMETRIC, PETSC_TRUE));
  PetscCall(MatSetOption(*J, MAT_SYMMETRY_ETERNAL, PETSC_TRUE));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothAssembleMatrix(Cloth c, const PetscScalar *x, PetscReal a, PetscReal b, Mat J)
{
  const PetscScalar *xl;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.jacobian, 0, 0, 0, 0));
  PetscCall(MatZeroEntries(J));
  PetscCall(ClothScatterPositions(c, x, &xl));
  PetscCall(ClothAddToMatrix(c, xl, a, b, J));
  PetscCall(ClothEndScatter(c, &xl));
  PetscCall(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  PetscCall(PetscLogEventEnd(drape_log.jacobian, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}
