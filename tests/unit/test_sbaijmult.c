static const char help[] = "Unit test of drape's SBAIJ product (src/integrate/sbaijmult.c): on SeqSBAIJ\n"
                           "matrices of block size 3 (a lattice's pattern with far blocks, empty rows, a row\n"
                           "without its diagonal block, and on many ranks MPISBAIJ), the product equals\n"
                           "PETSc's to the bit; any other matrix keeps PETSc's product.\n"
                           "Options: -seed <int>\n\n";

#include <petscmat.h>
#include <sbaijmult.h>

static PetscInt npassed = 0;

/* A symmetric matrix of block size 3 (SBAIJ, or AIJ for the untouched case) on a
 * lattice of nx x ny blocks: random blocks on the diagonal (but row `nodiag`'s, left
 * out) and between each block and its 8 neighbours, and `far` random pairs of
 * blocks anywhere (contact pairs); block rows in `empty` hold nothing at all. */
static PetscErrorCode BuildMatrix(MPI_Comm comm, MatType type, PetscInt nx, PetscInt ny, PetscInt far, PetscInt nodiag, PetscInt empty, PetscRandom rnd, Mat *A)
{
  const PetscInt n = nx * ny;
  PetscInt       rstart, rend;

  PetscFunctionBeginUser;
  PetscCall(MatCreate(comm, A));
  PetscCall(MatSetSizes(*A, PETSC_DECIDE, PETSC_DECIDE, 3 * n, 3 * n));
  PetscCall(MatSetBlockSize(*A, 3));
  PetscCall(MatSetType(*A, type));
  PetscCall(MatSeqSBAIJSetPreallocation(*A, 3, 10 + far, NULL));
  PetscCall(MatMPISBAIJSetPreallocation(*A, 3, 10 + far, NULL, 10 + far, NULL));
  PetscCall(MatSeqAIJSetPreallocation(*A, 3 * (20 + 2 * far), NULL));
  PetscCall(MatMPIAIJSetPreallocation(*A, 3 * (20 + 2 * far), NULL, 3 * (20 + 2 * far), NULL));
  PetscCall(MatSetOption(*A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE));
  {
    PetscBool sbaij;
    PetscCall(PetscObjectTypeCompareAny((PetscObject) *A, &sbaij, MATSEQSBAIJ, MATMPISBAIJ, ""));
    if (sbaij) PetscCall(MatSetOption(*A, MAT_IGNORE_LOWER_TRIANGULAR, PETSC_TRUE));
  }
  PetscCall(MatGetOwnershipRange(*A, &rstart, &rend));
  for (PetscInt p = 0; p < n; p++) { /* every rank draws the same numbers; each sets its own rows */
    const PetscInt i = p % nx, j = p / nx;
    for (PetscInt dj = 0; dj <= 1; dj++)
      for (PetscInt di = -1; di <= 1; di++) {
        const PetscInt ii = i + di, jj = j + dj, q = ii + nx * jj;
        PetscScalar    B[9], Bt[9];
        if (ii < 0 || ii >= nx || jj >= ny || q < p) continue;
        for (PetscInt r = 0; r < 9; r++) PetscCall(PetscRandomGetValueReal(rnd, &B[r]));
        if (q == p)
          for (PetscInt r = 0; r < 3; r++)
            for (PetscInt c = 0; c < r; c++) B[r + 3 * c] = B[c + 3 * r];
        for (PetscInt r = 0; r < 3; r++)
          for (PetscInt c = 0; c < 3; c++) Bt[r + 3 * c] = B[c + 3 * r];
        if (p == empty || q == empty || (q == p && p == nodiag)) continue;
        if (3 * p >= rstart && 3 * p < rend) PetscCall(MatSetValuesBlocked(*A, 1, &p, 1, &q, B, INSERT_VALUES));
        if (q != p && 3 * q >= rstart && 3 * q < rend) PetscCall(MatSetValuesBlocked(*A, 1, &q, 1, &p, Bt, INSERT_VALUES));
      }
  }
  for (PetscInt k = 0; k < far; k++) {
    PetscReal   u, w;
    PetscInt    p, q;
    PetscScalar B[9], Bt[9];
    PetscCall(PetscRandomGetValueReal(rnd, &u));
    PetscCall(PetscRandomGetValueReal(rnd, &w));
    for (PetscInt r = 0; r < 9; r++) PetscCall(PetscRandomGetValueReal(rnd, &B[r]));
    p = PetscMin((PetscInt) (u * n), n - 1), q = PetscMin((PetscInt) (w * n), n - 1);
    if (p == q || p == empty || q == empty) continue;
    for (PetscInt r = 0; r < 3; r++)
      for (PetscInt c = 0; c < 3; c++) Bt[r + 3 * c] = B[c + 3 * r];
    if (3 * p >= rstart && 3 * p < rend) PetscCall(MatSetValuesBlocked(*A, 1, &p, 1, &q, B, INSERT_VALUES));
    if (3 * q >= rstart && 3 * q < rend) PetscCall(MatSetValuesBlocked(*A, 1, &q, 1, &p, Bt, INSERT_VALUES));
  }
  PetscCall(MatAssemblyBegin(*A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*A, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

/* A x with PETSc's product and then with drape's, on a random x: equal to the bit
 * (SBAIJ), and for other types the product must be left as it was. */
static PetscErrorCode CheckProduct(const char *name, MatType type, PetscInt nx, PetscInt ny, PetscInt far, PetscInt nodiag, PetscInt empty, PetscRandom rnd)
{
  Mat       A;
  Vec       x, y0, y1;
  PetscBool same, sbaij;
  PetscReal norm;
  MPI_Comm  comm = PETSC_COMM_WORLD;
  void (*before)(void), (*after)(void);
  Mat D;

  PetscFunctionBeginUser;
  PetscCall(BuildMatrix(comm, type, nx, ny, far, nodiag, empty, rnd, &A));
  PetscCall(MatCreateVecs(A, &x, &y0));
  PetscCall(VecDuplicate(y0, &y1));
  { /* x_k = sin(k), k its global index: the same on any number of ranks */
    PetscInt     lo, hi;
    PetscScalar *xa;
    PetscCall(VecGetOwnershipRange(x, &lo, &hi));
    PetscCall(VecGetArrayWrite(x, &xa));
    for (PetscInt k = lo; k < hi; k++) xa[k - lo] = PetscSinReal((PetscReal) k);
    PetscCall(VecRestoreArrayWrite(x, &xa));
  }
  PetscCall(MatMult(A, x, y0));
  PetscCall(PetscObjectTypeCompareAny((PetscObject) A, &sbaij, MATSEQSBAIJ, MATMPISBAIJ, ""));
  D = A;
  if (sbaij) {
    PetscBool mpi;
    PetscCall(PetscObjectTypeCompare((PetscObject) A, MATMPISBAIJ, &mpi));
    if (mpi) PetscCall(MatGetDiagonalBlock(A, &D));
  }
  PetscCall(MatGetOperation(D, MATOP_MULT, &before));
  PetscCall(DrapeMatUseSBAIJProduct(A));
  PetscCall(MatGetOperation(D, MATOP_MULT, &after));
  PetscCheck(sbaij == (PetscBool) (before != after), comm, PETSC_ERR_PLIB, "%s: the product was %s", name, sbaij ? "not replaced" : "replaced");
  PetscCall(VecSet(y1, 1e30)); /* (the product must overwrite every entry) */
  PetscCall(MatMult(A, x, y1));
  PetscCall(VecEqual(y0, y1, &same));
  PetscCall(VecNorm(y0, NORM_2, &norm));
  PetscCheck(same, comm, PETSC_ERR_PLIB, "%s: drape's product differs from PETSc's", name);
  PetscCheck(norm > 0, comm, PETSC_ERR_PLIB, "%s: an empty test (A x = 0)", name);
  PetscCall(PetscPrintf(comm, "%s: %s (|A x| = %g)\n", name, sbaij ? "the same bits as PETSc's" : "PETSc's product kept", (double) norm));
  npassed++;
  PetscCall(VecDestroy(&x));
  PetscCall(VecDestroy(&y0));
  PetscCall(VecDestroy(&y1));
  PetscCall(MatDestroy(&A));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscRandom rnd;
  PetscInt    seed = 7;
  PetscMPIInt size;

  PetscCall(PetscInitialize(&argc, &argv, NULL, help));
  PetscCallMPI(MPI_Comm_size(PETSC_COMM_WORLD, &size));
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-seed", &seed, NULL));
  PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd)); /* the same numbers on every rank */
  PetscCall(PetscRandomSetSeed(rnd, (unsigned long) seed));
  PetscCall(PetscRandomSeed(rnd));
  PetscCall(CheckProduct("a 12 x 9 lattice", MATSBAIJ, 12, 9, 0, -1, -1, rnd));
  PetscCall(CheckProduct("a 40 x 31 lattice with 300 far pairs", MATSBAIJ, 40, 31, 300, -1, -1, rnd));
  PetscCall(CheckProduct("a row without its diagonal block, an empty row", MATSBAIJ, 10, 10, 20, 17, 55, rnd));
  PetscCall(CheckProduct("AIJ (left alone)", MATAIJ, 8, 8, 10, -1, -1, rnd));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "on %d rank(s)\n%" PetscInt_FMT " passed, 0 failed\n", size, npassed));
  PetscCall(PetscRandomDestroy(&rnd));
  PetscCall(PetscFinalize());
  return 0;
}
