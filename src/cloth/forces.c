/* Loops of the element kernels over the local element lists: forces, energies,
 * Hessian products and the assembled implicit matrix. Nothing here knows how the
 * particles were distributed: only local arrays, element lists and index maps. */
#include "clothimpl.h"
#include "kernels.h"
#include <drape.h>

/* Ghosted local copy of the owned positions x (owned-particle order; the owned
 * particles come first in the local order, so without ghosts, on one rank, x itself
 * is the local array and nothing is copied). Collective (the scatter is made at the
 * first call). */
PetscErrorCode ClothScatterPositions(Cloth c, const PetscScalar *x, const PetscScalar **xl)
{
  PetscFunctionBeginUser;
  PetscCall(ClothSetUpGhosts(c));
  if (c->nlocal == c->nowned) {
    *xl = x;
    PetscFunctionReturn(0);
  }
  PetscCall(VecPlaceArray(c->Xg, x));
  PetscCall(VecScatterBegin(c->ghost, c->Xg, c->Xl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(c->ghost, c->Xg, c->Xl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecResetArray(c->Xg));
  PetscCall(VecGetArrayRead(c->Xl, xl));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothEndScatter(Cloth c, const PetscScalar **xl)
{
  PetscFunctionBeginUser;
  if (c->nlocal == c->nowned)
    *xl = NULL;
  else
    PetscCall(VecRestoreArrayRead(c->Xl, xl));
  PetscFunctionReturn(0);
}

/* fl[p] -= g for the n particles of an element. */
static inline void Scatter(PetscReal *restrict fl, PetscInt n, const PetscInt *restrict p, const PetscReal *restrict g)
{
  for (PetscInt k = 0; k < n; k++)
    for (PetscInt d = 0; d < 3; d++) fl[3 * p[k] + d] -= g[3 * k + d];
}

/* Angle elements in chunks: first the coefficients of ANGLE_CHUNK elements (each
 * a chain of square roots and divisions, and for shear an asin, independent of the
 * others, so the processor overlaps them), then their gradients in list order. The
 * sums per particle are the same, in the same order, as element by element. */
#define ANGLE_CHUNK 64

static inline void AccumulateBendForces(const ClothElements *el, const PetscReal *restrict xl, PetscReal *restrict fl)
{
  PetscReal w[3 * ANGLE_CHUNK], g[9];

  for (PetscInt e0 = 0; e0 < el->n; e0 += ANGLE_CHUNK) {
    const PetscInt  n = PetscMin(ANGLE_CHUNK, el->n - e0);
    const PetscInt *p = el->p + 3 * e0;
    for (PetscInt k = 0; k < n; k++) KernelAngleCoefficients(PETSC_TRUE, xl + 3 * p[3 * k], xl + 3 * p[3 * k + 1], xl + 3 * p[3 * k + 2], ElemCoef(el, e0 + k), ElemLaw(el, e0 + k), w + 3 * k);
    for (PetscInt k = 0; k < n; k++) {
      KernelAngleGradientFromCoefficients(w + 3 * k, xl + 3 * p[3 * k], xl + 3 * p[3 * k + 1], xl + 3 * p[3 * k + 2], g);
      Scatter(fl, 3, p + 3 * k, g);
    }
  }
}

/* Shear by cells: the shear list holds each lattice cell as its four corners in a
 * row, the vertex of corner q being cell particle q (clothimpl.h). The corners share
 * the cell's four edges, so a cell computes four edge vectors and updates four
 * particles, where corner by corner it would be twelve. Chunked like the bending. */
static inline void AccumulateShearForces(const ClothElements *el, const PetscReal *restrict xl, PetscReal *restrict fl)
{
  const PetscInt ncell = el->n / 4;
  PetscReal      w[8 * ANGLE_CHUNK], g[12];

  for (PetscInt c0 = 0; c0 < ncell; c0 += ANGLE_CHUNK) {
    const PetscInt  n = PetscMin(ANGLE_CHUNK, ncell - c0);
    const PetscInt *p = el->p + 12 * c0;
    for (PetscInt k = 0; k < n; k++) {
      const PetscInt *q = p + 12 * k;
      KernelShearCellCoefficients(xl + 3 * q[2], xl + 3 * q[5], xl + 3 * q[8], xl + 3 * q[11], ElemCoef(el, 4 * (c0 + k)), w + 8 * k);
    }
    for (PetscInt k = 0; k < n; k++) {
      const PetscInt *q      = p + 12 * k;
      const PetscInt  idx[4] = {q[2], q[5], q[8], q[11]};
      KernelShearCellGradient(w + 8 * k, xl + 3 * idx[0], xl + 3 * idx[1], xl + 3 * idx[2], xl + 3 * idx[3], g);
      Scatter(fl, 4, idx, g);
    }
  }
}

/* The bending friction at the plastic curvatures of the last step (KernelFriction). */
static inline void AccumulateFrictionForces(Cloth c, const PetscReal *restrict xl, PetscReal *restrict fl)
{
  const ClothFrictionList *fr = &c->friction_el;
  PetscReal                g[15];

  for (PetscInt e = 0; e < fr->n; e++) {
    const PetscInt      *p = fr->p + 5 * e;
    const KernelFriction f = FrictionOf(c, fr, e);
    KernelFrictionEnergy(&f, fr->kp[e], xl + 3 * p[0], xl + 3 * p[1], xl + 3 * p[2], xl + 3 * p[3], xl + 3 * p[4], g, NULL);
    Scatter(fl, 5, p, g);
  }
}

/* fl (ghosted, zeroed by the caller) -= gradient of the internal energy at xl. */
static void AccumulateInternalForce(Cloth c, const PetscReal *restrict xl, PetscReal *restrict fl)
{
  const ClothElements *st = &c->stretch_el;
  PetscReal            g[9];

  for (PetscInt e = 0; e < st->n; e++) {
    KernelStretchGradient(xl + 3 * st->p[2 * e], xl + 3 * st->p[2 * e + 1], ElemCoef(st, e), ElemRest(st, e), g);
    Scatter(fl, 2, st->p + 2 * e, g);
  }
  AccumulateShearForces(&c->shear_el, xl, fl);
  AccumulateBendForces(&c->bend_el, xl, fl);
  AccumulateFrictionForces(c, xl, fl);
}

/* The element lists' loop: the internal force on the owned particles, scaled and
 * shifted to an acceleration when v is given (a = F/m + g - c v, 0 on pinned
 * particles), else the force itself. */
static PetscErrorCode ElementsForce(Cloth c, const PetscScalar *x, const PetscScalar *v, PetscScalar *out)
{
  const PetscScalar *xl;
  PetscScalar       *fl;
  Vec                Yl;

  PetscFunctionBeginUser;
  PetscCall(ClothScatterPositions(c, x, &xl));
  PetscCall(ClothGetLocalWork(c, &Yl));
  PetscCall(VecGetArray(Yl, &fl));
  PetscCall(PetscArrayzero(fl, 3 * c->nlocal));
  AccumulateInternalForce(c, xl, fl);
  for (PetscInt k = 0; k < c->nowned; k++) {
    const PetscScalar *F = fl + 3 * c->owned_local[k];
    for (PetscInt d = 0; d < 3; d++) {
      if (!v)
        out[3 * k + d] = F[d];
      else
        out[3 * k + d] = c->pinned[k] ? 0 : F[d] / c->mass[k] + c->gravity[d] - c->damping * v[3 * k + d];
    }
  }
  PetscCall(VecRestoreArray(Yl, &fl));
  PetscCall(ClothEndScatter(c, &xl));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothComputeInternalForce(Cloth c, const PetscScalar *x, PetscScalar *f)
{
  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.forces, 0, 0, 0, 0));
  if (c->lattice)
    PetscCall(ClothLatticeComputeForce(c, x, f));
  else
    PetscCall(ElementsForce(c, x, NULL, f));
  PetscCall(PetscLogEventEnd(drape_log.forces, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

/* owned particle k is local particle k (owned_local[k] = k) */
PetscErrorCode ClothComputeAcceleration(Cloth c, const PetscScalar *x, const PetscScalar *v, PetscScalar *a)
{
  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.forces, 0, 0, 0, 0));
  if (c->lattice)
    PetscCall(ClothLatticeComputeAcceleration(c, x, v, a));
  else
    PetscCall(ElementsForce(c, x, v, a));
  PetscCall(PetscLogEventEnd(drape_log.forces, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothKickDrift(Cloth c, PetscScalar *x, PetscScalar *v, PetscReal kick, PetscReal drift, PetscBool *done)
{
  PetscFunctionBeginUser;
  *done = (PetscBool) (c->lattice != NULL);
  if (!*done) PetscFunctionReturn(0);
  PetscCall(PetscLogEventBegin(drape_log.forces, 0, 0, 0, 0));
  PetscCall(ClothLatticeKickDrift(c, x, v, kick, drift));
  PetscCall(PetscLogEventEnd(drape_log.forces, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothComputeEnergies(Cloth c, const PetscScalar *x, const PetscScalar *v, ClothEnergies *en)
{
  const ClothElements     *st = &c->stretch_el, *sh = &c->shear_el, *be = &c->bend_el;
  const ClothFrictionList *fr = &c->friction_el;
  const PetscScalar       *xl;
  PetscReal                local[5] = {0, 0, 0, 0, 0}, sum[5], strain = -1;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.energies, 0, 0, 0, 0));
  for (PetscInt k = 0; k < c->nowned; k++) {
    if (!c->active[k]) continue;
    for (PetscInt d = 0; d < 3; d++) {
      local[0] += 0.5 * c->mass[k] * v[3 * k + d] * v[3 * k + d];
      local[1] -= c->mass[k] * c->gravity[d] * x[3 * k + d];
    }
  }
  if (c->lattice) { /* the same elements, from the lattice's patch */
    PetscCall(ClothLatticeEnergies(c, x, local + 2, &strain));
    goto reduce;
  }
  PetscCall(ClothScatterPositions(c, x, &xl));
  for (PetscInt e = 0; e < st->n; e++) {
    const PetscReal *a = xl + 3 * st->p[2 * e], *b = xl + 3 * st->p[2 * e + 1], L = ElemRest(st, e);
    if (!st->own[e]) continue;
    local[2] += KernelStretch(a, b, ElemCoef(st, e), L, NULL, NULL, PETSC_FALSE);
    strain = PetscMax(strain, PetscSqrtReal(PetscSqr(b[0] - a[0]) + PetscSqr(b[1] - a[1]) + PetscSqr(b[2] - a[2])) / L - 1);
  }
  for (PetscInt e = 0; e < sh->n; e++)
    if (sh->own[e]) local[3] += KernelAngle(KERNEL_SHEAR, xl + 3 * sh->p[3 * e], xl + 3 * sh->p[3 * e + 1], xl + 3 * sh->p[3 * e + 2], ElemCoef(sh, e), NULL, NULL, NULL, PETSC_FALSE);
  for (PetscInt e = 0; e < be->n; e++)
    if (be->own[e]) local[4] += KernelAngle(KERNEL_BEND, xl + 3 * be->p[3 * e], xl + 3 * be->p[3 * e + 1], xl + 3 * be->p[3 * e + 2], ElemCoef(be, e), ElemLaw(be, e), NULL, NULL, PETSC_FALSE);
  for (PetscInt e = 0; e < fr->n; e++) {
    const PetscInt      *p = fr->p + 5 * e;
    const KernelFriction f = FrictionOf(c, fr, e);
    if (fr->own[e]) local[4] += KernelFrictionEnergy(&f, fr->kp[e], xl + 3 * p[0], xl + 3 * p[1], xl + 3 * p[2], xl + 3 * p[3], xl + 3 * p[4], NULL, NULL);
  }
  PetscCall(ClothEndScatter(c, &xl));
reduce:
  PetscCall(MPIU_Allreduce(local, sum, 5, MPIU_REAL, MPI_SUM, c->comm));
  PetscCall(MPIU_Allreduce(&strain, &en->strain_max, 1, MPIU_REAL, MPIU_MAX, c->comm));
  if (!c->nstretch) en->strain_max = (PetscReal) NAN; /* no stretch edges: not measured */
  en->kinetic = sum[0];
  en->gravity = sum[1];
  en->stretch = sum[2];
  en->shear   = sum[3];
  en->bend    = sum[4];
  PetscCall(PetscLogEventEnd(drape_log.energies, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothSetConstraints(Cloth c, const ClothConstraint type[], const PetscReal normal[], const PetscReal block[])
{
  PetscScalar *buf, *l;
  PetscInt     count = 0;

  PetscFunctionBeginUser;
  if (!c->ctype) PetscCall(PetscMalloc3(c->nlocal, &c->ctype, 3 * c->nlocal, &c->cnormal, 9 * c->nowned + 1, &c->cblock));
  for (PetscInt i = 0; i < 9 * c->nowned; i++) c->cblock[i] = block && type ? block[i] : 0;
  /* owned values to the ghosts: the normals, then the types (one real each) */
  PetscCall(PetscMalloc1(3 * c->nowned + 1, &buf));
  for (PetscInt k = 0; k < c->nowned; k++)
    for (PetscInt d = 0; d < 3; d++) buf[3 * k + d] = type && type[k] == CLOTH_SLIDE ? normal[3 * k + d] : 0;
  PetscCall(VecPlaceArray(c->Xg, buf));
  PetscCall(VecScatterBegin(c->ghost, c->Xg, c->Zl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(c->ghost, c->Xg, c->Zl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecGetArray(c->Zl, &l));
  PetscCall(PetscArraycpy(c->cnormal, l, 3 * c->nlocal));
  PetscCall(VecRestoreArray(c->Zl, &l));
  for (PetscInt k = 0; k < c->nowned; k++) buf[3 * k] = buf[3 * k + 1] = buf[3 * k + 2] = type ? (PetscScalar) type[k] : 0;
  PetscCall(VecScatterBegin(c->ghost, c->Xg, c->Zl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(c->ghost, c->Xg, c->Zl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecResetArray(c->Xg));
  PetscCall(VecGetArray(c->Zl, &l));
  for (PetscInt k = 0; k < c->nlocal; k++) {
    c->ctype[k] = c->pinned_local[k] ? CLOTH_FREE : (ClothConstraint) (PetscInt) PetscRealPart(l[3 * k]);
    count += c->ctype[k] != CLOTH_FREE;
  }
  PetscCall(VecRestoreArray(c->Zl, &l));
  PetscCall(PetscFree(buf));
  c->constrained = (PetscBool) (count > 0);
  PetscFunctionReturn(0);
}

/* B <- S B (left) or B S (right), S = I - n n^T (sliding) or 0 (fixed); B 3x3 with row stride ld. */
static inline void ProjectBlock(ClothConstraint type, const PetscReal *n, PetscReal *B, PetscInt ld, PetscBool left)
{
  if (type == CLOTH_FIXED) {
    for (PetscInt i = 0; i < 3; i++) B[ld * i] = B[ld * i + 1] = B[ld * i + 2] = 0;
    return;
  }
  if (left) {
    for (PetscInt j = 0; j < 3; j++) {
      PetscReal s = n[0] * B[j] + n[1] * B[ld + j] + n[2] * B[2 * ld + j];
      for (PetscInt i = 0; i < 3; i++) B[ld * i + j] -= n[i] * s;
    }
  } else {
    for (PetscInt i = 0; i < 3; i++) {
      PetscReal s = B[ld * i] * n[0] + B[ld * i + 1] * n[1] + B[ld * i + 2] * n[2];
      for (PetscInt j = 0; j < 3; j++) B[ld * i + j] -= s * n[j];
    }
  }
}

/* Element Hessian H (m x m) <- S H S for constrained particles. */
static inline void FilterElementHessian(Cloth c, PetscInt n, const PetscInt *p, PetscReal *H)
{
  const PetscInt m = 3 * n;
  for (PetscInt a = 0; a < n; a++) {
    const ClothConstraint t = c->ctype[p[a]];
    if (t == CLOTH_FREE) continue;
    for (PetscInt b = 0; b < n; b++) {
      ProjectBlock(t, c->cnormal + 3 * p[a], H + m * 3 * a + 3 * b, m, PETSC_TRUE);
      ProjectBlock(t, c->cnormal + 3 * p[a], H + m * 3 * b + 3 * a, m, PETSC_FALSE);
    }
  }
}

/* Diagonal block of owned particle k besides the Hessian: a m S + d (I - S) (+ the
 * block of ClothSetConstraints when sliding), with
 * d = a m + b tr(H_kk)/3 the mean diagonal of its unconstrained block, so that a
 * constrained row is scaled like its neighbours (m would do for the answer, but at
 * large steps, h^2 H >> M, it leaves rows a thousand times smaller than the others:
 * bad for the preconditioners, AMG above all). Pinned particles get m I. */
static inline void MassBlock(Cloth c, PetscInt k, PetscReal a, PetscReal b, PetscReal D[9])
{
  const PetscReal       m = c->mass[k];
  const ClothConstraint t = c->pinned[k] ? CLOTH_FIXED : (c->constrained ? c->ctype[c->owned_local[k]] : CLOTH_FREE);
  const PetscReal      *H = c->hdiag + 9 * k, d = c->pinned[k] ? m : a * m + b * (H[0] + H[4] + H[8]) / 3;

  for (PetscInt i = 0; i < 9; i++) D[i] = 0;
  D[0] = D[4] = D[8] = t == CLOTH_FIXED ? d : a * m;
  if (t == CLOTH_SLIDE) {
    const PetscReal *n = c->cnormal + 3 * c->owned_local[k], *B = c->cblock + 9 * k;
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < 3; j++) D[3 * i + j] += (d - a * m) * n[i] * n[j] + B[3 * i + j];
  }
}

PetscErrorCode ClothGetConstraintScale(Cloth c, PetscReal a, PetscReal b, PetscInt k, PetscReal *d)
{
  PetscFunctionBeginUser;
  *d = c->hdiag ? a * c->mass[k] + b * (c->hdiag[9 * k] + c->hdiag[9 * k + 4] + c->hdiag[9 * k + 8]) / 3 : c->mass[k];
  PetscFunctionReturn(0);
}

/* The implicit matrix's block of element e of list `kind`: the (projected unless
 * -cloth_hessian exact) Hessian, filtered by the contact constraints; its diagonal
 * blocks before the filter are summed into c->hdiag (owned particles). */
static inline void MatrixElementHessian(Cloth c, PetscInt kind, PetscInt e, const PetscReal *xl, PetscReal *H)
{
  const PetscInt  n = KindSize(kind), m = 3 * n;
  const PetscInt *p = KindParticles(c, kind, e);

  ElementHessian(c, (PetscBool) !c->exact_hessian, kind, e, xl, H);
  for (PetscInt a = 0; a < n; a++)
    if (p[a] < c->nowned)
      for (PetscInt i = 0; i < 3; i++)
        for (PetscInt j = 0; j < 3; j++) c->hdiag[9 * p[a] + 3 * i + j] += H[m * (3 * a + i) + 3 * a + j];
  if (c->constrained) FilterElementHessian(c, n, p, H);
}

PetscErrorCode ClothGetHessianDiagonal(Cloth c, const PetscReal **hdiag)
{
  PetscFunctionBeginUser;
  *hdiag = c->hdiag;
  PetscFunctionReturn(0);
}

/* The implicit matrix, of type `type` unless -drape_mat_type says otherwise, with
 * the exact nonzero pattern of the element lists. The element blocks are summed
 * into drape's row buffer (below); -drape_mat_assembly says how the rows reach
 * PETSc: csr, copied into AIJ's own value arrays (the default for AIJ: the buffer's
 * rows are its CSR rows; RowBufferToAIJ); coo, MatSetValuesCOO with the pattern
 * given once by MatSetPreallocationCOO (the default for other types that implement
 * COO natively; its map costs 16 bytes per nonzero, 2.6 kB per particle); or rows,
 * one MatSetValuesBlocked per block row (every other type: SBAIJ, BAIJ, dense; on
 * several ranks (S)BAIJ's rows are summed in its diagonal block's array and only
 * the cut rows' blocks outside it inserted: RowBufferSplitPositions). */
static PetscErrorCode ClothBuildRowBuffer(Cloth, Mat);

PetscErrorCode ClothCreateMatrix(Cloth c, MatType type, Mat *J)
{
  PetscInt  n = 3 * c->nowned;
  PetscBool native, aij;
  void (*coo)(void);
  const char *const modes[] = {"coo", "rows", "csr"};
  PetscInt          mode;

  PetscFunctionBeginUser;
  PetscCall(MatCreate(c->comm, J));
  PetscCall(MatSetSizes(*J, n, n, PETSC_DETERMINE, PETSC_DETERMINE));
  PetscCall(MatSetBlockSize(*J, 3));
  PetscCall(MatSetType(*J, type));
  PetscCall(MatSetOptionsPrefix(*J, "drape_"));
  PetscCall(MatSetFromOptions(*J));
  PetscCall(PetscObjectQueryFunction((PetscObject) *J, "MatSetPreallocationCOO_C", &coo));
  native = (PetscBool) (coo != NULL);
  PetscCall(PetscObjectTypeCompareAny((PetscObject) *J, &aij, MATSEQAIJ, MATMPIAIJ, ""));
  mode = aij ? 2 : native ? 0 : 1;
  PetscOptionsBegin(c->comm, "drape_", "Implicit matrix assembly", "ClothCreateMatrix");
  PetscCall(PetscOptionsEList("-mat_assembly",
                              "How the summed rows reach the matrix: csr (copied into AIJ's arrays; default for AIJ), coo (MatSetValuesCOO; default for other types that have it) or rows (MatSetValuesBlocked per block row; default for the rest)",
                              "ClothCreateMatrix", modes, 3, modes[mode], &mode, NULL));
  PetscOptionsEnd();
  if (mode == 2 && !aij) {
    MatType t;
    PetscCall(MatGetType(*J, &t));
    SETERRQ(c->comm, PETSC_ERR_USER_INPUT, "-drape_mat_assembly csr copies rows into AIJ's arrays, and the matrix is %s; use -drape_mat_assembly coo or rows with it", t);
  }
  c->rb_coo   = (PetscBool) (mode == 0);
  c->rb_csr   = (PetscBool) (mode == 2);
  c->rb_block = (PetscBool) (mode == 1);
  { /* one rank, a matrix whose array holds the buffer's layout: the buffer is that array (no buffer of drape's) */
    PetscBool seqaij, seqblock;
    PetscCall(PetscObjectTypeCompare((PetscObject) *J, MATSEQAIJ, &seqaij));
    PetscCall(PetscObjectTypeCompareAny((PetscObject) *J, &seqblock, MATSEQBAIJ, MATSEQSBAIJ, ""));
    c->rb_alias = (PetscBool) ((c->rb_csr && seqaij) || (c->rb_block && seqblock));
  }
  PetscCall(ClothBuildRowBuffer(c, *J));
  if (c->rb_coo) {
    /* one COO entry per row-buffer value, in the buffer's order (unique entries:
     * drape sums the element blocks; types without a native COO take PETSc's basic
     * implementation, MatSetValue per entry) */
    const PetscCount ncoo = c->rb_start[c->nowned];
    PetscInt        *ci, *cj, q = 0;
    PetscCall(PetscMalloc2(ncoo + 1, &ci, ncoo + 1, &cj));
    for (PetscInt k = 0; k < c->nowned; k++)
      for (PetscInt i = 0; i < 3; i++)
        for (PetscInt l = 0; l < c->rb_ncols[k]; l++)
          for (PetscInt j = 0; j < 3; j++, q++) {
            ci[q] = 3 * c->global[k] + i;
            cj[q] = 3 * c->rb_cols[c->rb_colstart[k] + l] + j;
          }
    PetscCall(MatSetPreallocationCOO(*J, ncoo, ci, cj));
    PetscCall(PetscFree2(ci, cj));
  } else {
    PetscInt     wide = 0;
    PetscScalar *zero;
    PetscBool    xaij;
    for (PetscInt k = 0; k < c->nowned; k++) wide = PetscMax(wide, c->rb_ncols[k]);
    PetscCall(PetscCalloc1(9 * wide + 1, &zero));
    PetscCall(PetscObjectTypeCompareAny((PetscObject) *J, &xaij, MATSEQAIJ, MATMPIAIJ, MATSEQBAIJ, MATMPIBAIJ, MATSEQSBAIJ, MATMPISBAIJ, ""));
    if (xaij) { /* the exact counts of the row buffer's rows (upper blocks only for SBAIJ, as the buffer holds), then the pattern as zeros: MATPREALLOCATOR's hash table took 5 % of a 40-step run at 512^2 */
      PetscInt *dnnz, *onnz;
      PetscCall(PetscMalloc2(c->nowned + 1, &dnnz, c->nowned + 1, &onnz));
      for (PetscInt k = 0; k < c->nowned; k++) {
        const PetscInt *col = c->rb_cols + c->rb_colstart[k];
        dnnz[k]             = 0;
        for (PetscInt l = 0; l < c->rb_ncols[k]; l++) dnnz[k] += col[l] >= c->rstart && col[l] < c->rstart + c->nowned;
        onnz[k] = c->rb_ncols[k] - dnnz[k];
      }
      PetscCall(MatXAIJSetPreallocation(*J, 3, dnnz, onnz, dnnz, onnz));
      PetscCall(PetscFree2(dnnz, onnz));
      for (PetscInt k = 0; k < c->nowned; k++) PetscCall(MatSetValuesBlocked(*J, 1, &c->global[k], c->rb_ncols[k], c->rb_cols + c->rb_colstart[k], zero, INSERT_VALUES));
      PetscCall(MatAssemblyBegin(*J, MAT_FINAL_ASSEMBLY));
      PetscCall(MatAssemblyEnd(*J, MAT_FINAL_ASSEMBLY));
    } else { /* dense and the rest: through MATPREALLOCATOR */
      Mat P;
      PetscCall(MatCreate(c->comm, &P));
      PetscCall(MatSetSizes(P, n, n, PETSC_DETERMINE, PETSC_DETERMINE));
      PetscCall(MatSetBlockSize(P, 3));
      PetscCall(MatSetType(P, MATPREALLOCATOR));
      PetscCall(MatSetUp(P));
      for (PetscInt k = 0; k < c->nowned; k++) PetscCall(MatSetValuesBlocked(P, 1, &c->global[k], c->rb_ncols[k], c->rb_cols + c->rb_colstart[k], zero, INSERT_VALUES));
      PetscCall(MatAssemblyBegin(P, MAT_FINAL_ASSEMBLY));
      PetscCall(MatAssemblyEnd(P, MAT_FINAL_ASSEMBLY));
      PetscCall(MatPreallocatorPreallocate(P, PETSC_TRUE, *J));
      PetscCall(MatDestroy(&P));
    }
    PetscCall(PetscFree(zero));
    PetscCall(MatSetOption(*J, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
    PetscCall(MatSetOption(*J, MAT_NO_OFF_PROC_ENTRIES, PETSC_TRUE));
  }
  PetscCall(MatSetOption(*J, MAT_SYMMETRIC, PETSC_TRUE));
  PetscCall(MatSetOption(*J, MAT_SYMMETRY_ETERNAL, PETSC_TRUE));
  PetscFunctionReturn(0);
}

/* Row-buffer assembly: the element blocks are summed into drape's own buffer, one
 * block row per owned particle with sorted global block columns, which then goes
 * to PETSc whole (MatSetValuesCOO) or row by row (MatSetValuesBlocked; element by
 * element, PETSc's MPISBAIJ insertion cost more than computing the Hessians).
 * Symmetric storage keeps only the blocks with global column >= row. */
/* Does the row buffer hold the block (a, b) of local particles a, b: a owned and
 * free, b free, and in the upper half for symmetric storage? */
static inline PetscBool RowBufferHolds(Cloth c, PetscBool sym, PetscInt a, PetscInt b)
{
  const PetscInt col = c->col_map[b];
  return (PetscBool) (a < c->nowned && c->row_map[a] >= 0 && col >= 0 && !(sym && col < c->row_map[a]));
}

/* Does the row buffer hold the extra block (owned row, global column) (not in the
 * lower half for symmetric storage)? */
static inline PetscBool BlockHeld(Cloth c, PetscBool sym, PetscInt row, PetscInt col) { return (PetscBool) (c->row_map[row] >= 0 && !(sym && col < c->row_map[row])); }

static inline PetscBool ExtraHeld(Cloth c, PetscBool sym, PetscInt e) { return BlockHeld(c, sym, c->ex_row[e], c->ex_col[e]); }

/* The n keys in [0, bound) sorted ascending, by their digits of RADIX_BITS from the
 * lowest (a stable counting sort each): the same order as PetscSortInt64's, in a few
 * passes over the keys. The present blocks of the drapebe sphere drop at 64^2 are
 * 17 000 to 47 000 keys (16 a pair, most of them repeats) at nearly every step, and
 * PetscSortInt64's quicksort took 1.7 % of the run. */
#define RADIX_BITS 11
static PetscErrorCode SortKeysRadix(PetscInt n, PetscInt64 bound, PetscInt64 *key)
{
  PetscInt64 *tmp, *from = key, *to;
  PetscInt   *count;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc1(n + 1, &tmp));
  PetscCall(PetscMalloc1((1 << RADIX_BITS) + 1, &count));
  to = tmp;
  for (PetscInt shift = 0; shift < 63 && (bound - 1) >> shift; shift += RADIX_BITS) {
    const PetscInt64 mask = (1 << RADIX_BITS) - 1;
    PetscInt         sum  = 0;
    PetscCall(PetscArrayzero(count, 1 << RADIX_BITS));
    for (PetscInt i = 0; i < n; i++) count[(from[i] >> shift) & mask]++;
    for (PetscInt d = 0; d < 1 << RADIX_BITS; d++) {
      const PetscInt c = count[d];
      count[d]         = sum;
      sum += c;
    }
    for (PetscInt i = 0; i < n; i++) to[count[(from[i] >> shift) & mask]++] = from[i];
    to   = from;
    from = from == key ? tmp : key;
  }
  if (from != key) PetscCall(PetscArraycpy(key, from, n));
  PetscCall(PetscFree(count));
  PetscCall(PetscFree(tmp));
  PetscFunctionReturn(0);
}

/* The extra blocks the next pattern holds: those of every earlier pattern and the
 * present ones (sorted, no repeats). The self-contact pairs of a step come and go
 * from step to step; a pattern of the present ones only was remade at 590 of the
 * sphere scene's 750 steps (a new matrix, row buffer, COO map and ICC symbolic
 * factorisation each time). Blocks of pairs gone stay as zeros, until the union
 * holds more than twice the present blocks and 1024: then it starts again from them
 * (*kept false). The union is sorted (row, column); the present blocks are sorted
 * and merged into it. */
static PetscErrorCode PatternMerge(Cloth c, PetscBool *kept)
{
  const PetscInt64 N = (PetscInt64) c->Mx * c->My;
  const PetscInt   n = c->px_n > 2 * c->ex_n + 1024 ? 0 : c->px_n;
  PetscInt64      *key;
  PetscInt        *row, *col, m = 0, i = 0, j = 0;

  PetscFunctionBeginUser;
  *kept = (PetscBool) (n == c->px_n);
  PetscCall(PetscMalloc1(c->ex_n + 1, &key));
  for (PetscInt e = 0; e < c->ex_n; e++) key[e] = (PetscInt64) c->ex_row[e] * N + c->ex_col[e];
  PetscCall(SortKeysRadix(c->ex_n, N * N, key));
  PetscCall(PetscMalloc2(n + c->ex_n + 1, &row, n + c->ex_n + 1, &col));
  while (i < n || j < c->ex_n) {
    const PetscInt64 a = i < n ? (PetscInt64) c->px_row[i] * N + c->px_col[i] : N * N;
    const PetscInt64 b = j < c->ex_n ? key[j] : N * N, k = PetscMin(a, b);
    if (a == k) i++;
    if (b == k) j++;
    if (m && (PetscInt64) row[m - 1] * N + col[m - 1] == k) continue;
    row[m] = (PetscInt) (k / N), col[m] = (PetscInt) (k % N), m++;
  }
  PetscCall(PetscFree(key));
  PetscCall(PetscFree2(c->px_row, c->px_col));
  c->px_row = row, c->px_col = col, c->px_n = m;
  PetscFunctionReturn(0);
}

/* The extra blocks' positions in the row buffer; *fits: all held blocks found. */
/* The row buffer's layout: per block row, its blocks in column order; a block's
 * (i, j) entry at si i + sj j from its start. AIJ (csr, coo): the three scalar rows
 * of the block row one after the other (si = 3 ncols, sj = 1), CSR rows. By rows
 * (MatSetValuesBlocked, column-oriented) and in (S)BAIJ's own array: each block
 * whole, by columns (si = 1, sj = 3), as BAIJ and SBAIJ store their blocks. */
/* The position of block loc of row k (RowBufferAt) */
static inline PetscInt RowBufferBlock(Cloth c, PetscInt k, PetscInt loc)
{
  if (c->rb_split == 1) { /* the diagonal block's array, or rb_gval for the blocks outside it */
    const PetscInt lo = c->rb_lo[k], nown = (c->rb_vstart[k + 1] - c->rb_vstart[k]) / 9;
    if (loc >= lo && loc < lo + nown) return c->rb_vstart[k] + 9 * (loc - lo);
    return c->rb_nva + c->rb_gstart[k] + 9 * (loc < lo ? loc : loc - nown);
  }
  return c->rb_start[k] + (c->rb_block ? 9 : 3) * loc;
}

/* The values at position pos (RowBufferBlock), val the buffer (rb_val) */
static inline PetscReal *RowBufferAt(Cloth c, PetscReal *val, PetscInt pos) { return pos < c->rb_nva ? val + pos : c->rb_gval + (pos - c->rb_nva); }

static inline void RowBufferStrides(Cloth c, PetscInt k, PetscInt *si, PetscInt *sj)
{
  *si = c->rb_block ? 1 : 3 * c->rb_ncols[k];
  *sj = c->rb_block ? 3 : 1;
}

static PetscErrorCode ExtraMap(Cloth c, PetscBool *fits)
{
  PetscFunctionBeginUser;
  if (fits) *fits = PETSC_TRUE;
  for (PetscInt e = 0; e < c->ex_n; e++) {
    const PetscInt k   = c->ex_row[e];
    PetscInt       loc = -1;
    c->ex_map[e]       = -1;
    if (!ExtraHeld(c, c->rb_sym, e)) continue;
    PetscCall(PetscFindInt(c->ex_col[e], c->rb_ncols[k], c->rb_cols + c->rb_colstart[k], &loc));
    if (loc < 0) {
      if (fits) *fits = PETSC_FALSE;
      continue;
    }
    c->ex_map[e] = RowBufferBlock(c, k, loc);
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ClothSetExtraBlocks(Cloth c, PetscInt n, const PetscInt rows[], const PetscInt cols[], const PetscReal vals[], PetscBool *fits)
{
  PetscFunctionBeginUser;
  if (n > c->ex_m) {
    PetscCall(PetscFree4(c->ex_row, c->ex_col, c->ex_map, c->ex_val));
    c->ex_m = PetscMax(n, 2 * c->ex_m);
    PetscCall(PetscMalloc4(c->ex_m, &c->ex_row, c->ex_m, &c->ex_col, c->ex_m, &c->ex_map, 9 * c->ex_m, &c->ex_val));
  }
  c->ex_n = n;
  for (PetscInt e = 0; e < n; e++) {
    PetscCheck(rows[e] >= 0 && rows[e] < c->nowned, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "Extra block row %" PetscInt_FMT " is not an owned particle (0..%" PetscInt_FMT ")", rows[e], c->nowned - 1);
    c->ex_row[e] = rows[e];
    c->ex_col[e] = cols[e];
  }
  PetscCall(PetscArraycpy(c->ex_val, vals, 9 * n));
  if (c->rb_start)
    PetscCall(ExtraMap(c, fits));
  else if (fits)
    *fits = PETSC_FALSE;
  PetscFunctionReturn(0);
}

/* The order of the assembly (ClothAddToMatrixRows). A pass over all the elements of
 * one kind after another streams the whole buffer through memory once per kind (it
 * is far larger than the caches at 512^2). Instead the owned rows are cut into tiles
 * of RB_TILE particles, each list into chunks (chunk t: the elements after those of
 * chunks < t whose rows reach at most tile t, by the running maximum of an element's
 * largest owned particle), and step s zeroes tile s and then adds chunk s - lag[kind]
 * of each kind in turn: the rows being summed stay in the cache. Every buffer entry
 * must still receive its terms in the order of the passes (all of kind 0 in list
 * order, then kind 1, ...), so that the matrix is the same to the bit: a row's
 * last chunk of a kind, shifted by that kind's lag, must not come after its first
 * chunk of a later kind, shifted by the later lag. The smallest lags that do this,
 * lag[kind] = kind L, are computed here; an order of the particles where L would be
 * large (no lattice order) takes one tile and no lag: the passes as they were. */
#define RB_TILE    256
#define RB_MAX_LAG 64
static PetscErrorCode RowBufferSchedule(Cloth c)
{
  const PetscInt nowned = c->nowned, ntile = PetscMax(1, (nowned + RB_TILE - 1) / RB_TILE);
  PetscInt      *lo, *hi, L = 0;

  PetscFunctionBeginUser;
  PetscCall(PetscFree(c->rb_chunk));
  PetscCall(PetscMalloc1(CLOTH_KINDS * (ntile + 1), &c->rb_chunk));
  PetscCall(PetscMalloc2(CLOTH_KINDS * nowned + 1, &lo, CLOTH_KINDS * nowned + 1, &hi));
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt n = KindSize(kind), ne = KindCount(c, kind);
    PetscInt      *ch = c->rb_chunk + kind * (ntile + 1), t = 0, top = 0;
    for (PetscInt k = 0; k < nowned; k++) lo[kind * nowned + k] = PETSC_MAX_INT, hi[kind * nowned + k] = -1;
    ch[0] = 0;
    for (PetscInt e = 0; e < ne; e++) {
      const PetscInt *p = KindParticles(c, kind, e);
      for (PetscInt a = 0; a < n; a++)
        if (p[a] < nowned) top = PetscMax(top, p[a]);
      while (t + 1 < ntile && top >= (t + 1) * RB_TILE) ch[++t] = e;
      for (PetscInt a = 0; a < n; a++) {
        if (p[a] >= nowned) continue;
        lo[kind * nowned + p[a]] = PetscMin(lo[kind * nowned + p[a]], t);
        hi[kind * nowned + p[a]] = PetscMax(hi[kind * nowned + p[a]], t);
      }
    }
    while (t + 1 <= ntile) ch[++t] = ne;
  }
  /* L >= (hi_kind - lo_later) / (later - kind) at every row */
  for (PetscInt k = 0; k < nowned; k++)
    for (PetscInt k1 = 0; k1 < CLOTH_KINDS; k1++)
      for (PetscInt k2 = k1 + 1; k2 < CLOTH_KINDS; k2++) {
        const PetscInt h = hi[k1 * nowned + k], l = lo[k2 * nowned + k];
        if (h >= 0 && l != PETSC_MAX_INT && h > l) L = PetscMax(L, (h - l + (k2 - k1) - 1) / (k2 - k1));
      }
  PetscCall(PetscFree2(lo, hi));
  if (L > RB_MAX_LAG) { /* one tile: the kinds one after the other */
    for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
      c->rb_chunk[2 * kind]     = 0;
      c->rb_chunk[2 * kind + 1] = KindCount(c, kind);
    }
    c->rb_ntile = 1;
    c->rb_tile  = PetscMax(nowned, 1);
    L           = 0;
  } else {
    c->rb_ntile = ntile;
    c->rb_tile  = RB_TILE;
  }
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) c->rb_lag[kind] = kind * L;
  PetscCall(PetscInfo(NULL, "Row buffer: %" PetscInt_FMT " tiles of %" PetscInt_FMT " rows, the kinds' chunks %" PetscInt_FMT " steps apart\n", c->rb_ntile, c->rb_tile, L));
  PetscFunctionReturn(0);
}

/* The row buffer of the present pattern grown by the extra blocks PatternMerge
 * added to it (its union kept, the elements' blocks as they were: every block of the
 * old pattern is in the new one): each row's columns merged with its new extra
 * blocks', and every position moved to its block's new place in its row. The same
 * pattern and positions as ClothBuildRowBuffer's, without its search per element
 * block and sort per row (a new pattern at 170 of the 206 steps of the drapebe
 * sphere drop with self-contact at 64^2 and 1e-2 s, 10 % of the run). */
static PetscErrorCode RowBufferGrow(Cloth c, Mat J)
{
  const PetscInt nowned = c->nowned, bs = c->rb_block ? 9 : 3; /* a block's place along its row (RowBufferBlock) */
  PetscInt      *ostart, *ocolstart, *oncols, *cols, *remap, held = 0, e = 0, q = 0, npairs = 0;

  PetscFunctionBeginUser;
  for (PetscInt x = 0; x < c->px_n; x++) held += BlockHeld(c, c->rb_sym, c->px_row[x], c->px_col[x]);
  PetscCall(PetscMalloc4(nowned + 1, &ostart, nowned + 1, &ocolstart, nowned + 1, &oncols, c->rb_colstart[nowned] + 1, &remap));
  PetscCall(PetscArraycpy(ostart, c->rb_start, nowned + 1));
  PetscCall(PetscArraycpy(ocolstart, c->rb_colstart, nowned + 1));
  PetscCall(PetscArraycpy(oncols, c->rb_ncols, nowned));
  PetscCall(PetscMalloc1(c->rb_colstart[nowned] + held + 1, &cols));
  for (PetscInt k = 0; k < nowned; k++) { /* the row's old columns and its held extra blocks (PatternMerge: by row, then column), merged */
    const PetscInt *oc = c->rb_cols + ocolstart[k];
    PetscInt        i = 0, n = 0;
    c->rb_colstart[k] = q;
    while (e < c->px_n && c->px_row[e] < k) e++;
    while (i < oncols[k] || (e < c->px_n && c->px_row[e] == k)) {
      PetscInt col;
      if (e < c->px_n && c->px_row[e] == k && !BlockHeld(c, c->rb_sym, k, c->px_col[e])) {
        e++;
        continue;
      }
      col = i < oncols[k] ? oc[i] : PETSC_MAX_INT;
      if (e < c->px_n && c->px_row[e] == k) col = PetscMin(col, c->px_col[e]);
      if (i < oncols[k] && oc[i] == col) remap[ocolstart[k] + i++] = n;
      if (e < c->px_n && c->px_row[e] == k && c->px_col[e] == col) e++;
      cols[q + n++] = col;
    }
    c->rb_ncols[k] = n;
    q += n;
    c->rb_start[k + 1] = c->rb_start[k] + 9 * n;
  }
  c->rb_colstart[nowned] = q;
  PetscCall(PetscFree(c->rb_cols));
  c->rb_cols = cols;
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt n = KindSize(kind);
    for (PetscInt el = 0; el < KindCount(c, kind); el++) {
      const PetscInt *p = KindParticles(c, kind, el);
      for (PetscInt a = 0; a < n; a++)
        for (PetscInt b = 0; b < n; b++, npairs++)
          if (c->rb_map[npairs] >= 0) c->rb_map[npairs] = c->rb_start[p[a]] + bs * remap[ocolstart[p[a]] + (c->rb_map[npairs] - ostart[p[a]]) / bs];
    }
  }
  for (PetscInt k = 0; k < nowned; k++) c->rb_diag[k] = c->rb_start[k] + bs * remap[ocolstart[k] + (c->rb_diag[k] - ostart[k]) / bs];
  PetscCall(PetscFree4(ostart, ocolstart, oncols, remap));
  PetscCall(PetscFree(c->rb_val));
  if (!c->rb_alias) PetscCall(PetscMalloc1(c->rb_start[nowned] + 1, &c->rb_val));
  c->rb_mat   = J;
  c->rb_split = -1; /* (asked again of the new matrix) */
  PetscCall(ExtraMap(c, NULL));
  PetscFunctionReturn(0);
}

static PetscErrorCode ClothBuildRowBuffer(Cloth c, Mat J)
{
  PetscInt *count, total = 0, npairs = 0;
  PetscBool sym, kept, grow;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompareAny((PetscObject) J, &sym, MATSEQSBAIJ, MATMPISBAIJ, ""));
  PetscCall(PatternMerge(c, &kept));
  grow = (PetscBool) (kept && c->rb_start && c->rb_split != 1 && c->rb_sym == sym && c->rb_built_block == c->rb_block); /* the last buffer's positions are the buffer's, of the same layout */
  PetscCall(PetscInfo(NULL, "Row buffer pattern: %" PetscInt_FMT " extra blocks, %s\n", c->px_n, grow ? "grown" : "built"));
  if (grow) {
    PetscCall(RowBufferGrow(c, J));
    PetscFunctionReturn(0);
  }
  PetscCall(PetscFree5(c->rb_start, c->rb_ncols, c->rb_colstart, c->rb_map, c->rb_diag));
  PetscCall(PetscFree(c->rb_cols));
  PetscCall(PetscFree(c->rb_val));
  PetscCall(PetscFree(c->rb_gval));
  c->rb_split = -1; /* (the positions below are the buffer's) */
  c->rb_nva   = PETSC_MAX_INT;
  PetscCall(PetscCalloc1(c->nowned + 1, &count));
  for (PetscInt k = 0; k < c->nowned; k++) count[k] = 1; /* the diagonal block */
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt n = KindSize(kind);
    for (PetscInt e = 0; e < KindCount(c, kind); e++) {
      const PetscInt *p = KindParticles(c, kind, e);
      for (PetscInt a = 0; a < n; a++)
        if (p[a] < c->nowned)
          for (PetscInt b = 0; b < n; b++) count[p[a]]++;
      npairs += n * n;
    }
  }
  for (PetscInt e = 0; e < c->px_n; e++)
    if (BlockHeld(c, sym, c->px_row[e], c->px_col[e])) count[c->px_row[e]]++;
  for (PetscInt k = 0; k < c->nowned; k++) total += count[k];
  PetscCall(PetscMalloc5(c->nowned + 1, &c->rb_start, c->nowned, &c->rb_ncols, c->nowned + 1, &c->rb_colstart, npairs, &c->rb_map, c->nowned, &c->rb_diag));
  PetscCall(PetscMalloc1(total + 1, &c->rb_cols));
  c->rb_colstart[0] = 0;
  for (PetscInt k = 0; k < c->nowned; k++) {
    c->rb_colstart[k + 1]                            = c->rb_colstart[k] + count[k];
    c->rb_ncols[k]                                   = 0;
    c->rb_cols[c->rb_colstart[k] + c->rb_ncols[k]++] = c->global[k];
  }
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt n = KindSize(kind);
    for (PetscInt e = 0; e < KindCount(c, kind); e++) {
      const PetscInt *p = KindParticles(c, kind, e);
      for (PetscInt a = 0; a < n; a++)
        for (PetscInt b = 0; b < n; b++)
          if (RowBufferHolds(c, sym, p[a], p[b])) c->rb_cols[c->rb_colstart[p[a]] + c->rb_ncols[p[a]]++] = c->col_map[p[b]];
    }
  }
  for (PetscInt e = 0; e < c->px_n; e++)
    if (BlockHeld(c, sym, c->px_row[e], c->px_col[e])) c->rb_cols[c->rb_colstart[c->px_row[e]] + c->rb_ncols[c->px_row[e]]++] = c->px_col[e];
  c->rb_start[0] = 0;
  for (PetscInt k = 0; k < c->nowned; k++) {
    PetscCall(PetscSortRemoveDupsInt(&c->rb_ncols[k], c->rb_cols + c->rb_colstart[k]));
    c->rb_start[k + 1] = c->rb_start[k] + 9 * c->rb_ncols[k];
    PetscCall(PetscFindInt(c->global[k], c->rb_ncols[k], c->rb_cols + c->rb_colstart[k], &c->rb_diag[k]));
    c->rb_diag[k] = RowBufferBlock(c, k, c->rb_diag[k]);
  }
  {
    /* the rows' columns close up: each row had room for every element's blocks (about
     * 81 a particle on the lattice, 17 once the repeats are gone; 256 bytes a
     * particle kept for the run) */
    PetscInt *cols, q = 0;
    for (PetscInt k = 0; k < c->nowned; k++) q += c->rb_ncols[k];
    PetscCall(PetscMalloc1(q + 1, &cols));
    q = 0;
    for (PetscInt k = 0; k < c->nowned; k++) {
      PetscCall(PetscArraycpy(cols + q, c->rb_cols + c->rb_colstart[k], c->rb_ncols[k]));
      c->rb_colstart[k] = q;
      q += c->rb_ncols[k];
    }
    c->rb_colstart[c->nowned] = q;
    PetscCall(PetscFree(c->rb_cols));
    c->rb_cols = cols;
  }
  npairs = 0;
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt n = KindSize(kind);
    for (PetscInt e = 0; e < KindCount(c, kind); e++) {
      const PetscInt *p = KindParticles(c, kind, e);
      for (PetscInt a = 0; a < n; a++) {
        for (PetscInt b = 0; b < n; b++, npairs++) {
          const PetscInt col = c->col_map[p[b]];
          PetscInt       loc = -1;
          c->rb_map[npairs]  = -1;
          if (!RowBufferHolds(c, sym, p[a], p[b])) continue;
          PetscCall(PetscFindInt(col, c->rb_ncols[p[a]], c->rb_cols + c->rb_colstart[p[a]], &loc));
          PetscCheck(loc >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "Block column %" PetscInt_FMT " missing from the row buffer", col);
          c->rb_map[npairs] = RowBufferBlock(c, p[a], loc);
        }
      }
    }
  }
  if (!c->rb_alias) PetscCall(PetscMalloc1(c->rb_start[c->nowned] + 1, &c->rb_val));
  PetscCall(PetscFree(count));
  c->rb_mat         = J;
  c->rb_sym         = sym;
  c->rb_split       = -1;
  c->rb_built_block = c->rb_block;
  PetscCall(ExtraMap(c, NULL));
  PetscCall(RowBufferSchedule(c));
  PetscFunctionReturn(0);
}

/* One rank, a matrix of the buffer's exact pattern: the buffer is the matrix's own
 * value array while it is assembled (get), and no array of drape's (restore). */
static PetscErrorCode RowBufferAlias(Cloth c, Mat J, PetscBool get)
{
  PetscBool aij, baij;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) J, MATSEQAIJ, &aij));
  PetscCall(PetscObjectTypeCompare((PetscObject) J, MATSEQBAIJ, &baij));
  if (get) {
    if (aij)
      PetscCall(MatSeqAIJGetArrayWrite(J, &c->rb_val));
    else if (baij)
      PetscCall(MatSeqBAIJGetArray(J, &c->rb_val));
    else
      PetscCall(MatSeqSBAIJGetArray(J, &c->rb_val));
  } else {
    if (aij)
      PetscCall(MatSeqAIJRestoreArrayWrite(J, &c->rb_val));
    else if (baij)
      PetscCall(MatSeqBAIJRestoreArray(J, &c->rb_val));
    else
      PetscCall(MatSeqSBAIJRestoreArray(J, &c->rb_val));
    c->rb_val = NULL;
  }
  PetscFunctionReturn(0);
}

/* The row buffer copied into an AIJ matrix of its exact pattern (ClothCreateMatrix):
 * a block row's three scalar rows are CSR rows with sorted global columns (on one
 * rank they are the matrix's value array in order, and the buffer is that array:
 * rb_alias, no copy). MPIAIJ keeps each row in a
 * diagonal block (the owned columns) and an off-diagonal block (the others, in
 * global order: its column map garray is sorted), so a row goes in three runs:
 * columns below the owned range, in it, above it. */
static PetscErrorCode RowBufferToAIJ(Cloth c, Mat J)
{
  Mat          A = J, B = NULL;
  PetscScalar *va, *vb  = NULL;
  PetscInt     rstart, rend, oa = 0, ob = 0;
  PetscBool    mpi;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) J, MATMPIAIJ, &mpi));
  if (mpi) PetscCall(MatMPIAIJGetSeqAIJ(J, &A, &B, NULL));
  PetscCall(MatGetOwnershipRange(J, &rstart, &rend));
  rstart /= 3, rend /= 3; /* block rows */
  PetscCall(MatSeqAIJGetArrayWrite(A, &va));
  if (B) PetscCall(MatSeqAIJGetArrayWrite(B, &vb));
  for (PetscInt k = 0; k < c->nowned; k++) {
    const PetscInt   n = c->rb_ncols[k], *col = c->rb_cols + c->rb_colstart[k];
    PetscInt         lo  = 0, hi;
    const PetscReal *row = c->rb_val + c->rb_start[k];
    while (lo < n && col[lo] < rstart) lo++;
    for (hi = lo; hi < n && col[hi] < rend; hi++) {}
    PetscCheck(B || (lo == 0 && hi == n), PETSC_COMM_SELF, PETSC_ERR_PLIB, "A column of the row buffer is outside the one-rank matrix");
    for (PetscInt i = 0; i < 3; i++, row += 3 * n) {
      PetscCall(PetscArraycpy(va + oa, row + 3 * lo, 3 * (hi - lo)));
      oa += 3 * (hi - lo);
      if (!B) continue;
      PetscCall(PetscArraycpy(vb + ob, row, 3 * lo));
      PetscCall(PetscArraycpy(vb + ob + 3 * lo, row + 3 * hi, 3 * (n - hi)));
      ob += 3 * (lo + n - hi);
    }
  }
  PetscCall(MatSeqAIJRestoreArrayWrite(A, &va));
  if (B) PetscCall(MatSeqAIJRestoreArrayWrite(B, &vb));
  PetscFunctionReturn(0);
}

/* The row buffer into an MPIBAIJ or MPISBAIJ matrix of its pattern, on several
 * ranks: a block row's blocks in the owned column range are one run of the row of
 * the rank's diagonal block (MatGetDiagonalBlock; blocks by columns, as the buffer
 * holds them), copied into its value array, each tile of rows as soon as its sums
 * are complete (rb_done: while they are in the cache; the mass blocks added there,
 * in the same order as before); the blocks outside that range, only in the rows
 * along a cut (rb_cut), go through MatSetValuesBlocked. MatSetValuesBlocked for
 * every row, a search per block, took 4-5 % of each rank's time in drapebe's 2-rank
 * run at 512^2 (perf), a cost one rank (rb_alias) does not have. The diagonal
 * block's pattern is compared with the buffer's once per matrix; where it differs
 * (rb_split 0) every row goes through MatSetValuesBlocked. */
/* The buffer's positions (rb_map, rb_diag, ex_map) moved to the diagonal block's
 * array and rb_gval (RowBufferBlock with rb_split 1), and the buffer freed: the
 * rows are summed where the matrix keeps them, and only the cut rows' blocks
 * outside the diagonal block are handed to PETSc. The same sums in the same order:
 * the same matrix to the bit, with no copy of it (on two ranks at 512^2 the copy was
 * 2 % of a rank's time, and the buffer a second matrix in memory). */
static PetscErrorCode RowBufferSplitPositions(Cloth c)
{
  PetscInt q = 0;

  PetscFunctionBeginUser;
  c->rb_split = 1; /* RowBufferBlock's new positions; a block's place in its row from the buffer's (rb_start) */
  c->rb_nva   = c->rb_vstart[c->nowned];
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt n = KindSize(kind);
    for (PetscInt e = 0; e < KindCount(c, kind); e++) {
      const PetscInt *p = KindParticles(c, kind, e);
      for (PetscInt a = 0; a < n; a++)
        for (PetscInt b = 0; b < n; b++, q++)
          if (c->rb_map[q] >= 0) c->rb_map[q] = RowBufferBlock(c, p[a], (c->rb_map[q] - c->rb_start[p[a]]) / 9);
    }
  }
  for (PetscInt k = 0; k < c->nowned; k++) c->rb_diag[k] = RowBufferBlock(c, k, (c->rb_diag[k] - c->rb_start[k]) / 9);
  PetscCall(ExtraMap(c, NULL));
  PetscCall(PetscFree(c->rb_val));
  PetscCall(PetscMalloc1(c->rb_gstart[c->nowned] + 1, &c->rb_gval));
  PetscFunctionReturn(0);
}

static PetscErrorCode RowBufferSplitCheck(Cloth c, Mat J)
{
  Mat             A;
  const PetscInt *ia, *ja;
  PetscInt        n, rstart, rend, ncut = 0;
  PetscBool       got, same;

  PetscFunctionBeginUser;
  PetscCall(PetscFree5(c->rb_lo, c->rb_cut, c->rb_done, c->rb_vstart, c->rb_gstart));
  c->rb_split = 0;
  c->rb_ncut  = 0;
  PetscCall(PetscObjectTypeCompareAny((PetscObject) J, &same, MATMPISBAIJ, MATMPIBAIJ, ""));
  if (!same || !c->rb_block || c->rb_coo || c->rb_alias) PetscFunctionReturn(0);
  PetscCall(MatAssembled(J, &same));
  if (!same) { /* no pattern yet: rows through MatSetValuesBlocked, and the question asked again */
    c->rb_split = -1;
    PetscFunctionReturn(0);
  }
  PetscCall(MatGetOwnershipRange(J, &rstart, &rend));
  rstart /= 3, rend /= 3; /* block rows */
  PetscCall(MatGetDiagonalBlock(J, &A));
  PetscCall(MatGetRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &got));
  same = (PetscBool) (got && n == c->nowned && rend - rstart == c->nowned);
  PetscCall(PetscMalloc5(c->nowned + 1, &c->rb_lo, c->nowned + 1, &c->rb_cut, c->rb_ntile + 1, &c->rb_done, c->nowned + 1, &c->rb_vstart, c->nowned + 1, &c->rb_gstart));
  for (PetscInt k = 0; same && k < c->nowned; k++) {
    const PetscInt m = c->rb_ncols[k], *col = c->rb_cols + c->rb_colstart[k];
    PetscInt       lo = 0, hi;
    while (lo < m && col[lo] < rstart) lo++;
    for (hi = lo; hi < m && col[hi] < rend; hi++) {}
    same = (PetscBool) (c->global[k] == rstart + k && ia[k + 1] - ia[k] == hi - lo);
    for (PetscInt t = 0; same && t < hi - lo; t++) same = (PetscBool) (ja[ia[k] + t] == col[lo + t] - rstart);
    c->rb_lo[k]     = lo;
    c->rb_vstart[k] = 9 * ia[k];
    c->rb_gstart[k] = k ? c->rb_gstart[k - 1] + 9 * (c->rb_ncols[k - 1] - (ia[k] - ia[k - 1])) : 0;
    if (lo > 0 || hi < m) c->rb_cut[ncut++] = k;
  }
  if (same) {
    c->rb_vstart[c->nowned] = 9 * ia[c->nowned];
    c->rb_gstart[c->nowned] = c->nowned ? c->rb_gstart[c->nowned - 1] + 9 * (c->rb_ncols[c->nowned - 1] - (ia[c->nowned] - ia[c->nowned - 1])) : 0;
  }
  if (got) PetscCall(MatRestoreRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &got));
  if (!same) {
    PetscCall(PetscFree5(c->rb_lo, c->rb_cut, c->rb_done, c->rb_vstart, c->rb_gstart));
    PetscFunctionReturn(0);
  }
  /* the step of ClothAddToMatrixRows after which tile t's sums are complete: its
   * own (zeroed then), or the last chunk of any kind with an owned particle in it */
  for (PetscInt t = 0; t < c->rb_ntile; t++) c->rb_done[t] = t;
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt  sz = KindSize(kind);
    const PetscInt *ch = c->rb_chunk + kind * (c->rb_ntile + 1);
    for (PetscInt t = 0; t < c->rb_ntile; t++)
      for (PetscInt e = ch[t]; e < ch[t + 1]; e++) {
        const PetscInt *p = KindParticles(c, kind, e);
        for (PetscInt a = 0; a < sz; a++)
          if (p[a] < c->nowned) c->rb_done[p[a] / c->rb_tile] = PetscMax(c->rb_done[p[a] / c->rb_tile], t + c->rb_lag[kind]);
      }
  }
  c->rb_ncut = ncut;
  PetscCall(RowBufferSplitPositions(c));
  PetscFunctionReturn(0);
}

/* Rows [k0, k1): the mass blocks added. */
static void RowBufferFinishRows(Cloth c, PetscInt k0, PetscInt k1, PetscReal a, PetscReal b)
{
  PetscReal D[9];

  for (PetscInt k = k0; k < k1; k++) {
    PetscInt   si, sj;
    PetscReal *v = RowBufferAt(c, c->rb_val, c->rb_diag[k]);
    RowBufferStrides(c, k, &si, &sj);
    MassBlock(c, k, a, b, D);
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < 3; j++) v[si * i + sj * j] += D[3 * i + j];
  }
}

/* ---- The element blocks into the row buffer ----
 *
 * Each element block the buffer holds (rb_map >= 0) is formed alone, from the
 * element's few numbers (a stretch edge's h, an angle element's H6), filtered by the
 * constraints and added: symmetric storage skips the blocks of the lower half before
 * computing them, and no element matrix is written out. Every buffer entry and
 * every hdiag entry receives the same terms, the same values, in the same (element)
 * order as from the element's whole matrix (MatrixElementHessian and
 * FilterElementHessian, ClothAssembleMatrixElementwise): the matrix is the same to
 * the bit. */

/* The element blocks are formed in the buffer's layout (blk: by columns, as (S)BAIJ
 * store a block; else by rows, the three scalar rows of AIJ): entry (i, j) of a block
 * at Layout(blk, i, j) of its nine. */
static inline PetscInt Layout(PetscBool blk, PetscInt i, PetscInt j) { return blk ? i + 3 * j : 3 * i + j; }

/* v += b B, B in the layout; the block's rows si apart when not blk */
static inline void AddBlock(PetscBool blk, PetscReal *restrict v, PetscInt si, PetscReal b, const PetscReal *restrict B)
{
  if (blk)
    for (PetscInt q = 0; q < 9; q++) v[q] += b * B[q];
  else
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < 3; j++) v[si * i + j] += b * B[3 * i + j];
}

/* hdiag of owned particle k += B (B in the layout, hdiag by rows) */
static inline void AddHdiag(Cloth c, PetscBool blk, PetscInt k, const PetscReal *restrict B)
{
  PetscReal *restrict h = c->hdiag + 9 * k;
  for (PetscInt i = 0; i < 3; i++)
    for (PetscInt j = 0; j < 3; j++) h[3 * i + j] += B[Layout(blk, i, j)];
}

/* v += b S_a B S_b for block (pa, pb) of an element on particles p (B in the
 * layout): the projections in FilterElementHessian's order (by S_a first when
 * pa <= pb), on the block by rows. */
static inline void AddFilteredBlock(Cloth c, PetscBool blk, const PetscInt *p, PetscInt pa, PetscInt pb, PetscReal *restrict v, PetscInt si, PetscReal b, const PetscReal *restrict Bl)
{
  const ClothConstraint ta = c->ctype[p[pa]], tb = c->ctype[p[pb]];
  const PetscReal      *na = c->cnormal + 3 * p[pa], *nb = c->cnormal + 3 * p[pb];
  PetscReal             B[9], Bo[9];

  if (ta == CLOTH_FREE && tb == CLOTH_FREE) { /* nothing to project: the same values */
    AddBlock(blk, v, si, b, Bl);
    return;
  }
  for (PetscInt i = 0; i < 3; i++)
    for (PetscInt j = 0; j < 3; j++) B[3 * i + j] = Bl[Layout(blk, i, j)];
  if (pa <= pb) {
    if (ta != CLOTH_FREE) ProjectBlock(ta, na, B, 3, PETSC_TRUE);
    if (tb != CLOTH_FREE) ProjectBlock(tb, nb, B, 3, PETSC_FALSE);
  } else {
    if (tb != CLOTH_FREE) ProjectBlock(tb, nb, B, 3, PETSC_FALSE);
    if (ta != CLOTH_FREE) ProjectBlock(ta, na, B, 3, PETSC_TRUE);
  }
  for (PetscInt i = 0; i < 3; i++)
    for (PetscInt j = 0; j < 3; j++) Bo[Layout(blk, i, j)] = B[3 * i + j];
  AddBlock(blk, v, si, b, Bo);
}

/* Does an element on particles p[0..n) need AddFilteredBlock: is one constrained? */
static inline PetscBool ElementConstrained(Cloth c, const PetscInt *p, PetscInt n)
{
  PetscBool any = PETSC_FALSE;

  if (c->constrained)
    for (PetscInt a = 0; a < n; a++) any = (PetscBool) (any || c->ctype[p[a]] != CLOTH_FREE);
  return any;
}

/* The buffer's row stride of row k when not blk (RowBufferStrides' si) */
static inline PetscInt RowStride(Cloth c, PetscBool blk, PetscInt k) { return blk ? 1 : 3 * c->rb_ncols[k]; }

/* The stretch edges [e0, e1); map: the list's rb_map entries (4 each). */
static inline void AddStretchBlocks(Cloth c, PetscBool blk, PetscReal b, const PetscReal *restrict xl, const PetscInt *restrict map, PetscInt e0, PetscInt e1)
{
  const ClothElements *el      = &c->stretch_el;
  const PetscBool      project = (PetscBool) !c->exact_hessian;
  PetscReal *restrict val      = c->rb_val;

  map += 4 * e0;
  for (PetscInt e = e0; e < e1; e++, map += 4) {
    const PetscInt *p = el->p + 2 * e;
    PetscReal       h[9], B[2][9]; /* h, -h in the layout */
    KernelStretchHessianBlock(xl + 3 * p[0], xl + 3 * p[1], ElemCoef(el, e), ElemRest(el, e), project, h);
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < 3; j++) {
        B[0][Layout(blk, i, j)] = h[3 * i + j];
        B[1][Layout(blk, i, j)] = -h[3 * i + j];
      }
    const PetscBool filter = ElementConstrained(c, p, 2);
    for (PetscInt a = 0; a < 2; a++)
      if (p[a] < c->nowned) AddHdiag(c, blk, p[a], B[0]);
    for (PetscInt a = 0; a < 2; a++) {
      PetscInt si;
      if (map[2 * a] < 0 && map[2 * a + 1] < 0) continue;
      si = RowStride(c, blk, p[a]);
      for (PetscInt q = 0; q < 2; q++) {
        const PetscInt pos = map[2 * a + q];
        if (pos < 0) continue;
        if (filter)
          AddFilteredBlock(c, blk, p, a, q, RowBufferAt(c, val, pos), si, b, B[a != q]);
        else
          AddBlock(blk, RowBufferAt(c, val, pos), si, b, B[a != q]);
      }
    }
  }
}

/* H6 of the angle elements in L's lanes [0, n) (KernelAngleHessian6Lanes), with the
 * instruction set chosen when the program starts (x86-64: AVX-512, AVX2, or the
 * baseline SSE2), as LatticeSweepRows: the lanes take 8, 4 or 2 elements an
 * instruction. The build contracts no multiply-add (ISO C: -ffp-contract=off), so
 * every version gives the same bits. */
DRAPE_TARGET_CLONES_FLATTEN
static void AngleHessianLanes(KernelAngleKind kind, PetscInt n, const PetscReal kappa[KERNEL_LANES], const KernelBendLaw *const *law, KernelAngleLanes *L, PetscBool project, PetscReal H6[36][KERNEL_LANES])
{
  if (kind == KERNEL_SHEAR)
    KernelAngleLanesPartials(KERNEL_SHEAR, n, kappa, NULL, L);
  else if (!law)
    KernelAngleLanesPartials(KERNEL_BEND, n, kappa, NULL, L); /* the linear law: loops without a branch */
  else
    KernelAngleLanesPartials(KERNEL_BEND, n, kappa, law, L);
  KernelAngleHessian6Lanes(n, L, project, H6);
}

/* The shear corners (kind 1) or bending triples (kind 2) [e0, e1); map: 9 each. The
 * nine blocks of the 9 x 9 Hessian from H6's four, in the sums of KernelAngle. */
static inline void AddAngleBlocks(Cloth c, PetscInt kind, PetscBool blk, PetscReal b, const PetscReal *restrict xl, const PetscInt *restrict map, PetscInt e0, PetscInt e1)
{
  const ClothElements  *el      = KindList(c, kind);
  const KernelAngleKind ak      = kind == 1 ? KERNEL_SHEAR : KERNEL_BEND;
  const PetscBool       project = (PetscBool) !c->exact_hessian;
  PetscReal *restrict val       = c->rb_val;

  map += 9 * e0;
  for (PetscInt e = e0; e < e1; e += KERNEL_LANES) {
    const PetscInt       n = PetscMin(KERNEL_LANES, e1 - e);
    KernelAngleLanes     L;
    PetscReal            H6[36][KERNEL_LANES], kappa[KERNEL_LANES];
    const KernelBendLaw *law[KERNEL_LANES];
    for (PetscInt k = 0; k < n; k++) {
      const PetscInt  *p  = el->p + 3 * (e + k);
      const PetscReal *xa = xl + 3 * p[0], *xb = xl + 3 * p[1], *xc = xl + 3 * p[2];
      for (PetscInt i = 0; i < 3; i++) L.e1[i][k] = xa[i] - xc[i], L.e2[i][k] = xb[i] - xc[i];
      kappa[k] = ElemCoef(el, e + k);
      law[k]   = ElemLaw(el, e + k);
    }
    AngleHessianLanes(ak, n, kappa, el->has_law ? law : NULL, &L, project, H6);
    for (PetscInt k = 0; k < n; k++, map += 9) {
      const PetscInt *p = el->p + 3 * (e + k);
      PetscReal       B[9][9]; /* block (a, q) at B[3 a + q], in the layout */
      for (PetscInt i = 0; i < 3; i++) {
        for (PetscInt j = 0; j < 3; j++) {
          const PetscReal h11 = H6[6 * i + j][k], h12 = H6[6 * i + 3 + j][k], h21 = H6[6 * (3 + i) + j][k], h22 = H6[6 * (3 + i) + 3 + j][k];
          const PetscInt  l = Layout(blk, i, j);
          B[0][l]           = h11;
          B[1][l]           = h12;
          B[2][l]           = -(h11 + h12);
          B[3][l]           = h21;
          B[4][l]           = h22;
          B[5][l]           = -(h21 + h22);
          B[6][l]           = -(h11 + h21);
          B[7][l]           = -(h12 + h22);
          B[8][l]           = h11 + h12 + h21 + h22;
        }
      }
      const PetscBool filter = ElementConstrained(c, p, 3);
      for (PetscInt a = 0; a < 3; a++)
        if (p[a] < c->nowned) AddHdiag(c, blk, p[a], B[4 * a]);
      for (PetscInt a = 0; a < 3; a++) {
        PetscInt si;
        if (map[3 * a] < 0 && map[3 * a + 1] < 0 && map[3 * a + 2] < 0) continue;
        si = RowStride(c, blk, p[a]);
        for (PetscInt q = 0; q < 3; q++) {
          const PetscInt pos = map[3 * a + q];
          if (pos < 0) continue;
          if (filter)
            AddFilteredBlock(c, blk, p, a, q, RowBufferAt(c, val, pos), si, b, B[3 * a + q]);
          else
            AddBlock(blk, RowBufferAt(c, val, pos), si, b, B[3 * a + q]);
        }
      }
    }
  }
}

/* Elements of any kind through their whole matrix (the bending friction: its five
 * particles may repeat one, so blocks may meet in one buffer block, and their order
 * is the element matrix's); map: n^2 each. */
static void AddElementMatrices(Cloth c, PetscInt kind, PetscReal b, const PetscReal *xl, const PetscInt *map, PetscInt e0, PetscInt e1)
{
  const PetscInt n = KindSize(kind), m = 3 * n;
  PetscReal      H[225];

  map += n * n * e0;
  for (PetscInt e = e0; e < e1; e++) {
    const PetscInt *p = KindParticles(c, kind, e);
    MatrixElementHessian(c, kind, e, xl, H);
    for (PetscInt pa = 0; pa < n; pa++) {
      for (PetscInt pb = 0; pb < n; pb++, map++) {
        const PetscInt pos = *map;
        PetscInt       si, sj;
        PetscReal     *v;
        if (pos < 0) continue;
        v = RowBufferAt(c, c->rb_val, pos);
        RowBufferStrides(c, p[pa], &si, &sj);
        for (PetscInt i = 0; i < 3; i++)
          for (PetscInt j = 0; j < 3; j++) v[si * i + sj * j] += b * H[m * (3 * pa + i) + 3 * pb + j];
      }
    }
  }
}

/* Elements [e0, e1) of list `kind` into the buffer; map: the list's rb_map entries.
 * Compiled for the CPU's instruction set with the element kernels inlined: the blocks'
 * sums and the buffer's adds take AVX2's or AVX-512's lanes, the same bits (the 64^2
 * assembly 0.93 x the CPU time, a few % of a drapebe run; BENCHMARKS.md). */
DRAPE_TARGET_CLONES_FLATTEN
static void AddKindRange(Cloth c, PetscInt kind, PetscReal b, const PetscReal *xl, const PetscInt *map, PetscInt e0, PetscInt e1)
{
  if (e0 >= e1) return;
  if (kind == 0) {
    if (c->rb_block)
      AddStretchBlocks(c, PETSC_TRUE, b, xl, map, e0, e1);
    else
      AddStretchBlocks(c, PETSC_FALSE, b, xl, map, e0, e1);
  } else if (kind < 3) {
    if (c->rb_block)
      AddAngleBlocks(c, kind, PETSC_TRUE, b, xl, map, e0, e1);
    else
      AddAngleBlocks(c, kind, PETSC_FALSE, b, xl, map, e0, e1);
  } else
    AddElementMatrices(c, kind, b, xl, map, e0, e1);
}

static PetscErrorCode ClothAddToMatrixRows(Cloth c, const PetscReal *xl, PetscReal a, PetscReal b, Mat J)
{
  const PetscInt *map[CLOTH_KINDS];
  Mat             A     = NULL;
  MatScalar      *va    = NULL;
  PetscBool       fused = PETSC_FALSE, sym = PETSC_FALSE;

  PetscFunctionBeginUser;
  if (c->rb_alias) PetscCall(RowBufferAlias(c, J, PETSC_TRUE));
  map[0] = c->rb_map;
  for (PetscInt kind = 1; kind < CLOTH_KINDS; kind++) map[kind] = map[kind - 1] + KindSize(kind - 1) * KindSize(kind - 1) * KindCount(c, kind - 1);
  /* several ranks, (S)BAIJ: the diagonal block's array, filled tile by tile when no
   * extra block is held (they are added after the element sums, before the mass) */
  if (c->rb_split < 0) PetscCall(RowBufferSplitCheck(c, J));
  if (c->rb_split == 1) {
    PetscCall(MatGetDiagonalBlock(J, &A));
    PetscCall(PetscObjectTypeCompare((PetscObject) A, MATSEQSBAIJ, &sym));
    if (sym)
      PetscCall(MatSeqSBAIJGetArray(A, &va));
    else
      PetscCall(MatSeqBAIJGetArray(A, &va));
    c->rb_val = va; /* (RowBufferSplitPositions) */
    fused     = PETSC_TRUE;
    for (PetscInt e = 0; e < c->ex_n && fused; e++) fused = (PetscBool) (c->ex_map[e] < 0);
  }
  /* the tiles' schedule (RowBufferSchedule): at step s, the rows of tile s zeroed,
   * then each kind's chunk s - lag */
  for (PetscInt step = 0; step < c->rb_ntile + c->rb_lag[CLOTH_KINDS - 1]; step++) {
    if (step < c->rb_ntile) {
      const PetscInt k0 = PetscMin(step * c->rb_tile, c->nowned), k1 = PetscMin(k0 + c->rb_tile, c->nowned);
      if (c->rb_split == 1) {
        PetscCall(PetscArrayzero(c->rb_val + c->rb_vstart[k0], c->rb_vstart[k1] - c->rb_vstart[k0]));
        PetscCall(PetscArrayzero(c->rb_gval + c->rb_gstart[k0], c->rb_gstart[k1] - c->rb_gstart[k0]));
      } else
        PetscCall(PetscArrayzero(c->rb_val + c->rb_start[k0], c->rb_start[k1] - c->rb_start[k0]));
      PetscCall(PetscArrayzero(c->hdiag + 9 * k0, 9 * (k1 - k0)));
    }
    for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
      const PetscInt  t  = step - c->rb_lag[kind];
      const PetscInt *ch = c->rb_chunk + kind * (c->rb_ntile + 1);
      if (t < 0 || t >= c->rb_ntile) continue;
      AddKindRange(c, kind, b, xl, map[kind], ch[t], ch[t + 1]);
    }
    if (fused)
      for (PetscInt t = 0; t < c->rb_ntile; t++)
        if (c->rb_done[t] == step) RowBufferFinishRows(c, PetscMin(t * c->rb_tile, c->nowned), PetscMin((t + 1) * c->rb_tile, c->nowned), a, b);
  }
  if (!fused) {
    for (PetscInt e = 0; e < c->ex_n; e++) {
      const PetscInt pos = c->ex_map[e];
      PetscInt       si, sj;
      PetscReal     *v;
      if (pos < 0) continue;
      v = RowBufferAt(c, c->rb_val, pos);
      RowBufferStrides(c, c->ex_row[e], &si, &sj);
      for (PetscInt i = 0; i < 3; i++)
        for (PetscInt j = 0; j < 3; j++) v[si * i + sj * j] += b * c->ex_val[9 * e + 3 * i + j];
    }
    RowBufferFinishRows(c, 0, c->nowned, a, b);
  }
  if (va) {
    c->rb_val = NULL;
    if (sym)
      PetscCall(MatSeqSBAIJRestoreArray(A, &va));
    else
      PetscCall(MatSeqBAIJRestoreArray(A, &va));
  }
  /* the hand-off (J is rb_mat: ClothAssembleMatrix): the values already in place,
   * through COO (assembled on return), copied into AIJ's arrays, or row by row (on
   * several ranks (S)BAIJ's rows along a cut only, their blocks outside the
   * diagonal block) */
  if (c->rb_coo) {
    PetscCall(MatSetValuesCOO(J, c->rb_val, INSERT_VALUES));
    PetscFunctionReturn(0);
  }
  if (c->rb_alias)
    PetscCall(RowBufferAlias(c, J, PETSC_FALSE));
  else if (c->rb_csr)
    PetscCall(RowBufferToAIJ(c, J));
  else if (c->rb_split == 1) {
    PetscCall(MatSetOption(J, MAT_ROW_ORIENTED, PETSC_FALSE)); /* block after block, each by columns */
    for (PetscInt q = 0; q < c->rb_ncut; q++) {
      const PetscInt   k = c->rb_cut[q], m = c->rb_ncols[k], lo = c->rb_lo[k], *col = c->rb_cols + c->rb_colstart[k];
      const PetscReal *out = c->rb_gval + c->rb_gstart[k]; /* the blocks below the owned columns, then those above */
      const PetscInt   hi  = lo + (c->rb_vstart[k + 1] - c->rb_vstart[k]) / 9;
      if (lo > 0) PetscCall(MatSetValuesBlocked(J, 1, &c->global[k], lo, col, out, INSERT_VALUES));
      if (hi < m) PetscCall(MatSetValuesBlocked(J, 1, &c->global[k], m - hi, col + hi, out + 9 * lo, INSERT_VALUES));
    }
  } else {
    PetscCall(MatSetOption(J, MAT_ROW_ORIENTED, PETSC_FALSE)); /* block after block, each by columns */
    for (PetscInt k = 0; k < c->nowned; k++) PetscCall(MatSetValuesBlocked(J, 1, &c->global[k], c->rb_ncols[k], c->rb_cols + c->rb_colstart[k], c->rb_val + c->rb_start[k], INSERT_VALUES));
  }
  PetscCall(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY)); /* a new state, which the preconditioner sees */
  PetscCall(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothAssembleMatrix(Cloth c, const PetscScalar *x, PetscReal a, PetscReal b, Mat J)
{
  const PetscScalar *xl;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.jacobian, 0, 0, 0, 0));
  if (!c->hdiag) PetscCall(PetscMalloc1(9 * c->nowned + 1, &c->hdiag)); /* zeroed tile by tile (ClothAddToMatrixRows) */
  if (c->rb_mat != J) {                                                 /* a matrix ClothCreateMatrix did not make: rows into its own pattern */
    c->rb_coo = c->rb_csr = c->rb_alias = PETSC_FALSE;
    c->rb_block                         = PETSC_TRUE;
    PetscCall(ClothBuildRowBuffer(c, J));
  }
  PetscCall(ClothScatterPositions(c, x, &xl));
  PetscCall(ClothAddToMatrixRows(c, xl, a, b, J));
  PetscCall(ClothEndScatter(c, &xl));
  PetscCall(PetscLogEventEnd(drape_log.jacobian, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

/* The reference of the tests: J += a M + b H(x) as the assembly was first written,
 * element by element, each element's whole matrix (MatrixElementHessian, filtered
 * by FilterElementHessian) added block by block with MatSetValuesBlocked, then the
 * extra blocks and the mass blocks; every block of both halves. J: any matrix of
 * block size 3 that accepts the pattern (AIJ without preallocation errors).
 * ClothGetHessianDiagonal then gives this assembly's. Collective. */
PetscErrorCode ClothAssembleMatrixElementwise(Cloth c, const PetscScalar *x, PetscReal a, PetscReal b, Mat J)
{
  const PetscScalar *xl;
  PetscReal          H[225], B[9];

  PetscFunctionBeginUser;
  if (!c->hdiag) PetscCall(PetscMalloc1(9 * c->nowned + 1, &c->hdiag));
  PetscCall(PetscArrayzero(c->hdiag, 9 * c->nowned));
  PetscCall(ClothScatterPositions(c, x, &xl));
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt n = KindSize(kind), m = 3 * n;
    for (PetscInt e = 0; e < KindCount(c, kind); e++) {
      const PetscInt *p = KindParticles(c, kind, e);
      MatrixElementHessian(c, kind, e, xl, H);
      for (PetscInt pa = 0; pa < n; pa++) {
        const PetscInt row = p[pa] < c->nowned ? c->row_map[p[pa]] : -1;
        if (row < 0) continue;
        for (PetscInt pb = 0; pb < n; pb++) {
          const PetscInt col = c->col_map[p[pb]];
          if (col < 0) continue;
          for (PetscInt i = 0; i < 3; i++)
            for (PetscInt j = 0; j < 3; j++) B[3 * i + j] = b * H[m * (3 * pa + i) + 3 * pb + j];
          PetscCall(MatSetValuesBlocked(J, 1, &row, 1, &col, B, ADD_VALUES));
        }
      }
    }
  }
  PetscCall(ClothEndScatter(c, &xl));
  for (PetscInt e = 0; e < c->ex_n; e++) {
    if (!BlockHeld(c, PETSC_FALSE, c->ex_row[e], c->ex_col[e])) continue;
    for (PetscInt i = 0; i < 9; i++) B[i] = b * c->ex_val[9 * e + i];
    PetscCall(MatSetValuesBlocked(J, 1, &c->global[c->ex_row[e]], 1, &c->ex_col[e], B, ADD_VALUES));
  }
  for (PetscInt k = 0; k < c->nowned; k++) {
    MassBlock(c, k, a, b, B);
    PetscCall(MatSetValuesBlocked(J, 1, &c->global[k], 1, &c->global[k], B, ADD_VALUES));
  }
  PetscCall(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothUpdatePlasticState(Cloth c, const PetscScalar *x)
{
  ClothFrictionList *fr = &c->friction_el;
  const PetscScalar *xl;

  PetscFunctionBeginUser;
  if (!(c->hysteresis[0] > 0 || c->hysteresis[1] > 0)) PetscFunctionReturn(0);
  PetscCall(ClothScatterPositions(c, x, &xl));
  for (PetscInt e = 0; e < fr->n; e++) {
    const PetscInt      *p = fr->p + 5 * e;
    const KernelFriction f = FrictionOf(c, fr, e);
    fr->kp[e]              = KernelFrictionReturn(&f, KernelTurning(xl + 3 * p[0], xl + 3 * p[1], xl + 3 * p[2], xl + 3 * p[3], xl + 3 * p[4], NULL) / f.L, fr->kp[e]);
  }
  PetscCall(ClothEndScatter(c, &xl));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothGetPlasticCount(Cloth c, PetscInt *n)
{
  PetscInt m = 0;

  PetscFunctionBeginUser;
  for (PetscInt e = 0; e < c->friction_el.n; e++) m += c->friction_el.own[e] && c->friction_el.kp[e] != 0;
  PetscCall(MPIU_Allreduce(&m, n, 1, MPIU_INT, MPI_SUM, c->comm));
  PetscFunctionReturn(0);
}
