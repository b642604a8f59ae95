/* PCLATTICEMG: geometric multigrid on the cloth's lattice (include/pclatticemg.h).
 *
 * Why: block IC(0) and IC(1) take CG iterations that grow with the lattice (the
 * Cusick scene: 14.5, 22.7 and 47.7 a step at 81^2, 161^2 and 241^2; BENCHMARKS.md),
 * and drape's AMG (ML) holds 12.8 kB a particle. With this: 4.1, 4.4 and 9.2 at
 * 81^2, 161^2 and 321^2, 3.0 kB a particle (the whole of drapebe, the stiff hang).
 * The lattice is a grid: its coarse levels need no aggregation, and their
 * interpolation no storage.
 *
 * Levels. Level 0 is the matrix (one block row per particle, its lattice node
 * node[k]); level l + 1 keeps the nodes of level l with even indices along each
 * direction that has more than 3 nodes (n -> n / 2 + 1). Interpolation is bilinear,
 * one weight for the three components: an even fine node takes its coarse node, an
 * odd one half of each of its two neighbours (a quarter of four on the diagonals).
 * On level 0 it is filtered by the rows' constraints, P_k = S_k w (S_k: I, I - n n^T
 * when sliding, 0 when fixed or pinned), as in Tamstorf, Jones & McCormick (2015):
 * the constrained directions are decoupled in the matrix (S J S + (I - S) D) and take
 * no coarse correction. The coarse operator is P^T A P, each of A's blocks (upper
 * triangle, and its transpose) added to the coarse blocks its nodes' weights reach.
 * A fine coupling of at most two nodes gives a coarse one of at most two, so every
 * coarse level's operator has 5 x 5 blocks a node, of which it stores the upper
 * triangle's 13 (LMGUpper; the sweeps take the lower triangle's as their transposes,
 * LMGUpperScatter, so the operator is symmetric to the bit); a coupling beyond (a self-contact
 * pair across a fold) keeps its diagonal parts and drops its coarse cross terms,
 * which leaves the coarse operator positive semi-definite.
 *
 * The cycle: (1,1), symmetric, a V-cycle from the finest level to the first coarse
 * one and a W-cycle below it (-pc_latticemg_gamma 2, LMGCoarseSolve: at 321^2 6.4
 * CG iterations a step against 9.2, 12 % less time a step). Finest level: block IC (an inner PCBLOCKICC of the
 * same matrix, options prefix -mg_fine_; IC(1) from its first factorisation that
 * compensated, a poor smoother otherwise) before and after the coarse correction,
 * with a product with A for each residual; or block Gauss-Seidel (-pc_latticemg_
 * smoother sgs), forward before and backward after. V(1,1) is positive definite
 * where 2 M - A is (M the finest smoother); the hybrid cycle (-pc_latticemg_hybrid)
 * M^-1 + (I - M^-1 A) Q (I - A M^-1) for any positive definite M, with the same
 * products and solves (BENCHMARKS.md: the Cusick scene at 81^2 and 4 ms steps, where
 * block IC(0) misses A by more than 2). The coarse levels' operators are made again
 * at every -pc_latticemg_coarse_lag-th set-up, stored in single precision (the
 * sweeps stream half the bytes; the same CG iterations; the diagonal blocks'
 * inverses stay double, since a block's condition number, the in-plane stretch over
 * the out-of-plane mass, reaches 1e6 at 321^2). Coarser levels: block Gauss-Seidel
 * forward before, backward after (LMGCycle), each diagonal block inverted by an LDL^T that drops a pivot below 1e-10 of
 * its diagonal entry or 1e-9 of the level's largest (a direction every fine row's
 * filter removed: a generalised inverse, exact on the residuals, which have no
 * component there). Coarsest: a dense LDL^T with the same drop, if it has at most
 * -pc_latticemg_coarse_nodes nodes, else one symmetric Gauss-Seidel sweep.
 *
 * On several ranks (MPISBAIJ) each rank holds its own rows of the finest level and
 * every coarse level whole: the first coarse operator is each rank's rows' share
 * (its diagonal block's, and through MatGetRow its blocks in other ranks' columns,
 * with those columns' nodes and constraints from their owners) summed over the
 * ranks; a cycle restricts each rank's rows, sums the restriction over the ranks,
 * runs the coarse levels on every rank (the same numbers) and interpolates to each
 * rank's rows. The finest level's smoother is each rank's block (block IC or block
 * Gauss-Seidel of the diagonal block: block Jacobi over the ranks). The coarse
 * levels' work and memory are not divided: about 210 bytes a particle of the whole
 * lattice on every rank, and one sum over the ranks of the first coarse level's
 * residual (24 bytes a coarse node) a cycle (BENCHMARKS.md, "The lattice multigrid on
 * two ranks").
 *
 * Blocks are PETSc's: 9 values by columns, B(r, c) = b[r + 3 c]. */
#include <petsc/private/pcimpl.h>
#include <petscsf.h>
#include <pclatticemg.h>
#include <pcblockicc.h>

#define LMG_W          5       /* a node's stencil: offsets -2 .. 2 along each direction */
#define LMG_U          13      /* blocks a node stored: its own and the upper triangle's, (dx, dy) with dy > 0, or dy = 0 and dx >= 0 */
#define LMG_DROP_OWN   1.0e-10 /* a pivot at most this times its diagonal entry is dropped */
#define LMG_DROP_LEVEL 1.0e-9  /* ... or this times the level's largest diagonal entry */

typedef struct {
  PetscInt     nx, ny, n; /* nodes along x and y, n = nx ny (node j nx + i)             */
  float       *a;         /* 13 blocks a node, the upper triangle: block (I, I + (dx, dy)) at 9 (13 I + LMGUpper(dx, dy)); single precision (half the bytes the sweeps stream) */
  PetscScalar *g;         /* the diagonal blocks' generalised inverses (not on a dense coarsest level), symmetric; in double: a block's condition number reaches the cloth's stiff over soft, 1e6 */
  PetscScalar *b, *x;     /* right-hand side and correction: 3 n each                   */
  PetscScalar *r, *x1;    /* the W-cycle's: b and the first correction, kept (3 n each; coarse levels past the first) */
} LMGLevel;

typedef enum {
  LMG_SMOOTH_SGS,
  LMG_SMOOTH_BLOCKICC
} LMGSmoother;
static const char *const LMGSmoothers[] = {"sgs", "blockicc", "LMGSmoother", "LMG_SMOOTH_", NULL};

typedef struct {
  PetscInt         Mx, My;   /* the lattice                                                */
  PetscInt         nrows;    /* the matrix's block rows                                    */
  PetscInt        *node;     /* each row's node, j Mx + i                                  */
  PetscBool       *pinned;   /* each row's pin                                             */
  unsigned char   *kind;     /* each row: 0 free, 1 sliding, 2 fixed or pinned (the filter) */
  const PetscReal *normal;   /* a sliding row's normal, 3 a row: the caller's (PCLatticeMGSetConstraints) */
  PetscInt         nlevels;  /* coarse levels                                              */
  LMGLevel        *lev;      /* lev[0] the first coarse level, lev[nlevels - 1] the coarsest */
  PetscScalar     *dense;    /* the coarsest level's LDL^T (L below the diagonal, D on it), or NULL */
  LMGSmoother      smoother; /* the finest level's: block Gauss-Seidel, or block IC (fine)  */
  PetscScalar     *dinv;     /* block Gauss-Seidel: the matrix's diagonal blocks inverted, 9 a row */
  PC               fine;     /* block IC                                                   */
  Vec              w, y;     /* fine work vectors (y for the hybrid cycle only)            */
  PetscInt         max_levels, coarse_nodes;
  PetscInt         coarse_lag; /* the coarse levels are made again at every coarse_lag-th set-up */
  PetscInt         gamma;      /* cycles on each level past the first coarse one: 1 V, 2 W */
  PetscInt         setups;     /* set-ups since the coarse levels were made                 */
  PetscBool        fill_auto;  /* block IC smoother: IC(1) once IC(0) had to compensate     */
  PetscBool        hybrid;     /* M^-1 + (I - M^-1 A) Q (I - A M^-1) instead of the V(1,1) cycle: SPD for any SPD smoother */
  PetscMPIInt      size;       /* ranks: on several, each holds its rows of the finest level and the coarse levels whole */
} PC_LatticeMG;

/* -log_view: a cycle's coarse correction (restriction, the sum over the ranks, the
 * coarse levels, interpolation) */
static PetscLogEvent LMG_Coarse;

static inline PetscInt LMGCoarseSize(PetscInt n) { return n <= 3 ? n : n / 2 + 1; }

/* The stored block of node I's row for its neighbour I + (dx, dy) in the upper
 * triangle (dy > 0, or dy = 0 and dx >= 0; |dx|, dy <= 2): 0 is its own */
static inline PetscInt LMGUpper(PetscInt dx, PetscInt dy) { return LMG_W * dy + dx; }

/* The coarse nodes of fine index i along a direction of n nodes, and their weights. */
static inline PetscInt LMGSupport1(PetscInt n, PetscInt i, PetscInt c[2], PetscReal w[2])
{
  if (n <= 3 || !(i & 1)) {
    c[0] = n <= 3 ? i : i / 2;
    w[0] = 1;
    return 1;
  }
  c[0] = i / 2, c[1] = i / 2 + 1;
  w[0] = w[1] = 0.5;
  return 2;
}

/* The coarse nodes (their coordinates) of fine node (i, j) of an nx x ny level. */
static inline PetscInt LMGSupport(PetscInt nx, PetscInt ny, PetscInt i, PetscInt j, PetscInt ci[4], PetscInt cj[4], PetscReal w[4])
{
  PetscInt  cx[2], cy[2], mx, my, m = 0;
  PetscReal wx[2], wy[2];

  mx = LMGSupport1(nx, i, cx, wx);
  my = LMGSupport1(ny, j, cy, wy);
  for (PetscInt b = 0; b < my; b++)
    for (PetscInt a = 0; a < mx; a++, m++) ci[m] = cx[a], cj[m] = cy[b], w[m] = wx[a] * wy[b];
  return m;
}

/* y = S_k y for a row's filter */
static inline void LMGFilter(const PC_LatticeMG *mg, PetscInt k, PetscScalar y[3])
{
  if (mg->kind[k] == 1) {
    const PetscReal *n = mg->normal + 3 * k, d = n[0] * y[0] + n[1] * y[1] + n[2] * y[2];
    for (PetscInt r = 0; r < 3; r++) y[r] -= d * n[r];
  } else if (mg->kind[k] == 2)
    y[0] = y[1] = y[2] = 0;
}

/* b = S_k b S_m for rows k, m of kinds kk, km (1 sliding, along the normals nk, nm;
 * b by columns; fixed rows are skipped before) */
static inline void LMGFilterBlockOf(unsigned char kk, const PetscReal *nk, unsigned char km, const PetscReal *nm, PetscScalar b[9])
{
  if (kk == 1) { /* (I - n n^T) b: each column */
    const PetscReal *n = nk;
    for (PetscInt c = 0; c < 3; c++) {
      const PetscScalar d = n[0] * b[3 * c] + n[1] * b[1 + 3 * c] + n[2] * b[2 + 3 * c];
      for (PetscInt r = 0; r < 3; r++) b[r + 3 * c] -= d * n[r];
    }
  }
  if (km == 1) { /* b (I - n n^T): each row */
    const PetscReal *n = nm;
    for (PetscInt r = 0; r < 3; r++) {
      const PetscScalar d = b[r] * n[0] + b[r + 3] * n[1] + b[r + 6] * n[2];
      for (PetscInt c = 0; c < 3; c++) b[r + 3 * c] -= d * n[c];
    }
  }
}

/* b = S_k b S_m for the rank's rows k, m */
static inline void LMGFilterBlock(const PC_LatticeMG *mg, PetscInt k, PetscInt m, PetscScalar b[9]) { LMGFilterBlockOf(mg->kind[k], mg->kind[k] == 1 ? mg->normal + 3 * k : NULL, mg->kind[m], mg->kind[m] == 1 ? mg->normal + 3 * m : NULL, b); }

/* The rank's rows and the blocks among them: the matrix on one rank, its diagonal block on several */
static PetscErrorCode LMGLocalMatrix(Mat A, Mat *Ad)
{
  PetscBool mpi;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) A, MATMPISBAIJ, &mpi));
  if (mpi)
    PetscCall(MatGetDiagonalBlock(A, Ad));
  else
    *Ad = A;
  PetscFunctionReturn(0);
}

/* LDL^T of the symmetric n x n matrix a (by columns, leading dimension n) in place,
 * a pivot dropped (set to 0) where at most LMG_DROP_OWN times its diagonal entry or
 * tol: L below the diagonal, D on it. */
static void LMGFactorDense(PetscInt n, PetscScalar *a, PetscReal tol)
{
  for (PetscInt j = 0; j < n; j++) {
    const PetscReal ajj = PetscRealPart(a[j + n * j]);
    PetscScalar     d   = a[j + n * j];
    for (PetscInt k = 0; k < j; k++) d -= a[j + n * k] * a[j + n * k] * a[k + n * k];
    if (!(PetscRealPart(d) > LMG_DROP_OWN * ajj && PetscRealPart(d) > tol)) {
      a[j + n * j] = 0;
      for (PetscInt i = j + 1; i < n; i++) a[i + n * j] = 0;
      continue;
    }
    a[j + n * j] = d;
    for (PetscInt i = j + 1; i < n; i++) {
      PetscScalar s = a[i + n * j];
      for (PetscInt k = 0; k < j; k++) s -= a[i + n * k] * a[j + n * k] * a[k + n * k];
      a[i + n * j] = s / d;
    }
  }
}

/* x = (L D L^T)^+ x with the factor of LMGFactorDense (a dropped pivot gives 0) */
static void LMGSolveDense(PetscInt n, const PetscScalar *a, PetscScalar *x)
{
  for (PetscInt j = 0; j < n; j++)
    for (PetscInt i = j + 1; i < n; i++) x[i] -= a[i + n * j] * x[j];
  for (PetscInt j = 0; j < n; j++) x[j] = a[j + n * j] != 0.0 ? x[j] / a[j + n * j] : 0;
  for (PetscInt j = n - 1; j >= 0; j--)
    for (PetscInt i = j + 1; i < n; i++) x[j] -= a[i + n * j] * x[i];
}

/* The generalised inverse of a symmetric 3 x 3 block */
static void LMGBlockInverse(const PetscScalar *d, PetscReal tol, PetscScalar *g)
{
  PetscScalar f[9];

  for (PetscInt c = 0; c < 3; c++)
    for (PetscInt r = 0; r < 3; r++) f[r + 3 * c] = 0.5 * (d[r + 3 * c] + d[c + 3 * r]);
  LMGFactorDense(3, f, tol);
  for (PetscInt c = 0; c < 3; c++) {
    PetscScalar e[3] = {0, 0, 0};
    e[c]             = 1;
    LMGSolveDense(3, f, e);
    for (PetscInt r = 0; r < 3; r++) g[r + 3 * c] = e[r];
  }
}

static PetscErrorCode LMGFreeLevels(PC_LatticeMG *mg)
{
  PetscFunctionBeginUser;
  for (PetscInt l = 0; l < mg->nlevels; l++) {
    PetscCall(PetscFree(mg->lev[l].a));
    PetscCall(PetscFree(mg->lev[l].g));
    PetscCall(PetscFree2(mg->lev[l].b, mg->lev[l].x));
    PetscCall(PetscFree2(mg->lev[l].r, mg->lev[l].x1));
  }
  PetscCall(PetscFree(mg->lev));
  PetscCall(PetscFree(mg->dense));
  mg->nlevels = 0;
  mg->setups  = 0;
  PetscFunctionReturn(0);
}

/* The levels' sizes and storage, made once for the lattice */
static PetscErrorCode LMGCreateLevels(PC_LatticeMG *mg)
{
  PetscInt nx = mg->Mx, ny = mg->My, nl = 0, cx[64], cy[64];

  PetscFunctionBeginUser;
  for (;;) {
    const PetscInt ncx = LMGCoarseSize(nx), ncy = LMGCoarseSize(ny);
    cx[nl] = ncx, cy[nl] = ncy, nl++;
    if (ncx * ncy <= mg->coarse_nodes || (mg->max_levels > 0 && nl + 1 >= mg->max_levels) || (ncx == nx && ncy == ny) || nl == 64) break;
    nx = ncx, ny = ncy;
  }
  PetscCall(PetscCalloc1(nl, &mg->lev));
  mg->nlevels = nl;
  for (PetscInt l = 0; l < nl; l++) {
    LMGLevel *L = &mg->lev[l];
    L->nx = cx[l], L->ny = cy[l], L->n = cx[l] * cy[l];
    PetscCall(PetscMalloc1(9 * LMG_U * L->n, &L->a));
    PetscCall(PetscMalloc2(3 * L->n, &L->b, 3 * L->n, &L->x));
    if (l > 0 && mg->gamma > 1) PetscCall(PetscMalloc2(3 * L->n, &L->r, 3 * L->n, &L->x1));
    if (l < nl - 1 || L->n > mg->coarse_nodes) PetscCall(PetscMalloc1(9 * L->n, &L->g));
  }
  {
    const LMGLevel *L = &mg->lev[nl - 1];
    if (L->n <= mg->coarse_nodes) PetscCall(PetscMalloc1(9 * L->n * L->n, &mg->dense));
  }
  PetscFunctionReturn(0);
}

/* Add wt B (and to the transposed position wt B^T, when transpose) to the coarse
 * blocks of fine nodes (i, j) and (i2, j2) of level (nx, ny), coarse level C: the
 * upper triangle's only (a coarse block below the diagonal is the transpose of one
 * above it, which the same sum reaches; on the diagonal both add). */
static inline void LMGAddProduct(LMGLevel *C, PetscInt nx, PetscInt ny, PetscInt i, PetscInt j, PetscInt i2, PetscInt j2, const PetscScalar *B, PetscBool transpose)
{
  PetscInt  ai[4], aj[4], bi[4], bj[4];
  PetscReal aw[4], bw[4];
  PetscInt  na = LMGSupport(nx, ny, i, j, ai, aj, aw), nb = LMGSupport(nx, ny, i2, j2, bi, bj, bw);

  for (PetscInt p = 0; p < na; p++) {
    const PetscInt ic = aj[p] * C->nx + ai[p];
    for (PetscInt q = 0; q < nb; q++) {
      const PetscInt  dx = bi[q] - ai[p], dy = bj[q] - aj[p];
      const PetscReal wt = aw[p] * bw[q];
      const PetscInt  u  = LMGUpper(dx, dy);
      if (dx < -2 || dx > 2 || dy < -2 || dy > 2) continue; /* a far pair's cross terms */
      if (u >= 0) {
        float *c = C->a + 9 * (LMG_U * ic + u);
        for (PetscInt s = 0; s < 9; s++) c[s] += wt * B[s];
      }
      if (transpose && u <= 0) {
        const PetscInt jc = bj[q] * C->nx + bi[q];
        float         *c  = C->a + 9 * (LMG_U * jc - u);
        for (PetscInt r = 0; r < 3; r++)
          for (PetscInt s = 0; s < 3; s++) c[r + 3 * s] += wt * B[s + 3 * r];
      }
    }
  }
}

/* On several ranks, the blocks of the rank's rows in other ranks' columns (the upper
 * triangle's: each such block is held by one rank, the owner of its row), added to
 * the first coarse level's operator: read by MatGetRow (PETSc 3.18 has no accessor
 * of MPISBAIJ's off-diagonal part), their columns' nodes and constraints from the
 * columns' owners (a star forest over the block rows). */
static PetscErrorCode LMGGalerkinCut(PC pc, PC_LatticeMG *mg, Mat A)
{
  LMGLevel      *C    = &mg->lev[0];
  MPI_Comm       comm = PetscObjectComm((PetscObject) pc);
  const PetscInt Mx   = mg->Mx;
  PetscInt       rstart, rend, nb = 0, mb = 0, nleaf = 0, *brow = NULL, *bcol = NULL, *leaf, *rint, *lint;
  PetscScalar   *bval = NULL;
  PetscReal     *rnrm, *lnrm;
  PetscSF        sf;
  PetscLayout    map;
  MPI_Datatype   unit;

  PetscFunctionBeginUser;
  PetscCall(MatGetOwnershipRange(A, &rstart, &rend));
  rstart /= 3, rend /= 3; /* block rows */
  PetscCall(MatGetRowUpperTriangular(A));
  for (PetscInt k = 0; k < mg->nrows; k++) {
    const PetscInt first = nb;
    if (mg->kind[k] == 2) continue;
    for (PetscInt r = 0; r < 3; r++) { /* the block row's three rows: the same block columns, sorted */
      PetscInt           nz, q = first;
      const PetscInt    *cols;
      const PetscScalar *v;
      PetscCall(MatGetRow(A, 3 * (rstart + k) + r, &nz, &cols, &v));
      for (PetscInt e = 0; e < nz; e++) {
        const PetscInt g = cols[e] / 3;
        if (g >= rstart && g < rend) continue;
        if (r == 0 && cols[e] % 3 == 0) { /* a new block */
          if (nb == mb) {
            mb = 2 * mb + 256;
            PetscCall(PetscRealloc(mb * sizeof(*brow), &brow));
            PetscCall(PetscRealloc(mb * sizeof(*bcol), &bcol));
            PetscCall(PetscRealloc(9 * mb * sizeof(*bval), &bval));
          }
          brow[nb] = k, bcol[nb] = g;
          PetscCall(PetscArrayzero(bval + 9 * nb, 9));
          nb++;
        }
        while (q < nb && bcol[q] != g) q++;
        PetscCheck(q < nb, PETSC_COMM_SELF, PETSC_ERR_PLIB, "block row %" PetscInt_FMT ": column %" PetscInt_FMT " in its row %" PetscInt_FMT " only", rstart + k, cols[e], r);
        bval[9 * q + r + 3 * (cols[e] % 3)] = v[e];
      }
      PetscCall(MatRestoreRow(A, 3 * (rstart + k) + r, &nz, &cols, &v));
    }
  }
  PetscCall(MatRestoreRowUpperTriangular(A));
  /* the columns' nodes, kinds and normals from their owners */
  PetscCall(PetscMalloc1(nb + 1, &leaf));
  PetscCall(PetscArraycpy(leaf, bcol, nb));
  nleaf = nb;
  PetscCall(PetscSortRemoveDupsInt(&nleaf, leaf));
  PetscCall(PetscMalloc4(2 * mg->nrows + 1, &rint, 2 * nleaf + 1, &lint, 3 * mg->nrows + 1, &rnrm, 3 * nleaf + 1, &lnrm));
  for (PetscInt k = 0; k < mg->nrows; k++) {
    rint[2 * k] = mg->node[k], rint[2 * k + 1] = mg->kind[k];
    for (PetscInt d = 0; d < 3; d++) rnrm[3 * k + d] = mg->kind[k] == 1 ? mg->normal[3 * k + d] : 0;
  }
  PetscCall(PetscLayoutCreateFromSizes(comm, mg->nrows, PETSC_DECIDE, 1, &map));
  PetscCall(PetscSFCreate(comm, &sf));
  PetscCall(PetscSFSetGraphLayout(sf, map, nleaf, NULL, PETSC_USE_POINTER, leaf));
  PetscCallMPI(MPI_Type_contiguous(2, MPIU_INT, &unit)); /* node, kind */
  PetscCallMPI(MPI_Type_commit(&unit));
  PetscCall(PetscSFBcastBegin(sf, unit, rint, lint, MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sf, unit, rint, lint, MPI_REPLACE));
  PetscCallMPI(MPI_Type_free(&unit));
  PetscCallMPI(MPI_Type_contiguous(3, MPIU_REAL, &unit)); /* normal */
  PetscCallMPI(MPI_Type_commit(&unit));
  PetscCall(PetscSFBcastBegin(sf, unit, rnrm, lnrm, MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sf, unit, rnrm, lnrm, MPI_REPLACE));
  PetscCallMPI(MPI_Type_free(&unit));
  PetscCall(PetscSFDestroy(&sf));
  PetscCall(PetscLayoutDestroy(&map));
  for (PetscInt b = 0; b < nb; b++) {
    const PetscInt k = brow[b];
    PetscInt       m = -1;
    PetscCall(PetscFindInt(bcol[b], nleaf, leaf, &m));
    if (lint[2 * m + 1] == 2) continue;
    if (mg->kind[k] == 1 || lint[2 * m + 1] == 1) LMGFilterBlockOf(mg->kind[k], mg->kind[k] == 1 ? mg->normal + 3 * k : NULL, (unsigned char) lint[2 * m + 1], lnrm + 3 * m, bval + 9 * b);
    LMGAddProduct(C, mg->Mx, mg->My, mg->node[k] % Mx, mg->node[k] / Mx, lint[2 * m] % Mx, lint[2 * m] / Mx, bval + 9 * b, PETSC_TRUE);
  }
  PetscCall(PetscLogFlops(18.0 * 9 * nb));
  PetscCall(PetscFree4(rint, lint, rnrm, lnrm));
  PetscCall(PetscFree(leaf));
  PetscCall(PetscFree(brow));
  PetscCall(PetscFree(bcol));
  PetscCall(PetscFree(bval));
  PetscFunctionReturn(0);
}

/* The first coarse level's operator, P^T A P from A's upper triangle of blocks: on
 * several ranks each rank's rows' share, summed over the ranks (every rank holds
 * the coarse levels whole) */
static PetscErrorCode LMGGalerkinFine(PC pc, PC_LatticeMG *mg, Mat Aall)
{
  LMGLevel       *C = &mg->lev[0];
  const PetscInt *ia, *ja, Mx = mg->Mx;
  PetscInt        n;
  PetscBool       done;
  MatScalar      *aa;
  Mat             A;

  PetscFunctionBeginUser;
  PetscCall(LMGLocalMatrix(Aall, &A));
  PetscCall(MatGetRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  PetscCheck(done && n == mg->nrows, PetscObjectComm((PetscObject) pc), PETSC_ERR_ARG_WRONG, "-pc_type latticemg: the matrix has %" PetscInt_FMT " block rows and the lattice given %" PetscInt_FMT " particles", n, mg->nrows);
  PetscCall(MatSeqSBAIJGetArray(A, &aa));
  PetscCall(PetscArrayzero(C->a, 9 * LMG_U * C->n));
  for (PetscInt k = 0; k < n; k++) {
    if (mg->kind[k] == 2) continue;
    for (PetscInt p = ia[k]; p < ia[k + 1]; p++) {
      const PetscInt m = ja[p];
      PetscScalar    B[9];
      if (mg->kind[m] == 2) continue;
      PetscCall(PetscArraycpy(B, aa + 9 * p, 9));
      if (mg->kind[k] == 1 || mg->kind[m] == 1) LMGFilterBlock(mg, k, m, B);
      LMGAddProduct(C, mg->Mx, mg->My, mg->node[k] % Mx, mg->node[k] / Mx, mg->node[m] % Mx, mg->node[m] / Mx, B, (PetscBool) (m != k));
    }
  }
  PetscCall(PetscLogFlops(18.0 * 9 * ia[n]));
  PetscCall(MatSeqSBAIJRestoreArray(A, &aa));
  PetscCall(MatRestoreRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  if (A != Aall) {
    PetscCall(LMGGalerkinCut(pc, mg, Aall));
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, C->a, (PetscMPIInt) (9 * LMG_U * C->n), MPI_FLOAT, MPI_SUM, PetscObjectComm((PetscObject) pc)));
  }
  PetscFunctionReturn(0);
}

/* Level l + 1's operator from level l's upper triangle */
static PetscErrorCode LMGGalerkinCoarse(PC_LatticeMG *mg, PetscInt l)
{
  const LMGLevel *F = &mg->lev[l];
  LMGLevel       *C = &mg->lev[l + 1];

  PetscFunctionBeginUser;
  PetscCall(PetscArrayzero(C->a, 9 * LMG_U * C->n));
  for (PetscInt j = 0; j < F->ny; j++)
    for (PetscInt i = 0; i < F->nx; i++)
      for (PetscInt dy = 0; dy <= PetscMin(2, F->ny - 1 - j); dy++)
        for (PetscInt dx = dy ? PetscMax(-2, -i) : 0; dx <= PetscMin(2, F->nx - 1 - i); dx++) {
          const float *b = F->a + 9 * (LMG_U * (j * F->nx + i) + LMGUpper(dx, dy));
          PetscScalar  B[9];
          for (PetscInt q = 0; q < 9; q++) B[q] = b[q];
          LMGAddProduct(C, F->nx, F->ny, i, j, i + dx, j + dy, B, (PetscBool) (dx || dy));
        }
  PetscCall(PetscLogFlops(18.0 * 9 * LMG_U * F->n));
  PetscFunctionReturn(0);
}

/* The level's smoother: the diagonal blocks' inverses, or the dense factor */
static PetscErrorCode LMGSetUpSmoother(PC_LatticeMG *mg, PetscInt l)
{
  LMGLevel *L   = &mg->lev[l];
  PetscReal big = 0, tol;

  PetscFunctionBeginUser;
  for (PetscInt ic = 0; ic < L->n; ic++)
    for (PetscInt r = 0; r < 3; r++) big = PetscMax(big, PetscRealPart(L->a[9 * LMG_U * ic + 4 * r]));
  tol = LMG_DROP_LEVEL * big;
  if (L->g)
    for (PetscInt ic = 0; ic < L->n; ic++) {
      PetscScalar d[9], g[9];
      for (PetscInt q = 0; q < 9; q++) d[q] = L->a[9 * LMG_U * ic + q];
      LMGBlockInverse(d, tol, g);
      for (PetscInt r = 0; r < 3; r++) /* symmetric to the bit: the sweeps backward are the transposes of those forward */
        for (PetscInt c = 0; c < 3; c++) L->g[9 * ic + r + 3 * c] = 0.5 * (g[r + 3 * c] + g[c + 3 * r]);
    }
  if (l == mg->nlevels - 1 && mg->dense) {
    const PetscInt N = 3 * L->n;
    PetscCall(PetscArrayzero(mg->dense, N * N));
    for (PetscInt j = 0; j < L->ny; j++)
      for (PetscInt i = 0; i < L->nx; i++)
        for (PetscInt dy = 0; dy <= PetscMin(2, L->ny - 1 - j); dy++)
          for (PetscInt dx = dy ? PetscMax(-2, -i) : 0; dx <= PetscMin(2, L->nx - 1 - i); dx++) {
            const PetscInt ic = j * L->nx + i, jc = (j + dy) * L->nx + i + dx;
            const float   *B = L->a + 9 * (LMG_U * ic + LMGUpper(dx, dy));
            for (PetscInt c = 0; c < 3; c++)
              for (PetscInt r = 0; r < 3; r++) mg->dense[3 * ic + r + N * (3 * jc + c)] = mg->dense[3 * jc + c + N * (3 * ic + r)] = B[r + 3 * c];
          }
    LMGFactorDense(N, mg->dense, tol);
  }
  PetscFunctionReturn(0);
}

/* s -= sum over the upper triangle's blocks of row I, its own excepted, of A_IJ y_J
 * (a row of U y), on level L */
static inline void LMGUpperProduct(const LMGLevel *L, PetscInt ic, const PetscScalar *y, PetscScalar s[3])
{
  const PetscInt i = ic % L->nx, j = ic / L->nx;

  for (PetscInt dy = 0; dy <= PetscMin(2, L->ny - 1 - j); dy++)
    for (PetscInt dx = dy ? PetscMax(-2, -i) : 1; dx <= PetscMin(2, L->nx - 1 - i); dx++) {
      const float       *B  = L->a + 9 * (LMG_U * ic + LMGUpper(dx, dy));
      const PetscScalar *yj = y + 3 * (ic + dy * L->nx + dx);
      for (PetscInt r = 0; r < 3; r++) s[r] -= B[r] * yj[0] + B[r + 3] * yj[1] + B[r + 6] * yj[2];
    }
}

/* y_J -= A_IJ^T x_I over the upper triangle's blocks of row I, its own excepted
 * (column I of L = U^T times x_I), on level L */
static inline void LMGUpperScatter(const LMGLevel *L, PetscInt ic, const PetscScalar xi[3], PetscScalar *y)
{
  const PetscInt i = ic % L->nx, j = ic / L->nx;

  for (PetscInt dy = 0; dy <= PetscMin(2, L->ny - 1 - j); dy++)
    for (PetscInt dx = dy ? PetscMax(-2, -i) : 1; dx <= PetscMin(2, L->nx - 1 - i); dx++) {
      const float *B  = L->a + 9 * (LMG_U * ic + LMGUpper(dx, dy));
      PetscScalar *yj = y + 3 * (ic + dy * L->nx + dx);
      for (PetscInt c = 0; c < 3; c++) yj[c] -= B[3 * c] * xi[0] + B[3 * c + 1] * xi[1] + B[3 * c + 2] * xi[2];
    }
}

/* s -= D_I x_I, D_I row I's own block */
static inline void LMGDiagonalSubtract(const LMGLevel *L, PetscInt ic, const PetscScalar *x, PetscScalar s[3])
{
  const float       *D  = L->a + 9 * LMG_U * ic;
  const PetscScalar *xi = x + 3 * ic;

  for (PetscInt r = 0; r < 3; r++) s[r] -= D[r] * xi[0] + D[r + 3] * xi[1] + D[r + 6] * xi[2];
}

/* x_I = G_I s */
static inline void LMGDiagonalSolve(const LMGLevel *L, PetscInt ic, const PetscScalar s[3])
{
  const PetscScalar *g = L->g + 9 * ic;

  for (PetscInt r = 0; r < 3; r++) L->x[3 * ic + r] = g[r] * s[0] + g[r + 3] * s[1] + g[r + 6] * s[2];
}

/* C->b_I += w r for each coarse node I of fine node (i, j) of an nx x ny level (the
 * restriction, the interpolation's transpose, one fine node at a time) */
static inline void LMGRestrictNode(LMGLevel *C, PetscInt nx, PetscInt ny, PetscInt i, PetscInt j, const PetscScalar r[3])
{
  PetscInt  ci[4], cj[4], m;
  PetscReal w[4];

  m = LMGSupport(nx, ny, i, j, ci, cj, w);
  for (PetscInt p = 0; p < m; p++)
    for (PetscInt s = 0; s < 3; s++) C->b[3 * (cj[p] * C->nx + ci[p]) + s] += w[p] * r[s];
}

/* e = (P C->x) at fine node (i, j) of an nx x ny level */
static inline void LMGInterpolateNode(const LMGLevel *C, PetscInt nx, PetscInt ny, PetscInt i, PetscInt j, PetscScalar e[3])
{
  PetscInt  ci[4], cj[4], m;
  PetscReal w[4];

  e[0] = e[1] = e[2] = 0;
  m                  = LMGSupport(nx, ny, i, j, ci, cj, w);
  for (PetscInt p = 0; p < m; p++)
    for (PetscInt s = 0; s < 3; s++) e[s] += w[p] * C->x[3 * (cj[p] * C->nx + ci[p]) + s];
}

static void LMGCycle(PC_LatticeMG *, PetscInt);

/* b = r - A x on level L: row I's own block and upper triangle as stored, its
 * lower triangle from the rows above it, transposed */
static void LMGResidual(const LMGLevel *L, const PetscScalar *r, const PetscScalar *x, PetscScalar *b)
{
  for (PetscInt q = 0; q < 3 * L->n; q++) b[q] = r[q];
  for (PetscInt ic = 0; ic < L->n; ic++) {
    LMGDiagonalSubtract(L, ic, x, b + 3 * ic);
    LMGUpperProduct(L, ic, x, b + 3 * ic);
    LMGUpperScatter(L, ic, x + 3 * ic, b);
  }
}

/* lev[l].x from lev[l].b with gamma cycles (a W-cycle for 2): x = B b, then x += B (b -
 * A x); symmetric, 2 B - B A B, positive definite since B A's eigenvalues lie in (0, 1] */
static void LMGCoarseSolve(PC_LatticeMG *mg, PetscInt l)
{
  LMGLevel *L = &mg->lev[l];

  if (mg->gamma < 2 || !L->r || (l == mg->nlevels - 1 && mg->dense)) {
    LMGCycle(mg, l);
    return;
  }
  for (PetscInt q = 0; q < 3 * L->n; q++) L->r[q] = L->b[q];
  LMGCycle(mg, l);
  for (PetscInt q = 0; q < 3 * L->n; q++) L->x1[q] = L->x[q];
  LMGResidual(L, L->r, L->x1, L->b);
  LMGCycle(mg, l);
  for (PetscInt q = 0; q < 3 * L->n; q++) L->x[q] += L->x1[q];
}

/* The cycle from coarse level l down: lev[l].x from lev[l].b, which it overwrites.
 * The level's matrix is stored as its upper triangle, D + U (L = U^T); G is D's
 * generalised inverse, symmetric. The forward sweep from 0, x_I = G t_I with t = b -
 * L x, runs by L's columns (t_J -= A_IJ^T x_I once x_I is known, in x itself) and
 * keeps t in b; row I's residual, t_I - D x_I - (U x)_I, is formed and restricted
 * once the last node it reads (I + 2 nx + 2) is known. After the coarse correction
 * one ascending pass adds it, e, and turns b into t - L e = b - L x; the backward
 * sweep, x_I = G (b - L x_old - U x_new)_I, is the forward one's transpose. Each pass
 * streams the level's 13 blocks a node once (the residual's rows again, from the
 * cache). */
static void LMGCycle(PC_LatticeMG *mg, PetscInt l)
{
  LMGLevel      *L = &mg->lev[l];
  LMGLevel      *C = l < mg->nlevels - 1 ? &mg->lev[l + 1] : NULL;
  const PetscInt n = L->n, lag = 2 * L->nx + 2;

  for (PetscInt q = 0; q < 3 * n; q++) L->x[q] = L->b[q];
  if (l == mg->nlevels - 1 && mg->dense) {
    LMGSolveDense(3 * n, mg->dense, L->x);
    return;
  }
  if (C)
    for (PetscInt q = 0; q < 3 * C->n; q++) C->b[q] = 0;
  for (PetscInt ic = 0; ic < n + (C ? lag : 0); ic++) {
    if (ic < n) { /* x_I = G_I t_I, then its column of L */
      for (PetscInt s = 0; s < 3; s++) L->b[3 * ic + s] = L->x[3 * ic + s];
      LMGDiagonalSolve(L, ic, L->b + 3 * ic);
      LMGUpperScatter(L, ic, L->x + 3 * ic, L->x);
    }
    if (C && ic >= lag) { /* row ic - lag's residual, restricted */
      const PetscInt p    = ic - lag;
      PetscScalar    r[3] = {L->b[3 * p], L->b[3 * p + 1], L->b[3 * p + 2]};
      LMGDiagonalSubtract(L, p, L->x, r);
      LMGUpperProduct(L, p, L->x, r);
      LMGRestrictNode(C, L->nx, L->ny, p % L->nx, p / L->nx, r);
    }
  }
  if (C) {
    LMGCoarseSolve(mg, l + 1);
    for (PetscInt ic = 0; ic < n; ic++) { /* x += e, b -= L e */
      PetscScalar e[3];
      LMGInterpolateNode(C, L->nx, L->ny, ic % L->nx, ic / L->nx, e);
      for (PetscInt s = 0; s < 3; s++) L->x[3 * ic + s] += e[s];
      LMGUpperScatter(L, ic, e, L->b);
    }
  }
  for (PetscInt ic = n - 1; ic >= 0; ic--) { /* x_I = G_I (b - L x_old - U x_new)_I */
    PetscScalar s[3] = {L->b[3 * ic], L->b[3 * ic + 1], L->b[3 * ic + 2]};
    LMGUpperProduct(L, ic, L->x, s);
    LMGDiagonalSolve(L, ic, s);
  }
}

/* The finest level's smoother set up for the matrix A */
static PetscErrorCode LMGFineSetUp(PC_LatticeMG *mg, Mat A)
{
  const PetscInt *ia, *ja;
  PetscInt        n;
  PetscBool       done;
  MatScalar      *aa;

  PetscFunctionBeginUser;
  if (mg->smoother == LMG_SMOOTH_BLOCKICC) {
    PetscInt levels;
    /* Where drapebe holds this PC across steps (-drape_pc_lag), the block IC is made
     * again all the same, by its own PCApply, for each new matrix: the coarse levels
     * lag, the smoother does not. Held too (PCSetReusePreconditioner), the Cusick
     * scene at 41^2 took 8.6 CG iterations a step instead of 2.5 in its first 0.3 s. */
    PetscCall(PCSetUp(mg->fine));
    PetscCall(PCBlockICCGetLevels(mg->fine, &levels));
    if (mg->fill_auto && levels == 0) { /* a compensated IC(0) smooths poorly: IC(1), from now on (on several ranks, every rank's once any rank's compensated) */
      PetscBool compensated;
      PetscCall(PCBlockICCGetCompensated(mg->fine, &compensated));
      if (compensated) {
        PetscCall(PCBlockICCSetLevels(mg->fine, 1));
        PetscCall((*mg->fine->ops->setup)(mg->fine));
      }
    }
    PetscFunctionReturn(0);
  }
  if (!mg->dinv) PetscCall(PetscMalloc1(9 * mg->nrows, &mg->dinv));
  PetscCall(LMGLocalMatrix(A, &A));
  PetscCall(MatGetRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  PetscCall(MatSeqSBAIJGetArray(A, &aa));
  for (PetscInt k = 0; k < n; k++) {
    PetscCheck(ia[k] < ia[k + 1] && ja[ia[k]] == k, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG, "-pc_type latticemg needs every diagonal block in the matrix's pattern, and block row %" PetscInt_FMT " has none", k);
    LMGBlockInverse(aa + 9 * ia[k], 0, mg->dinv + 9 * k);
  }
  PetscCall(MatSeqSBAIJRestoreArray(A, &aa));
  PetscCall(MatRestoreRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  PetscFunctionReturn(0);
}

/* x = M^-1 b (pre) or M^-T b (post), x may be b: block IC, symmetric; or block Gauss-Seidel,
 * M = D + L (a forward sweep from 0, in place: each row's update taken from the rows
 * below it through the upper triangle's blocks, transposed) and M^T = D + U (a
 * backward substitution through the upper triangle). On several ranks, of the
 * rank's diagonal block (block Jacobi over the ranks). */
static PetscErrorCode LMGFineSmooth(PC pc, PC_LatticeMG *mg, PetscBool pre, Vec b, Vec x)
{
  const PetscInt    *ia, *ja;
  PetscInt           n;
  PetscBool          done;
  MatScalar         *aa;
  PetscScalar       *y;
  const PetscScalar *bb;
  Mat                A;

  PetscFunctionBeginUser;
  if (mg->smoother == LMG_SMOOTH_BLOCKICC) {
    if (b == x)
      PetscCall(PCBlockICCApplyInPlace(mg->fine, x));
    else
      PetscCall(PCApply(mg->fine, b, x));
    PetscFunctionReturn(0);
  }
  PetscCall(LMGLocalMatrix(pc->pmat, &A));
  PetscCall(MatGetRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  PetscCall(MatSeqSBAIJGetArray(A, &aa));
  if (b == x) { /* in place: row k's right-hand side is read before its result is written */
    PetscCall(VecGetArray(x, &y));
    bb = y;
  } else {
    PetscCall(VecGetArrayRead(b, &bb));
    PetscCall(VecGetArrayWrite(x, &y));
  }
  if (pre) {
    if (y != bb) PetscCall(PetscArraycpy(y, bb, 3 * n));
    for (PetscInt k = 0; k < n; k++) {
      const PetscScalar *d = mg->dinv + 9 * k, t[3] = {y[3 * k], y[3 * k + 1], y[3 * k + 2]};
      PetscScalar        yk[3];
      for (PetscInt r = 0; r < 3; r++) yk[r] = y[3 * k + r] = d[r] * t[0] + d[r + 3] * t[1] + d[r + 6] * t[2];
      for (PetscInt p = ia[k] + 1; p < ia[k + 1]; p++) {
        const MatScalar *B  = aa + 9 * p;
        PetscScalar     *yj = y + 3 * ja[p];
        for (PetscInt r = 0; r < 3; r++) yj[r] -= B[3 * r] * yk[0] + B[3 * r + 1] * yk[1] + B[3 * r + 2] * yk[2];
      }
    }
  } else {
    for (PetscInt k = n - 1; k >= 0; k--) {
      const PetscScalar *d    = mg->dinv + 9 * k;
      PetscScalar        t[3] = {bb[3 * k], bb[3 * k + 1], bb[3 * k + 2]};
      for (PetscInt p = ia[k] + 1; p < ia[k + 1]; p++) {
        const MatScalar   *B  = aa + 9 * p;
        const PetscScalar *yj = y + 3 * ja[p];
        for (PetscInt r = 0; r < 3; r++) t[r] -= B[r] * yj[0] + B[r + 3] * yj[1] + B[r + 6] * yj[2];
      }
      for (PetscInt r = 0; r < 3; r++) y[3 * k + r] = d[r] * t[0] + d[r + 3] * t[1] + d[r + 6] * t[2];
    }
  }
  if (b == x)
    PetscCall(VecRestoreArray(x, &y));
  else {
    PetscCall(VecRestoreArrayWrite(x, &y));
    PetscCall(VecRestoreArrayRead(b, &bb));
  }
  PetscCall(PetscLogFlops(18.0 * (ia[n] + n)));
  PetscCall(MatSeqSBAIJRestoreArray(A, &aa));
  PetscCall(MatRestoreRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &n, &ia, &ja, &done));
  PetscFunctionReturn(0);
}

/* x += sign P B_c P^T r: the coarse levels' cycle (B_c) on the restricted r, the
 * interpolation and restriction filtered by the rows' constraints. On several ranks
 * each rank restricts its rows, the sum goes to every rank, every rank runs the
 * coarse cycle (the same numbers) and interpolates to its rows. */
static PetscErrorCode LMGCoarseCorrect(PC pc, PC_LatticeMG *mg, Vec r, PetscReal sign, Vec x)
{
  LMGLevel          *C  = &mg->lev[0];
  const PetscInt     Mx = mg->Mx;
  const PetscScalar *w;
  PetscScalar       *xx;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(LMG_Coarse, 0, 0, 0, 0));
  PetscCall(VecGetArrayRead(r, &w));
  PetscCall(PetscArrayzero(C->b, 3 * C->n));
  for (PetscInt k = 0; k < mg->nrows; k++) {
    PetscScalar rk[3] = {w[3 * k], w[3 * k + 1], w[3 * k + 2]};
    if (mg->kind[k] == 2) continue;
    LMGFilter(mg, k, rk);
    LMGRestrictNode(C, mg->Mx, mg->My, mg->node[k] % Mx, mg->node[k] / Mx, rk);
  }
  PetscCall(VecRestoreArrayRead(r, &w));
  if (mg->size > 1) PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, C->b, (PetscMPIInt) (3 * C->n), MPIU_SCALAR, MPIU_SUM, PetscObjectComm((PetscObject) pc)));
  LMGCycle(mg, 0);
  PetscCall(VecGetArray(x, &xx));
  for (PetscInt k = 0; k < mg->nrows; k++) {
    PetscScalar e[3];
    if (mg->kind[k] == 2) continue;
    LMGInterpolateNode(C, mg->Mx, mg->My, mg->node[k] % Mx, mg->node[k] / Mx, e);
    LMGFilter(mg, k, e);
    for (PetscInt s = 0; s < 3; s++) xx[3 * k + s] += sign * e[s];
  }
  PetscCall(VecRestoreArray(x, &xx));
  PetscCall(PetscLogEventEnd(LMG_Coarse, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

/* The hybrid cycle needs a symmetric smoother: refused, with the error code given, with sgs */
static PetscErrorCode LMGCheckHybrid(PC pc, const PC_LatticeMG *mg, PetscErrorCode code)
{
  PetscFunctionBeginUser;
  PetscCheck(!mg->hybrid || mg->smoother == LMG_SMOOTH_BLOCKICC, PetscObjectComm((PetscObject) pc), code,
             "-pc_latticemg_hybrid needs the block IC smoother, a symmetric one: with -pc_latticemg_smoother sgs the V(1,1) cycle is positive definite already (Gauss-Seidel's M + M^T - A is the diagonal)");
  PetscFunctionReturn(0);
}

static PetscErrorCode PCApply_LatticeMG(PC pc, Vec b, Vec x)
{
  PC_LatticeMG *mg = (PC_LatticeMG *) pc->data;

  PetscFunctionBeginUser;
  PetscCall(LMGCheckHybrid(pc, mg, PETSC_ERR_ARG_INCOMP)); /* PCLatticeMGSetHybrid may come after the options */
  if (mg->hybrid) {                                        /* x = M^-1 b + (I - M^-1 A) Q (I - A M^-1) b, Q = P B_c P^T: SPD for any SPD M */
    PetscCall(LMGFineSmooth(pc, mg, PETSC_TRUE, b, x));
    PetscCall(MatMult(pc->pmat, x, mg->w));
    PetscCall(VecAYPX(mg->w, -1.0, b));
    if (!mg->y) PetscCall(VecDuplicate(mg->w, &mg->y));
    PetscCall(VecZeroEntries(mg->y));
    PetscCall(LMGCoarseCorrect(pc, mg, mg->w, 1.0, mg->y)); /* e = Q w */
    PetscCall(VecAXPY(x, 1.0, mg->y));
    PetscCall(MatMult(pc->pmat, mg->y, mg->w)); /* A e */
    PetscCall(LMGFineSmooth(pc, mg, PETSC_FALSE, mg->w, mg->y));
    PetscCall(VecAXPY(x, -1.0, mg->y));
    PetscFunctionReturn(0);
  }
  PetscCall(LMGFineSmooth(pc, mg, PETSC_TRUE, b, x)); /* pre-smoothing from 0 */
  PetscCall(MatMult(pc->pmat, x, mg->w));
  PetscCall(VecAYPX(mg->w, -1.0, b));
  PetscCall(LMGCoarseCorrect(pc, mg, mg->w, 1.0, x));
  PetscCall(MatMult(pc->pmat, x, mg->w)); /* post-smoothing */
  PetscCall(VecAYPX(mg->w, -1.0, b));
  PetscCall(LMGFineSmooth(pc, mg, PETSC_FALSE, mg->w, mg->w));
  PetscCall(VecAXPY(x, 1.0, mg->w));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCSetUp_LatticeMG(PC pc)
{
  PC_LatticeMG *mg = (PC_LatticeMG *) pc->data;
  PetscMPIInt   size;
  PetscBool     sbaij;
  PetscInt      bs;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(PetscObjectComm((PetscObject) pc), &size));
  mg->size = size;
  PetscCheck(mg->node, PetscObjectComm((PetscObject) pc), PETSC_ERR_ARG_WRONGSTATE, "-pc_type latticemg needs the cloth's lattice (PCLatticeMGSetLattice): it is drapebe's preconditioner");
  PetscCall(PetscObjectTypeCompareAny((PetscObject) pc->pmat, &sbaij, MATSEQSBAIJ, MATMPISBAIJ, ""));
  PetscCall(MatGetBlockSize(pc->pmat, &bs));
  PetscCheck(sbaij && bs == 3, PetscObjectComm((PetscObject) pc), PETSC_ERR_SUP, "-pc_type latticemg takes an SBAIJ matrix of block size 3, and this one is %s with block size %" PetscInt_FMT, ((PetscObject) pc->pmat)->type_name, bs);
  if (!mg->lev) PetscCall(LMGCreateLevels(mg));
  if (!mg->w) PetscCall(MatCreateVecs(pc->pmat, &mg->w, NULL));
  PetscCall(PCSetOperators(mg->fine, pc->mat, pc->pmat)); /* drapebe makes a new matrix when self-contact's pairs leave its pattern */
  PetscCall(LMGFineSetUp(mg, pc->pmat));
  if (mg->setups++ % mg->coarse_lag == 0) {
    PetscCall(LMGGalerkinFine(pc, mg, pc->pmat));
    for (PetscInt l = 0; l < mg->nlevels - 1; l++) PetscCall(LMGGalerkinCoarse(mg, l));
    for (PetscInt l = 0; l < mg->nlevels; l++) PetscCall(LMGSetUpSmoother(mg, l));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode PCLatticeMGSetLattice_LatticeMG(PC pc, PetscInt Mx, PetscInt My, PetscInt n, const PetscInt node[], const PetscBool pinned[])
{
  PC_LatticeMG *mg = (PC_LatticeMG *) pc->data;

  PetscFunctionBeginUser;
  PetscCheck(Mx > 0 && My > 0 && n >= 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "a lattice of %" PetscInt_FMT " x %" PetscInt_FMT " nodes and %" PetscInt_FMT " rows", Mx, My, n);
  PetscCall(LMGFreeLevels(mg));
  PetscCall(PetscFree3(mg->node, mg->pinned, mg->kind));
  PetscCall(PetscMalloc3(n, &mg->node, n, &mg->pinned, n, &mg->kind));
  mg->normal = NULL;
  for (PetscInt k = 0; k < n; k++) {
    PetscCheck(node[k] >= 0 && node[k] < Mx * My, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "row %" PetscInt_FMT "'s node %" PetscInt_FMT " is outside the %" PetscInt_FMT " x %" PetscInt_FMT " lattice", k, node[k], Mx, My);
    mg->node[k]   = node[k];
    mg->pinned[k] = pinned ? pinned[k] : PETSC_FALSE;
    mg->kind[k]   = mg->pinned[k] ? 2 : 0;
  }
  mg->Mx = Mx, mg->My = My, mg->nrows = n;
  PetscFunctionReturn(0);
}

static PetscErrorCode PCLatticeMGSetConstraints_LatticeMG(PC pc, const ClothConstraint type[], const PetscReal normal[])
{
  PC_LatticeMG *mg = (PC_LatticeMG *) pc->data;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < mg->nrows; k++) {
    const ClothConstraint t = type ? type[k] : CLOTH_FREE;
    mg->kind[k]             = mg->pinned[k] || t == CLOTH_FIXED ? 2 : t == CLOTH_SLIDE ? 1 : 0;
    PetscCheck(mg->kind[k] != 1 || normal, PETSC_COMM_SELF, PETSC_ERR_ARG_NULL, "row %" PetscInt_FMT " slides and PCLatticeMGSetConstraints was given no normals", k);
  }
  mg->normal = normal;
  PetscFunctionReturn(0);
}

static PetscErrorCode PCLatticeMGSetHybrid_LatticeMG(PC pc, PetscBool hybrid)
{
  PetscFunctionBeginUser;
  ((PC_LatticeMG *) pc->data)->hybrid = hybrid;
  PetscFunctionReturn(0);
}

PetscErrorCode PCLatticeMGSetHybrid(PC pc, PetscBool hybrid)
{
  PetscFunctionBeginUser;
  PetscTryMethod(pc, "PCLatticeMGSetHybrid_C", (PC, PetscBool), (pc, hybrid));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCLatticeMGGetHybrid_LatticeMG(PC pc, PetscBool *hybrid)
{
  PetscFunctionBeginUser;
  *hybrid = ((PC_LatticeMG *) pc->data)->hybrid;
  PetscFunctionReturn(0);
}

PetscErrorCode PCLatticeMGGetHybrid(PC pc, PetscBool *hybrid)
{
  PetscFunctionBeginUser;
  *hybrid = PETSC_FALSE;
  PetscTryMethod(pc, "PCLatticeMGGetHybrid_C", (PC, PetscBool *), (pc, hybrid));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCLatticeMGHybridAllowed_LatticeMG(PC pc, PetscBool *allowed)
{
  PetscFunctionBeginUser;
  *allowed = (PetscBool) (((PC_LatticeMG *) pc->data)->smoother == LMG_SMOOTH_BLOCKICC); /* LMGCheckHybrid */
  PetscFunctionReturn(0);
}

PetscErrorCode PCLatticeMGHybridAllowed(PC pc, PetscBool *allowed)
{
  PetscFunctionBeginUser;
  *allowed = PETSC_FALSE;
  PetscTryMethod(pc, "PCLatticeMGHybridAllowed_C", (PC, PetscBool *), (pc, allowed));
  PetscFunctionReturn(0);
}

PetscErrorCode PCLatticeMGSetLattice(PC pc, PetscInt Mx, PetscInt My, PetscInt n, const PetscInt node[], const PetscBool pinned[])
{
  PetscFunctionBeginUser;
  PetscTryMethod(pc, "PCLatticeMGSetLattice_C", (PC, PetscInt, PetscInt, PetscInt, const PetscInt[], const PetscBool[]), (pc, Mx, My, n, node, pinned));
  PetscFunctionReturn(0);
}

PetscErrorCode PCLatticeMGSetConstraints(PC pc, const ClothConstraint type[], const PetscReal normal[])
{
  PetscFunctionBeginUser;
  PetscTryMethod(pc, "PCLatticeMGSetConstraints_C", (PC, const ClothConstraint[], const PetscReal[]), (pc, type, normal));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCReset_LatticeMG(PC pc)
{
  PC_LatticeMG *mg = (PC_LatticeMG *) pc->data;

  PetscFunctionBeginUser;
  PetscCall(LMGFreeLevels(mg));
  PetscCall(VecDestroy(&mg->w));
  PetscCall(VecDestroy(&mg->y));
  if (mg->fine) PetscCall(PCReset(mg->fine));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCDestroy_LatticeMG(PC pc)
{
  PC_LatticeMG *mg = (PC_LatticeMG *) pc->data;

  PetscFunctionBeginUser;
  PetscCall(PCReset_LatticeMG(pc));
  PetscCall(PCDestroy(&mg->fine));
  PetscCall(PetscFree3(mg->node, mg->pinned, mg->kind));
  PetscCall(PetscFree(mg->dinv));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGSetLattice_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGSetConstraints_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGSetHybrid_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGGetHybrid_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGHybridAllowed_C", NULL));
  PetscCall(PetscFree(pc->data));
  PetscFunctionReturn(0);
}

static PetscErrorCode PCSetFromOptions_LatticeMG(PC pc, PetscOptionItems *PetscOptionsObject)
{
  PC_LatticeMG *mg = (PC_LatticeMG *) pc->data;

  PetscFunctionBeginUser;
  PetscOptionsHeadBegin(PetscOptionsObject, "Geometric multigrid on the cloth's lattice");
  PetscCall(PetscOptionsInt("-pc_latticemg_levels", "The most levels, the finest included (0: down to -pc_latticemg_coarse_nodes)", "PCLATTICEMG", mg->max_levels, &mg->max_levels, NULL));
  PetscCheck(mg->max_levels == 0 || mg->max_levels >= 2, PetscObjectComm((PetscObject) pc), PETSC_ERR_USER_INPUT, "-pc_latticemg_levels %" PetscInt_FMT " is not a multigrid: give 2 or more, or 0 (as many as the lattice has)", mg->max_levels);
  PetscCall(PetscOptionsInt("-pc_latticemg_coarse_nodes", "The coarsest level is factored (dense) when it has at most this many nodes", "PCLATTICEMG", mg->coarse_nodes, &mg->coarse_nodes, NULL));
  PetscCheck(mg->coarse_nodes >= 1 && mg->coarse_nodes <= 1000, PetscObjectComm((PetscObject) pc), PETSC_ERR_USER_INPUT, "-pc_latticemg_coarse_nodes %" PetscInt_FMT " is outside [1, 1000]: the coarsest level is a dense matrix of 3 rows a node",
             mg->coarse_nodes);
  PetscCall(PetscOptionsInt("-pc_latticemg_coarse_lag", "Make the coarse levels' operators again at every this many set-ups (the finest level's smoother at every one)", "PCLATTICEMG", mg->coarse_lag, &mg->coarse_lag, NULL));
  PetscCheck(mg->coarse_lag >= 1, PetscObjectComm((PetscObject) pc), PETSC_ERR_USER_INPUT, "-pc_latticemg_coarse_lag %" PetscInt_FMT " is not a number of set-ups: give 1 or more", mg->coarse_lag);
  PetscCall(PetscOptionsInt("-pc_latticemg_gamma", "Cycles on each coarse level past the first: 1 a V-cycle, 2 a W-cycle", "PCLATTICEMG", mg->gamma, &mg->gamma, NULL));
  PetscCheck(mg->gamma == 1 || mg->gamma == 2, PetscObjectComm((PetscObject) pc), PETSC_ERR_USER_INPUT, "-pc_latticemg_gamma %" PetscInt_FMT " is not a cycle: give 1 (V) or 2 (W)", mg->gamma);
  PetscCall(PetscOptionsBool("-pc_latticemg_hybrid", "The finest level's smoother once, before the coarse correction and its own correction after (positive definite for any positive definite smoother) instead of the V(1,1) cycle", "PCLATTICEMG",
                             mg->hybrid, &mg->hybrid, NULL));
  PetscCall(PetscOptionsEnum("-pc_latticemg_smoother", "The finest level's smoother: sgs (block Gauss-Seidel, forward before the coarse correction and backward after) or blockicc (block IC, options -mg_fine_pc_blockicc_*)", "PCLATTICEMG",
                             LMGSmoothers, (PetscEnum) mg->smoother, (PetscEnum *) &mg->smoother, NULL));
  PetscOptionsHeadEnd();
  PetscCall(LMGCheckHybrid(pc, mg, PETSC_ERR_USER_INPUT));
  PetscCall(PCSetFromOptions(mg->fine));
  {
    const char *prefix;
    PetscBool   given;
    PetscCall(PCGetOptionsPrefix(mg->fine, &prefix));
    PetscCall(PetscOptionsHasName(NULL, prefix, "-pc_blockicc_levels", &given));
    mg->fill_auto = (PetscBool) !given;
  }
  PetscCall(LMGFreeLevels(mg)); /* made again at the next set-up */
  PetscFunctionReturn(0);
}

static PetscErrorCode PCView_LatticeMG(PC pc, PetscViewer viewer)
{
  PC_LatticeMG *mg = (PC_LatticeMG *) pc->data;
  PetscBool     ascii;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) viewer, PETSCVIEWERASCII, &ascii));
  if (ascii) {
    PetscCall(PetscViewerASCIIPrintf(viewer, "  geometric multigrid on the %" PetscInt_FMT " x %" PetscInt_FMT " lattice, %s, %" PetscInt_FMT " levels:", mg->Mx, mg->My,
                                     mg->hybrid ? "hybrid (smoother once, coarse correction, its correction)" : "V(1,1)", mg->nlevels + 1));
    for (PetscInt l = 0; l < mg->nlevels; l++) PetscCall(PetscViewerASCIIPrintf(viewer, " %" PetscInt_FMT " x %" PetscInt_FMT, mg->lev[l].nx, mg->lev[l].ny));
    PetscCall(PetscViewerASCIIPrintf(viewer, " (coarsest: %s)\n", mg->dense ? "dense LDL^T" : "symmetric block Gauss-Seidel"));
    if (mg->smoother == LMG_SMOOTH_SGS)
      PetscCall(PetscViewerASCIIPrintf(viewer, "  finest level's smoother: block Gauss-Seidel, forward before, backward after\n"));
    else {
      PetscCall(PetscViewerASCIIPrintf(viewer, "  finest level's smoother:\n"));
      PetscCall(PetscViewerASCIIPushTab(viewer));
      PetscCall(PCView(mg->fine, viewer));
      PetscCall(PetscViewerASCIIPopTab(viewer));
    }
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode PCCreate_LatticeMG(PC pc)
{
  PC_LatticeMG *mg;
  const char   *prefix;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&mg));
  mg->coarse_nodes = 64;
  mg->coarse_lag   = 4;
  mg->gamma        = 2;
  mg->smoother     = LMG_SMOOTH_BLOCKICC;
  mg->fill_auto    = PETSC_TRUE;
  PetscCall(PCCreate(PetscObjectComm((PetscObject) pc), &mg->fine));
  PetscCall(PetscObjectIncrementTabLevel((PetscObject) mg->fine, (PetscObject) pc, 1));
  PetscCall(PCGetOptionsPrefix(pc, &prefix));
  PetscCall(PCSetOptionsPrefix(mg->fine, prefix));
  PetscCall(PCAppendOptionsPrefix(mg->fine, "mg_fine_"));
  PetscCall(PCBlockICCRegister());
  PetscCall(PCSetType(mg->fine, PCBLOCKICC));
  pc->data                     = mg;
  pc->ops->setup               = PCSetUp_LatticeMG;
  pc->ops->apply               = PCApply_LatticeMG;
  pc->ops->applysymmetricleft  = NULL;
  pc->ops->applysymmetricright = NULL;
  pc->ops->reset               = PCReset_LatticeMG;
  pc->ops->destroy             = PCDestroy_LatticeMG;
  pc->ops->setfromoptions      = PCSetFromOptions_LatticeMG;
  pc->ops->view                = PCView_LatticeMG;
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGSetLattice_C", PCLatticeMGSetLattice_LatticeMG));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGSetConstraints_C", PCLatticeMGSetConstraints_LatticeMG));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGSetHybrid_C", PCLatticeMGSetHybrid_LatticeMG));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGGetHybrid_C", PCLatticeMGGetHybrid_LatticeMG));
  PetscCall(PetscObjectComposeFunction((PetscObject) pc, "PCLatticeMGHybridAllowed_C", PCLatticeMGHybridAllowed_LatticeMG));
  PetscFunctionReturn(0);
}

PetscErrorCode PCLatticeMGRegister(void)
{
  PetscFunctionBeginUser;
  PetscCall(PCRegister(PCLATTICEMG, PCCreate_LatticeMG));
  if (!LMG_Coarse) PetscCall(PetscLogEventRegister("PCLatticeMGCoarse", PC_CLASSID, &LMG_Coarse));
  PetscFunctionReturn(0);
}
