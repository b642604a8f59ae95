/* The factorisation and the triangular solves of PCBLOCKICC (pcblockicc.c), for one
 * storage of the factor: included by pcblockicc.c once per storage type, with
 * BICC_T the type of the stored blocks (float or double) and BICC(name) the name of
 * this instance's function. The arithmetic is PetscScalar's (double) in both: a
 * stored block is read into double, and the row being formed is summed in double
 * (icc->row) and rounded to BICC_T once, when it is complete. */

/* The factorisation; compensate: a dropped fill block E between rows k and j adds,
 * entry by entry, |E_rc| sqrt(a_r / a_c) to row k's diagonal entry r and |E_rc|
 * sqrt(a_c / a_r) to row j's entry c (a: A's diagonal entries), Ajiz and Jennings'
 * compensation (1984): each dropped pair becomes a positive semidefinite 2 x 2
 * added to the Schur complement, which then stays positive definite, so no pivot
 * fails. Without it, *ok says whether every pivot block passed (the factorisation
 * stops at the first that does not). *stored: every inverse pivot block is still
 * positive definite as stored (rounded to BICC_T); when one is not, the
 * factorisation stops there. */
static PetscErrorCode BICC(Numeric)(PC_BlockICC *icc, const MatScalar *aa, PetscBool compensate, PetscBool *ok, PetscBool *stored)
{
  const PetscInt n = icc->n, *ai = icc->fi, *aj = icc->fj, *Ai = icc->ai, *amap = icc->amap; /* ai, aj: the factor's pattern; Ai: A's */
  PetscInt      *pos = icc->pos, *first = icc->first, *next = icc->next;
  BICC_T        *fa  = (BICC_T *) icc->fa;
  PetscScalar   *row = icc->row, *dk = icc->row; /* row k being formed, its diagonal block first */
  PetscReal     *comp  = icc->comp;
  PetscLogDouble flops = 0;

  PetscFunctionBeginUser;
  *ok = *stored = PETSC_TRUE;
  PetscCall(PetscArrayzero(comp, 3 * n));
  for (PetscInt k = 0; k < n; k++) next[k] = n; /* every list empty */
  for (PetscInt k = 0; k < n && *ok && *stored; k++) {
    const PetscInt   rk = ai[k], len = ai[k + 1] - rk;
    const MatScalar *ak = aa + 9 * Ai[k]; /* A's row k, its diagonal block first */
    for (PetscInt p = rk; p < ai[k + 1]; p++) pos[aj[p]] = p - rk;
    if (!amap)
      PetscCall(PetscArraycpy(row, ak, 9 * len));
    else { /* A's blocks into the factor's row, the fill zero */
      PetscCall(PetscArrayzero(row, 9 * len));
      for (PetscInt p = Ai[k]; p < Ai[k + 1]; p++) PetscCall(PetscArraycpy(row + 9 * (amap[p] - rk), aa + 9 * p, 9));
    }
    for (PetscInt r = 0; r < 3; r++) dk[4 * r] += comp[3 * k + r];
    for (PetscInt i = next[k], inext; i < n; i = inext) {
      const BICC_T *di = fa + 9 * ai[i];
      BICC_T       *u  = fa + 9 * first[i];
      PetscScalar   w[9];
      inext = next[i];
      /* w = -D_i^-1 Ubar(i, k) = -U(i, k); D_k -= U(i, k)^T Ubar(i, k) */
      for (PetscInt c = 0; c < 3; c++)
        for (PetscInt r = 0; r < 3; r++) w[r + 3 * c] = -((PetscScalar) di[r] * u[3 * c] + (PetscScalar) di[r + 3] * u[3 * c + 1] + (PetscScalar) di[r + 6] * u[3 * c + 2]);
      for (PetscInt c = 0; c < 3; c++)
        for (PetscInt r = 0; r < 3; r++) dk[r + 3 * c] += w[3 * r] * u[3 * c] + w[3 * r + 1] * u[3 * c + 1] + w[3 * r + 2] * u[3 * c + 2];
      for (PetscInt c = 0; c < 9; c++) u[c] = (BICC_T) w[c];
      /* row k's blocks right of the diagonal: Ubar(k, j) -= U(i, k)^T Ubar(i, j) where (k, j) is in the pattern */
      for (PetscInt p = first[i] + 1; p < ai[i + 1]; p++) {
        const PetscInt j = aj[p], q = pos[j];
        const BICC_T  *v = fa + 9 * p;
        if (q >= 0) {
          PetscScalar *t = row + 9 * q;
          for (PetscInt c = 0; c < 3; c++)
            for (PetscInt r = 0; r < 3; r++) t[r + 3 * c] += w[3 * r] * v[3 * c] + w[3 * r + 1] * v[3 * c + 1] + w[3 * r + 2] * v[3 * c + 2];
        } else if (compensate) { /* fill IC(0) drops, given back to the two diagonals */
          const MatScalar *aj_ = aa + 9 * Ai[j];
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
      for (PetscInt c = 0; c < 9; c++) fa[9 * rk + c] = (BICC_T) dinv[c];
      if (sizeof(BICC_T) < sizeof(PetscScalar)) { /* rounded, the inverse must stay positive definite (a pivot block conditioned near 1/eps of BICC_T may not) */
        MatScalar rounded[9], unused[9];
        for (PetscInt c = 0; c < 9; c++) rounded[c] = fa[9 * rk + c];
        *stored = BlockInvertSPD(rounded, rounded, 0, unused);
      }
    }
    for (PetscInt c = 9; c < 9 * len; c++) fa[9 * rk + c] = (BICC_T) row[c];
    for (PetscInt p = rk; p < ai[k + 1]; p++) pos[aj[p]] = -1;
    BlockICCLink(icc, k, rk + 1);
  }
  if (!*ok || !*stored)
    for (PetscInt k = 0; k < n; k++) pos[k] = -1;
  PetscCall(PetscLogFlops(flops + 30.0 * n));
  PetscFunctionReturn(0);
}

/* y = (U^T D U)^-1 y with the stored blocks V = -U: forward U^T z = y (z_j += V(i,
 * j)^T z_i once z_i is final) and z_i = D_i^-1 z_i in the same pass, backward U x =
 * z (x_k += V(k, j) x_j). The next row's blocks are prefetched into every level of
 * the cache (T0), not past it (NTA, as PETSc's own AIJ products do): CG reads the
 * factor twice an iteration and again at the next, so it should stay where it fits.
 * On the Xeon of BENCHMARKS.md's 2026-12-02 sections NTA made each solve depend on
 * where the factor happened to lie (0.33 to 0.74 ms at 64^2 over the run's
 * allocations, 0.21 with none new) and T0 takes 0.18-0.19; drapebe's runs 5 to 22 %
 * faster, the most where the factor is larger than the L2 (128^2 and up). */
static void BICC(Solve)(const PC_BlockICC *icc, PetscScalar *restrict y)
{
  const PetscInt n = icc->n, *restrict ai = icc->fi, *restrict aj = icc->fj;
  const BICC_T *restrict fa = (const BICC_T *) icc->fa;

  for (PetscInt i = 0; i < n; i++) {
    const PetscScalar y0 = y[3 * i], y1 = y[3 * i + 1], y2 = y[3 * i + 2];
    PetscPrefetchBlock(fa + 9 * ai[i + 1], 9 * (ai[i + 1] - ai[i]), 0, PETSC_PREFETCH_HINT_T0);
    PetscPrefetchBlock(aj + ai[i + 1], ai[i + 1] - ai[i], 0, PETSC_PREFETCH_HINT_T0);
    for (PetscInt p = ai[i] + 1; p < ai[i + 1]; p++) {
      const BICC_T *v = fa + 9 * p;
      PetscScalar  *t = y + 3 * aj[p];
      t[0] += v[0] * y0 + v[1] * y1 + v[2] * y2;
      t[1] += v[3] * y0 + v[4] * y1 + v[5] * y2;
      t[2] += v[6] * y0 + v[7] * y1 + v[8] * y2;
    }
    {
      const BICC_T *d = fa + 9 * ai[i];
      PetscScalar  *t = y + 3 * i;
      t[0]            = d[0] * y0 + d[3] * y1 + d[6] * y2;
      t[1]            = d[1] * y0 + d[4] * y1 + d[7] * y2;
      t[2]            = d[2] * y0 + d[5] * y1 + d[8] * y2;
    }
  }
  for (PetscInt k = n - 1; k >= 0; k--) {
    const BICC_T *d = fa + 9 * ai[k];
    PetscScalar  *t = y + 3 * k, s0, s1, s2;
    /* the rows go down memory, each row up it: a pattern the hardware does not
     * prefetch (without this the pass takes 2.4 times as long), so fetch the next
     * row's blocks and columns, assumed as long as this one */
    PetscPrefetchBlock(d - 9 * (ai[k + 1] - ai[k]), 9 * (ai[k + 1] - ai[k]), 0, PETSC_PREFETCH_HINT_T0);
    PetscPrefetchBlock(aj + ai[k] - (ai[k + 1] - ai[k]), ai[k + 1] - ai[k], 0, PETSC_PREFETCH_HINT_T0);
    s0 = t[0], s1 = t[1], s2 = t[2];
    for (PetscInt p = ai[k] + 1; p < ai[k + 1]; p++) {
      const BICC_T      *v  = fa + 9 * p;
      const PetscScalar *xj = y + 3 * aj[p];
      s0 += v[0] * xj[0] + v[3] * xj[1] + v[6] * xj[2];
      s1 += v[1] * xj[0] + v[4] * xj[1] + v[7] * xj[2];
      s2 += v[2] * xj[0] + v[5] * xj[1] + v[8] * xj[2];
    }
    t[0] = s0, t[1] = s1, t[2] = s2;
  }
}
