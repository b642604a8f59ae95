/* The explicit schemes' force kernel on the lattice (-cloth_force_kernel lattice).
 *
 * The element lists (clothimpl.h) say which elements a rank computes; this kernel
 * computes the same elements, but reads them from a rectangular patch of the
 * lattice: the bounding box of the rank's ghosts and active owned particles (the
 * inactive ones, in no element, may lie anywhere: LatticeInPatch), with a frame of
 * one empty slot around it. An element is named by its kind and the slot of
 * its centre (or first corner), and its particles sit at fixed offsets from it: the
 * loops below run along a lattice row with unit stride and no index arrays, and the
 * compiler vectorises them (sqrt, division, and an asin of our own: KernelAsin).
 * Which elements are present, and their coefficients, is one byte per kind and slot:
 * the element's class in the list (0: absent). Absent elements are computed on
 * harmless numbers and multiplied by a coefficient 0: they add exact zeros.
 *
 * One sweep down the patch does everything: before the elements centred on row j
 * are computed, row j + 1's positions are copied from the caller's array (x, y, z
 * apart: structure of arrays) into a ring of four rows; after them, row j - 1's
 * forces are complete and go out at once (as forces, or as accelerations with
 * gravity and damping). Positions and forces of the whole patch are never held: the
 * step streams the caller's arrays once, and the rows it works on stay in the cache.
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

/* Local particles l, ..., l + n - 1 at patch columns p, ..., p + n - 1 of one row. */
typedef struct {
  PetscInt p, n, l;
} LatticeRun;

#define LATTICE_RING 4 /* rows of positions and forces held: j - 1, j, j + 1 and one free */

struct _n_ClothLattice {
  PetscInt       i0, j0, W, H, ld; /* patch origin and size in the lattice; padded row length W + 2 */
  PetscInt      *row_run;          /* runs of patch row r: row_run[r] .. row_run[r + 1] - 1          */
  LatticeRun    *run;              /* local particles by patch row, owned and ghost runs apart       */
  PetscInt       nowned;           /* local particles below nowned are owned                         */
  PetscInt       nout, *out;       /* owned particles outside the patch (inactive): no force          */
  VecScatter     ghosts;           /* owners -> G: the ghosts' positions, local particles nowned, ... */
  Vec            G;
  PetscReal     *x[3], *f[3];    /* rings of LATTICE_RING padded rows                              */
  unsigned char *cls[LAT_KINDS]; /* class + 1 of the element anchored at each padded slot, 0: none; NULL: no element of the kind */
  PetscReal      coef[LAT_KINDS][CLOTH_ELEMENT_CLASSES + 1];
  PetscReal      coef_rest[2][CLOTH_ELEMENT_CLASSES + 1]; /* stretch: k L */
  PetscReal      rest[2][CLOTH_ELEMENT_CLASSES + 1];      /* stretch: L */
  PetscReal     *tmp;                                     /* 12 rows of W + 4: one row's element gradients */
  PetscReal     *krow;                                    /* each kind's row of coefficients, mask, k L (3 W a kind) */
  PetscBool     *repeat;                                  /* [kind H + r]: patch row r's classes of the kind are row r - 1's */
};

/* What a sweep reads and where its forces go (owned particles): out = F (v ==
 * NULL); or the acceleration a = F/m + g - c v, 0 on pinned particles: out = a, or,
 * with kick != 0, the symplectic update in place v += kick a, then x += drift v. */
typedef struct {
  const PetscScalar *xo, *xg, *v; /* owned positions, ghosts' (local particle nowned + g at xg + 3 g) */
  const PetscReal   *mass, *gravity;
  const PetscBool   *pinned;
  PetscReal          damping, kick, drift;
  PetscScalar       *out, *x;
} LatticeSweep;

/* A bending triple's gradient with respect to x_a and x_b (x_c's is minus their sum)
 * from its arms e1 = x_a - x_c, e2 = x_b - x_c, by the general kernels (kernels.h,
 * linear law). m: 1 present, 0 absent; an absent one gets the arms of a right angle
 * (no division by zero) and kappa 0. */
static inline __attribute__((always_inline)) void LatticeBend(PetscReal m, PetscReal kappa, const PetscReal e1[3], const PetscReal e2[3], PetscReal ga[3], PetscReal gb[3])
{
  const PetscReal o[3] = {0, 0, 0}, a[3] = {m * e1[0] + (1 - m), m * e1[1], m * e1[2]}, bb[3] = {m * e2[0], m * e2[1] + (1 - m), m * e2[2]};
  PetscReal       w[3], g[9];

  KernelAngleCoefficients(PETSC_TRUE, a, bb, o, kappa, NULL, w);
  KernelAngleGradientFromCoefficients(w, a, bb, o, g);
  for (PetscInt d = 0; d < 3; d++) {
    ga[d] = g[d];
    gb[d] = g[3 + d];
  }
}

/* The coefficients of row b's elements of one kind, K (and for stretch k L, KL), and
 * the mask M (1: present, 0: absent), in a scalar pass: the vector loops then read
 * unit-stride rows, no table and no comparison. An absent element computes on
 * u = M u + (1 - M) = 1, s = M s = 0 (no division by zero) with coefficient 0. Each
 * kind has its own rows (LatticeKindRow), made again only where the row's classes
 * differ from the row above's: a sweep goes down the rows in order, so they hold the
 * row above's, and most rows of a cloth repeat it (this pass took 8 % of symplectic
 * Euler's step at 256^2 when it was made for every row and kind). */
static inline __attribute__((always_inline)) void LatticeCoefficients(const ClothLattice *L, PetscInt kind, PetscInt b, PetscReal *restrict K, PetscReal *restrict M, PetscReal *restrict KL)
{
  const unsigned char *restrict cls = L->cls[kind] + b;
  const PetscReal *restrict tab = L->coef[kind], *restrict tab_rest = L->coef_rest[kind < 2 ? kind : 0];
  const PetscInt W = L->W, r = b / L->ld - 1;

  if (r > 0 && L->repeat[kind * L->H + r]) return;
  for (PetscInt i = 0; i < W; i++) {
    const int c = cls[i];
    K[i]        = tab[c];
    M[i]        = c ? 1.0 : 0.0;
  }
  if (KL)
    for (PetscInt i = 0; i < W; i++) {
      const int c = cls[i];
      KL[i]       = tab_rest[c];
    }
}

/* Kind `kind`'s rows of coefficients K, mask M and k L (LatticeCoefficients). */
static inline PetscReal *LatticeKindRow(const ClothLattice *L, PetscInt kind) { return L->krow + 3 * L->W * kind; }

/* Three rows of a ring: -1, 0, +1 relative to the anchor row, each component apart. */
typedef struct {
  PetscReal *r[3][3]; /* [row][component] */
} LatticeRows;

/* A triple of kind `kind` along every anchor of row j: a in row ra at column offset
 * oa, b in row rb at offset ob (rows -1, 0, +1 as 0, 1, 2), the vertex in row j.
 * Each iteration writes three particles of three different rows, so the iterations
 * are independent. */
static inline __attribute__((always_inline)) void LatticeBendRow(const ClothLattice *L, PetscInt kind, PetscInt b, const LatticeRows *X, const LatticeRows *F, PetscInt ra, PetscInt oa, PetscInt rb, PetscInt ob)
{
  const PetscReal *restrict X0 = X->r[1][0], *restrict Y0 = X->r[1][1], *restrict Z0 = X->r[1][2];
  const PetscReal *restrict XA = X->r[ra][0] + oa, *restrict YA = X->r[ra][1] + oa, *restrict ZA = X->r[ra][2] + oa;
  const PetscReal *restrict XB = X->r[rb][0] + ob, *restrict YB = X->r[rb][1] + ob, *restrict ZB = X->r[rb][2] + ob;
  PetscReal *restrict FX0 = F->r[1][0], *restrict FY0 = F->r[1][1], *restrict FZ0 = F->r[1][2];
  PetscReal *restrict FXA = F->r[ra][0] + oa, *restrict FYA = F->r[ra][1] + oa, *restrict FZA = F->r[ra][2] + oa;
  PetscReal *restrict FXB = F->r[rb][0] + ob, *restrict FYB = F->r[rb][1] + ob, *restrict FZB = F->r[rb][2] + ob;
  PetscReal *restrict K = LatticeKindRow(L, kind), *restrict M = K + L->W;

  LatticeCoefficients(L, kind, b, K, M, NULL);
#pragma GCC ivdep
  for (PetscInt i = 0; i < L->W; i++) {
    const PetscReal e1[3] = {XA[i] - X0[i], YA[i] - Y0[i], ZA[i] - Z0[i]}, e2[3] = {XB[i] - X0[i], YB[i] - Y0[i], ZB[i] - Z0[i]};
    PetscReal       ga[3], gb[3];
    LatticeBend(M[i], K[i], e1, e2, ga, gb);
    FXA[i] -= ga[0];
    FYA[i] -= ga[1];
    FZA[i] -= ga[2];
    FXB[i] -= gb[0];
    FYB[i] -= gb[1];
    FZB[i] -= gb[2];
    FX0[i] += ga[0] + gb[0];
    FY0[i] += ga[1] + gb[1];
    FZ0[i] += ga[2] + gb[2];
  }
}

/* Forces of the elements anchored in row j (b: its first slot in the class arrays),
 * positions in the ring rows X, forces into the ring rows F. */
static inline __attribute__((always_inline)) void LatticeRow(const ClothLattice *L, PetscInt b, const LatticeRows *XR, const LatticeRows *FR)
{
  const PetscInt W = L->W, ld = L->ld, p0 = 0, p1 = W;
  const PetscReal *restrict X = XR->r[1][0], *restrict Y = XR->r[1][1], *restrict Z = XR->r[1][2];
  const PetscReal *restrict XP = XR->r[2][0], *restrict YP = XR->r[2][1], *restrict ZP = XR->r[2][2];
  PetscReal *restrict FX = FR->r[1][0], *restrict FY = FR->r[1][1], *restrict FZ = FR->r[1][2];
  PetscReal *restrict FXP = FR->r[2][0], *restrict FYP = FR->r[2][1], *restrict FZP = FR->r[2][2];
  PetscReal *restrict T[12];

  for (PetscInt k = 0; k < 12; k++) T[k] = L->tmp + k * (ld + 2) + 2; /* T[k][-2] .. T[k][W + 1] */

  if (L->cls[LAT_STRETCH_WARP]) { /* f_a += t e, f_b -= t e, b = a + 1: two passes */
    PetscReal *restrict K = LatticeKindRow(L, LAT_STRETCH_WARP), *restrict M = K + W, *restrict KL = K + 2 * W;
    PetscReal *restrict GX = T[0], *restrict GY = T[1], *restrict GZ = T[2];
    LatticeCoefficients(L, LAT_STRETCH_WARP, b, K, M, KL);
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
    PetscReal *restrict K = LatticeKindRow(L, LAT_STRETCH_WEFT), *restrict M = K + W, *restrict KL = K + 2 * W;
    LatticeCoefficients(L, LAT_STRETCH_WEFT, b, K, M, KL);
#pragma GCC ivdep
    for (PetscInt i = p0; i < p1; i++) {
      const PetscReal ex = XP[i] - X[i], ey = YP[i] - Y[i], ez = ZP[i] - Z[i];
      const PetscReal l2 = M[i] * (ex * ex + ey * ey + ez * ez) + (1 - M[i]), t = K[i] - KL[i] / PetscSqrtReal(l2);
      FX[i] += t * ex;
      FY[i] += t * ey;
      FZ[i] += t * ez;
      FXP[i] -= t * ex;
      FYP[i] -= t * ey;
      FZP[i] -= t * ez;
    }
  }
  if (L->cls[LAT_SHEAR]) { /* KernelShearCellCoefficients and KernelShearCellGradient; corners x0 = (i,j), x1 = (i+1,j), x2 = (i,j+1), x3 = (i+1,j+1) */
    PetscReal *restrict K = LatticeKindRow(L, LAT_SHEAR), *restrict M = K + W;
    PetscReal *restrict g0x = T[0], *restrict g0y = T[1], *restrict g0z = T[2], *restrict g1x = T[3], *restrict g1y = T[4], *restrict g1z = T[5];
    PetscReal *restrict g2x = T[6], *restrict g2y = T[7], *restrict g2z = T[8], *restrict g3x = T[9], *restrict g3y = T[10], *restrict g3z = T[11];
    LatticeCoefficients(L, LAT_SHEAR, b, K, M, NULL);
#pragma GCC ivdep
    for (PetscInt i = p0; i < p1; i++) {
      /* an absent cell computes on the unit square (no division by zero), kappa 0 */
      const PetscReal m = M[i], n = 1 - m;
      const PetscReal x0[3] = {m * X[i], m * Y[i], m * Z[i]}, x1[3] = {m * X[i + 1] + n, m * Y[i + 1], m * Z[i + 1]};
      const PetscReal x2[3] = {m * XP[i], m * YP[i] + n, m * ZP[i]}, x3[3] = {m * XP[i + 1] + n, m * YP[i + 1] + n, m * ZP[i + 1]};
      PetscReal       w[8], g[12];
      KernelShearCellCoefficients(x0, x1, x2, x3, K[i], w);
      KernelShearCellGradient(w, x0, x1, x2, x3, g);
      g0x[i] = g[0], g0y[i] = g[1], g0z[i] = g[2], g1x[i] = g[3], g1y[i] = g[4], g1z[i] = g[5];
      g2x[i] = g[6], g2y[i] = g[7], g2z[i] = g[8], g3x[i] = g[9], g3y[i] = g[10], g3z[i] = g[11];
    }
    for (PetscInt k = 0; k < 12; k++) T[k][p0 - 1] = T[k][p1] = 0;
      /* f(i,j) -= g_0(i) + g_1(i-1), f(i,j+1) -= g_2(i) + g_3(i-1) */
#pragma GCC ivdep
    for (PetscInt i = p0; i <= p1; i++) {
      FX[i] -= T[0][i] + T[3][i - 1];
      FY[i] -= T[1][i] + T[4][i - 1];
      FZ[i] -= T[2][i] + T[5][i - 1];
      FXP[i] -= T[6][i] + T[9][i - 1];
      FYP[i] -= T[7][i] + T[10][i - 1];
      FZP[i] -= T[8][i] + T[11][i - 1];
    }
  }
  if (L->cls[LAT_BEND_WARP]) { /* a = i-1, b = i+1 of the same row: gradients first, then the sums */
    PetscReal *restrict K = LatticeKindRow(L, LAT_BEND_WARP), *restrict M = K + W;
    LatticeCoefficients(L, LAT_BEND_WARP, b, K, M, NULL);
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
  if (L->cls[LAT_BEND_WEFT]) LatticeBendRow(L, LAT_BEND_WEFT, b, XR, FR, 0, 0, 2, 0);
  if (L->cls[LAT_BEND_DIAG]) LatticeBendRow(L, LAT_BEND_DIAG, b, XR, FR, 0, -1, 2, 1);
  if (L->cls[LAT_BEND_ANTI]) LatticeBendRow(L, LAT_BEND_ANTI, b, XR, FR, 2, -1, 0, 1);
}

/* Row r of a ring (r = -1 .. H): its column -1 .. W. */
static inline PetscReal *LatticeRingRow(PetscReal *ring, PetscInt ld, PetscInt r) { return ring + ((r + 1) % LATTICE_RING) * ld + 1; }

static inline void LatticeRingRows(const ClothLattice *L, PetscReal *const ring[3], PetscInt j, LatticeRows *R)
{
  for (PetscInt q = 0; q < 3; q++)
    for (PetscInt d = 0; d < 3; d++) R->r[q][d] = LatticeRingRow(ring[d], L->ld, j - 1 + q);
}

/* Patch row r's positions into the ring, from the owned and the ghosts' arrays. */
static inline void LatticeLoadRow(const ClothLattice *L, const LatticeSweep *S, PetscInt r)
{
  PetscReal *restrict X = LatticeRingRow(L->x[0], L->ld, r), *restrict Y = LatticeRingRow(L->x[1], L->ld, r), *restrict Z = LatticeRingRow(L->x[2], L->ld, r);

  for (PetscInt q = L->row_run[r]; q < L->row_run[r + 1]; q++) {
    const LatticeRun R             = L->run[q];
    const PetscScalar *restrict xl = R.l < L->nowned ? S->xo + 3 * R.l : S->xg + 3 * (R.l - L->nowned);
    for (PetscInt k = 0; k < R.n; k++) {
      X[R.p + k] = xl[3 * k];
      Y[R.p + k] = xl[3 * k + 1];
      Z[R.p + k] = xl[3 * k + 2];
    }
  }
}

/* Patch row r's forces, now complete, out to the owned particles. */
static inline void LatticeStoreRow(const ClothLattice *L, const LatticeSweep *S, PetscInt r)
{
  const PetscReal *restrict FX = LatticeRingRow(L->f[0], L->ld, r), *restrict FY = LatticeRingRow(L->f[1], L->ld, r), *restrict FZ = LatticeRingRow(L->f[2], L->ld, r);

  for (PetscInt q = L->row_run[r]; q < L->row_run[r + 1]; q++) {
    const LatticeRun R        = L->run[q];
    PetscScalar *restrict out = S->out + 3 * R.l;
    if (R.l >= L->nowned) continue;
    if (!S->v) {
      for (PetscInt k = 0; k < R.n; k++) {
        out[3 * k]     = FX[R.p + k];
        out[3 * k + 1] = FY[R.p + k];
        out[3 * k + 2] = FZ[R.p + k];
      }
    } else if (!S->kick) {
      const PetscScalar *restrict v = S->v + 3 * R.l;
      const PetscReal *restrict m = S->mass + R.l, *g = S->gravity, cd = S->damping;
      const PetscBool *restrict pin = S->pinned + R.l;
      for (PetscInt k = 0; k < R.n; k++) {
        const PetscReal h = pin[k] ? 0 : 1; /* pinned: no acceleration */
        out[3 * k]        = h * (FX[R.p + k] / m[k] + g[0] - cd * v[3 * k]);
        out[3 * k + 1]    = h * (FY[R.p + k] / m[k] + g[1] - cd * v[3 * k + 1]);
        out[3 * k + 2]    = h * (FZ[R.p + k] / m[k] + g[2] - cd * v[3 * k + 2]);
      }
    } else { /* the row's positions were read into the ring when it was loaded: x may change now */
      PetscScalar *restrict v = out, *restrict x = S->x + 3 * R.l;
      const PetscReal *restrict m = S->mass + R.l, *g = S->gravity, cd = S->damping, kick = S->kick, drift = S->drift;
      const PetscBool *restrict pin = S->pinned + R.l;
      for (PetscInt k = 0; k < R.n; k++) {
        const PetscReal h = pin[k] ? 0 : kick;
        v[3 * k] += h * (FX[R.p + k] / m[k] + g[0] - cd * v[3 * k]);
        v[3 * k + 1] += h * (FY[R.p + k] / m[k] + g[1] - cd * v[3 * k + 1]);
        v[3 * k + 2] += h * (FZ[R.p + k] / m[k] + g[2] - cd * v[3 * k + 2]);
      }
      if (drift)
        for (PetscInt k = 0; k < 3 * R.n; k++) x[k] += drift * v[k];
    }
  }
}

/* The sweep, with the instruction set chosen when the program starts (x86-64:
 * AVX-512, AVX2 with FMA, or the baseline SSE2): the build needs no -march, and runs on
 * any x86-64 processor at its own speed. The rounding differs between these (the
 * Makefile compiles this file with -ffp-contract=fast: the AVX2 and AVX-512 versions
 * fuse multiply-adds, the baseline cannot), so results agree across machines to
 * round-off; on one machine every rank takes the same version. */
DRAPE_TARGET_CLONES_FLATTEN
static void LatticeSweepRows(const ClothLattice *L, const LatticeSweep *S)
{
  LatticeRows X, F;

  if (!L->H) return;
  for (PetscInt d = 0; d < 3; d++) {
    PetscArrayzero(LatticeRingRow(L->f[d], L->ld, -1) - 1, L->ld);
    PetscArrayzero(LatticeRingRow(L->f[d], L->ld, 0) - 1, L->ld);
  }
  LatticeLoadRow(L, S, 0);
  for (PetscInt j = 0; j < L->H; j++) {
    if (j + 1 < L->H) LatticeLoadRow(L, S, j + 1);
    for (PetscInt d = 0; d < 3; d++) PetscArrayzero(LatticeRingRow(L->f[d], L->ld, j + 1) - 1, L->ld);
    LatticeRingRows(L, L->x, j, &X);
    LatticeRingRows(L, L->f, j, &F);
    LatticeRow(L, (j + 1) * L->ld + 1, &X, &F);
    if (j > 0) LatticeStoreRow(L, S, j - 1);
  }
  LatticeStoreRow(L, S, L->H - 1);
}

/* The owned particles outside the patch: no force (inactive: in no element). In the
 * symplectic update they keep their velocity (zero, pinned) and position. */
static void LatticeZeroOutside(const ClothLattice *L, PetscScalar *out)
{
  for (PetscInt q = 0; q < L->nout; q++) PetscArrayzero(out + 3 * L->out[q], 3);
}

/* The ghosts' positions, from their owners (collective). */
static PetscErrorCode LatticeGhosts(Cloth c, const PetscScalar *x, const PetscScalar **xg)
{
  ClothLattice *L = c->lattice;

  PetscFunctionBeginUser;
  PetscCall(VecPlaceArray(c->Xg, x));
  PetscCall(VecScatterBegin(L->ghosts, c->Xg, L->G, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(L->ghosts, c->Xg, L->G, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecResetArray(c->Xg));
  PetscCall(VecGetArrayRead(L->G, xg));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothLatticeGetGhosts(Cloth c, const PetscScalar *x, const PetscScalar **xg)
{
  PetscFunctionBeginUser;
  PetscCall(LatticeGhosts(c, x, xg));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothLatticeRestoreGhosts(Cloth c, const PetscScalar **xg)
{
  PetscFunctionBeginUser;
  PetscCall(VecRestoreArrayRead(c->lattice->G, xg));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothLatticeComputeForce(Cloth c, const PetscScalar *x, PetscScalar *f)
{
  LatticeSweep S = {x, NULL, NULL, NULL, NULL, NULL, 0, 0, 0, f, NULL};

  PetscFunctionBeginUser;
  PetscCall(LatticeGhosts(c, x, &S.xg));
  LatticeSweepRows(c->lattice, &S);
  LatticeZeroOutside(c->lattice, f);
  PetscCall(VecRestoreArrayRead(c->lattice->G, &S.xg));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothLatticeComputeAcceleration(Cloth c, const PetscScalar *x, const PetscScalar *v, PetscScalar *a)
{
  LatticeSweep S = {x, NULL, v, c->mass, c->gravity, c->pinned, c->damping, 0, 0, a, NULL};

  PetscFunctionBeginUser;
  PetscCall(LatticeGhosts(c, x, &S.xg));
  LatticeSweepRows(c->lattice, &S);
  LatticeZeroOutside(c->lattice, a); /* pinned: no acceleration */
  PetscCall(VecRestoreArrayRead(c->lattice->G, &S.xg));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothLatticeKickDrift(Cloth c, PetscScalar *x, PetscScalar *v, PetscReal kick, PetscReal drift)
{
  LatticeSweep S = {x, NULL, v, c->mass, c->gravity, c->pinned, c->damping, kick, drift, v, x};

  PetscFunctionBeginUser;
  PetscCheck(kick != 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "ClothLatticeKickDrift needs a kick");
  PetscCall(LatticeGhosts(c, x, &S.xg));
  LatticeSweepRows(c->lattice, &S);
  PetscCall(VecRestoreArrayRead(c->lattice->G, &S.xg));
  PetscFunctionReturn(0);
}

/* The elastic energies of the elements this rank counts (those centred on an owned
 * particle: the element lists' `own`) and the largest strain of its stretch edges,
 * by a sweep like the forces' with the general kernels (kernels.h) element by
 * element: energies are wanted every few steps, not every step. */
PetscErrorCode ClothLatticeEnergies(Cloth c, const PetscScalar *x, PetscReal energy[3], PetscReal *strain)
{
  ClothLattice *L  = c->lattice;
  LatticeSweep  S  = {x, NULL, NULL, NULL, NULL, NULL, 0, 0, 0, NULL, NULL};
  PetscReal     st = 0, sh = 0, be = 0, smax = -1;

  PetscFunctionBeginUser;
  PetscCall(LatticeGhosts(c, x, &S.xg));
  if (L->H) LatticeLoadRow(L, &S, 0);
  for (PetscInt j = 0; j < L->H; j++) {
    LatticeRows X;
    if (j + 1 < L->H) LatticeLoadRow(L, &S, j + 1);
    LatticeRingRows(L, L->x, j, &X);
    for (PetscInt q = L->row_run[j]; q < L->row_run[j + 1]; q++) {
      const LatticeRun R = L->run[q];
      if (R.l >= L->nowned) continue;
      for (PetscInt i = R.p; i < R.p + R.n; i++) {
        const PetscInt b = (j + 1) * L->ld + 1 + i;
        PetscReal      p[3][3][3]; /* rows j-1, j, j+1; columns i-1, i, i+1 */
        for (PetscInt r = 0; r < 3; r++)
          for (PetscInt o = 0; o < 3; o++)
            for (PetscInt d = 0; d < 3; d++) p[r][o][d] = X.r[r][d][i - 1 + o];
        for (PetscInt kind = LAT_STRETCH_WARP; kind <= LAT_STRETCH_WEFT; kind++) {
          const PetscReal *e = kind == LAT_STRETCH_WARP ? p[1][2] : p[2][1];
          PetscInt         k;
          if (!L->cls[kind] || !(k = L->cls[kind][b])) continue;
          st += KernelStretch(p[1][1], e, L->coef[kind][k], L->rest[kind][k], NULL, NULL, PETSC_FALSE);
          smax = PetscMax(smax, PetscSqrtReal(PetscSqr(e[0] - p[1][1][0]) + PetscSqr(e[1] - p[1][1][1]) + PetscSqr(e[2] - p[1][1][2])) / L->rest[kind][k] - 1);
        }
        if (L->cls[LAT_SHEAR] && L->cls[LAT_SHEAR][b]) { /* the cell's corners as the element lists have them (a, b, vertex) */
          const PetscReal  kappa = L->coef[LAT_SHEAR][L->cls[LAT_SHEAR][b]];
          const PetscReal *x0 = p[1][1], *x1 = p[1][2], *x2 = p[2][1], *x3 = p[2][2];
          sh += KernelAngle(KERNEL_SHEAR, x1, x2, x0, kappa, NULL, NULL, NULL, PETSC_FALSE) + KernelAngle(KERNEL_SHEAR, x0, x3, x1, kappa, NULL, NULL, NULL, PETSC_FALSE);
          sh += KernelAngle(KERNEL_SHEAR, x3, x0, x2, kappa, NULL, NULL, NULL, PETSC_FALSE) + KernelAngle(KERNEL_SHEAR, x2, x1, x3, kappa, NULL, NULL, NULL, PETSC_FALSE);
        }
        for (PetscInt kind = LAT_BEND_WARP; kind <= LAT_BEND_ANTI; kind++) {
          static const PetscInt ab[4][4] = {{1, 0, 1, 2}, {0, 1, 2, 1}, {0, 0, 2, 2}, {2, 0, 0, 2}}; /* row and column of a, of b */
          const PetscInt       *o        = ab[kind - LAT_BEND_WARP];
          PetscInt              k;
          if (!L->cls[kind] || !(k = L->cls[kind][b])) continue;
          be += KernelAngle(KERNEL_BEND, p[o[0]][o[1]], p[o[2]][o[3]], p[1][1], L->coef[kind][k], NULL, NULL, NULL, PETSC_FALSE);
        }
      }
    }
  }
  PetscCall(VecRestoreArrayRead(L->G, &S.xg));
  energy[0] = st;
  energy[1] = sh;
  energy[2] = be;
  *strain   = smax;
  PetscFunctionReturn(0);
}

/* Is local particle l in the patch? The ghosts and the active owned particles are;
 * an inactive owned one is in no element, and may lie far from the others (a graph
 * partition shares the inactive particles out over the ranks). */
static inline PetscBool LatticeInPatch(Cloth c, PetscInt l) { return (PetscBool) (l >= c->nowned || c->active[l]); }

/* Padded slot of local particle l in the class arrays. */
static inline PetscInt Slot(Cloth c, const ClothLattice *L, PetscInt l) { return (c->natural[l] / c->Mx - L->j0 + 1) * L->ld + (c->natural[l] % c->Mx - L->i0 + 1); }

/* The runs of each patch row: local particles with consecutive local numbers at
 * consecutive columns (owned and ghost particles are numbered apart, each in
 * natural order: a DMDA block row is one owned run and a ghost run or two). Owned
 * particles outside the patch (inactive ones: LatticeInPatch) are listed apart. */
static PetscErrorCode LatticeBuildRuns(Cloth c, ClothLattice *L)
{
  PetscInt *order, nrun = 0;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc1(c->nlocal, &order));
  for (PetscInt l = 0; l < c->nlocal; l++) order[l] = l;
  /* local particles by natural number (the patch's row-major order), owned first at equal rows */
  {
    PetscInt *key;
    PetscCall(PetscMalloc1(c->nlocal, &key));
    for (PetscInt l = 0; l < c->nlocal; l++) key[l] = c->natural[l];
    PetscCall(PetscSortIntWithArray(c->nlocal, key, order));
    PetscCall(PetscFree(key));
  }
  PetscCall(PetscCalloc1(L->H + 1, &L->row_run));
  PetscCall(PetscMalloc1(c->nlocal, &L->run));
  PetscCall(PetscMalloc1(c->nlocal + 1, &L->out));
  for (PetscInt q = 0; q < c->nlocal; q++) {
    const PetscInt l = order[q], r = c->natural[l] / c->Mx - L->j0, p = c->natural[l] % c->Mx - L->i0;
    LatticeRun    *R = nrun ? &L->run[nrun - 1] : NULL;
    if (!LatticeInPatch(c, l)) { /* (the patch is the box of the others) */
      L->out[L->nout++] = l;
      continue;
    }
    if (R && q > 0 && c->natural[order[q - 1]] / c->Mx - L->j0 == r && R->l + R->n == l && R->p + R->n == p && (R->l < c->nowned) == (l < c->nowned)) {
      R->n++;
      continue;
    }
    L->run[nrun].p = p;
    L->run[nrun].n = 1;
    L->run[nrun].l = l;
    nrun++;
    L->row_run[r + 1]++;
  }
  for (PetscInt r = 0; r < L->H; r++) L->row_run[r + 1] += L->row_run[r];
  PetscCall(PetscRealloc(nrun * sizeof(LatticeRun) + 1, &L->run));
  PetscCall(PetscRealloc(L->nout * sizeof(PetscInt) + 1, &L->out));
  PetscCall(PetscFree(order));
  PetscFunctionReturn(0);
}

/* The patch and the elements' classes, from the element lists: an element of the
 * lists is present in the patch, at its anchor, with its class. */
PetscErrorCode ClothLatticeSetUp(Cloth c)
{
  const char *const    kernels[] = {"lattice", "elements"};
  PetscInt             kernel = 0, imin = PETSC_MAX_INT, imax = -1, jmin = PETSC_MAX_INT, jmax = -1;
  ClothLattice        *L;
  PetscInt             nslot;
  const ClothElements *st = &c->stretch_el, *sh = &c->shear_el, *be = &c->bend_el;

  PetscFunctionBeginUser;
  PetscOptionsBegin(c->comm, NULL, "Explicit force kernel", "ClothLatticeSetUp");
  PetscCall(PetscOptionsEList("-cloth_force_kernel", "Force loop of the explicit schemes: lattice (structured, vectorised) or elements (the element lists; always used with -cloth_bend_table or -cloth_bend_hysteresis)", "ClothLatticeSetUp", kernels,
                              2, kernels[0], &kernel, NULL));
  PetscOptionsEnd();
  /* the same on every rank: the ghosts' scatter is collective */
  if (kernel == 1 || be->has_law || c->hysteresis[0] > 0 || c->hysteresis[1] > 0) PetscFunctionReturn(0);
  for (PetscInt l = 0; l < c->nlocal; l++) {
    const PetscInt i = c->natural[l] % c->Mx, j = c->natural[l] / c->Mx;
    if (!LatticeInPatch(c, l)) continue;
    imin = PetscMin(imin, i), imax = PetscMax(imax, i), jmin = PetscMin(jmin, j), jmax = PetscMax(jmax, j);
  }
  if (imax < 0) imin = jmin = 0, jmax = -1; /* an empty patch */
  PetscCall(PetscNew(&L));
  L->i0     = imin;
  L->j0     = jmin;
  L->W      = imax - imin + 1;
  L->H      = jmax - jmin + 1;
  L->ld     = L->W + 2;
  L->nowned = c->nowned;
  nslot     = L->ld * (L->H + 2);
  for (PetscInt d = 0; d < 3; d++) {
    PetscCall(PetscCalloc1(LATTICE_RING * L->ld, &L->x[d]));
    PetscCall(PetscCalloc1(LATTICE_RING * L->ld, &L->f[d]));
  }
  PetscCall(LatticeBuildRuns(c, L));
  { /* the ghosts' positions alone: the owned ones are read where they are */
    IS from, to;
    PetscCall(ISCreateBlock(c->comm, 3, c->nlocal - c->nowned, c->global + c->nowned, PETSC_USE_POINTER, &from));
    PetscCall(ISCreateStride(PETSC_COMM_SELF, 3 * (c->nlocal - c->nowned), 0, 1, &to));
    PetscCall(VecCreateSeq(PETSC_COMM_SELF, 3 * (c->nlocal - c->nowned), &L->G));
    PetscCall(VecScatterCreate(c->Xg, from, L->G, to, &L->ghosts));
    PetscCall(ISDestroy(&from));
    PetscCall(ISDestroy(&to));
  }
  PetscCall(PetscMalloc1(12 * (L->ld + 2), &L->tmp));
  PetscCall(PetscMalloc1(3 * L->W * LAT_KINDS, &L->krow));
#define KIND_ALLOC(kind)                                                                                                                                                                                                                                 \
  do {                                                                                                                                                                                                                                                   \
    if (!L->cls[kind]) PetscCall(PetscCalloc1(nslot, &L->cls[kind]));                                                                                                                                                                                    \
  } while (0)
  /* stretch: (a, b) with b the next particle along the warp or the weft */
  for (PetscInt e = 0; e < st->n; e++) {
    const PetscInt a = st->p[2 * e], bb = st->p[2 * e + 1], kind = c->natural[bb] - c->natural[a] == 1 ? LAT_STRETCH_WARP : LAT_STRETCH_WEFT;
    KIND_ALLOC(kind);
    L->cls[kind][Slot(c, L, a)]        = (unsigned char) (st->cls[e] + 1);
    L->coef[kind][st->cls[e] + 1]      = st->coef_tab[st->cls[e]];
    L->coef_rest[kind][st->cls[e] + 1] = st->coef_tab[st->cls[e]] * st->rest_tab[st->cls[e]];
    L->rest[kind][st->cls[e] + 1]      = st->rest_tab[st->cls[e]];
  }
  /* shear: cells of four corners, the vertex of the first being (i, j) */
  for (PetscInt e = 0; e < sh->n; e += 4) {
    KIND_ALLOC(LAT_SHEAR);
    L->cls[LAT_SHEAR][Slot(c, L, sh->p[3 * e + 2])] = (unsigned char) (sh->cls[e] + 1);
    L->coef[LAT_SHEAR][sh->cls[e] + 1]              = sh->coef_tab[sh->cls[e]];
  }
  /* bending: (a, b, vertex v); the kind from a's place relative to v */
  for (PetscInt e = 0; e < be->n; e++) {
    const PetscInt a = be->p[3 * e], v = be->p[3 * e + 2];
    const PetscInt di = c->natural[a] % c->Mx - c->natural[v] % c->Mx, dj = c->natural[a] / c->Mx - c->natural[v] / c->Mx;
    PetscInt       kind;
    if (dj == 0)
      kind = LAT_BEND_WARP;
    else if (di == 0)
      kind = LAT_BEND_WEFT;
    else if (dj == -1)
      kind = LAT_BEND_DIAG;
    else
      kind = LAT_BEND_ANTI;
    KIND_ALLOC(kind);
    L->cls[kind][Slot(c, L, v)]   = (unsigned char) (be->cls[e] + 1);
    L->coef[kind][be->cls[e] + 1] = be->coef_tab[be->cls[e]];
  }
#undef KIND_ALLOC
  PetscCall(PetscCalloc1(LAT_KINDS * L->H, &L->repeat));
  for (PetscInt kind = 0; kind < LAT_KINDS; kind++)
    for (PetscInt r = 1; r < L->H && L->cls[kind]; r++) L->repeat[kind * L->H + r] = (PetscBool) !memcmp(L->cls[kind] + (r + 1) * L->ld + 1, L->cls[kind] + r * L->ld + 1, L->W);
  c->lattice = L;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothLatticeDestroy(Cloth c)
{
  ClothLattice *L = c->lattice;

  PetscFunctionBeginUser;
  if (!L) PetscFunctionReturn(0);
  PetscCall(PetscFree(L->row_run));
  PetscCall(PetscFree(L->run));
  PetscCall(PetscFree(L->out));
  PetscCall(VecScatterDestroy(&L->ghosts));
  PetscCall(VecDestroy(&L->G));
  for (PetscInt d = 0; d < 3; d++) {
    PetscCall(PetscFree(L->x[d]));
    PetscCall(PetscFree(L->f[d]));
  }
  for (PetscInt k = 0; k < LAT_KINDS; k++) PetscCall(PetscFree(L->cls[k]));
  PetscCall(PetscFree(L->tmp));
  PetscCall(PetscFree(L->krow));
  PetscCall(PetscFree(L->repeat));
  PetscCall(PetscFree(c->lattice));
  PetscFunctionReturn(0);
}
