/* The explicit schemes' force kernel on the lattice (-cloth_force_kernel lattice).
 *
 * The element lists (clothimpl.h) say which elements a rank computes; this kernel
 * computes the same elements, but reads them from a rectangular patch of the
 * lattice: the bounding box of the rank's local (owned and ghost) particles, in
 * structure-of-arrays form (x, y, z and the forces each in its own array, row by
 * row, with a frame of one empty slot around it). An element is then named by its
 * kind and the slot of its centre (or first corner), and its particles sit at fixed
 * offsets from it: the loops below run along a lattice row with unit stride and no
 * index arrays, and the compiler vectorises them (sqrt, division, and an asin of our
 * own: KernelAsin). Which elements are present, and their coefficients, is one byte
 * per kind and slot: the element's class in the list (0: absent). Absent elements
 * are computed on harmless numbers and multiplied by a coefficient 0: they add exact
 * zeros.
 *
 * The kernel does not know how the particles were partitioned: any set of local
 * particles gives a patch (a DMDA block and its ghosts fill it; a METIS part leaves
 * slots empty). Each particle's force is summed in one order, by the row of the
 * element's centre, then by kind, whatever the patch: the same positions give the
 * same forces on any partition.
 *
 * Bending laws (-cloth_bend_table) and bending friction (-cloth_bend_hysteresis)
 * are not here: with them the element lists' loops (forces.c) do all the work. */
#include "clothimpl.h"
#include <drape.h>

/* Element kinds of the patch, each named by the slot (i, j) of its anchor. */
enum {
  LAT_STRETCH_WARP, /* (i,j)-(i+1,j)                          */
  LAT_STRETCH_WEFT, /* (i,j)-(i,j+1)                          */
  LAT_SHEAR,        /* cell with corners (i,j) ... (i+1,j+1)  */
  LAT_BEND_WARP,    /* (i-1,j), (i+1,j), vertex (i,j)         */
  LAT_BEND_WEFT,    /* (i,j-1), (i,j+1), vertex (i,j)         */
  LAT_BEND_DIAG,    /* (i-1,j-1), (i+1,j+1), vertex (i,j)     */
  LAT_BEND_ANTI,    /* (i-1,j+1), (i+1,j-1), vertex (i,j)     */
  LAT_KINDS
};

struct _n_ClothLattice {
  PetscInt       i0, j0, W, H, ld; /* patch origin and size in the lattice; padded row length W + 2 */
  PetscInt       nslot;            /* (W + 2) (H + 2)                                              */
  PetscInt      *slot;             /* local particle -> padded slot                                */
  PetscReal     *x[3], *f[3];      /* positions and forces, padded patch                           */
  unsigned char *cls[LAT_KINDS];   /* class + 1 of the element anchored at each slot, 0: none; NULL: no element of the kind */
  PetscReal      coef[LAT_KINDS][CLOTH_ELEMENT_CLASSES + 1];
  PetscReal      coef_rest[2][CLOTH_ELEMENT_CLASSES + 1]; /* stretch: k L */
  PetscReal     *tmp;                                     /* 12 rows of W + 4: one row's element gradients */
  PetscReal     *krow;                                    /* a row's coefficients, mask, k L (3 W)      */
};

/* asin(x) for |x| <= 1 to 2 ulp, in a form the compiler vectorises (no branch, no
 * table): asin(x) = x + x^3 P(x^2) on |x| <= 1/2, and pi/2 - 2 asin(sqrt((1 - |x|)/2))
 * above. P is a degree-11 polynomial fitted to the relative error of asin on
 * [0, 1/2] (Lawson-weighted least squares in 50-digit arithmetic; approximation
 * error 1.5e-17); against glibc's asin: at most 1 ulp below 1/2, 2 ulp above
 * (tests/unit/test_kernels.c). */
static inline __attribute__((always_inline)) PetscReal KernelAsin(PetscReal x)
{
  const PetscReal ax = PetscAbsReal(x);
  const PetscBool big = (PetscBool) (ax > 0.5);
  const PetscReal z = big ? 0.5 * (1 - ax) : x * x, s = big ? PetscSqrtReal(z) : ax;
  PetscReal       u = 0.03190975805482998;

  u = u * z - 0.01622056329858812;
  u = u * z + 0.019525904250609717;
  u = u * z + 0.006528838282604679;
  u = u * z + 0.012169013109334418;
  u = u * z + 0.013885265313232309;
  u = u * z + 0.01735970181594715;
  u = u * z + 0.022371758237395522;
  u = u * z + 0.030381959129763308;
  u = u * z + 0.04464285682847867;
  u = u * z + 0.07500000000336884;
  u = u * z + 0.16666666666665408;
  u = s + s * z * u;
  u = big ? 1.5707963267948966 - 2 * u : u;
  return x < 0 ? -u : u;
}

PetscReal ClothLatticeAsin(PetscReal x) { return KernelAsin(x); }

/* One shear corner (KernelShearCorner) with KernelAsin. */
static inline __attribute__((always_inline)) void LatticeShearCorner(PetscReal u, PetscReal w, PetscReal s, PetscReal kappa, PetscReal *q, PetscReal *beta)
{
  const PetscReal inv = 1 / (u * w), iP = PetscSqrtReal(u * w) * inv;
  const PetscReal c = PetscMin(PetscMax(s * iP, -1 + 1e-14), 1 - 1e-14), a = KernelAsin(c), g1 = 2 * a / PetscSqrtReal(1 - c * c);

  *q    = kappa * iP * (a * a - g1 * c);
  *beta = kappa * g1;
}

/* Bending coefficients (KernelAngleCoefficients, linear law) of the triple with
 * e1 = x_a - x_c, e2 = x_b - x_c, and its gradient with respect to x_a and x_b
 * (x_c's is minus their sum). m: 1 present, 0 absent. */
static inline __attribute__((always_inline)) void LatticeBend(PetscReal m, PetscReal kappa, const PetscReal e1[3], const PetscReal e2[3], PetscReal ga[3], PetscReal gb[3])
{
  PetscReal u = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2], v = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
  PetscReal s = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];

  u = m * u + (1 - m);
  v = m * v + (1 - m);
  s = m * s;
  {
    const PetscReal inv = 1 / (u * v), iP = PetscSqrtReal(u * v) * inv, c = s * iP;
    const PetscReal w0 = -kappa * c * v * inv, w2 = -kappa * c * u * inv, w1 = kappa * iP;
    for (PetscInt d = 0; d < 3; d++) {
      ga[d] = w0 * e1[d] + w1 * e2[d];
      gb[d] = w2 * e2[d] + w1 * e1[d];
    }
  }
}

/* The coefficients of row b's elements of one kind, K (and for stretch k L, KL), and
 * the mask M (1: present, 0: absent), in a scalar pass: the vector loops then read
 * unit-stride rows, no table and no comparison. An absent element computes on
 * u = M u + (1 - M) = 1, s = M s = 0 (no division by zero) with coefficient 0. */
static inline __attribute__((always_inline)) void LatticeCoefficients(const ClothLattice *L, PetscInt kind, PetscInt b, PetscInt p0, PetscInt p1, PetscReal *restrict K, PetscReal *restrict M, PetscReal *restrict KL)
{
  const unsigned char *restrict cls = L->cls[kind] + b;
  const PetscReal *restrict     tab = L->coef[kind], *restrict tab_rest = L->coef_rest[kind < 2 ? kind : 0];

  for (PetscInt i = p0; i < p1; i++) {
    const int c = cls[i];
    K[i]        = tab[c];
    M[i]        = c ? 1.0 : 0.0;
  }
  if (KL)
    for (PetscInt i = p0; i < p1; i++) {
      const int c = cls[i];
      KL[i]       = tab_rest[c];
    }
}

/* A triple of kind `kind` along every anchor of row j: a at offset oa, b at ob from
 * the vertex, in the rows above and below. Each iteration writes three particles of
 * three different rows, so the iterations are independent. */
static inline __attribute__((always_inline)) void LatticeBendRow(const ClothLattice *L, PetscInt kind, PetscInt b, PetscInt p0, PetscInt p1, PetscInt oa, PetscInt ob)
{
  const PetscReal *restrict X = L->x[0] + b, *restrict Y = L->x[1] + b, *restrict Z = L->x[2] + b;
  PetscReal *restrict       FX = L->f[0] + b, *restrict FY = L->f[1] + b, *restrict FZ = L->f[2] + b;
  PetscReal *restrict       K = L->krow, *restrict M = L->krow + L->W;

  LatticeCoefficients(L, kind, b, p0, p1, K, M, NULL);
#pragma GCC ivdep
  for (PetscInt i = p0; i < p1; i++) {
    const PetscReal e1[3] = {X[i + oa] - X[i], Y[i + oa] - Y[i], Z[i + oa] - Z[i]}, e2[3] = {X[i + ob] - X[i], Y[i + ob] - Y[i], Z[i + ob] - Z[i]};
    PetscReal       ga[3], gb[3];
    LatticeBend(M[i], K[i], e1, e2, ga, gb);
    FX[i + oa] -= ga[0];
    FY[i + oa] -= ga[1];
    FZ[i + oa] -= ga[2];
    FX[i + ob] -= gb[0];
    FY[i + ob] -= gb[1];
    FZ[i + ob] -= gb[2];
    FX[i] += ga[0] + gb[0];
    FY[i] += ga[1] + gb[1];
    FZ[i] += ga[2] + gb[2];
  }
}

/* Forces of the elements anchored in row j (padded row start b) at patch columns
 * p0 <= i < p1. */
static inline __attribute__((always_inline)) void LatticeRow(const ClothLattice *L, PetscInt b, PetscInt p0, PetscInt p1)
{
  const PetscInt   W = L->W, ld = L->ld;
  const PetscReal *restrict X = L->x[0] + b, *restrict Y = L->x[1] + b, *restrict Z = L->x[2] + b;
  PetscReal *restrict       FX = L->f[0] + b, *restrict FY = L->f[1] + b, *restrict FZ = L->f[2] + b;
  PetscReal *restrict       T[12];

  for (PetscInt k = 0; k < 12; k++) T[k] = L->tmp + k * (ld + 2) + 2; /* T[k][-2] .. T[k][W + 1] */

  if (L->cls[LAT_STRETCH_WARP]) { /* f_a += t e, f_b -= t e, b = a + 1: two passes */
    PetscReal *restrict K = L->krow, *restrict M = L->krow + W, *restrict KL = L->krow + 2 * W;
    PetscReal *restrict GX = T[0], *restrict GY = T[1], *restrict GZ = T[2];
    LatticeCoefficients(L, LAT_STRETCH_WARP, b, p0, p1, K, M, KL);
#pragma GCC ivdep
    for (PetscInt i = p0; i < p1; i++) {
      const PetscReal ex = X[i + 1] - X[i], ey = Y[i + 1] - Y[i], ez = Z[i + 1] - Z[i];
      const PetscReal l2 = M[i] * (ex * ex + ey * ey + ez * ez) + (1 - M[i]), t = K[i] - KL[i] / PetscSqrtReal(l2);
      GX[i] = t * ex;
      GY[i] = t * ey;
      GZ[i] = t * ez;
    }
    GX[p0 - 1] = GY[p0 - 1] = GZ[p0 - 1] = GX[p1] = GY[p1] = GZ[p1] = 0;
#pragma GCC ivdep
    for (PetscInt i = p0; i <= p1; i++) {
      FX[i] += GX[i] - GX[i - 1];
      FY[i] += GY[i] - GY[i - 1];
      FZ[i] += GZ[i] - GZ[i - 1];
    }
  }
  if (L->cls[LAT_STRETCH_WEFT]) {
    PetscReal *restrict K = L->krow, *restrict M = L->krow + W, *restrict KL = L->krow + 2 * W;
    LatticeCoefficients(L, LAT_STRETCH_WEFT, b, p0, p1, K, M, KL);
#pragma GCC ivdep
    for (PetscInt i = p0; i < p1; i++) {
      const PetscReal ex = X[i + ld] - X[i], ey = Y[i + ld] - Y[i], ez = Z[i + ld] - Z[i];
      const PetscReal l2 = M[i] * (ex * ex + ey * ey + ez * ez) + (1 - M[i]), t = K[i] - KL[i] / PetscSqrtReal(l2);
      FX[i] += t * ex;
      FY[i] += t * ey;
      FZ[i] += t * ez;
      FX[i + ld] -= t * ex;
      FY[i + ld] -= t * ey;
      FZ[i + ld] -= t * ez;
    }
  }
  if (L->cls[LAT_SHEAR]) { /* KernelShearCellCoefficients and KernelShearCellGradient; corners x0 = (i,j), x1 = (i+1,j), x2 = (i,j+1), x3 = (i+1,j+1) */
    PetscReal *restrict K = L->krow, *restrict M = L->krow + W;
    PetscReal *restrict g0x = T[0], *restrict g0y = T[1], *restrict g0z = T[2], *restrict g1x = T[3], *restrict g1y = T[4], *restrict g1z = T[5];
    PetscReal *restrict g2x = T[6], *restrict g2y = T[7], *restrict g2z = T[8], *restrict g3x = T[9], *restrict g3y = T[10], *restrict g3z = T[11];
    LatticeCoefficients(L, LAT_SHEAR, b, p0, p1, K, M, NULL);
#pragma GCC ivdep
    for (PetscInt i = p0; i < p1; i++) {
      const PetscReal kappa = K[i], m = M[i];
      const PetscReal Ax = X[i + 1] - X[i], Ay = Y[i + 1] - Y[i], Az = Z[i + 1] - Z[i];                          /* x1 - x0 */
      const PetscReal Bx = X[i + ld] - X[i], By = Y[i + ld] - Y[i], Bz = Z[i + ld] - Z[i];                       /* x2 - x0 */
      const PetscReal Cx = X[i + ld + 1] - X[i + ld], Cy = Y[i + ld + 1] - Y[i + ld], Cz = Z[i + ld + 1] - Z[i + ld]; /* x3 - x2 */
      const PetscReal Dx = X[i + ld + 1] - X[i + 1], Dy = Y[i + ld + 1] - Y[i + 1], Dz = Z[i + ld + 1] - Z[i + 1];    /* x3 - x1 */
      const PetscReal uA = m * (Ax * Ax + Ay * Ay + Az * Az) + (1 - m), uB = m * (Bx * Bx + By * By + Bz * Bz) + (1 - m);
      const PetscReal uC = m * (Cx * Cx + Cy * Cy + Cz * Cz) + (1 - m), uD = m * (Dx * Dx + Dy * Dy + Dz * Dz) + (1 - m);
      const PetscReal sAB = m * (Ax * Bx + Ay * By + Az * Bz), sAD = m * (Ax * Dx + Ay * Dy + Az * Dz);
      const PetscReal sCB = m * (Cx * Bx + Cy * By + Cz * Bz), sDC = m * (Dx * Cx + Dy * Cy + Dz * Cz);
      PetscReal       q0, q1, q2, q3, w4, w5, w6, w7, w0, w1, w2, w3;
      LatticeShearCorner(uA, uB, sAB, kappa, &q0, &w4);
      LatticeShearCorner(uA, uD, -sAD, kappa, &q1, &w5);
      LatticeShearCorner(uC, uB, -sCB, kappa, &q2, &w6);
      LatticeShearCorner(uD, uC, sDC, kappa, &q3, &w7);
      w0 = q0 * uB + q1 * uD;
      w1 = q0 * uA + q2 * uC;
      w2 = q3 * uD + q2 * uB;
      w3 = q1 * uA + q3 * uC;
      {
        const PetscReal gA = w0 * Ax + w4 * Bx - w5 * Dx, gB = w1 * Bx + w4 * Ax - w6 * Cx, gC = w2 * Cx + w7 * Dx - w6 * Bx, gD = w3 * Dx - w5 * Ax + w7 * Cx;
        g0x[i] = -gA - gB, g1x[i] = gA - gD, g2x[i] = gB - gC, g3x[i] = gC + gD;
      }
      {
        const PetscReal gA = w0 * Ay + w4 * By - w5 * Dy, gB = w1 * By + w4 * Ay - w6 * Cy, gC = w2 * Cy + w7 * Dy - w6 * By, gD = w3 * Dy - w5 * Ay + w7 * Cy;
        g0y[i] = -gA - gB, g1y[i] = gA - gD, g2y[i] = gB - gC, g3y[i] = gC + gD;
      }
      {
        const PetscReal gA = w0 * Az + w4 * Bz - w5 * Dz, gB = w1 * Bz + w4 * Az - w6 * Cz, gC = w2 * Cz + w7 * Dz - w6 * Bz, gD = w3 * Dz - w5 * Az + w7 * Cz;
        g0z[i] = -gA - gB, g1z[i] = gA - gD, g2z[i] = gB - gC, g3z[i] = gC + gD;
      }
    }
    for (PetscInt k = 0; k < 12; k++) T[k][p0 - 1] = T[k][p1] = 0;
    /* f(i,j) -= g_0(i) + g_1(i-1), f(i,j+1) -= g_2(i) + g_3(i-1) */
#pragma GCC ivdep
    for (PetscInt i = p0; i <= p1; i++) {
      FX[i] -= T[0][i] + T[3][i - 1];
      FY[i] -= T[1][i] + T[4][i - 1];
      FZ[i] -= T[2][i] + T[5][i - 1];
      FX[i + ld] -= T[6][i] + T[9][i - 1];
      FY[i + ld] -= T[7][i] + T[10][i - 1];
      FZ[i + ld] -= T[8][i] + T[11][i - 1];
    }
  }
  if (L->cls[LAT_BEND_WARP]) { /* a = i-1, b = i+1 of the same row: gradients first, then the sums */
    PetscReal *restrict K = L->krow, *restrict M = L->krow + W;
    LatticeCoefficients(L, LAT_BEND_WARP, b, p0, p1, K, M, NULL);
#pragma GCC ivdep
    for (PetscInt i = p0; i < p1; i++) {
      const PetscReal m     = M[i];
      const PetscReal e1[3] = {X[i - 1] - X[i], Y[i - 1] - Y[i], Z[i - 1] - Z[i]}, e2[3] = {X[i + 1] - X[i], Y[i + 1] - Y[i], Z[i + 1] - Z[i]};
      PetscReal       ga[3], gb[3];
      LatticeBend(m, K[i], e1, e2, ga, gb);
      for (PetscInt d = 0; d < 3; d++) {
        T[d][i]     = ga[d];
        T[3 + d][i] = gb[d];
      }
    }
    for (PetscInt k = 0; k < 6; k++) T[k][p0 - 2] = T[k][p0 - 1] = T[k][p1] = T[k][p1 + 1] = 0;
    /* f(i) += g_a(i) + g_b(i) - g_a(i+1) - g_b(i-1), i = -1 .. W */
#pragma GCC ivdep
    for (PetscInt i = p0 - 1; i <= p1; i++) {
      FX[i] += T[0][i] + T[3][i] - T[0][i + 1] - T[3][i - 1];
      FY[i] += T[1][i] + T[4][i] - T[1][i + 1] - T[4][i - 1];
      FZ[i] += T[2][i] + T[5][i] - T[2][i + 1] - T[5][i - 1];
    }
  }
  if (L->cls[LAT_BEND_WEFT]) LatticeBendRow(L, LAT_BEND_WEFT, b, p0, p1, -ld, ld);
  if (L->cls[LAT_BEND_DIAG]) LatticeBendRow(L, LAT_BEND_DIAG, b, p0, p1, -ld - 1, ld + 1);
  if (L->cls[LAT_BEND_ANTI]) LatticeBendRow(L, LAT_BEND_ANTI, b, p0, p1, ld - 1, -ld + 1);
}

/* Strips of LATTICE_STRIP lattice columns, bounded at multiples of LATTICE_STRIP in
 * the whole lattice (not the patch: a particle's force is summed in the same order on
 * every partition), each swept row by row: the three rows of positions and forces an
 * anchor row touches stay in the first-level cache as the sweep moves down. */
#define LATTICE_STRIP 128

/* All strips, with the instruction set chosen when the program starts (x86-64:
 * AVX-512, AVX2 with FMA, or the baseline SSE2): the build needs no -march, and runs on
 * any x86-64 processor at its own speed. The rounding may differ between these (fused
 * multiply-adds), so results agree across machines to round-off; on one machine every
 * rank takes the same version. */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__INTEL_COMPILER) && !defined(DRAPE_NO_TARGET_CLONES)
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#endif
static void
LatticeForces(const ClothLattice *L)
{
  for (PetscInt p0 = 0; p0 < L->W;) {
    const PetscInt p1 = PetscMin(L->W, p0 + LATTICE_STRIP - (L->i0 + p0) % LATTICE_STRIP);
    for (PetscInt j = 0; j < L->H; j++) LatticeRow(L, (j + 1) * L->ld + 1, p0, p1);
    p0 = p1;
  }
}

PetscErrorCode ClothLatticeComputeForces(Cloth c, const PetscScalar *xl)
{
  ClothLattice *L = c->lattice;

  PetscFunctionBeginUser;
  for (PetscInt l = 0; l < c->nlocal; l++) {
    const PetscInt s = L->slot[l];
    L->x[0][s]       = xl[3 * l];
    L->x[1][s]       = xl[3 * l + 1];
    L->x[2][s]       = xl[3 * l + 2];
  }
  for (PetscInt d = 0; d < 3; d++) PetscCall(PetscArrayzero(L->f[d], L->nslot));
  LatticeForces(L);
  PetscFunctionReturn(0);
}

PetscErrorCode ClothLatticeGetForces(Cloth c, const PetscInt **slot, const PetscReal *f[3])
{
  PetscFunctionBeginUser;
  *slot = c->lattice->slot;
  for (PetscInt d = 0; d < 3; d++) f[d] = c->lattice->f[d];
  PetscFunctionReturn(0);
}

/* The patch and the elements' classes, from the element lists: an element of the
 * lists is present in the patch, at its anchor, with its class. */
PetscErrorCode ClothLatticeSetUp(Cloth c)
{
  const char *const  kernels[] = {"lattice", "elements"};
  PetscInt           kernel = 0, imin = PETSC_MAX_INT, imax = -1, jmin = PETSC_MAX_INT, jmax = -1;
  ClothLattice      *L;
  const ClothElements *st = &c->stretch_el, *sh = &c->shear_el, *be = &c->bend_el;

  PetscFunctionBeginUser;
  PetscOptionsBegin(c->comm, NULL, "Explicit force kernel", "ClothLatticeSetUp");
  PetscCall(PetscOptionsEList("-cloth_force_kernel", "Force loop of the explicit schemes: lattice (structured, vectorised) or elements (the element lists; always used with -cloth_bend_table or -cloth_bend_hysteresis)", "ClothLatticeSetUp", kernels, 2, kernels[0], &kernel, NULL));
  PetscOptionsEnd();
  if (kernel == 1 || be->has_law || c->friction_el.n > 0 || c->nlocal == 0) PetscFunctionReturn(0);
  for (PetscInt l = 0; l < c->nlocal; l++) {
    const PetscInt i = c->natural[l] % c->Mx, j = c->natural[l] / c->Mx;
    imin = PetscMin(imin, i), imax = PetscMax(imax, i), jmin = PetscMin(jmin, j), jmax = PetscMax(jmax, j);
  }
  PetscCall(PetscNew(&L));
  L->i0    = imin;
  L->j0    = jmin;
  L->W     = imax - imin + 1;
  L->H     = jmax - jmin + 1;
  L->ld    = L->W + 2;
  L->nslot = L->ld * (L->H + 2);
  PetscCall(PetscMalloc1(c->nlocal, &L->slot));
  for (PetscInt l = 0; l < c->nlocal; l++) L->slot[l] = (c->natural[l] / c->Mx - L->j0 + 1) * L->ld + (c->natural[l] % c->Mx - L->i0 + 1);
  for (PetscInt d = 0; d < 3; d++) {
    PetscCall(PetscCalloc1(L->nslot, &L->x[d]));
    PetscCall(PetscMalloc1(L->nslot, &L->f[d]));
  }
  PetscCall(PetscMalloc1(12 * (L->ld + 2), &L->tmp));
  PetscCall(PetscMalloc1(3 * L->W, &L->krow));
#define KIND_ALLOC(kind) \
  do { \
    if (!L->cls[kind]) PetscCall(PetscCalloc1(L->nslot, &L->cls[kind])); \
  } while (0)
  /* stretch: (a, b) with b the next particle along the warp or the weft */
  for (PetscInt e = 0; e < st->n; e++) {
    const PetscInt a = st->p[2 * e], bb = st->p[2 * e + 1], kind = c->natural[bb] - c->natural[a] == 1 ? LAT_STRETCH_WARP : LAT_STRETCH_WEFT;
    KIND_ALLOC(kind);
    L->cls[kind][L->slot[a]]                 = (unsigned char) (st->cls[e] + 1);
    L->coef[kind][st->cls[e] + 1]            = st->coef_tab[st->cls[e]];
    L->coef_rest[kind][st->cls[e] + 1]       = st->coef_tab[st->cls[e]] * st->rest_tab[st->cls[e]];
  }
  /* shear: cells of four corners, the vertex of the first being (i, j) */
  for (PetscInt e = 0; e < sh->n; e += 4) {
    KIND_ALLOC(LAT_SHEAR);
    L->cls[LAT_SHEAR][L->slot[sh->p[3 * e + 2]]] = (unsigned char) (sh->cls[e] + 1);
    L->coef[LAT_SHEAR][sh->cls[e] + 1]           = sh->coef_tab[sh->cls[e]];
  }
  /* bending: (a, b, vertex v); the kind from a's place relative to v */
  for (PetscInt e = 0; e < be->n; e++) {
    const PetscInt a = be->p[3 * e], v = be->p[3 * e + 2];
    const PetscInt di = c->natural[a] % c->Mx - c->natural[v] % c->Mx, dj = c->natural[a] / c->Mx - c->natural[v] / c->Mx;
    PetscInt       kind;
    if (dj == 0) kind = LAT_BEND_WARP;
    else if (di == 0) kind = LAT_BEND_WEFT;
    else if (dj == -1) kind = LAT_BEND_DIAG;
    else kind = LAT_BEND_ANTI;
    KIND_ALLOC(kind);
    L->cls[kind][L->slot[v]]      = (unsigned char) (be->cls[e] + 1);
    L->coef[kind][be->cls[e] + 1] = be->coef_tab[be->cls[e]];
  }
#undef KIND_ALLOC
  c->lattice = L;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothLatticeDestroy(Cloth c)
{
  ClothLattice *L = c->lattice;

  PetscFunctionBeginUser;
  if (!L) PetscFunctionReturn(0);
  PetscCall(PetscFree(L->slot));
  for (PetscInt d = 0; d < 3; d++) {
    PetscCall(PetscFree(L->x[d]));
    PetscCall(PetscFree(L->f[d]));
  }
  for (PetscInt k = 0; k < LAT_KINDS; k++) PetscCall(PetscFree(L->cls[k]));
  PetscCall(PetscFree(L->tmp));
  PetscCall(PetscFree(L->krow));
  PetscCall(PetscFree(c->lattice));
  PetscFunctionReturn(0);
}
