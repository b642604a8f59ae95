/* The candidates' distances for the near list, in lanes (proximity.h): the
 * instruction set chosen when the program starts (x86-64: AVX-512, AVX2, or the
 * baseline SSE2), as the lattice's force sweep. Every version gives the bits of
 * PairClosest's distance: the same operations in the same order, no fused
 * multiply-adds (-ffp-contract=off; the Makefile also lets GCC compute both sides
 * of a select, -fno-trapping-math). */
#include "selfcontactimpl.h"
#include <drape.h>

DRAPE_TARGET_CLONES_FLATTEN
void SelfNearDistances(const SelfSet *s, PetscInt kind, PetscInt n, const PetscReal *X, PetscReal *dist)
{
  for (PetscInt k0 = 0; k0 < n; k0 += SELF_LANES) {
    PetscReal      P[4][3][SELF_LANES], d[SELF_LANES];
    const PetscInt m = PetscMin(SELF_LANES, n - k0);
    for (int l = 0; l < m; l++) {
      PetscInt p[4];
      PairParticles(s, kind, k0 + l, p);
      for (int i = 0; i < 4; i++)
        for (int c = 0; c < 3; c++) P[i][c][l] = X[3 * p[i] + c];
    }
    if (kind == 0)
      PointTriangleDistanceLanes((int) m, P, d);
    else
      SegmentSegmentDistanceLanes((int) m, P, d);
    for (int l = 0; l < m; l++) dist[k0 + l] = d[l];
  }
}

/* The motion of particles [0, n) since the lists were made, in one pass (the
 * filter's test of its lists at every step): list[6 j + d] and list[6 j + 3 + d] the
 * largest x_j - hi and lo - x_j in direction d (x_0 = x0, x_1 = x1; when lo is
 * given), near[6 j + d] and near[6 j + 3 + d] the largest a_j and -a_j of a = (x0 -
 * xr, x1 - xr, x1 - x0) (when xr is given), and *zero the sum of 0 * every
 * coordinate (NaN once one is not finite). Lanes of 8 particles' 24 coordinates,
 * each lane keeping its own maxima (exact: a maximum is the same in any order). */
#define MOTION_LANES 24
DRAPE_TARGET_CLONES
void SelfMotionMaxima(PetscInt n, const PetscReal *x0, const PetscReal *x1, const PetscReal *lo, const PetscReal *hi, const PetscReal *xr, PetscReal list[12], PetscReal near[18], PetscReal *zero)
{
  PetscReal       m[10][MOTION_LANES], z[MOTION_LANES];
  const PetscInt  N    = 3 * n;
  const PetscReal none = -PETSC_MAX_REAL;

  for (int c = 0; c < 10; c++)
    for (int l = 0; l < MOTION_LANES; l++) m[c][l] = none;
  for (int l = 0; l < MOTION_LANES; l++) z[l] = 0;
  for (PetscInt i0 = 0; i0 < N; i0 += MOTION_LANES) {
    const int L = (int) PetscMin(MOTION_LANES, N - i0); /* (a multiple of 3) */
    for (int l = 0; l < L; l++) z[l] += 0 * x0[i0 + l] + 0 * x1[i0 + l];
    if (lo)
      for (int l = 0; l < L; l++) {
        const PetscReal a = x0[i0 + l] - hi[i0 + l], b = lo[i0 + l] - x0[i0 + l], c = x1[i0 + l] - hi[i0 + l], d = lo[i0 + l] - x1[i0 + l];
        m[0][l] = a > m[0][l] ? a : m[0][l];
        m[1][l] = b > m[1][l] ? b : m[1][l];
        m[2][l] = c > m[2][l] ? c : m[2][l];
        m[3][l] = d > m[3][l] ? d : m[3][l];
      }
    if (xr)
      for (int l = 0; l < L; l++) {
        const PetscReal a = x0[i0 + l] - xr[i0 + l], b = x1[i0 + l] - xr[i0 + l], c = x1[i0 + l] - x0[i0 + l];
        m[4][l] = a > m[4][l] ? a : m[4][l];
        m[5][l] = -a > m[5][l] ? -a : m[5][l];
        m[6][l] = b > m[6][l] ? b : m[6][l];
        m[7][l] = -b > m[7][l] ? -b : m[7][l];
        m[8][l] = c > m[8][l] ? c : m[8][l];
        m[9][l] = -c > m[9][l] ? -c : m[9][l];
      }
  }
  for (int i = 0; i < 12; i++) list[i] = none;
  for (int i = 0; i < 18; i++) near[i] = none;
  *zero = 0;
  for (int l = 0; l < MOTION_LANES; l++) {
    const int d = l % 3;
    *zero += z[l];
    for (int j = 0; j < 2; j++) {
      list[6 * j + d]     = PetscMax(list[6 * j + d], m[2 * j][l]);
      list[6 * j + 3 + d] = PetscMax(list[6 * j + 3 + d], m[2 * j + 1][l]);
    }
    for (int j = 0; j < 3; j++) {
      near[6 * j + d]     = PetscMax(near[6 * j + d], m[4 + 2 * j][l]);
      near[6 * j + 3 + d] = PetscMax(near[6 * j + 3 + d], m[5 + 2 * j][l]);
    }
  }
}
