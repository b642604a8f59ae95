/* The product of drape's implicit matrix in symmetric storage (include/sbaijmult.h).
 *
 * PETSc's MatMult_SeqSBAIJ_3 adds each block's upper-triangle term into z[3 i]
 * in memory: z may alias x for all the compiler knows, so every block's three sums
 * are stored and loaded again, a chain through the store buffer at each of a row's
 * blocks; and it prefetches the next row past the caches (NTA), which CG, reading
 * the matrix at every iteration, pays for at the next (pcblockicc_kernels.h says
 * what that cost block IC's solves). Here the row's sums stay in registers and
 * the next row goes into the caches; every sum is PETSc's, in PETSc's order (each
 * z[3 i + r] starts from what the rows above scattered into it, then its diagonal
 * block's term, then its blocks' in order), so the product is PETSc's to the bit
 * (tests/unit/test_sbaijmult.c). */
#include <sbaijmult.h>

static PetscErrorCode MatMult_DrapeSBAIJ3(Mat A, Vec xx, Vec zz)
{
  const PetscInt    *ai, *aj;
  const PetscScalar *xa;
  MatScalar         *va;
  PetscScalar       *za;
  PetscInt           mbs, nz, nonzerorow = 0;
  PetscBool          done;

  PetscFunctionBeginUser;
  PetscCall(MatGetRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &mbs, &ai, &aj, &done));
  PetscCheck(done, PetscObjectComm((PetscObject) A), PETSC_ERR_SUP, "drape's SBAIJ product could not read the matrix's block pattern");
  PetscCall(MatSeqSBAIJGetArray(A, &va)); /* (read only; SBAIJ's restore leaves the state as it was) */
  PetscCall(VecGetArrayRead(xx, &xa));
  PetscCall(VecGetArrayWrite(zz, &za));
  PetscCall(PetscArrayzero(za, 3 * mbs));
  {
    const PetscScalar *restrict x = xa; /* (MatMult refuses x == z) */
    PetscScalar *restrict z       = za;
    const MatScalar *v            = va;
    for (PetscInt i = 0; i < mbs; i++) {
      const PetscInt    n = ai[i + 1] - ai[i], *ib = aj + ai[i];
      const PetscScalar x1 = x[3 * i], x2 = x[3 * i + 1], x3 = x[3 * i + 2];
      PetscScalar       z1 = z[3 * i], z2 = z[3 * i + 1], z3 = z[3 * i + 2];
      PetscInt          jmin = 0;
      nonzerorow += (n > 0);
      if (n > 0 && ib[0] == i) { /* the diagonal block, by its upper triangle */
        z1 += v[0] * x1 + v[3] * x2 + v[6] * x3;
        z2 += v[3] * x1 + v[4] * x2 + v[7] * x3;
        z3 += v[6] * x1 + v[7] * x2 + v[8] * x3;
        v += 9;
        jmin = 1;
      }
      PetscPrefetchBlock(ib + n, n, 0, PETSC_PREFETCH_HINT_T0);                 /* the next row's columns, */
      PetscPrefetchBlock(v + 9 * (n - jmin), 9 * n, 0, PETSC_PREFETCH_HINT_T0); /* and blocks, assumed as many */
      for (PetscInt j = jmin; j < n; j++, v += 9) {
        const PetscInt c = 3 * ib[j];
        z[c] += v[0] * x1 + v[1] * x2 + v[2] * x3; /* the lower triangle's block (j, i) */
        z[c + 1] += v[3] * x1 + v[4] * x2 + v[5] * x3;
        z[c + 2] += v[6] * x1 + v[7] * x2 + v[8] * x3;
        z1 += v[0] * x[c] + v[3] * x[c + 1] + v[6] * x[c + 2]; /* the upper's (i, j) */
        z2 += v[1] * x[c] + v[4] * x[c + 1] + v[7] * x[c + 2];
        z3 += v[2] * x[c] + v[5] * x[c + 1] + v[8] * x[c + 2];
      }
      z[3 * i] = z1, z[3 * i + 1] = z2, z[3 * i + 2] = z3;
    }
  }
  PetscCall(VecRestoreArrayWrite(zz, &za));
  PetscCall(VecRestoreArrayRead(xx, &xa));
  PetscCall(MatSeqSBAIJRestoreArray(A, &va));
  nz = ai[mbs];
  PetscCall(MatRestoreRowIJ(A, 0, PETSC_FALSE, PETSC_TRUE, &mbs, &ai, &aj, &done));
  PetscCall(PetscLogFlops(18.0 * (2.0 * nz - nonzerorow) - nonzerorow)); /* (PETSc's count) */
  PetscFunctionReturn(0);
}

/* The matrix whose product is drape's or PETSc's: J, or its diagonal block (MPISBAIJ),
 * NULL when J is neither SeqSBAIJ nor MPISBAIJ of block size 3 */
static PetscErrorCode ProductMatrix(Mat J, Mat *A)
{
  PetscBool mpi, seq;
  PetscInt  bs;

  PetscFunctionBeginUser;
  *A = J;
  PetscCall(PetscObjectTypeCompare((PetscObject) J, MATMPISBAIJ, &mpi));
  if (mpi) PetscCall(MatGetDiagonalBlock(J, A)); /* MatMult_MPISBAIJ takes its diagonal block's product */
  PetscCall(PetscObjectTypeCompare((PetscObject) *A, MATSEQSBAIJ, &seq));
  PetscCall(MatGetBlockSize(*A, &bs));
  if (!seq || bs != 3) *A = NULL;
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeMatUseSBAIJProduct(Mat J)
{
  Mat A;

  PetscFunctionBeginUser;
  PetscCall(ProductMatrix(J, &A));
  if (A) PetscCall(MatSetOperation(A, MATOP_MULT, (void (*)(void)) MatMult_DrapeSBAIJ3));
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeMatHasSBAIJProduct(Mat J, PetscBool *has)
{
  Mat A;
  void (*mult)(void) = NULL;

  PetscFunctionBeginUser;
  PetscCall(ProductMatrix(J, &A));
  if (A) PetscCall(MatGetOperation(A, MATOP_MULT, &mult));
  *has = (PetscBool) (mult == (void (*)(void)) MatMult_DrapeSBAIJ3);
  PetscFunctionReturn(0);
}
