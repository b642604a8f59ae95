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
 * With -pc_blockicc_levels 1 (PCBlockICCSetLevels; drapebe sets it when IC(0) had
 * to compensate) the factor's pattern also holds the level-1 fill, the blocks (k, j)
 * that a row i < k holding both k and j fills (PCBlockICCFill): IC(1). The
 * factorisation is the same, over that pattern; what falls outside it is dropped,
 * or compensated, as at level 0.
 *
 * The factor is stored in single precision unless -pc_blockicc_precision double
 * (pcblockicc_kernels.h, compiled once for each): the triangular solves stream the
 * factor once each way per CG iteration, and float halves those bytes (on one core
 * the solves took 45 % less time at 512^2: BENCHMARKS.md). The arithmetic stays
 * double: each row is formed in double and rounded once, so the preconditioner is
 * the double factor's within float's rounding, and U^T D U of the rounded blocks is
 * still symmetric, as CG needs. Positive definite too, while every rounded inverse
 * pivot block D_k^-1 is: that is checked, and where one is not (a pivot block
 * conditioned beyond 1/eps of float) the factorisation is made again in double, and
 * stays double for the rest of the run.
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

typedef enum {
  PC_BLOCKICC_SINGLE,
  PC_BLOCKICC_DOUBLE
} PCBlockICCPrecision;
static const char *const PCBlockICCPrecisions[] = {"single", "double", "PCBlockICCPrecision", "PC_BLOCKICC_", NULL};

typedef struct {
  PetscInt            n;            /* block rows                                       */
  PetscInt           *ai, *aj;      /* A's upper pattern (the diagonal first in each row) */
  PetscInt            levels;       /* fill: 0, A's pattern; 1, the fill of two of A's blocks */
  PetscInt           *fi, *fj;      /* the factor's pattern (ai, aj at level 0)           */
  PetscInt           *amap;         /* A's block p at factor position amap[p] (NULL at level 0) */
  void               *fa;           /* factor: D_k^-1 at fi[k], -U(k, j) after it; float or double (single) */
  PetscScalar        *row;          /* the block row being formed, 9 per block            */
  PetscInt           *pos;          /* column -> position in the row being formed, or -1  */
  PetscInt           *first, *next; /* linked lists: rows waiting on a column           */
  PetscReal          *comp;         /* diagonal entries the compensation adds to rows to come */
  PetscReal           pivot_tol;    /* a pivot must exceed this times A's diagonal entry  */
  PCBlockICCType      type;         /* plain IC(0), compensated, or plain unless a pivot fails */
  PetscBool           compensated;  /* the last factorisation was compensated            */
  PCBlockICCPrecision precision;    /* the factor's storage asked for                      */
  PetscBool           single;       /* fa is float                                          */
  PetscBool           widened;      /* single asked, a rounded pivot block was not positive definite: double from then on */
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
  if (p < icc->fi[i + 1]) {
    const PetscInt j = icc->fj[p];
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

#define BICC_T     float
#define BICC(name) PCBlockICC##name##_Single
#include "pcblockicc_kernels.h"
#undef BICC_T
#undef BICC
#define BICC_T     double
#define BICC(name) PCBlockICC##name##_Double
#include "pcblockicc_kernels.h"
#undef BICC_T
#undef BICC

/* The factor's pattern with level-1 fill: row k holds A's row k and the columns j >
 * k of the rows i < k that hold k (U(i, k) U(i, j) of two of A's blocks); sorted,
 * the diagonal first. amap: where each of A's blocks lies in it. */
static PetscErrorCode PCBlockICCFill(PC_BlockICC *icc)
{
  const PetscInt n = icc->n, *ai = icc->ai, *aj = icc->aj;
  PetscInt      *cs, *cr, *mark, *fi = NULL, *fj = NULL, nf = 0;

  PetscFunctionBeginUser;
  PetscCall(PetscCalloc2(n + 1, &cs, n, &mark));
  for (PetscInt p = 0; p < ai[n]; p++) cs[aj[p] + 1]++; /* A's rows holding each column (the diagonal too) */
  for (PetscInt k = 0; k < n; k++) cs[k + 1] += cs[k];
  PetscCall(PetscMalloc1(ai[n], &cr));
  for (PetscInt i = 0; i < n; i++)
    for (PetscInt p = ai[i]; p < ai[i + 1]; p++) cr[cs[aj[p]]++] = i;
  for (PetscInt k = n; k > 0; k--) cs[k] = cs[k - 1];
  cs[0] = 0;
  for (PetscInt pass = 0; pass < 2; pass++) { /* count, then fill */
    for (PetscInt k = 0; k < n; k++) mark[k] = -1;
    nf = 0;
    for (PetscInt k = 0; k < n; k++) {
      const PetscInt start = nf;
      for (PetscInt p = ai[k]; p < ai[k + 1]; p++) {
        mark[aj[p]] = k;
        if (pass) fj[nf] = aj[p];
        nf++;
      }
      for (PetscInt q = cs[k]; q < cs[k + 1]; q++) {
        const PetscInt i = cr[q];
        if (i == k) continue;
        for (PetscInt p = ai[i] + 1; p < ai[i + 1]; p++) {
          const PetscInt j = aj[p];
          if (j <= k || mark[j] == k) continue;
          mark[j] = k;
          if (pass) fj[nf] = j;
          nf++;
        }
      }
      if (pass) {
        PetscCall(PetscSortInt(nf - start - 1, fj + start + 1));
        fi[k + 1] = nf;
      }
    }
    if (!pass) {
      PetscCall(PetscMalloc3(n + 1, &fi, nf, &fj, ai[n], &icc->amap));
      fi[0] = 0;
    }
  }
  for (PetscInt k = 0; k < n; k++) {
    PetscInt q = fi[k];
    for (PetscInt p = ai[k]; p < ai[k + 1]; p++) {
      while (fj[q] != aj[p]) q++;
      icc->amap[p] = q;
    }
  }
  icc->fi = fi, icc->fj = fj;
  PetscCall(PetscFree2(cs, mark));
  PetscCall(PetscFree(cr));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCBlockICCFreePattern(PC_BlockICC *icc)
{
  PetscFunctionBeginUser;
  if (icc->amap) PetscCall(PetscFree3(icc->fi, icc->fj, icc->amap));
  icc->fi = icc->fj = NULL;
  PetscCall(PetscFree2(icc->ai, icc->aj));
  PetscCall(PetscFree(icc->fa));
  PetscCall(PetscFree5(icc->pos, icc->first, icc->next, icc->comp, icc->row));
  icc->n = 0;
  PetscFunctionReturn(0);
}

static PetscErrorCode PCBlockICCSymbolic(PC pc, PC_BlockICC *icc, Mat A)
{
  const PetscInt *ia, *ja;
  PetscInt        n;
  PetscBool       done;

  PetscFunctionBeginUser;
  PetscCall(PCBlockICCFreePattern(icc));
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
  if (icc->levels > 0)
    PetscCall(PCBlockICCFill(icc));
  else
    icc->fi = icc->ai, icc->fj = icc->aj;
  {
    PetscInt maxrow = 0;
    for (PetscInt k = 0; k < n; k++) maxrow = PetscMax(maxrow, icc->fi[k + 1] - icc->fi[k]);
    PetscCall(PetscMalloc5(n, &icc->pos, n, &icc->first, n, &icc->next, 3 * n, &icc->comp, 9 * maxrow, &icc->row));
  }
  for (PetscInt k = 0; k < n; k++) icc->pos[k] = -1;
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
  MatScalar   *aa;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) A, MATMPISBAIJ, &mpi));
  if (mpi) PetscCall(MatGetDiagonalBlock(pc->pmat, &A));
  PetscCall(PetscObjectTypeCompare((PetscObject) A, MATSEQSBAIJ, &sbaij));
  PetscCall(MatGetBlockSize(A, &bs));
  PetscCheck(sbaij && bs == 3, PetscObjectComm((PetscObject) pc), PETSC_ERR_SUP, "-pc_type blockicc factors an SBAIJ matrix of block size 3, and this one is %s with block size %" PetscInt_FMT " (give -drape_mat_type sbaij)",
             ((PetscObject) pc->pmat)->type_name, bs);
  PetscCall(PCBlockICCSamePattern(icc, A, &same));
  if (!same) PetscCall(PCBlockICCSymbolic(pc, icc, A));
  PetscCall(MatSeqSBAIJGetArray(A, &aa));
  for (;;) { /* in single storage unless a rounded pivot block is not positive definite: then in double, from then on */
    const PetscBool single = (PetscBool) (icc->precision == PC_BLOCKICC_SINGLE && !icc->widened);
    PetscBool       stored = PETSC_TRUE;
    if (!icc->fa || single != icc->single) {
      PetscCall(PetscFree(icc->fa));
      PetscCall(PetscMalloc(9 * icc->fi[icc->n] * (single ? sizeof(float) : sizeof(double)), &icc->fa));
      icc->single = single;
    }
    icc->compensated = PETSC_FALSE;
    ok               = PETSC_FALSE;
    if (icc->type != PC_BLOCKICC_COMPENSATED) {
      PetscCall(single ? PCBlockICCNumeric_Single(icc, aa, PETSC_FALSE, &ok, &stored) : PCBlockICCNumeric_Double(icc, aa, PETSC_FALSE, &ok, &stored));
      PetscCheck(ok || !stored || icc->type == PC_BLOCKICC_AUTO, PETSC_COMM_SELF, PETSC_ERR_MAT_CH_ZRPVT,
                 "-pc_blockicc_type plain: a pivot block of IC(0) is not positive definite (-pc_blockicc_type auto or compensated compensates the dropped fill)");
    }
    if (!ok && stored) {
      PetscCall(single ? PCBlockICCNumeric_Single(icc, aa, PETSC_TRUE, &ok, &stored) : PCBlockICCNumeric_Double(icc, aa, PETSC_TRUE, &ok, &stored));
      icc->compensated = PETSC_TRUE;
    }
    if (stored) break;
    icc->widened = PETSC_TRUE;
  }
  PetscCall(MatSeqSBAIJRestoreArray(A, &aa));
  PetscFunctionReturn(0);
}

/* x = (U^T D U)^-1 b (pcblockicc_kernels.h) */
/* y = (L D L^T)^-1 y, in place */
static PetscErrorCode PCBlockICCSolveArray(PC_BlockICC *icc, PetscScalar *y)
{
  PetscFunctionBeginUser;
  if (icc->single)
    PCBlockICCSolve_Single(icc, y);
  else
    PCBlockICCSolve_Double(icc, y);
  PetscCall(PetscLogFlops(36.0 * (icc->fi[icc->n] - icc->n) + 15.0 * icc->n));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCApply_BlockICC(PC pc, Vec b, Vec x)
{
  PC_BlockICC       *icc = (PC_BlockICC *) pc->data;
  const PetscScalar *bb;
  PetscScalar       *y;

  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(b, &bb));
  PetscCall(VecGetArrayWrite(x, &y));
  PetscCall(PetscArraycpy(y, bb, 3 * icc->n));
  PetscCall(VecRestoreArrayRead(b, &bb));
  PetscCall(PCBlockICCSolveArray(icc, y));
  PetscCall(VecRestoreArrayWrite(x, &y));
  PetscFunctionReturn(0);
}

PetscErrorCode PCBlockICCApplyInPlace(PC pc, Vec x)
{
  PetscBool    is;
  PetscScalar *y;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) pc, PCBLOCKICC, &is));
  PetscCheck(is, PetscObjectComm((PetscObject) pc), PETSC_ERR_ARG_WRONG, "PCBlockICCApplyInPlace takes a PC of type %s, and this one is %s", PCBLOCKICC, ((PetscObject) pc)->type_name);
  PetscCheck(pc->setupcalled, PetscObjectComm((PetscObject) pc), PETSC_ERR_ORDER, "PCBlockICCApplyInPlace needs the PC set up (PCSetUp)");
  PetscCall(PetscLogEventBegin(PC_Apply, pc, x, x, 0));
  PetscCall(VecGetArray(x, &y));
  PetscCall(PCBlockICCSolveArray((PC_BlockICC *) pc->data, y));
  PetscCall(VecRestoreArray(x, &y));
  PetscCall(PetscLogEventEnd(PC_Apply, pc, x, x, 0));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCReset_BlockICC(PC pc)
{
  PC_BlockICC *icc = (PC_BlockICC *) pc->data;

  PetscFunctionBeginUser;
  PetscCall(PCBlockICCFreePattern(icc));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCDestroy_BlockICC(PC pc)
{
  PetscFunctionBeginUser;
  PetscCall(PCReset_BlockICC(pc));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCBlockICCGetCompensated_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCBlockICCSetLevels_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCBlockICCGetLevels_C", NULL));
  PetscCall(PetscFree(pc->data));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCBlockICCSetLevels_BlockICC(PC pc, PetscInt levels)
{
  PC_BlockICC *icc = (PC_BlockICC *) pc->data;

  PetscFunctionBeginUser;
  PetscCheck(levels == 0 || levels == 1, PetscObjectComm((PetscObject) pc), PETSC_ERR_ARG_OUTOFRANGE, "block IC(0) fills at level 0 or 1, not %" PetscInt_FMT, levels);
  if (levels == icc->levels) PetscFunctionReturn(0);
  PetscCall(PCBlockICCFreePattern(icc)); /* made again at the next set-up */
  icc->levels = levels;
  PetscFunctionReturn(0);
}

static PetscErrorCode PCSetFromOptions_BlockICC(PC pc, PetscOptionItems *PetscOptionsObject)
{
  PC_BlockICC *icc = (PC_BlockICC *) pc->data;

  PetscFunctionBeginUser;
  PetscOptionsHeadBegin(PetscOptionsObject, "Block IC(0), positive definite");
  PetscCall(
    PetscOptionsReal("-pc_blockicc_pivot_tol", "A pivot of a 3 x 3 pivot block must exceed this times the matrix's diagonal entry, else the block is replaced by the matrix's diagonal block", "PCBLOCKICC", icc->pivot_tol, &icc->pivot_tol, NULL));
  PetscCall(PetscOptionsEnum("-pc_blockicc_precision", "Storage of the factor: single (float: half the memory the triangular solves stream; the arithmetic stays double) or double", "PCBLOCKICC", PCBlockICCPrecisions, (PetscEnum) icc->precision,
                             (PetscEnum *) &icc->precision, NULL));
  {
    PetscInt  levels = icc->levels;
    PetscBool set;
    PetscCall(PetscOptionsInt("-pc_blockicc_levels", "Fill of the factor: 0, the matrix's pattern (IC(0)); 1, also the blocks two of the matrix's blocks fill (IC(1))", "PCBLOCKICC", levels, &levels, &set));
    PetscCheck(levels == 0 || levels == 1, PetscObjectComm((PetscObject) pc), PETSC_ERR_USER_INPUT, "-pc_blockicc_levels %" PetscInt_FMT " is not a fill this preconditioner makes: 0 (IC(0)) or 1 (IC(1))", levels);
    if (set) PetscCall(PCBlockICCSetLevels_BlockICC(pc, levels));
  }
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
  if (ascii) {
    PetscCall(PetscViewerASCIIPrintf(viewer, "  IC(%" PetscInt_FMT ") in 3 x 3 blocks (%s), pivot tolerance %g; the last factorisation %s\n", icc->levels, PCBlockICCTypes[icc->type], (double) icc->pivot_tol,
                                     icc->compensated ? "compensated the dropped fill" : "plain"));
    PetscCall(PetscViewerASCIIPrintf(viewer, "  factor stored in %s precision%s, %.2f blocks a block row (the matrix's upper triangle: %.2f)\n", icc->single ? "single" : "double",
                                     icc->widened ? " (single was asked for, and a rounded pivot block was not positive definite)" : "", icc->n ? (double) icc->fi[icc->n] / icc->n : 0.0, icc->n ? (double) icc->ai[icc->n] / icc->n : 0.0));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode PCBlockICCGetCompensated_BlockICC(PC pc, PetscBool *compensated)
{
  PetscFunctionBeginUser;
  PetscCall(MPIU_Allreduce(&((PC_BlockICC *) pc->data)->compensated, compensated, 1, MPIU_BOOL, MPI_LOR, PetscObjectComm((PetscObject) pc)));
  PetscFunctionReturn(0);
}

PetscErrorCode PCBlockICCSetLevels(PC pc, PetscInt levels)
{
  PetscFunctionBeginUser;
  PetscTryMethod(pc, "PCBlockICCSetLevels_C", (PC, PetscInt), (pc, levels));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCBlockICCGetLevels_BlockICC(PC pc, PetscInt *levels)
{
  PetscFunctionBeginUser;
  *levels = ((PC_BlockICC *) pc->data)->levels;
  PetscFunctionReturn(0);
}

PetscErrorCode PCBlockICCGetLevels(PC pc, PetscInt *levels)
{
  PetscFunctionBeginUser;
  *levels = -1;
  PetscTryMethod(pc, "PCBlockICCGetLevels_C", (PC, PetscInt *), (pc, levels));
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
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCBlockICCSetLevels_C", PCBlockICCSetLevels_BlockICC));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCBlockICCGetLevels_C", PCBlockICCGetLevels_BlockICC));
  PetscFunctionReturn(0);
}

PetscErrorCode PCBlockICCRegister(void)
{
  PetscFunctionBeginUser;
  PetscCall(PCRegister(PCBLOCKICC, PCCreate_BlockICC));
  PetscFunctionReturn(0);
}
