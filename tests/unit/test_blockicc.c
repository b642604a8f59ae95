static const char help[] = "Unit tests of the block IC(0) preconditioner (src/integrate/pcblockicc.c):\n"
                           "exact on a block chain (no fill), PETSc's ICC(0) where that is positive definite,\n"
                           "symmetric and positive definite where pivot blocks are replaced; its factor\n"
                           "stored in single precision within float's rounding of the double one, and in\n"
                           "double where a rounded pivot block would not be positive definite; with\n"
                           "level-1 fill, exact on a ladder where IC(0) is not.\n"
                           "Options: -seed <int>\n\n";

#include <petscksp.h>
#include <pcblockicc.h>

static PetscInt npassed = 0;

/* An SPD SBAIJ matrix of block size 3 on an nx x ny grid of blocks: a mass m on each
 * diagonal block plus, for each link of the stencil (the 8 neighbours when
 * diagonals, else the 4), a spring k (u u^T) between its two blocks, u a random unit
 * vector: the shape of drape's backward-Euler matrix. */
static PetscErrorCode BuildMatrix(PetscInt nx, PetscInt ny, PetscBool diagonals, PetscReal m, PetscReal k, PetscRandom rnd, Mat *A)
{
  const PetscInt n = nx * ny;

  PetscFunctionBeginUser;
  PetscCall(MatCreateSeqSBAIJ(PETSC_COMM_SELF, 3, 3 * n, 3 * n, 5, NULL, A));
  PetscCall(MatSetOption(*A, MAT_IGNORE_LOWER_TRIANGULAR, PETSC_TRUE));
  for (PetscInt b = 0; b < n; b++) {
    PetscScalar d[9] = {m, 0, 0, 0, m, 0, 0, 0, m};
    PetscCall(MatSetValuesBlocked(*A, 1, &b, 1, &b, d, ADD_VALUES));
  }
  for (PetscInt j = 0; j < ny; j++) {
    for (PetscInt i = 0; i < nx; i++) {
      const PetscInt off[4][2] = {{1, 0}, {0, 1}, {1, 1}, {-1, 1}};
      for (PetscInt l = 0; l < (diagonals ? 4 : 2); l++) {
        const PetscInt ii = i + off[l][0], jj = j + off[l][1];
        PetscInt       p = i + nx * j, q = ii + nx * jj, pq[2];
        PetscReal      u[3], s           = 0;
        PetscScalar    K[9], Kn[9];
        if (ii < 0 || ii >= nx || jj >= ny) continue;
        for (PetscInt r = 0; r < 3; r++) {
          PetscCall(PetscRandomGetValueReal(rnd, &u[r]));
          u[r] -= 0.5;
          s += u[r] * u[r];
        }
        for (PetscInt r = 0; r < 3; r++) u[r] /= PetscSqrtReal(s);
        for (PetscInt r = 0; r < 3; r++)
          for (PetscInt c = 0; c < 3; c++) {
            K[r + 3 * c]  = k * u[r] * u[c];
            Kn[r + 3 * c] = -K[r + 3 * c];
          }
        pq[0] = PetscMin(p, q), pq[1] = PetscMax(p, q);
        PetscCall(MatSetValuesBlocked(*A, 1, &pq[0], 1, &pq[0], K, ADD_VALUES));
        PetscCall(MatSetValuesBlocked(*A, 1, &pq[1], 1, &pq[1], K, ADD_VALUES));
        PetscCall(MatSetValuesBlocked(*A, 1, &pq[0], 1, &pq[1], Kn, ADD_VALUES));
      }
    }
  }
  PetscCall(MatAssemblyBegin(*A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*A, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

/* Mass m on each block and bending along the grid lines in z: for each triple (a,
 * b, c) of consecutive blocks along the grid's lines and diagonals, kappa d d^T in the z entries, d = (1, -2, 1): the
 * out-of-plane part of drape's matrix, a fourth difference that is no M-matrix,
 * where IC(0) fails when kappa / m is large. */
static PetscErrorCode BuildBendMatrix(PetscInt nx, PetscInt ny, PetscReal m, PetscReal kappa, Mat *A)
{
  const PetscInt n = nx * ny;

  PetscFunctionBeginUser;
  PetscCall(MatCreateSeqSBAIJ(PETSC_COMM_SELF, 3, 3 * n, 3 * n, 13, NULL, A));
  PetscCall(MatSetOption(*A, MAT_IGNORE_LOWER_TRIANGULAR, PETSC_TRUE));
  for (PetscInt b = 0; b < n; b++) {
    PetscScalar d[9] = {m, 0, 0, 0, m, 0, 0, 0, m};
    PetscCall(MatSetValuesBlocked(*A, 1, &b, 1, &b, d, ADD_VALUES));
  }
  for (PetscInt dir = 0; dir < 4; dir++)
    for (PetscInt j = 0; j < ny; j++)
      for (PetscInt i = 0; i < nx; i++) {
        const PetscInt  di = dir == 1 ? 0 : (dir == 3 ? -1 : 1), dj = dir == 0 ? 0 : 1, t[3] = {i + nx * j, (i + di) + nx * (j + dj), (i + 2 * di) + nx * (j + 2 * dj)};
        const PetscReal d[3] = {1, -2, 1};
        if (i + 2 * di < 0 || i + 2 * di >= nx || j + 2 * dj >= ny) continue;
        for (PetscInt a = 0; a < 3; a++)
          for (PetscInt b = a; b < 3; b++) {
            PetscScalar K[9] = {0};
            K[8]             = kappa * d[a] * d[b];
            PetscCall(MatSetValuesBlocked(*A, 1, &t[a], 1, &t[b], K, ADD_VALUES));
          }
      }
  PetscCall(MatAssemblyBegin(*A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*A, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

/* precision: the factor's storage for PCBLOCKICC ("single" or "double"), or NULL
 * (the default); levels: its fill ("0" or "1"), or NULL */
static PetscErrorCode MakePCLevels(Mat A, PCType type, const char *precision, const char *levels, PC *pc)
{
  PetscFunctionBeginUser;
  PetscCall(PCCreate(PETSC_COMM_SELF, pc));
  PetscCall(PCSetType(*pc, type));
  PetscCall(PCSetOperators(*pc, A, A));
  if (precision || levels) {
    PetscCall(PCSetOptionsPrefix(*pc, "t_"));
    if (precision) PetscCall(PetscOptionsSetValue(NULL, "-t_pc_blockicc_precision", precision));
    if (levels) PetscCall(PetscOptionsSetValue(NULL, "-t_pc_blockicc_levels", levels));
    PetscCall(PCSetFromOptions(*pc));
    PetscCall(PetscOptionsClearValue(NULL, "-t_pc_blockicc_precision"));
    PetscCall(PetscOptionsClearValue(NULL, "-t_pc_blockicc_levels"));
  }
  PetscCall(PCSetUp(*pc));
  PetscFunctionReturn(0);
}

static PetscErrorCode MakePC(Mat A, PCType type, const char *precision, PC *pc)
{
  PetscFunctionBeginUser;
  PetscCall(MakePCLevels(A, type, precision, NULL, pc));
  PetscFunctionReturn(0);
}

/* |M^-1 b - y| / |y| for the PC's M */
static PetscErrorCode ApplyError(PC pc, Vec b, Vec y, PetscReal *err)
{
  Vec       z;
  PetscReal ny;

  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(y, &z));
  PetscCall(PCApply(pc, b, z));
  PetscCall(VecAXPY(z, -1, y));
  PetscCall(VecNorm(z, NORM_2, err));
  PetscCall(VecNorm(y, NORM_2, &ny));
  *err /= ny;
  PetscCall(VecDestroy(&z));
  PetscFunctionReturn(0);
}

/* On a chain of blocks (block tridiagonal) IC(0) drops nothing: it is the exact
 * factorisation, and M^-1 A x = x, to round-off in double storage and to float's
 * rounding in single (and not to double's: the single storage is float). */
static PetscErrorCode TestChainIsExact(PetscRandom rnd)
{
  Mat       A;
  PC        dbl, sgl;
  Vec       x, b;
  PetscReal err, err_single;
  PetscBool compensated;

  PetscFunctionBeginUser;
  PetscCall(BuildMatrix(40, 1, PETSC_FALSE, 1.0, 10.0, rnd, &A));
  PetscCall(MakePC(A, PCBLOCKICC, "double", &dbl));
  PetscCall(MakePC(A, PCBLOCKICC, "single", &sgl));
  PetscCall(MatCreateVecs(A, &x, &b));
  PetscCall(VecSetRandom(x, rnd));
  PetscCall(MatMult(A, x, b));
  PetscCall(ApplyError(dbl, b, x, &err));
  PetscCall(ApplyError(sgl, b, x, &err_single));
  PetscCall(PCBlockICCGetCompensated(dbl, &compensated));
  PetscCheck(err <= 1e-10 && !compensated, PETSC_COMM_SELF, PETSC_ERR_PLIB, "block IC(0) of a block chain is not exact: |M^-1 A x - x| / |x| = %g, compensated %d", (double) err, (int) compensated);
  PetscCheck(err_single <= 1e-5 && err_single > 1e-12, PETSC_COMM_SELF, PETSC_ERR_PLIB, "block IC(0) of a block chain stored in single precision: |M^-1 A x - x| / |x| = %g, not float's rounding", (double) err_single);
  npassed++;
  PetscCall(VecDestroy(&x));
  PetscCall(VecDestroy(&b));
  PetscCall(PCDestroy(&dbl));
  PetscCall(PCDestroy(&sgl));
  PetscCall(MatDestroy(&A));
  PetscFunctionReturn(0);
}

/* Where PETSc's ICC(0) of the SBAIJ matrix is positive definite (mass-dominated),
 * the two preconditioners are the same to round-off (double storage), and to
 * float's rounding (single). */
static PetscErrorCode TestAgreesWithICC(PetscRandom rnd)
{
  Mat       A;
  PC        dbl, sgl, petsc;
  Vec       b, z;
  PetscReal err, err_single;
  PetscBool compensated;

  PetscFunctionBeginUser;
  PetscCall(BuildMatrix(12, 9, PETSC_TRUE, 1.0, 0.5, rnd, &A));
  PetscCall(MakePC(A, PCBLOCKICC, "double", &dbl));
  PetscCall(MakePC(A, PCBLOCKICC, "single", &sgl));
  PetscCall(MakePC(A, PCICC, NULL, &petsc));
  PetscCall(MatCreateVecs(A, &b, &z));
  PetscCall(VecSetRandom(b, rnd));
  PetscCall(PCApply(petsc, b, z));
  PetscCall(ApplyError(dbl, b, z, &err));
  PetscCall(ApplyError(sgl, b, z, &err_single));
  PetscCall(PCBlockICCGetCompensated(dbl, &compensated));
  PetscCheck(err <= 1e-12 && !compensated, PETSC_COMM_SELF, PETSC_ERR_PLIB, "block IC(0) differs from PETSc's ICC(0): relative %g, compensated %d", (double) err, (int) compensated);
  PetscCheck(err_single <= 1e-5, PETSC_COMM_SELF, PETSC_ERR_PLIB, "block IC(0) stored in single precision differs from PETSc's ICC(0) by %g, more than float's rounding", (double) err_single);
  npassed++;
  PetscCall(VecDestroy(&b));
  PetscCall(VecDestroy(&z));
  PetscCall(PCDestroy(&dbl));
  PetscCall(PCDestroy(&sgl));
  PetscCall(PCDestroy(&petsc));
  PetscCall(MatDestroy(&A));
  PetscFunctionReturn(0);
}

/* A ladder, 2 x 20 blocks with the 4 neighbours: its exact Cholesky factor fills
 * the block (2j + 1, 2j + 2) of each rung from the two links of block 2j, and no
 * more. So IC(1) is exact there (M^-1 A x = x to round-off) and IC(0), which drops
 * that fill, is not: the fill is really added, and only where it belongs. */
static PetscErrorCode TestLevelOneExactOnLadder(PetscRandom rnd)
{
  Mat       A;
  PC        ic0, ic1;
  Vec       x, b;
  PetscReal err0, err1;

  PetscFunctionBeginUser;
  PetscCall(BuildMatrix(2, 20, PETSC_FALSE, 1.0, 10.0, rnd, &A));
  PetscCall(MakePCLevels(A, PCBLOCKICC, "double", "0", &ic0));
  PetscCall(MakePCLevels(A, PCBLOCKICC, "double", "1", &ic1));
  PetscCall(MatCreateVecs(A, &x, &b));
  PetscCall(VecSetRandom(x, rnd));
  PetscCall(MatMult(A, x, b));
  PetscCall(ApplyError(ic0, b, x, &err0));
  PetscCall(ApplyError(ic1, b, x, &err1));
  PetscCheck(err1 <= 1e-10, PETSC_COMM_SELF, PETSC_ERR_PLIB, "block IC(1) of a ladder is not exact: |M^-1 A x - x| / |x| = %g", (double) err1);
  PetscCheck(err0 > 1e-4, PETSC_COMM_SELF, PETSC_ERR_PLIB, "block IC(0) of a ladder is exact (|M^-1 A x - x| / |x| = %g): the test does not show the fill", (double) err0);
  npassed++;
  PetscCall(VecDestroy(&x));
  PetscCall(VecDestroy(&b));
  PetscCall(PCDestroy(&ic0));
  PetscCall(PCDestroy(&ic1));
  PetscCall(MatDestroy(&A));
  PetscFunctionReturn(0);
}

/* A pivot block conditioned beyond float: one block, eigenvalues 1, 1 and 1e-12 in
 * a random frame. Its inverse rounded to float is indefinite (entries of 1e12 lose
 * 6e4, against the eigenvalues 1), so the single storage asked for gives way to
 * double, and M^-1 A x = x still holds (M = A: one block drops nothing). */
static PetscErrorCode TestSingleWidens(PetscRandom rnd)
{
  Mat         A;
  PC          pc;
  Vec         x, b;
  PetscReal   q[3][3], err;
  PetscScalar a[9];
  PetscInt    zero = 0;

  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < 3; c++) { /* a random orthonormal frame (Gram-Schmidt) */
    PetscReal s = 0;
    for (PetscInt r = 0; r < 3; r++) {
      PetscCall(PetscRandomGetValueReal(rnd, &q[c][r]));
      q[c][r] -= 0.5;
    }
    for (PetscInt d = 0; d < c; d++) {
      const PetscReal dot = q[c][0] * q[d][0] + q[c][1] * q[d][1] + q[c][2] * q[d][2];
      for (PetscInt r = 0; r < 3; r++) q[c][r] -= dot * q[d][r];
    }
    for (PetscInt r = 0; r < 3; r++) s += q[c][r] * q[c][r];
    for (PetscInt r = 0; r < 3; r++) q[c][r] /= PetscSqrtReal(s);
  }
  for (PetscInt r = 0; r < 3; r++)
    for (PetscInt c = 0; c < 3; c++) a[r + 3 * c] = q[0][r] * q[0][c] + q[1][r] * q[1][c] + 1e-12 * q[2][r] * q[2][c];
  PetscCall(MatCreateSeqSBAIJ(PETSC_COMM_SELF, 3, 3, 3, 1, NULL, &A));
  PetscCall(MatSetValuesBlocked(A, 1, &zero, 1, &zero, a, INSERT_VALUES));
  PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  PetscCall(MakePC(A, PCBLOCKICC, "single", &pc));
  PetscCall(MatCreateVecs(A, &x, &b));
  for (PetscInt r = 0; r < 3; r++) PetscCall(VecSetValue(x, r, q[2][r] + 0.5 * q[0][r], INSERT_VALUES)); /* the stiff and the soft directions */
  PetscCall(VecAssemblyBegin(x));
  PetscCall(VecAssemblyEnd(x));
  PetscCall(MatMult(A, x, b));
  PetscCall(ApplyError(pc, b, x, &err));
  PetscCheck(err <= 1e-3, PETSC_COMM_SELF, PETSC_ERR_PLIB, "block IC(0) asked to store in single precision a pivot block conditioned at 1e12: |M^-1 A x - x| / |x| = %g (it should have stored double)", (double) err);
  npassed++;
  PetscCall(VecDestroy(&x));
  PetscCall(VecDestroy(&b));
  PetscCall(PCDestroy(&pc));
  PetscCall(MatDestroy(&A));
  PetscFunctionReturn(0);
}

/* Where IC(0) fails (bending over a small mass: PETSc's ICC(0) is indefinite there),
 * the compensated factor is symmetric and positive definite: y^T M^-1 x = x^T M^-1
 * y and x^T M^-1 x > 0, and CG converges, where it fails with PETSc's ICC(0). */
static PetscErrorCode TestCompensatedIsSPD(PetscRandom rnd)
{
  Mat                A;
  PC                 pc;
  KSP                ksp;
  Vec                x, y, mx, my, b;
  PetscScalar        xmy, ymx, xmx;
  PetscInt           its;
  PetscBool          compensated;
  KSPConvergedReason reason;

  PetscFunctionBeginUser;
  PetscCall(BuildBendMatrix(16, 12, 1e-6, 1.0, &A));
  PetscCall(MakePC(A, PCBLOCKICC, NULL, &pc));
  PetscCall(PCBlockICCGetCompensated(pc, &compensated));
  PetscCheck(compensated, PETSC_COMM_SELF, PETSC_ERR_PLIB, "IC(0) of the bending matrix did not fail: the test does not test the compensation");
  PetscCall(MatCreateVecs(A, &x, &y));
  PetscCall(VecDuplicate(x, &mx));
  PetscCall(VecDuplicate(x, &my));
  PetscCall(VecDuplicate(x, &b));
  for (PetscInt t = 0; t < 5; t++) {
    PetscCall(VecSetRandom(x, rnd));
    PetscCall(VecSetRandom(y, rnd));
    PetscCall(PCApply(pc, x, mx));
    PetscCall(PCApply(pc, y, my));
    PetscCall(VecDot(y, mx, &ymx));
    PetscCall(VecDot(x, my, &xmy));
    PetscCall(VecDot(x, mx, &xmx));
    PetscCheck(PetscAbsScalar(ymx - xmy) <= 1e-10 * PetscAbsScalar(xmx) && PetscRealPart(xmx) > 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "compensated block IC(0) is not SPD: y.Mx %g, x.My %g, x.Mx %g", (double) PetscRealPart(ymx),
               (double) PetscRealPart(xmy), (double) PetscRealPart(xmx));
  }
  for (PetscInt ours = 0; ours < 2; ours++) {
    PetscCall(KSPCreate(PETSC_COMM_SELF, &ksp));
    PetscCall(KSPSetType(ksp, KSPCG));
    PetscCall(KSPSetOperators(ksp, A, A));
    if (ours)
      PetscCall(KSPSetPC(ksp, pc));
    else {
      PC icc;
      PetscCall(KSPGetPC(ksp, &icc));
      PetscCall(PCSetType(icc, PCICC));
    }
    PetscCall(KSPSetTolerances(ksp, 1e-10, PETSC_DEFAULT, PETSC_DEFAULT, 5000));
    PetscCall(VecSetRandom(b, rnd));
    PetscCall(KSPSolve(ksp, b, x));
    PetscCall(KSPGetConvergedReason(ksp, &reason));
    PetscCall(KSPGetIterationNumber(ksp, &its));
    if (ours)
      PetscCheck(reason > 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "CG with compensated block IC(0) did not converge: reason %s after %" PetscInt_FMT " iterations", KSPConvergedReasons[reason], its);
    else
      PetscCheck(reason == KSP_DIVERGED_INDEFINITE_PC, PETSC_COMM_SELF, PETSC_ERR_PLIB, "CG with PETSc's ICC(0) on the bending matrix ended with %s, not an indefinite preconditioner: the test does not show what the compensation is for",
                 KSPConvergedReasons[reason]);
    PetscCall(KSPDestroy(&ksp));
  }
  npassed++;
  PetscCall(VecDestroy(&x));
  PetscCall(VecDestroy(&y));
  PetscCall(VecDestroy(&mx));
  PetscCall(VecDestroy(&my));
  PetscCall(VecDestroy(&b));
  PetscCall(PCDestroy(&pc));
  PetscCall(MatDestroy(&A));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscRandom rnd;
  PetscInt    seed = 7;

  PetscCall(PetscInitialize(&argc, &argv, NULL, help));
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-seed", &seed, NULL));
  PetscCall(PCBlockICCRegister());
  PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
  PetscCall(PetscRandomSetSeed(rnd, (unsigned long) seed));
  PetscCall(PetscRandomSeed(rnd));
  PetscCall(TestChainIsExact(rnd));
  PetscCall(TestAgreesWithICC(rnd));
  PetscCall(TestCompensatedIsSPD(rnd));
  PetscCall(TestSingleWidens(rnd));
  PetscCall(TestLevelOneExactOnLadder(rnd));
  PetscCall(PetscRandomDestroy(&rnd));
  PetscCall(PetscPrintf(PETSC_COMM_SELF, "%" PetscInt_FMT " passed, 0 failed\n", npassed));
  PetscCall(PetscFinalize());
  return 0;
}
