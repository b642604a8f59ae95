static const char help[] = "Cusick drape test analysis on constructed silhouettes with known answers.\n";

#include <analysis.h>
#include <petscdmda.h>
#include <drape.h>

#define CHECK(cond, ...) PetscCheck(cond, PETSC_COMM_WORLD, PETSC_ERR_PLIB, __VA_ARGS__)

int main(int argc, char **argv)
{
  Cloth        cloth;
  ClothInfo    info;
  PetscScalar *x0, *x, *v;
  PetscReal    c[2] = {0, 0}, area, radius[720], dc, rp = 0.09, *xy;
  PetscInt     folds, passed = 0, n, k = 0;

  PetscCall(PetscInitialize(&argc, &argv, NULL, help));
  PetscCall(DrapeInitialize());

  /* 1. a square of side 0.2 m as two triangles: area 0.04 m^2, no folds beyond its 4 corners */
  {
    const PetscReal sq[12] = {-0.1, -0.1, 0.1, -0.1, 0.1, 0.1, -0.1, -0.1, 0.1, 0.1, -0.1, 0.1};
    PetscCall(CusickSilhouette(2, sq, c, 0.2, 1000, &area, 720, radius));
    PetscCall(CusickCountFolds(720, radius, 0.005, &folds));
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "square 0.2 m: area %.6f m^2 (exact 0.04), %" PetscInt_FMT " maxima (corners: 4)\n", (double) area, folds));
    CHECK(PetscAbsReal(area - 0.04) < 1e-3 * 0.04 && folds == 4, "square silhouette wrong");
    passed++;
  }
  /* 2. a star r = 0.1 + 0.02 cos(7 t), fan of 360 triangles: 7 folds, area of the polygon */
  {
    PetscReal exact = 0;
    PetscCall(PetscMalloc1(6 * 360, &xy));
    for (PetscInt t = 0; t < 360; t++) {
      PetscReal a0 = 2 * PETSC_PI * t / 360, a1 = 2 * PETSC_PI * (t + 1) / 360, r0 = 0.1 + 0.02 * PetscCosReal(7 * a0), r1 = 0.1 + 0.02 * PetscCosReal(7 * a1);
      PetscReal p[6] = {0, 0, r0 * PetscCosReal(a0), r0 * PetscSinReal(a0), r1 * PetscCosReal(a1), r1 * PetscSinReal(a1)};
      for (PetscInt q = 0; q < 6; q++) xy[6 * t + q] = p[q];
      exact += 0.5 * (p[2] * p[5] - p[4] * p[3]);
    }
    PetscCall(CusickSilhouette(360, xy, c, 0.15, 1200, &area, 720, radius));
    PetscCall(CusickCountFolds(720, radius, 0.005, &folds));
    PetscCall(PetscFree(xy));
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "7-lobed star: area %.6f m^2 (exact %.6f), %" PetscInt_FMT " folds (exact 7)\n", (double) area, (double) exact, folds));
    CHECK(PetscAbsReal(area - exact) < 2e-3 * exact && folds == 7, "star silhouette wrong");
    passed++;
  }

  /* the specimen: a circular lattice (-cloth_shape circle -cloth_size 0.3) */
  PetscCall(ClothCreate(PETSC_COMM_WORLD, &cloth));
  PetscCall(ClothSetFromOptions(cloth));
  PetscCall(ClothSetUp(cloth));
  PetscCall(ClothGetInfo(cloth, &info));
  n = 3 * info.nowned;
  PetscCall(PetscMalloc3(n, &x0, n, &x, n, &v));
  PetscCall(ClothSetInitialState(cloth, x0, v));

  /* 3. the flat specimen: DC = 1 */
  PetscCall(CusickAnalyse(cloth, x0, x0, rp, c, &dc, &folds));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "flat specimen: DC = %.6f (exact 1), %" PetscInt_FMT " folds\n", (double) dc, folds));
  CHECK(dc == 1 && folds == 0, "flat specimen: DC %g, folds %" PetscInt_FMT, (double) dc, folds);
  passed++;

  /* 4. hanging straight down the pedestal edge: DC = 0 */
  for (k = 0; k < n / 3; k++) {
    PetscReal *p = x + 3 * k, *q = x0 + 3 * k, rho = PetscSqrtReal(q[0] * q[0] + q[1] * q[1]);
    p[0] = q[0], p[1] = q[1], p[2] = q[2];
    if (rho > rp) {
      p[0] = q[0] * rp / rho;
      p[1] = q[1] * rp / rho;
      p[2] = q[2] - (rho - rp);
    }
  }
  PetscCall(CusickAnalyse(cloth, x, x0, rp, c, &dc, &folds));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "hanging straight down: DC = %.6f (exact 0), %" PetscInt_FMT " folds\n", (double) dc, folds));
  CHECK(PetscAbsReal(dc) < 0.02 && folds == 0, "hanging specimen: DC %g", (double) dc);
  passed++;

  /* 5. the flat specimen shrunk by s: its silhouette is s^2 A0, with A0 the area of
   *    the lattice cells inside the circle, so DC = (s^2 A0 - Ad)/(A0 - Ad) */
  {
    const PetscReal s = 0.8, Ad = PETSC_PI * rp * rp;
    PetscReal       A0 = 0, expect;
    for (PetscInt j = 0; j + 1 < info.My; j++)
      for (PetscInt i = 0; i + 1 < info.Mx; i++)
        if (ClothIsActive(cloth, i, j) && ClothIsActive(cloth, i + 1, j) && ClothIsActive(cloth, i, j + 1) && ClothIsActive(cloth, i + 1, j + 1)) A0 += info.spacing[0] * info.spacing[1];
    expect = (s * s * A0 - Ad) / (A0 - Ad);
    for (PetscInt i = 0; i < n; i++) x[i] = (i % 3 == 2) ? x0[i] : s * x0[i];
    PetscCall(CusickAnalyse(cloth, x, x0, rp, c, &dc, &folds));
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "specimen shrunk by %g: DC = %.6f (exact %.6f from the cell area %.6f m^2)\n", (double) s, (double) dc, (double) expect, (double) A0));
    CHECK(PetscAbsReal(dc - expect) < 5e-3, "shrunk specimen: DC %g, expected %g", (double) dc, (double) expect);
    passed++;
  }

  /* 6. an 8-lobed drape: the overhang pulled in to rp + (rho - rp)(0.6 + 0.3 cos 8 theta)
   *    and lowered: 8 folds; the DC printed to the bit, which must not depend on the
   *    ranks or the partition (tests/test_unit.py compares runs) */
  for (k = 0; k < n / 3; k++) {
    PetscReal *p = x + 3 * k, *q = x0 + 3 * k, rho = PetscSqrtReal(q[0] * q[0] + q[1] * q[1]), th = PetscAtan2Real(q[1], q[0]);
    p[0] = q[0], p[1] = q[1], p[2] = q[2];
    if (rho > rp) {
      PetscReal r = rp + (rho - rp) * (0.6 + 0.3 * PetscCosReal(8 * th));
      p[0]        = r * PetscCosReal(th);
      p[1]        = r * PetscSinReal(th);
      p[2]        = q[2] - (rho - rp) * 0.5;
    }
  }
  PetscCall(CusickAnalyse(cloth, x, x0, rp, c, &dc, &folds));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "8-lobed drape: DC = %.17g, %" PetscInt_FMT " folds\n", (double) dc, folds));
  CHECK(dc > 0.2 && dc < 0.9 && folds == 8, "8-lobed drape: DC %g, folds %" PetscInt_FMT, (double) dc, folds);
  passed++;

  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "%" PetscInt_FMT " passed, 0 failed\n", passed));
  PetscCall(PetscFree3(x0, x, v));
  PetscCall(ClothDestroy(&cloth));
  PetscCall(DrapeFinalize());
  PetscCall(PetscFinalize());
  return 0;
}
