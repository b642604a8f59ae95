/* The candidates' distances for the near list, in lanes (proximity.h): the
 * instruction set chosen when the program starts (x86-64: AVX-512, AVX2, or the
 * baseline SSE2), as the lattice's force sweep. Every version gives the bits of
 * PairClosest's distance: the same operations in the same order, no fused
 * multiply-adds (-ffp-contract=off; the Makefile also lets GCC compute both sides
 * of a select, -fno-trapping-math). */
#include "selfcontactimpl.h"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__INTEL_COMPILER) && !defined(DRAPE_NO_TARGET_CLONES)
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"), flatten))
#endif
void
SelfNearDistances(const SelfSet *s, PetscInt kind, PetscInt n, const PetscReal *X, PetscReal *dist)
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
