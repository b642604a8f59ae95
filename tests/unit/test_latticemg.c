static const char help[] = "Unit tests of the lattice multigrid (src/integrate/pclatticemg.c): its V(1,1),\n"
                           "W and hybrid cycles symmetric to round-off and positive definite, with the\n"
                           "contact constraints' filter (sliding, fixed and pinned rows) and either\n"
                           "smoother, on lattices of odd and even sizes; CG iterations that do not grow\n"
                           "with the lattice where block IC's do; block IC applied in place as out of place.\n"
                           "Options: -seed <int>\n\n";

#include <petscksp.h>
#include <pcblockicc.h>
#include <pclatticemg.h>

static PetscInt npassed = 0;

/* A random unit vector */
static PetscErrorCode RandomUnit(PetscRandom rnd, PetscReal u[3])
{
  PetscReal s = 0;

  PetscFunctionBeginUser;
  for (PetscInt r = 0; r < 3; r++) {
    PetscCall(PetscRandomGetValueReal(rnd, &u[r]));
    u[r] -= 0.5;
    s += u[r] * u[r];
  }
  for (PetscInt r = 0; r < 3; r++) u[r] /= PetscSqrtReal(s);
  PetscFunctionReturn(0);
}

/* An SPD SBAIJ matrix of block size 3 on an nx x ny lattice, node j nx + i: a mass m
 * on each diagonal block, a spring k (u u^T, u a random unit vector, stiffer along
 * x than along y: the warp and weft) on each link to the 8 neighbours, and a spring
 * kb on each link two nodes apart along x and y (the bending's reach): the shape of
 * drape's backward-Euler matrix, whose coarse operators fill the 5 x 5 stencil. */
static PetscErrorCode BuildMatrix(PetscInt nx, PetscInt ny, PetscReal m, PetscReal k, PetscReal kb, PetscRandom rnd, Mat *A)
{
  const PetscInt n = nx * ny;

  PetscFunctionBeginUser;
  PetscCall(MatCreateSeqSBAIJ(PETSC_COMM_SELF, 3, 3 * n, 3 * n, 7, NULL, A));
  PetscCall(MatSetOption(*A, MAT_IGNORE_LOWER_TRIANGULAR, PETSC_TRUE));
  for (PetscInt b = 0; b < n; b++) {
    PetscScalar d[9] = {m, 0, 0, 0, m, 0, 0, 0, m};
    PetscCall(MatSetValuesBlocked(*A, 1, &b, 1, &b, d, ADD_VALUES));
  }
  for (PetscInt j = 0; j < ny; j++) {
    for (PetscInt i = 0; i < nx; i++) {
      const PetscInt  off[6][2] = {{1, 0}, {0, 1}, {1, 1}, {-1, 1}, {2, 0}, {0, 2}};
      const PetscReal stiff[6]  = {4 * k, k, k, k, kb, kb};
      for (PetscInt l = 0; l < 6; l++) {
        const PetscInt ii = i + off[l][0], jj = j + off[l][1];
        PetscInt       p = i + nx * j, q = ii + nx * jj;
        PetscReal      u[3];
        PetscScalar    K[9], Kn[9];
        if (ii < 0 || ii >= nx || jj >= ny) continue;
        PetscCall(RandomUnit(rnd, u));
        for (PetscInt r = 0; r < 3; r++)
          for (PetscInt c = 0; c < 3; c++) {
            K[r + 3 * c]  = stiff[l] * u[r] * u[c];
            Kn[r + 3 * c] = -K[r + 3 * c];
          }
        PetscCall(MatSetValuesBlocked(*A, 1, &p, 1, &p, K, ADD_VALUES));
        PetscCall(MatSetValuesBlocked(*A, 1, &q, 1, &q, K, ADD_VALUES));
        PetscCall(MatSetValuesBlocked(*A, 1, &p, 1, &q, Kn, ADD_VALUES)); /* p < q */
      }
    }
  }
  PetscCall(MatAssemblyBegin(*A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*A, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

/* The lattice multigrid of A on the nx x ny lattice (one row a node, in order); with
 * constraints, every 7th row slides on a random plane, every 11th is fixed, every
 * 13th pinned. smoother: "blockicc" or "sgs"; hybrid: the hybrid cycle. normal must
 * outlive the PC. */
static PetscErrorCode MakeMG(Mat A, PetscInt nx, PetscInt ny, PetscBool constraints, const char *smoother, PetscBool hybrid, PetscRandom rnd, PetscReal *normal, PC *pc)
{
  const PetscInt   n = nx * ny;
  PetscInt        *node;
  PetscBool       *pinned;
  ClothConstraint *type;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc3(n, &node, n, &pinned, n, &type));
  for (PetscInt k = 0; k < n; k++) {
    node[k]   = k;
    pinned[k] = (PetscBool) (constraints && k % 13 == 5);
    type[k]   = !constraints ? CLOTH_FREE : k % 7 == 3 ? CLOTH_SLIDE : k % 11 == 2 ? CLOTH_FIXED : CLOTH_FREE;
    PetscCall(RandomUnit(rnd, normal + 3 * k));
  }
  PetscCall(PetscOptionsSetValue(NULL, "-pc_latticemg_smoother", smoother));
  PetscCall(PCCreate(PETSC_COMM_SELF, pc));
  PetscCall(PCSetType(*pc, PCLATTICEMG));
  PetscCall(PCSetFromOptions(*pc));
  PetscCall(PCLatticeMGSetLattice(*pc, nx, ny, n, node, pinned));
  PetscCall(PCLatticeMGSetConstraints(*pc, type, normal));
  PetscCall(PCLatticeMGSetHybrid(*pc, hybrid));
  PetscCall(PCSetOperators(*pc, A, A));
  PetscCall(PCSetUp(*pc));
  PetscCall(PetscOptionsClearValue(NULL, "-pc_latticemg_smoother"));
  PetscCall(PetscFree3(node, pinned, type));
  PetscFunctionReturn(0);
}

/* y.Bx = x.By and x.Bx > 0 for random x, y: CG needs both. The sweeps backward are
 * the transposes of those forward from the same stored (single-precision) numbers and
 * every residual is exact, so the asymmetry is the double arithmetic's round-off
 * (measured: at most 5e-10 of sqrt(x.Bx y.By) on this matrix, whose condition number
 * is about 4e4; a coarse operator whose triangles were rounded apart, or the hybrid
 * cycle with a Gauss-Seidel smoother, give 1e-7 and more). */
static PetscErrorCode TestSymmetricPositive(PetscRandom rnd)
{
  const PetscInt sizes[2][2]  = {{33, 29}, {24, 18}};
  const char    *smoothers[2] = {"blockicc", "sgs"};

  PetscFunctionBeginUser;
  for (PetscInt z = 0; z < 2; z++) {
    const PetscInt nx = sizes[z][0], ny = sizes[z][1];
    Mat            A;
    PetscReal     *normal;
    PetscCall(BuildMatrix(nx, ny, 1e-4, 1.0, 0.05, rnd, &A));
    PetscCall(PetscMalloc1(3 * nx * ny, &normal));
    for (PetscInt v = 0; v < 16; v++) {
      const PetscBool constraints = (PetscBool) (v & 1), hybrid = (PetscBool) ((v >> 1) & 1);
      const char     *smoother = smoothers[(v >> 2) & 1], *gamma = (v >> 3) ? "2" : "1";
      PC              pc;
      Vec             x, y, bx, by;
      if (hybrid && (v >> 2) & 1) continue; /* refused: TestHybridNeedsBlockIC */
      PetscCall(PetscOptionsSetValue(NULL, "-pc_latticemg_gamma", gamma));
      PetscCall(MakeMG(A, nx, ny, constraints, smoother, hybrid, rnd, normal, &pc));
      PetscCall(PetscOptionsClearValue(NULL, "-pc_latticemg_gamma"));
      PetscCall(MatCreateVecs(A, &x, &y));
      PetscCall(VecDuplicate(x, &bx));
      PetscCall(VecDuplicate(x, &by));
      for (PetscInt t = 0; t < 3; t++) {
        PetscScalar ybx, xby, xbx, yby;
        PetscCall(VecSetRandom(x, rnd));
        PetscCall(VecSetRandom(y, rnd));
        PetscCall(PCApply(pc, x, bx));
        PetscCall(PCApply(pc, y, by));
        PetscCall(VecDot(y, bx, &ybx));
        PetscCall(VecDot(x, by, &xby));
        PetscCall(VecDot(x, bx, &xbx));
        PetscCall(VecDot(y, by, &yby));
        PetscCheck(PetscAbsScalar(ybx - xby) <= 1e-8 * PetscSqrtReal(PetscRealPart(xbx) * PetscRealPart(yby)), PETSC_COMM_SELF, PETSC_ERR_PLIB,
                   "the lattice multigrid (%" PetscInt_FMT " x %" PetscInt_FMT ", %s, constraints %d, hybrid %d, gamma %s) is not symmetric: y.Bx %.17g, x.By %.17g", nx, ny, smoother, (int) constraints, (int) hybrid, gamma,
                   (double) PetscRealPart(ybx), (double) PetscRealPart(xby));
        PetscCheck(PetscRealPart(xbx) > 0 && PetscRealPart(yby) > 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "the lattice multigrid (%s, constraints %d, hybrid %d) is not positive: x.Bx %g, y.By %g", smoother, (int) constraints, (int) hybrid,
                   (double) PetscRealPart(xbx), (double) PetscRealPart(yby));
      }
      PetscCall(VecDestroy(&x));
      PetscCall(VecDestroy(&y));
      PetscCall(VecDestroy(&bx));
      PetscCall(VecDestroy(&by));
      PetscCall(PCDestroy(&pc));
    }
    PetscCall(PetscFree(normal));
    PetscCall(MatDestroy(&A));
  }
  npassed++;
  PetscFunctionReturn(0);
}

/* CG to 1e-8 (the residual's norm) on 33^2, 65^2 and 129^2 (16 times the nodes):
 * with the multigrid (its hybrid cycle: block IC(0) of this matrix misses it by more
 * than 2 somewhere, and V(1,1) is indefinite) the iterations grow by at most 1.5 x,
 * with block IC(0) by more than 2 x; and the multigrid's solution is the system's
 * (its residual, computed anew). */
static PetscErrorCode TestIterationsDoNotGrow(PetscRandom rnd)
{
  const PetscInt sizes[3] = {33, 65, 129};
  PetscInt       its[2][3];

  PetscFunctionBeginUser;
  for (PetscInt z = 0; z < 3; z++) {
    const PetscInt n = sizes[z];
    Mat            A;
    PetscReal     *normal;
    PetscCall(BuildMatrix(n, n, 1e-4, 1.0, 0.05, rnd, &A));
    PetscCall(PetscMalloc1(3 * n * n, &normal));
    for (PetscInt mg = 0; mg < 2; mg++) {
      KSP                ksp;
      PC                 pc;
      Vec                b, x, r;
      KSPConvergedReason reason;
      PetscReal          rn, bn;
      PetscCall(KSPCreate(PETSC_COMM_SELF, &ksp));
      PetscCall(KSPSetType(ksp, KSPCG));
      PetscCall(KSPSetOperators(ksp, A, A));
      if (mg) {
        PetscCall(MakeMG(A, n, n, PETSC_FALSE, "blockicc", PETSC_TRUE, rnd, normal, &pc));
        PetscCall(KSPSetPC(ksp, pc));
        PetscCall(PCDestroy(&pc));
      } else {
        PetscCall(KSPGetPC(ksp, &pc));
        PetscCall(PCSetType(pc, PCBLOCKICC));
      }
      PetscCall(KSPSetTolerances(ksp, 1e-8, PETSC_DEFAULT, PETSC_DEFAULT, 10000));
      PetscCall(KSPSetNormType(ksp, KSP_NORM_UNPRECONDITIONED));
      PetscCall(MatCreateVecs(A, &x, &b));
      PetscCall(VecDuplicate(b, &r));
      PetscCall(VecSetRandom(b, rnd));
      PetscCall(KSPSolve(ksp, b, x));
      PetscCall(KSPGetConvergedReason(ksp, &reason));
      PetscCall(KSPGetIterationNumber(ksp, &its[mg][z]));
      PetscCheck(reason > 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "CG with %s on %" PetscInt_FMT "^2 did not converge: %s", mg ? "the lattice multigrid" : "block IC(0)", n, KSPConvergedReasons[reason]);
      PetscCall(MatMult(A, x, r));
      PetscCall(VecAYPX(r, -1.0, b));
      PetscCall(VecNorm(r, NORM_2, &rn));
      PetscCall(VecNorm(b, NORM_2, &bn));
      PetscCheck(rn <= 1e-7 * bn, PETSC_COMM_SELF, PETSC_ERR_PLIB, "CG's solution with %s on %" PetscInt_FMT "^2 leaves a residual of %g of the right-hand side", mg ? "the lattice multigrid" : "block IC(0)", n, (double) (rn / bn));
      PetscCall(VecDestroy(&x));
      PetscCall(VecDestroy(&b));
      PetscCall(VecDestroy(&r));
      PetscCall(KSPDestroy(&ksp));
    }
    PetscCall(PetscFree(normal));
    PetscCall(MatDestroy(&A));
  }
  PetscCall(PetscPrintf(PETSC_COMM_SELF, "CG iterations on 33^2, 65^2, 129^2: lattice multigrid %" PetscInt_FMT ", %" PetscInt_FMT ", %" PetscInt_FMT "; block IC(0) %" PetscInt_FMT ", %" PetscInt_FMT ", %" PetscInt_FMT "\n", its[1][0], its[1][1],
                        its[1][2], its[0][0], its[0][1], its[0][2]));
  PetscCheck(its[1][2] <= 1.5 * its[1][0], PETSC_COMM_SELF, PETSC_ERR_PLIB, "the lattice multigrid's CG iterations grow from %" PetscInt_FMT " to %" PetscInt_FMT " on 16 times the nodes", its[1][0], its[1][2]);
  PetscCheck(its[0][2] > 2 * its[0][0], PETSC_COMM_SELF, PETSC_ERR_PLIB, "block IC(0)'s iterations grow only from %" PetscInt_FMT " to %" PetscInt_FMT ": the matrix does not test what multigrid is for", its[0][0], its[0][2]);
  npassed++;
  PetscFunctionReturn(0);
}

/* The hybrid cycle with the Gauss-Seidel smoother (not symmetric: M^-1 + ... is not)
 * is refused with a sentence, at the first application. */
static PetscErrorCode TestHybridNeedsBlockIC(PetscRandom rnd)
{
  Mat            A;
  PC             pc;
  Vec            b, x;
  PetscReal     *normal;
  PetscErrorCode ierr;

  PetscFunctionBeginUser;
  PetscCall(BuildMatrix(9, 9, 1e-4, 1.0, 0.05, rnd, &A));
  PetscCall(PetscMalloc1(3 * 81, &normal));
  PetscCall(MakeMG(A, 9, 9, PETSC_FALSE, "sgs", PETSC_TRUE, rnd, normal, &pc));
  PetscCall(MatCreateVecs(A, &x, &b));
  PetscCall(VecSetRandom(b, rnd));
  PetscCall(PetscPushErrorHandler(PetscReturnErrorHandler, NULL));
  ierr = PCApply(pc, b, x);
  PetscCall(PetscPopErrorHandler());
  PetscCheck(ierr == PETSC_ERR_ARG_INCOMP, PETSC_COMM_SELF, PETSC_ERR_PLIB, "the hybrid cycle with the Gauss-Seidel smoother was not refused (error %d)", (int) ierr);
  PetscCall(VecDestroy(&x));
  PetscCall(VecDestroy(&b));
  PetscCall(PCDestroy(&pc));
  PetscCall(PetscFree(normal));
  PetscCall(MatDestroy(&A));
  npassed++;
  PetscFunctionReturn(0);
}

/* PCBlockICCApplyInPlace gives PCApply's result to the bit (the same solve, on the
 * same numbers), and refuses a PC of another type. */
static PetscErrorCode TestInPlace(PetscRandom rnd)
{
  Mat            A;
  PC             pc;
  Vec            b, x, y;
  PetscBool      equal;
  PetscErrorCode ierr;

  PetscFunctionBeginUser;
  PetscCall(BuildMatrix(20, 17, 1e-4, 1.0, 0.05, rnd, &A));
  PetscCall(PCCreate(PETSC_COMM_SELF, &pc));
  PetscCall(PCSetType(pc, PCBLOCKICC));
  PetscCall(PCSetOperators(pc, A, A));
  PetscCall(PCSetUp(pc));
  PetscCall(MatCreateVecs(A, &x, &b));
  PetscCall(VecDuplicate(b, &y));
  PetscCall(VecSetRandom(b, rnd));
  PetscCall(PCApply(pc, b, x));
  PetscCall(VecCopy(b, y));
  PetscCall(PCBlockICCApplyInPlace(pc, y));
  PetscCall(VecEqual(x, y, &equal));
  PetscCheck(equal, PETSC_COMM_SELF, PETSC_ERR_PLIB, "block IC applied in place differs from PCApply");
  PetscCall(PCSetType(pc, PCJACOBI));
  PetscCall(PetscPushErrorHandler(PetscReturnErrorHandler, NULL));
  ierr = PCBlockICCApplyInPlace(pc, y);
  PetscCall(PetscPopErrorHandler());
  PetscCheck(ierr == PETSC_ERR_ARG_WRONG, PETSC_COMM_SELF, PETSC_ERR_PLIB, "PCBlockICCApplyInPlace took a PC of type jacobi (error %d)", (int) ierr);
  PetscCall(VecDestroy(&x));
  PetscCall(VecDestroy(&y));
  PetscCall(VecDestroy(&b));
  PetscCall(PCDestroy(&pc));
  PetscCall(MatDestroy(&A));
  npassed++;
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscRandom rnd;
  PetscInt    seed = 11;

  PetscCall(PetscInitialize(&argc, &argv, NULL, help));
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-seed", &seed, NULL));
  PetscCall(PCBlockICCRegister());
  PetscCall(PCLatticeMGRegister());
  PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
  PetscCall(PetscRandomSetSeed(rnd, (unsigned long) seed));
  PetscCall(PetscRandomSeed(rnd));
  PetscCall(TestSymmetricPositive(rnd));
  PetscCall(TestIterationsDoNotGrow(rnd));
  PetscCall(TestHybridNeedsBlockIC(rnd));
  PetscCall(TestInPlace(rnd));
  PetscCall(PetscRandomDestroy(&rnd));
  PetscCall(PetscPrintf(PETSC_COMM_SELF, "%" PetscInt_FMT " passed, 0 failed\n", npassed));
  PetscCall(PetscFinalize());
  return 0;
}
