/* Tiles of the lattice: when a list still holds, patch by patch.
 *
 * A candidate list (a Verlet list) and a near list are kept while the motion since
 * they were made cannot have brought a pair they left out within reach. The test
 * of selfcontact.c allows one translation of the whole cloth: a sheet that falls or
 * slides as a whole keeps its lists. A cloth whose parts move against each other
 * (a skirt swinging about a held middle, folds sliding over a sphere) fails it as
 * soon as one part has moved a margin against another, though each part carries
 * its own pairs along with it. Here the lattice is cut into square tiles; a
 * primitive (vertex, edge, triangle: at most one cell) lies in the patch of its
 * lowest corner's tile, that tile and its three neighbours above it. Every pair is a
 * pair of patches (P, Q), P = Q included, and the list holds it if either
 *   - P and Q together pass the test of one translation (their own translation, no
 *     other patch's), or
 *   - P and Q are far apart: the boxes the list was made from, grown by how far
 *     every particle of each patch has left them since, are still further apart
 *     than the reach in some direction, so no pair of theirs can be close.
 * The first is the whole cloth's test restricted to P and Q, the second a bound on
 * the distance of every pair of the two; either gives every pair of (P, Q) the
 * guarantee the whole cloth's test gives every pair. So the lists hold the same
 * pairs: the passes act on the same pairs in the same order, only the lists are
 * made less often. Every quantity is a maximum over a tile's own particles, reduced
 * over the ranks, so every rank decides the same. (The candidate list is tested so
 * in the explicit schemes only: SetListValid says why.) */
#include "selfcontactimpl.h"

/* Tiles of at least this many particles a side, and at most about this many a side
 * of the lattice: the tests of every pair of patches cost (tiles)^2 / 2, below the
 * test of every particle up to 16^2 tiles. */
#define SELF_PATCH_TILE_MIN  8
#define SELF_PATCH_TILE_MOST 16

PetscErrorCode SelfPatchesSetUp(SelfContact sc, const PetscInt *natural)
{
  SelfPatches *T = &sc->patches;

  PetscFunctionBeginUser;
  T->side = PetscMax(SELF_PATCH_TILE_MIN, (PetscMax(sc->Mx, sc->My) + SELF_PATCH_TILE_MOST - 1) / SELF_PATCH_TILE_MOST);
  T->nx   = (sc->Mx + T->side - 1) / T->side;
  T->ny   = (sc->My + T->side - 1) / T->side;
  T->n    = T->nx * T->ny;
  PetscCall(PetscMalloc1(sc->nowned + 1, &T->of));
  for (PetscInt k = 0; k < sc->nowned; k++) T->of[k] = (natural[k] / sc->Mx) / T->side * T->nx + (natural[k] % sc->Mx) / T->side;
  PetscCall(PetscMalloc4(6 * T->n, &T->list_box, 6 * T->n, &T->near_box, 18 * T->n, &T->work, 18 * T->n, &T->ext));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfPatchesDestroy(SelfContact sc)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree(sc->patches.of));
  PetscCall(PetscFree4(sc->patches.list_box, sc->patches.near_box, sc->patches.work, sc->patches.ext));
  PetscFunctionReturn(0);
}

/* work (nv maxima per tile, over this rank's particles) reduced over the ranks,
 * then each patch's: the maxima over its tile and the three above it, into out. */
static PetscErrorCode PatchesReduce(SelfContact sc, PetscInt nv, PetscReal *work, PetscReal *out)
{
  const SelfPatches *T = &sc->patches;

  PetscFunctionBeginUser;
  if (sc->size > 1) PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, work, (PetscMPIInt) (nv * T->n), MPIU_REAL, MPIU_MAX, sc->comm));
  for (PetscInt tj = 0; tj < T->ny; tj++)
    for (PetscInt ti = 0; ti < T->nx; ti++) {
      PetscReal *o = out + nv * (tj * T->nx + ti);
      for (PetscInt c = 0; c < nv; c++) o[c] = work[nv * (tj * T->nx + ti) + c];
      for (PetscInt dj = 0; dj < 2; dj++)
        for (PetscInt di = 0; di < 2; di++) {
          const PetscReal *w = work + nv * ((tj + dj) * T->nx + ti + di);
          if ((!di && !dj) || ti + di >= T->nx || tj + dj >= T->ny) continue;
          for (PetscInt c = 0; c < nv; c++) o[c] = PetscMax(o[c], w[c]);
        }
    }
  PetscFunctionReturn(0);
}

/* Each patch's box (-lo, hi: 6 maxima) over the own particles' boxes lo .. hi into box. Collective. */
PetscErrorCode SelfPatchesBoxes(SelfContact sc, const PetscReal *lo, const PetscReal *hi, PetscReal *box)
{
  SelfPatches *T = &sc->patches;

  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < 6 * T->n; i++) T->work[i] = -PETSC_MAX_REAL;
  for (PetscInt k = 0; k < sc->nowned; k++) {
    PetscReal *w = T->work + 6 * T->of[k];
    for (PetscInt d = 0; d < 3; d++) w[d] = PetscMax(w[d], -lo[3 * k + d]), w[3 + d] = PetscMax(w[3 + d], hi[3 * k + d]);
  }
  PetscCall(PatchesReduce(sc, 6, T->work, box));
  PetscFunctionReturn(0);
}

/* Is the gap between the boxes a and b (-lo, hi each), less what the particles of
 * each left them by (ea, eb: 6 each, how far past -lo and past hi), more than
 * reach in some direction? */
static inline PetscBool Apart(const PetscReal *a, const PetscReal *ea, const PetscReal *b, const PetscReal *eb, PetscReal reach)
{
  for (PetscInt d = 0; d < 3; d++) {
    if (-b[d] - a[3 + d] - ea[3 + d] - eb[d] > reach) return PETSC_TRUE; /* b above a */
    if (-a[d] - b[3 + d] - eb[3 + d] - ea[d] > reach) return PETSC_TRUE;
  }
  return PETSC_FALSE;
}

/* The candidate list, with the start and end positions x0, x1 of the own particles
 * and their boxes lo .. hi (SetBoxes), margin m (m) and the thickness H: does every
 * pair of patches pass one of the two tests? The one translation of P and Q: per
 * direction and position (start, end), the largest x - hi and the largest lo - x over
 * both sum to at most 2 m (SetListValid). Apart: the list's patch boxes
 * (list_box) less the largest excursions past them (the same maxima, at either
 * position) further apart than H. Collective. */
PetscErrorCode SelfPatchesListValid(SelfContact sc, const PetscReal *x0, const PetscReal *x1, const PetscReal *lo, const PetscReal *hi, PetscReal m, PetscReal H, PetscBool *valid)
{
  SelfPatches *T = &sc->patches;
  PetscReal   *e = T->ext + 12 * T->n; /* the excursions at either position: 6 a patch */

  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < 12 * T->n; i++) T->work[i] = -PETSC_MAX_REAL;
  for (PetscInt k = 0; k < sc->nowned; k++) {
    PetscReal *w = T->work + 12 * T->of[k];
    for (PetscInt d = 0; d < 3; d++) {
      const PetscReal l = lo[3 * k + d], h = hi[3 * k + d];
      w[d] = PetscMax(w[d], l - x0[3 * k + d]), w[3 + d] = PetscMax(w[3 + d], x0[3 * k + d] - h);
      w[6 + d] = PetscMax(w[6 + d], l - x1[3 * k + d]), w[9 + d] = PetscMax(w[9 + d], x1[3 * k + d] - h);
    }
  }
  PetscCall(PatchesReduce(sc, 12, T->work, T->ext));
  for (PetscInt P = 0; P < T->n; P++)
    for (PetscInt c = 0; c < 6; c++) e[6 * P + c] = PetscMax(T->ext[12 * P + c], T->ext[12 * P + 6 + c]);
  *valid = PETSC_TRUE;
  for (PetscInt P = 0; P < T->n && *valid; P++) {
    const PetscReal *a = T->ext + 12 * P;
    for (PetscInt Q = P; Q < T->n; Q++) {
      const PetscReal *b = T->ext + 12 * Q;
      PetscReal        u[12]; /* P and Q together (the test is the same either way round) */
      for (PetscInt c = 0; c < 12; c++) u[c] = PetscMax(a[c], b[c]);
      if (SelfListTranslates(u, m) || (Q != P && Apart(T->list_box + 6 * P, e + 6 * P, T->list_box + 6 * Q, e + 6 * Q, H))) continue;
      *valid = PETSC_FALSE;
      break;
    }
  }
  PetscFunctionReturn(0);
}

/* The near list, made at xr (its patch boxes near_box) with radius R: with the own
 * particles' displacements x0 - xr, x1 - xr and their motion x1 - x0, does every pair
 * of patches keep every pair the near list left out beyond reach (and, gap_at_end,
 * its gap at x1 along its normal at x0)? P and Q together: their displacements less
 * one translation (the half-diagonals delta of their boxes) as in NearHolds. Apart:
 * the distance of their boxes at xr less the largest displacement of either, and
 * gap_at_end twice their largest motions too. Collective. */
PetscErrorCode SelfPatchesNearHolds(SelfContact sc, const PetscReal *x0, const PetscReal *x1, const PetscReal *xr, PetscReal R, PetscReal reach, PetscBool gap_at_end, PetscBool *holds)
{
  SelfPatches *T = &sc->patches;

  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < 18 * T->n; i++) T->work[i] = -PETSC_MAX_REAL;
  for (PetscInt k = 0; k < sc->nowned; k++) {
    PetscReal *w = T->work + 18 * T->of[k];
    for (PetscInt d = 0; d < 3; d++) {
      const PetscReal a[3] = {x0[3 * k + d] - xr[3 * k + d], x1[3 * k + d] - xr[3 * k + d], x1[3 * k + d] - x0[3 * k + d]};
      for (PetscInt j = 0; j < 3; j++) w[6 * j + d] = PetscMax(w[6 * j + d], a[j]), w[6 * j + 3 + d] = PetscMax(w[6 * j + 3 + d], -a[j]);
    }
  }
  PetscCall(PatchesReduce(sc, 18, T->work, T->ext));
  /* each patch's largest displacement (start or end; along the step it is a convex
   * combination of the two) and largest motion over the step, in work */
  for (PetscInt P = 0; P < T->n; P++) {
    const PetscReal *c   = T->ext + 18 * P;
    PetscReal        q01 = 0, qD = 0;
    for (PetscInt d = 0; d < 3; d++) {
      q01 += PetscSqr(PetscMax(0, PetscMax(PetscMax(c[d], c[3 + d]), PetscMax(c[6 + d], c[9 + d]))));
      qD += PetscSqr(PetscMax(0, PetscMax(c[12 + d], c[15 + d])));
    }
    T->work[2 * P] = PetscSqrtReal(q01), T->work[2 * P + 1] = PetscSqrtReal(qD);
  }
  *holds = PETSC_TRUE;
  for (PetscInt P = 0; P < T->n && *holds; P++) {
    const PetscReal *a = T->ext + 18 * P, *ba = T->near_box + 6 * P;
    for (PetscInt Q = P; Q < T->n; Q++) {
      const PetscReal *b = T->ext + 18 * Q, *bb = T->near_box + 6 * Q;
      PetscReal        u[18], delta[3], far = 0, m01, mD;
      for (PetscInt c = 0; c < 18; c++) u[c] = PetscMax(a[c], b[c]); /* P and Q together */
      SelfNearDelta(u, delta);
      if (SelfNearHolds(R, delta, reach, gap_at_end)) continue;
      if (Q == P) {
        *holds = PETSC_FALSE;
        break;
      }
      /* apart: the distance of the boxes at xr, less each patch's largest displacement */
      for (PetscInt d = 0; d < 3; d++) {
        const PetscReal gap = PetscMax(-bb[d] - ba[3 + d], -ba[d] - bb[3 + d]);
        far += PetscSqr(PetscMax(0, gap));
      }
      m01 = T->work[2 * P] + T->work[2 * Q], mD = T->work[2 * P + 1] + T->work[2 * Q + 1];
      far = (1 - 1e-9) * PetscSqrtReal(far) - (1 + 1e-9) * m01;
      if (far > reach && (!gap_at_end || far - 2 * (1 + 1e-9) * mD > reach)) continue;
      *holds = PETSC_FALSE;
      break;
    }
  }
  PetscFunctionReturn(0);
}
