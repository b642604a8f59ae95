/* PCBLOCKICC: IC(0) in 3 x 3 blocks that stays positive definite (include/pcblockicc.h).
 *
 * The factor is A ~ U^T D U, U unit upper triangular in blocks with A's pattern (no
 * fill), D block diagonal. Row k is formed from A's row k and the rows i < k whose
 * U(i, k) is in the pattern (left-looking, the rows waiting on each column held in
 * linked lists, as in PETSc's own SBAIJ factorisations); an update that would fall
 * outside the pattern is dropped. The blocks of row k are stored as they are
 * formed (Ubar(k, j) = D_k U(k, j)) and each is scaled to -U(k, j) when the row of
 * its column consumes it.
 *
 * Each pivot block D_k is tested by a 3 x 3 LDL^T (every pivot above pivot_tol
 * times A's diagonal entry). IC(0) of drape's matrix can fail that test: the
 * out-of-plane part is mass plus bending, a fourth-difference operator that is no
 * M-matrix, and the fill IC(0) drops there is larger than what the rows keep.
 * Then the factorisation is made again with the dropped fill compensated on the
 * diagonal (Ajiz and Jennings 1984; PCBlockICCNumeric), which keeps every Schur
 * complement positive definite: U^T D U is positive definite and CG never meets an
 * indefinite preconditioner. A factorisation that needs no compensation is IC(0)'s,
 * the same as PETSc's ICC(0) to round-off (tests/unit/test_blockicc.c).
 *
 * Blocks are PETSc's: 9 values by columns, B(r, c) = b[r + 3 c]. */
#include <petsc/private/pcimpl.h>
#include <pcblockicc.h>

typedef enum {
  PC_BLOCKICC_AUTO,
  PC_BLOCKICC_PLAIN,
  PC_BLOCKICC_COMPENSATED
} PCBlockICCType;
static const char *const PCBlockICCTypes[] = {"auto", "plain", "compensated", "PCBlockICCType", "PC_BLOCKICC_", NULL};

typedef struct {
  PetscInt       n;            /* block rows                                       */
  PetscInt      *ai, *aj;      /* A's upper pattern (the diagonal first in each row) */
  MatScalar     *fa;           /* factor: D_k^-1 at ai[k], -U(k, j) after it         */
  PetscInt      *pos;          /* column -> position in the row being formed, or -1  */
  PetscInt      *first, *next; /* linked lists: rows waiting on a column           */
  PetscReal     *comp;         /* diagonal entries the compensation adds to rows to come */
  PetscReal      pivot_tol;    /* a pivot must exceed this times A's diagonal entry  */
  PCBlockICCType type;         /* plain IC(0), compensated, or plain unless a pivot fails */
  PetscBool      compensated;  /* the last factorisation was compensated            */
} PC_BlockICC;

/* The LDL^T pivots of the symmetric 3 x 3 block d (by columns) are each above tol
 * times the matching diagonal entry of a; then its inverse in dinv. */
static PetscBool BlockInvertSPD(const MatScalar *d, const MatScalar *a, PetscReal tol, MatScalar *dinv)
{
  const PetscReal d00 = d[0], d10 = 0.5 * (d[1] + d[3]), d20 = 0.5 * (d[2] + d[6]), d11 = d[4], d21 = 0.5 * (d[5] + d[7]), d22 = d[8];
  PetscReal       p0, p1, p2, l10, l20, l21, det;

  p0 = d00;
  if (!(p0 > tol * a[0])) return PETSC_FALSE;
  l10 = d10 / p0;
  l20 = d20 / p0;
  p1  = d11 - l10 * d10;
  if (!(p1 > tol * a[4])) return PETSC_FALSE;
  l21 = (d21 - l20 * d10) / p1;
  p2  = d22 - l20 * d20 - l21 * (d21 - l20 * d10);
  if (!(p2 > tol * a[8])) return PETSC_FALSE;
  /* the inverse of the symmetric block: its adjugate over its determinant p0 p1 p2 */
  det     = p0 * p1 * p2;
  dinv[0] = (d11 * d22 - d21 * d21) / det;
  dinv[4] = (d00 * d22 - d20 * d20) / det;
  dinv[8] = (d00 * d11 - d10 * d10) / det;
  dinv[1] = dinv[3] = (d20 * d21 - d10 * d22) / det;
  dinv[2] = dinv[6] = (d10 * d21 - d20 * d11) / det;
  dinv[5] = dinv[7] = (d10 * d20 - d00 * d21) / det;
  return PETSC_TRUE;
}

/* Row i waits on the column of its block at position p (if it has one). */
static inline void BlockICCLink(PC_BlockICC *icc, PetscInt i, PetscInt p)
{
  if (p < icc->ai[i + 1]) {
    const PetscInt j = icc->aj[p];
    icc->first[i]    = p;
    icc->next[i]     = icc->next[j];
    icc->next[j]     = i;
  }
}

/* The pattern is compared, not A's nonzero state: drape's COO assembly gives the
 * matrix a new pattern (contacts' blocks) without a new nonzero state. */
static PetscErrorCode PCBlockICCSamePattern(PC_BlockICC *icc, Mat A, PetscBool *same)
{
  const PetscInt *ia, *ja;
  PetscInt        n;
  PetscBool       done;

  PetscFunctionBeginUser;
  *same = PETSC_FALSE;
  if (!icc->ai) PetscFunctionReturn(0);
  PetscCall(MatGetRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  if (done && n == icc->n && ia[n] == icc->ai[n]) {
    PetscCall(PetscArraycmp(ia, icc->ai, n + 1, same));
    if (*same) PetscCall(PetscArraycmp(ja, icc->aj, ia[n], same));
  }
  PetscCall(MatRestoreRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCBlockICCSymbolic(PC pc, PC_BlockICC *icc, Mat A)
{
  const PetscInt *ia, *ja;
  PetscInt        n;
  PetscBool       done;

  PetscFunctionBeginUser;
  PetscCall(PetscFree2(icc->ai, icc->aj));
  PetscCall(PetscFree5(icc->fa, icc->pos, icc->first, icc->next, icc->comp));
  PetscCall(MatGetRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  PetscCheck(done, PetscObjectComm((PetscObject) pc), PETSC_ERR_SUP, "-pc_type blockicc could not read the matrix's block pattern");
  PetscCall(PetscMalloc2(n + 1, &icc->ai, ia[n], &icc->aj));
  PetscCall(PetscArraycpy(icc->ai, ia, n + 1));
  PetscCall(PetscArraycpy(icc->aj, ja, ia[n]));
  icc->n = n;
  PetscCall(MatRestoreRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done)); /* which zeroes n */
  n = icc->n;
  for (PetscInt k = 0; k < n; k++)
    PetscCheck(icc->ai[k] < icc->ai[k + 1] && icc->aj[icc->ai[k]] == k, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "-pc_type blockicc needs every diagonal block in the matrix's pattern, and block row %" PetscInt_FMT " has none", k);
  PetscCall(PetscMalloc5(9 * icc->ai[n], &icc->fa, n, &icc->pos, n, &icc->first, n, &icc->next, 3 * n, &icc->comp));
  for (PetscInt k = 0; k < n; k++) icc->pos[k] = -1;
  PetscFunctionReturn(0);
}

/* The factorisation; compensate: a dropped fill block E between rows k and j adds,
 * entry by entry, |E_rc| sqrt(a_r / a_c) to row k's diagonal entry r and |E_rc|
 * sqrt(a_c / a_r) to row j's entry c (a: A's diagonal entries), Ajiz and Jennings'
 * compensation (1984): each dropped pair becomes a positive semidefinite 2 x 2
 * added to the Schur complement, which then stays positive definite, so no pivot
 * fails. Without it, *ok says whether every pivot block passed (the factorisation
 * stops at the first that does not). */
static PetscErrorCode PCBlockICCNumeric(PC_BlockICC *icc, Mat A, PetscBool compensate, PetscBool *ok)
{
  const PetscInt n = icc->n, *ai = icc->ai, *aj = icc->aj;
  PetscInt      *pos = icc->pos, *first = icc->first, *next = icc->next;
  MatScalar     *fa    = icc->fa, *aa;
  PetscReal     *comp  = icc->comp;
  PetscLogDouble flops = 0;

  PetscFunctionBeginUser;
  *ok = PETSC_TRUE;
  PetscCall(MatSeqSBAIJGetArray(A, &aa));
  PetscCall(PetscArraycpy(fa, aa, 9 * ai[n]));
  PetscCall(PetscArrayzero(comp, 3 * n));
  for (PetscInt k = 0; k < n; k++) next[k] = n; /* every list empty */
  for (PetscInt k = 0; k < n && *ok; k++) {
    MatScalar       *dk = fa + 9 * ai[k];
    const MatScalar *ak = aa + 9 * ai[k];
    for (PetscInt p = ai[k]; p < ai[k + 1]; p++) pos[aj[p]] = p;
    for (PetscInt r = 0; r < 3; r++) dk[4 * r] += comp[3 * k + r];
    for (PetscInt i = next[k], inext; i < n; i = inext) {
      const MatScalar *di = fa + 9 * ai[i];
      MatScalar       *u  = fa + 9 * first[i], w[9];
      inext               = next[i];
      /* w = -D_i^-1 Ubar(i, k) = -U(i, k); D_k -= U(i, k)^T Ubar(i, k) */
      for (PetscInt c = 0; c < 3; c++)
        for (PetscInt r = 0; r < 3; r++) w[r + 3 * c] = -(di[r] * u[3 * c] + di[r + 3] * u[3 * c + 1] + di[r + 6] * u[3 * c + 2]);
      for (PetscInt c = 0; c < 3; c++)
        for (PetscInt r = 0; r < 3; r++) dk[r + 3 * c] += w[3 * r] * u[3 * c] + w[3 * r + 1] * u[3 * c + 1] + w[3 * r + 2] * u[3 * c + 2];
      PetscCall(PetscArraycpy(u, w, 9));
      /* row k's blocks right of the diagonal: Ubar(k, j) -= U(i, k)^T Ubar(i, j) where (k, j) is in the pattern */
      for (PetscInt p = first[i] + 1; p < ai[i + 1]; p++) {
        const PetscInt   j = aj[p], q = pos[j];
        const MatScalar *v = fa + 9 * p;
        if (q >= 0) {
          MatScalar *t = fa + 9 * q;
          for (PetscInt c = 0; c < 3; c++)
            for (PetscInt r = 0; r < 3; r++) t[r + 3 * c] += w[3 * r] * v[3 * c] + w[3 * r + 1] * v[3 * c + 1] + w[3 * r + 2] * v[3 * c + 2];
        } else if (compensate) { /* fill IC(0) drops, given back to the two diagonals */
          const MatScalar *aj_ = aa + 9 * ai[j];
          for (PetscInt c = 0; c < 3; c++)
            for (PetscInt r = 0; r < 3; r++) {
              const PetscReal e = PetscAbsReal(w[3 * r] * v[3 * c] + w[3 * r + 1] * v[3 * c + 1] + w[3 * r + 2] * v[3 * c + 2]), s = PetscSqrtReal(ak[4 * r] / aj_[4 * c]);
              dk[4 * r] += e * s;
              comp[3 * j + c] += e / s;
            }
        }
        flops += 54;
      }
      flops += 108;
      BlockICCLink(icc, i, first[i] + 1);
    }
    {
      MatScalar dinv[9];
      if (!BlockInvertSPD(dk, ak, icc->pivot_tol, dinv)) { /* the dropped fill took more than the block had */
        *ok = compensate;
        if (!*ok) continue; /* the loop ends; the factor is made again, compensated */
        /* round-off only: the compensated Schur complement is positive definite */
        PetscCheck(BlockInvertSPD(ak, ak, 0, dinv), PETSC_COMM_SELF, PETSC_ERR_MAT_CH_ZRPVT, "-pc_type blockicc needs a symmetric positive definite matrix, and its diagonal block %" PetscInt_FMT " is not", k);
      }
      PetscCall(PetscArraycpy(dk, dinv, 9));
    }
    for (PetscInt p = ai[k]; p < ai[k + 1]; p++) pos[aj[p]] = -1;
    BlockICCLink(icc, k, ai[k] + 1);
  }
  if (!*ok)
    for (PetscInt k = 0; k < n; k++) pos[k] = -1;
  PetscCall(MatSeqSBAIJRestoreArray(A, &aa));
  PetscCall(PetscLogFlops(flops + 30.0 * n));
  PetscFunctionReturn(0);
}

/* On many ranks the rank's diagonal block of the MPISBAIJ matrix: block Jacobi
 * built in, the PC type the same on any number of ranks. */
static PetscErrorCode PCSetUp_BlockICC(PC pc)
{
  PC_BlockICC *icc = (PC_BlockICC *) pc->data;
  Mat          A   = pc->pmat;
  PetscBool    sbaij, mpi, same, ok = PETSC_FALSE;
  PetscInt     bs;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) A, MATMPISBAIJ, &mpi));
  if (mpi) PetscCall(MatGetDiagonalBlock(pc->pmat, &A));
  PetscCall(PetscObjectTypeCompare((PetscObject) A, MATSEQSBAIJ, &sbaij));
  PetscCall(MatGetBlockSize(A, &bs));
  PetscCheck(sbaij && bs == 3, PetscObjectComm((PetscObject) pc), PETSC_ERR_SUP, "-pc_type blockicc factors an SBAIJ matrix of block size 3, and this one is %s with block size %" PetscInt_FMT " (give -drape_mat_type sbaij)",
             ((PetscObject) pc->pmat)->type_name, bs);
  PetscCall(PCBlockICCSamePattern(icc, A, &same));
  if (!same) PetscCall(PCBlockICCSymbolic(pc, icc, A));
  icc->compensated = PETSC_FALSE;
  if (icc->type != PC_BLOCKICC_COMPENSATED) {
    PetscCall(PCBlockICCNumeric(icc, A, PETSC_FALSE, &ok));
    PetscCheck(ok || icc->type == PC_BLOCKICC_AUTO, PETSC_COMM_SELF, PETSC_ERR_MAT_CH_ZRPVT, "-pc_blockicc_type plain: a pivot block of IC(0) is not positive definite (-pc_blockicc_type auto or compensated compensates the dropped fill)");
  }
  if (!ok) {
    PetscCall(PCBlockICCNumeric(icc, A, PETSC_TRUE, &ok));
    icc->compensated = PETSC_TRUE;
  }
  PetscFunctionReturn(0);
}

/* x = (U^T D U)^-1 b with the stored blocks V = -U: forward U^T y = b (y_j += V(i,
 * j)^T y_i once y_i is final) and y_i = D_i^-1 y_i in the same pass, backward U x =
 * y (x_k += V(k, j) x_j). */
static PetscErrorCode PCApply_BlockICC(PC pc, Vec b, Vec x)
{
  PC_BlockICC   *icc = (PC_BlockICC *) pc->data;
  const PetscInt n = icc->n, *restrict ai = icc->ai, *restrict aj = icc->aj;
  const MatScalar *restrict fa = icc->fa;
  const PetscScalar *bb;
  PetscScalar       *y;

  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(b, &bb));
  PetscCall(VecGetArrayWrite(x, &y));
  PetscCall(PetscArraycpy(y, bb, 3 * n));
  PetscCall(VecRestoreArrayRead(b, &bb));
  for (PetscInt i = 0; i < n; i++) {
    const PetscScalar y0 = y[3 * i], y1 = y[3 * i + 1], y2 = y[3 * i + 2];
    PetscPrefetchBlock(fa + 9 * ai[i + 1], 9 * (ai[i + 1] - ai[i]), 0, PETSC_PREFETCH_HINT_NTA);
    PetscPrefetchBlock(aj + ai[i + 1], ai[i + 1] - ai[i], 0, PETSC_PREFETCH_HINT_NTA);
    for (PetscInt p = ai[i] + 1; p < ai[i + 1]; p++) {
      const MatScalar *v = fa + 9 * p;
      PetscScalar     *t = y + 3 * aj[p];
      t[0] += v[0] * y0 + v[1] * y1 + v[2] * y2;
      t[1] += v[3] * y0 + v[4] * y1 + v[5] * y2;
      t[2] += v[6] * y0 + v[7] * y1 + v[8] * y2;
    }
    {
      const MatScalar *d = fa + 9 * ai[i];
      PetscScalar     *t = y + 3 * i;
      t[0]               = d[0] * y0 + d[3] * y1 + d[6] * y2;
      t[1]               = d[1] * y0 + d[4] * y1 + d[7] * y2;
      t[2]               = d[2] * y0 + d[5] * y1 + d[8] * y2;
    }
  }
  for (PetscInt k = n - 1; k >= 0; k--) {
    const MatScalar *d = fa + 9 * ai[k];
    PetscScalar     *t = y + 3 * k, s0, s1, s2;
    /* the rows go down memory, each row up it: a pattern the hardware does not
     * prefetch (without this the pass takes 2.4 times as long), so fetch the next
     * row's blocks and columns, assumed as long as this one */
    PetscPrefetchBlock(d - 9 * (ai[k + 1] - ai[k]), 9 * (ai[k + 1] - ai[k]), 0, PETSC_PREFETCH_HINT_NTA);
    PetscPrefetchBlock(aj + ai[k] - (ai[k + 1] - ai[k]), ai[k + 1] - ai[k], 0, PETSC_PREFETCH_HINT_NTA);
    s0 = t[0], s1 = t[1], s2 = t[2];
    for (PetscInt p = ai[k] + 1; p < ai[k + 1]; p++) {
      const MatScalar   *v  = fa + 9 * p;
      const PetscScalar *xj = y + 3 * aj[p];
      s0 += v[0] * xj[0] + v[3] * xj[1] + v[6] * xj[2];
      s1 += v[1] * xj[0] + v[4] * xj[1] + v[7] * xj[2];
      s2 += v[2] * xj[0] + v[5] * xj[1] + v[8] * xj[2];
    }
    t[0] = s0, t[1] = s1, t[2] = s2;
  }
  PetscCall(VecRestoreArrayWrite(x, &y));
  PetscCall(PetscLogFlops(36.0 * (ai[n] - n) + 15.0 * n));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCReset_BlockICC(PC pc)
{
  PC_BlockICC *icc = (PC_BlockICC *) pc->data;

  PetscFunctionBeginUser;
  PetscCall(PetscFree2(icc->ai, icc->aj));
  PetscCall(PetscFree5(icc->fa, icc->pos, icc->first, icc->next, icc->comp));
  icc->n = 0;
  PetscFunctionReturn(0);
}

static PetscErrorCode PCDestroy_BlockICC(PC pc)
{
  PetscFunctionBeginUser;
  PetscCall(PCReset_BlockICC(pc));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCBlockICCGetCompensated_C", NULL));
  PetscCall(PetscFree(pc->data));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCSetFromOptions_BlockICC(PC pc, PetscOptionItems *PetscOptionsObject)
{
  PC_BlockICC *icc = (PC_BlockICC *) pc->data;

  PetscFunctionBeginUser;
  PetscOptionsHeadBegin(PetscOptionsObject, "Block IC(0), positive definite");
  PetscCall(
    PetscOptionsReal("-pc_blockicc_pivot_tol", "A pivot of a 3 x 3 pivot block must exceed this times the matrix's diagonal entry, else the block is replaced by the matrix's diagonal block", "PCBLOCKICC", icc->pivot_tol, &icc->pivot_tol, NULL));
  PetscCall(PetscOptionsEnum("-pc_blockicc_type", "auto: IC(0), compensated when a pivot block fails; plain: IC(0), an error when one fails; compensated: always", "PCBLOCKICC", PCBlockICCTypes, (PetscEnum) icc->type, (PetscEnum *) &icc->type, NULL));
  PetscCheck(icc->pivot_tol >= 0 && icc->pivot_tol < 1, PetscObjectComm((PetscObject) pc), PETSC_ERR_USER_INPUT, "-pc_blockicc_pivot_tol %g is outside [0, 1): a pivot is compared with this fraction of the matrix's diagonal entry",
             (double) icc->pivot_tol);
  PetscOptionsHeadEnd();
  PetscFunctionReturn(0);
}

static PetscErrorCode PCView_BlockICC(PC pc, PetscViewer viewer)
{
  PC_BlockICC *icc = (PC_BlockICC *) pc->data;
  PetscBool    ascii;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) viewer, PETSCVIEWERASCII, &ascii));
  if (ascii) PetscCall(PetscViewerASCIIPrintf(viewer, "  IC(0) in 3 x 3 blocks (%s), pivot tolerance %g; the last factorisation %s\n", PCBlockICCTypes[icc->type], (double) icc->pivot_tol, icc->compensated ? "compensated the dropped fill" : "plain"));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCBlockICCGetCompensated_BlockICC(PC pc, PetscBool *compensated)
{
  PetscFunctionBeginUser;
  PetscCall(MPIU_Allreduce(&((PC_BlockICC *) pc->data)->compensated, compensated, 1, MPIU_BOOL, MPI_LOR, PetscObjectComm((PetscObject) pc)));
  PetscFunctionReturn(0);
}

PetscErrorCode PCBlockICCGetCompensated(PC pc, PetscBool *compensated)
{
  PetscFunctionBeginUser;
  *compensated = PETSC_FALSE;
  PetscTryMethod(pc, "PCBlockICCGetCompensated_C", (PC, PetscBool *), (pc, compensated));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCCreate_BlockICC(PC pc)
{
  PC_BlockICC *icc;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&icc));
  icc->pivot_tol               = 1e-8;
  pc->data                     = icc;
  pc->ops->setup               = PCSetUp_BlockICC;
  pc->ops->apply               = PCApply_BlockICC;
  pc->ops->applysymmetricleft  = NULL;
  pc->ops->applysymmetricright = NULL;
  pc->ops->reset               = PCReset_BlockICC;
  pc->ops->destroy             = PCDestroy_BlockICC;
  pc->ops->setfromoptions      = PCSetFromOptions_BlockICC;
  pc->ops->view                = PCView_BlockICC;
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCBlockICCGetCompensated_C", PCBlockICCGetCompensated_BlockICC));
  PetscFunctionReturn(0);
}

PetscErrorCode PCBlockICCRegister(void)
{
  PetscFunctionBeginUser;
  PetscCall(PCRegister(PCBLOCKICC, PCCreate_BlockICC));
  PetscFunctionReturn(0);
}
