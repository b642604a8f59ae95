static const char help[] = "The implicit matrix J = a M + b H of ClothAssembleMatrix (drape's row buffer:\n"
                           "element blocks formed alone, tiles, every matrix type and hand-off) against the\n"
                           "reference that adds each element's whole matrix (ClothAssembleMatrixElementwise),\n"
                           "at distorted positions (compressed edges, indefinite angle Hessians), without and\n"
                           "with contact constraints (sliding and fixed particles).\n";

#include <cloth.h>
#include <drape.h>
#include <cloth/clothimpl.h>

/* max |J - R| and max |R| over all entries (J converted to AIJ: SBAIJ's lower half
 * from its upper) */
static PetscErrorCode Compare(Mat J, Mat R, PetscReal *diff, PetscReal *scale)
{
  Mat       A;
  PetscInt  r0, r1;
  PetscReal d = 0, s = 0;

  PetscFunctionBeginUser;
  PetscCall(MatConvert(J, MATAIJ, MAT_INITIAL_MATRIX, &A));
  PetscCall(MatGetOwnershipRange(R, &r0, &r1));
  for (PetscInt r = r0; r < r1; r++) {
    const PetscInt    *ca, *cr;
    const PetscScalar *va, *vr;
    PetscInt           na, nr, i = 0, j = 0;
    PetscCall(MatGetRow(A, r, &na, &ca, &va));
    PetscCall(MatGetRow(R, r, &nr, &cr, &vr));
    while (i < na || j < nr) { /* merge the two sorted rows; an entry missing from one is 0 there */
      PetscReal x = 0, y = 0;
      if (j >= nr || (i < na && ca[i] < cr[j]))
        x = PetscRealPart(va[i++]);
      else if (i >= na || cr[j] < ca[i])
        y = PetscRealPart(vr[j++]);
      else
        x = PetscRealPart(va[i++]), y = PetscRealPart(vr[j++]);
      d = PetscMax(d, PetscAbsReal(x - y));
      s = PetscMax(s, PetscAbsReal(y));
    }
    PetscCall(MatRestoreRow(A, r, &na, &ca, &va));
    PetscCall(MatRestoreRow(R, r, &nr, &cr, &vr));
  }
  PetscCall(MatDestroy(&A));
  PetscCall(MPIU_Allreduce(&d, diff, 1, MPIU_REAL, MPIU_MAX, PetscObjectComm((PetscObject) R)));
  PetscCall(MPIU_Allreduce(&s, scale, 1, MPIU_REAL, MPIU_MAX, PetscObjectComm((PetscObject) R)));
  PetscFunctionReturn(0);
}

/* R = the reference (ClothAssembleMatrixElementwise) of J = a M + b H(x), in AIJ */
static PetscErrorCode Reference(Cloth cloth, const PetscScalar *x, PetscReal a, PetscReal b, PetscInt n, Mat *R)
{
  PetscFunctionBeginUser;
  PetscCall(MatCreateAIJ(cloth->comm, n, n, PETSC_DETERMINE, PETSC_DETERMINE, 81, NULL, 81, NULL, R));
  PetscCall(MatSetBlockSize(*R, 3));
  PetscCall(MatSetOption(*R, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE));
  PetscCall(ClothAssembleMatrixElementwise(cloth, x, a, b, *R));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  const char *const types[][2] = {{MATAIJ, "csr"}, {MATAIJ, "coo"}, {MATAIJ, "rows"}, {MATBAIJ, "rows"}, {MATSBAIJ, "rows"}, {MATSBAIJ, "coo"}};
  MPI_Comm          comm;
  Cloth             cloth;
  ClothInfo         info;
  PetscRandom       rnd;
  PetscScalar      *x, *v;
  PetscReal        *normal, *hdiag;
  ClothConstraint  *type;
  const PetscReal   a = 1.3, b = 2.7e-4;
  PetscInt          n, passed  = 0;

  PetscCall(PetscInitialize(&argc, &argv, NULL, help));
  comm = PETSC_COMM_WORLD;
  PetscCall(DrapeInitialize());
  PetscCall(ClothCreate(comm, &cloth));
  PetscCall(ClothSetFromOptions(cloth));
  PetscCall(ClothSetUp(cloth));
  PetscCall(ClothSetUpImplicit(cloth));
  PetscCall(ClothGetInfo(cloth, &info));
  n = 3 * info.nowned;
  PetscCall(PetscMalloc5(n + 1, &x, n + 1, &v, n + 1, &normal, 9 * info.nowned + 1, &hdiag, info.nowned + 1, &type));
  PetscCall(PetscRandomCreate(comm, &rnd));
  PetscCall(PetscRandomSetSeed(rnd, 11));
  PetscCall(PetscRandomSeed(rnd));
  PetscCall(ClothSetInitialState(cloth, x, v));
  /* distorted: every particle moved by up to 0.3 spacings in each direction, so that
   * edges are compressed and stretched and angle Hessians indefinite */
  for (PetscInt i = 0; i < n; i++) {
    PetscReal r;
    PetscCall(PetscRandomGetValueReal(rnd, &r));
    x[i] += 0.6 * (r - 0.5) * info.spacing[0];
  }
  for (PetscInt k = 0; k < info.nowned; k++) { /* every third particle sliding, every seventh fixed */
    PetscReal nn[3], l;
    for (PetscInt d = 0; d < 3; d++) PetscCall(PetscRandomGetValueReal(rnd, &nn[d]));
    nn[2] += 1;
    l = PetscSqrtReal(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
    for (PetscInt d = 0; d < 3; d++) normal[3 * k + d] = nn[d] / l;
    type[k] = k % 7 == 3 ? CLOTH_FIXED : (k % 3 == 1 ? CLOTH_SLIDE : CLOTH_FREE);
  }
  for (PetscInt constrained = 0; constrained < 2; constrained++) {
    PetscCall(ClothSetConstraints(cloth, constrained ? type : NULL, normal, NULL));
    for (size_t t = 0; t < sizeof(types) / sizeof(types[0]); t++) {
      Mat              J, R;
      PetscReal        diff, scale, hd = 0, hdmax;
      const PetscReal *hd1;
      PetscBool        sym;
      PetscCall(PetscStrcmp(types[t][0], MATSBAIJ, &sym));
      PetscCall(PetscOptionsSetValue(NULL, "-drape_mat_assembly", types[t][1]));
      PetscCall(ClothCreateMatrix(cloth, types[t][0], &J));
      PetscCall(ClothAssembleMatrix(cloth, x, a, b, J));
      PetscCall(ClothGetHessianDiagonal(cloth, &hd1));
      PetscCall(PetscArraycpy(hdiag, hd1, 9 * info.nowned));
      PetscCall(Reference(cloth, x, a, b, n, &R));
      PetscCall(ClothGetHessianDiagonal(cloth, &hd1));
      for (PetscInt i = 0; i < 9 * info.nowned; i++) hd = PetscMax(hd, PetscAbsReal(hdiag[i] - hd1[i]));
      PetscCall(MPIU_Allreduce(&hd, &hdmax, 1, MPIU_REAL, MPIU_MAX, comm));
      PetscCall(Compare(J, R, &diff, &scale));
      /* the same sums in the same order: equal to the bit; SBAIJ's lower half is the
       * transpose of its upper, the reference's is computed (equal to round-off) */
      PetscCheck(scale > 0 && (sym ? diff <= 1e-13 * scale : diff == 0) && hdmax == 0, comm, PETSC_ERR_PLIB, "%s (%s)%s: max |J - reference| = %g of max |reference| %g, hdiag differs by %g", types[t][0], types[t][1],
                 constrained ? " with constraints" : "", (double) diff, (double) scale, (double) hdmax);
      passed++;
      PetscCall(MatDestroy(&R));
      PetscCall(MatDestroy(&J));
    }
  }
  /* extra blocks (self-contact's pairs) that leave the pattern: a new matrix that
   * holds them, grown from the last one's buffer while the union of the blocks is
   * kept (RowBufferGrow: set 1 keeps every other pair of set 0 and adds 600 draws),
   * made anew once the union is reset (set 2: 20 new pairs against about 2400 held
   * blocks); bitwise (AIJ, BAIJ) or to round-off (SBAIJ) the reference's */
  PetscCall(ClothSetConstraints(cloth, NULL, normal, NULL));
  for (size_t t = 0; t < sizeof(types) / sizeof(types[0]); t++) {
    Mat        J = NULL;
    PetscBool  sym;
    PetscInt  *rows, *cols, ne = 0;
    PetscReal *vals;
    PetscCall(PetscStrcmp(types[t][0], MATSBAIJ, &sym));
    PetscCall(PetscOptionsSetValue(NULL, "-drape_mat_assembly", types[t][1]));
    PetscCall(PetscMalloc3(4800, &rows, 4800, &cols, 9 * 4800, &vals));
    for (PetscInt set = 0; set < 3; set++) {
      PetscReal diff, scale;
      PetscBool fits;
      Mat       R;
      if (set == 1) { /* every other pair of set 0 */
        PetscInt m = 0;
        for (PetscInt e = 0; e < ne; e += 4, m += 2) {
          for (PetscInt f = 0; f < 2; f++) rows[m + f] = rows[e + f], cols[m + f] = cols[e + f];
          PetscCall(PetscArraycpy(vals + 9 * m, vals + 9 * e, 18));
        }
        ne = m;
      } else
        ne = 0;
      PetscCall(PetscRandomSetSeed(rnd, 100 * set + t));
      PetscCall(PetscRandomSeed(rnd));
      for (PetscInt q = 0; q < (set == 2 ? 20 : 600); q++) { /* a pair of free owned particles (a, b): blocks (a, b) and (b, a) = (a, b)^T */
        PetscInt  pa, pb;
        PetscReal r;
        PetscCall(PetscRandomGetValueReal(rnd, &r));
        pa = (PetscInt) (r * info.nowned) % info.nowned;
        PetscCall(PetscRandomGetValueReal(rnd, &r));
        pb = (PetscInt) (r * info.nowned) % info.nowned;
        if (pa == pb || cloth->row_map[pa] < 0 || cloth->row_map[pb] < 0) continue;
        rows[ne] = pa, cols[ne] = cloth->global[pb], rows[ne + 1] = pb, cols[ne + 1] = cloth->global[pa];
        for (PetscInt i = 0; i < 9; i++) {
          PetscCall(PetscRandomGetValueReal(rnd, &r));
          vals[9 * ne + i] = r - 0.5;
        }
        for (PetscInt i = 0; i < 3; i++)
          for (PetscInt j = 0; j < 3; j++) vals[9 * (ne + 1) + 3 * i + j] = vals[9 * ne + 3 * j + i];
        ne += 2;
      }
      PetscCall(ClothSetExtraBlocks(cloth, ne, rows, cols, vals, &fits));
      PetscCheck(!fits, PETSC_COMM_SELF, PETSC_ERR_PLIB, "set %" PetscInt_FMT ": %" PetscInt_FMT " extra blocks, new ones among them, reported within the last pattern", set, ne);
      PetscCall(MatDestroy(&J));
      PetscCall(ClothCreateMatrix(cloth, types[t][0], &J));
      PetscCall(ClothAssembleMatrix(cloth, x, a, b, J));
      PetscCall(Reference(cloth, x, a, b, n, &R));
      PetscCall(Compare(J, R, &diff, &scale));
      PetscCheck(scale > 0 && (sym ? diff <= 1e-13 * scale : diff == 0), comm, PETSC_ERR_PLIB, "%s (%s), extra blocks set %" PetscInt_FMT ": max |J - reference| = %g of max |reference| %g", types[t][0], types[t][1], set, (double) diff,
                 (double) scale);
      passed++;
      PetscCall(MatDestroy(&R));
    }
    PetscCall(MatDestroy(&J));
    PetscCall(ClothSetExtraBlocks(cloth, 0, NULL, NULL, NULL, NULL));
    PetscCall(PetscFree3(rows, cols, vals));
  }
  PetscCall(PetscOptionsClearValue(NULL, "-drape_mat_assembly"));
  PetscCall(PetscPrintf(comm, "%" PetscInt_FMT " passed, 0 failed\n", passed));
  PetscCall(PetscRandomDestroy(&rnd));
  PetscCall(PetscFree5(x, v, normal, hdiag, type));
  PetscCall(ClothDestroy(&cloth));
  PetscCall(DrapeFinalize());
  PetscCall(PetscFinalize());
  return 0;
}
