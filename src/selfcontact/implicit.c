/* Self-contact inside an implicit step: the step's close pairs as one-sided
 * penalties (include/selfcontact.h says what they are; TSDRAPEBE takes them into
 * its residual, its matrix and its active set).
 *
 * Why inside the solve: the filter after the step stops a pair's approach by
 * impulses on the pair's four particles alone. A free edge landing on a layer at
 * v is stopped by v h in position per step, against a lattice spacing of a few
 * thicknesses: the 81^2 sphere landing strained 15-31 % so (BENCHMARKS.md). In
 * the solve, the stop is one more stiff term of the linear system: the cloth's
 * elasticity spreads it over the step, as it does the solid's.
 *
 * On many ranks. A rank holds every candidate pair with one of its own particles
 * (the local set of selfcontact.c, whose halo holds the pair's others); it adds a
 * pair's force to its own particles and its matrix rows for them. Every rank that
 * holds a pair computes it from the same numbers (positions moved in by the halo's
 * PetscSF), so its activity is decided alike everywhere. */
#include "selfcontactimpl.h"
#include <drape.h>

/* Pairs within this many thicknesses at the start of the step or at the end of
 * their free motion are the step's. */
#define SELF_SOLVE_REACH 2.0
/* A pair joins the active set after a solve only when the step carries it this
 * fraction of the thickness below its rest gap (shallower: the filter after the
 * step), so that pairs at the edge of a contact do not make the solves cycle. */
#define SELF_SOLVE_SHALLOW 0.1
/* The penalty's stiffness k h^2 / m: a particle of mass m landing at one
 * thickness per step on a layer that holds still ends the step 1/(1 + this) of a
 * thickness into it (backward Euler: v+ = v / (1 + k h^2 / m)). Stiffer gains
 * little and costs CG iterations (the fast fold: 34 a step at k = Y (33), 12
 * without the penalties). */
#define SELF_SOLVE_STIFFNESS 10.0
/* The penalties are soft against the cloth when their default stiffness is below
 * the cloth's stretch rigidity over this (SelfContactSolveSoft): then drapebe cuts
 * the step after one whose filter added energy. The sphere drop at 64^2 has 1/135
 * at 1e-2 s and 1/34 at 5e-3 s (folds pushed by the cloth behind them sink into
 * each other; it needed a cut at each), the fast fold of tests/test_self_contact.py
 * 1/23 at 5 ms (left as it was: a 16th cut it once), the shipped scenes at 2 ms
 * 1/2.2 (sphere) to 1/3.5 (pile). A step cut to a quarter has penalties 16 times
 * stiffer. */
#define SELF_SOLVE_SOFT    32.0
#define SELF_SOLVE_FEATURE 1e-6
/* Edge-edge pairs (-contact_self_solve_edges). Their stiffness tapers to nothing
 * within SELF_SOLVE_EDGE_TAPER of an end of either edge, and as the edges turn
 * parallel, from the sine 2 SELF_SOLVE_PARALLEL of their angle down to
 * SELF_SOLVE_PARALLEL, below which they are left out (EdgeShare). */
#define SELF_SOLVE_EDGE_TAPER 0.25
#define SELF_SOLVE_PARALLEL   0.05

PetscErrorCode SelfSolveDestroy(SelfContact sc)
{
  SelfSolve *q = &sc->solve;

  PetscFunctionBeginUser;
  PetscCall(PetscFree(q->pair));
  PetscCall(PetscFree3(q->xs, q->S, q->gid));
  PetscCall(PetscFree(q->brow));
  PetscCall(PetscFree(q->bcol));
  PetscCall(PetscFree(q->bval));
  q->n = q->m = q->ns = q->nb = q->mb = 0;
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSolveEnabled(SelfContact sc, PetscBool *enabled)
{
  PetscFunctionBeginUser;
  *enabled = (PetscBool) (sc->enabled && sc->solve.enabled);
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSolveSoft(SelfContact sc, PetscReal h, PetscReal rigidity, PetscBool *soft)
{
  const SelfSolve *q = &sc->solve;

  PetscFunctionBeginUser;
  *soft = (PetscBool) (sc->enabled && q->enabled && q->k_set <= 0 && h > 0 && SELF_SOLVE_SOFT * SELF_SOLVE_STIFFNESS * q->mass / (h * h) < rigidity);
  PetscFunctionReturn(0);
}

/* The pair's gap C(X) = sum_i w_i n.X_i. */
static inline PetscReal SolveGap(const SolvePair *sp, const PetscReal *X)
{
  const Pair      *pr = &sp->pr;
  const PetscReal *n  = sp->n;
  PetscReal        g  = 0;
  for (PetscInt i = 0; i < 4; i++) g += pr->w[i] * (n[0] * X[3 * pr->p[i]] + n[1] * X[3 * pr->p[i] + 1] + n[2] * X[3 * pr->p[i] + 2]);
  return g;
}

/* The trial positions of the local set: owned from x, the halo's from their owners. */
static PetscErrorCode SolvePositions(SelfContact sc, const PetscScalar *x)
{
  SelfSolve *q = &sc->solve;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < 3 * sc->local.nown; k++) q->xs[k] = PetscRealPart(x[k]);
  PetscCall(SelfHaloUpdate(sc, NULL, q->xs, NULL));
  PetscFunctionReturn(0);
}

/* The triangles that hold the closest point of point-triangle pair pr (its
 * triangle's interior: 1; an edge: the triangles on that edge; a corner: the
 * triangles at that particle): so many pairs of the point have the same closest
 * point, and each takes that share of the stiffness. A closest point within
 * SELF_SOLVE_FEATURE (barycentric) of an edge or corner is on it: layers of one
 * lattice meet with points right above edges and corners, where rounding
 * decides the branch of the closest-point test, and with it the share. */
static PetscInt FeatureTriangles(SelfContact sc, const Pair *pr)
{
  const SelfSet *s = &sc->local;
  PetscInt       f[3], nf = 0, count = 0;

  for (PetscInt i = 1; i < 4; i++)
    if (-pr->w[i] > SELF_SOLVE_FEATURE) f[nf++] = s->nat[pr->p[i]];
  if (nf == 3) return 1;
  {
    PetscInt key[6], nt = SelfParticleTriangles(sc, f[0], key);
    for (PetscInt a = 0; a < nt; a++) {
      PetscInt T[3];
      SelfTriangleParticles(sc->Mx, key[a], T);
      if (nf == 1 || T[0] == f[1] || T[1] == f[1] || T[2] == f[1]) count++;
    }
  }
  return PetscMax(count, 1);
}

/* The share of the stiffness of an edge-edge pair whose closest points are at
 * fractions a and b along its edges, sine the sine of the edges' angle: 1 inside
 * the edges, falling linearly to 0 within SELF_SOLVE_EDGE_TAPER of either end of
 * either edge, and to 0 as sine falls from 2 to 1 SELF_SOLVE_PARALLEL.
 * - Ends. Near an end the closest points are nearly those of a point-triangle
 *   pair (that end, or the other edge's, against a triangle), which already holds
 *   that contact. Two flat layers whose lattices lie nearly over each other cross
 *   edges close to their particles: at full stiffness such pairs stacked on the
 *   point-triangle ones (the stacked-sheets hairpin at rest: 1448 edge-edge pairs
 *   of the step with 2280 point-triangle ones; ICC(0) of the matrix broke down,
 *   the solve failed at every step size). Across a one-line crease, the pairs the
 *   filter pushed (two cells' diagonals either side of the crease) meet near the
 *   middle of both edges: the whole stiffness.
 * - Parallel edges. The closest points of two nearly parallel edges slide along
 *   them with the least change of position (the layers of a flat fold, lattice
 *   lines facing each other), so the pair's weights would follow rounding: the
 *   fast fold on 1 and 2 ranks took different pairs and parted by 1.7 mm. The
 *   point-triangle pairs of their ends hold such edges.
 * Continuous, so that rounding does not switch a pair's stiffness on or off (a
 * pair is left out only where its share is 0, or below 4e-6 at an end). */
static PetscReal EdgeShare(const Pair *pr, PetscReal sine)
{
  const PetscReal a = -pr->w[1], b = pr->w[3]; /* WeightsEE */
  const PetscReal ta = PetscMin(a, 1 - a) / SELF_SOLVE_EDGE_TAPER, tb = PetscMin(b, 1 - b) / SELF_SOLVE_EDGE_TAPER, tp = sine / SELF_SOLVE_PARALLEL - 1;

  return PetscMin(ta, 1) * PetscMin(tb, 1) * PetscMin(tp, 1);
}

/* Room for one more pair of the step. */
static PetscErrorCode SolvePairNew(SelfSolve *q, SolvePair **sp)
{
  PetscFunctionBeginUser;
  if (q->n == q->m) {
    q->m = 2 * q->m + 64;
    PetscCall(PetscRealloc(q->m * sizeof(*q->pair), &q->pair));
  }
  *sp = q->pair + q->n++;
  PetscFunctionReturn(0);
}

/* Can candidate pair p (primitives p[0..na) and p[na..4)) be a pair of the step,
 * within reach r? Its distance at the start is at least the separation of its
 * primitives' boxes there, and its gap at the end of its free motion (along the
 * start's normal, with weights whose magnitudes sum to 2) at least that less twice
 * the largest displacement of its particles. PETSC_FALSE only for pairs that
 * SolvePairMake leaves out, without their closest points (the same pairs, the
 * same frames; most of a kept list's candidates). */
static PetscBool SolveReachable(const SelfSet *s, const PetscInt p[4], PetscInt na, PetscReal r)
{
  PetscReal dmax = 0;

  for (PetscInt i = 0; i < 4; i++) {
    PetscReal d[3];
    V3Sub(s->x1 + 3 * p[i], s->x0 + 3 * p[i], d);
    dmax = PetscMax(dmax, V3Dot(d, d));
  }
  r = 1.001 * (r + 2 * PetscSqrtReal(dmax)) + 1e-12; /* slack for rounding: never skips a pair of the step */
  for (PetscInt d = 0; d < 3; d++) {
    PetscReal alo = PETSC_MAX_REAL, ahi = -PETSC_MAX_REAL, blo = PETSC_MAX_REAL, bhi = -PETSC_MAX_REAL;
    for (PetscInt i = 0; i < 4; i++) {
      const PetscReal a = s->x0[3 * p[i] + d];
      if (i < na)
        alo = PetscMin(alo, a), ahi = PetscMax(ahi, a);
      else
        blo = PetscMin(blo, a), bhi = PetscMax(bhi, a);
    }
    if (alo > bhi + r || blo > ahi + r) return PETSC_FALSE;
  }
  return PETSC_TRUE;
}

/* Candidate (kind, c) as a pair of the step, if it is within reach: its weights
 * and normal at the start, its rest gap, whether its free motion ends below it,
 * and for an edge-edge pair its share of the stiffness (EdgeShare; a
 * point-triangle pair's is the caller's). Edge-edge candidates only when the
 * closest points are inside both edges: at an end of either edge, a
 * point-triangle pair (that end against a triangle of the other edge) has the same
 * closest points and already pushes them apart. PETSC_FALSE: not a pair of the
 * step. */
static PetscBool SolvePairMake(const SelfSet *s, PetscReal H, PetscInt kind, PetscInt c, SolvePair *sp)
{
  Pair      pr;
  PetscReal n[3], dist, gp = 0, sine = 1;

  PairParticles(s, kind, c, pr.p);
  if (s->invm[pr.p[0]] == 0 && s->invm[pr.p[1]] == 0 && s->invm[pr.p[2]] == 0 && s->invm[pr.p[3]] == 0) return PETSC_FALSE;
  if (!SolveReachable(s, pr.p, kind == 0 ? 1 : 2, SELF_SOLVE_REACH * H)) return PETSC_FALSE;
  dist = PairClosest(kind, s->x0, &pr, n);
  if (!(dist > 0)) return PETSC_FALSE; /* touching: no normal (the filter's fail-safe takes it) */
  if (kind == 1) {
    const PetscReal a = -pr.w[1], b = pr.w[3]; /* the closest points' parameters along the edges (WeightsEE) */
    PetscReal       e[3], f[3], c[3];
    if (!(a > SELF_SOLVE_FEATURE && a < 1 - SELF_SOLVE_FEATURE && b > SELF_SOLVE_FEATURE && b < 1 - SELF_SOLVE_FEATURE)) return PETSC_FALSE;
    V3Sub(s->x0 + 3 * pr.p[1], s->x0 + 3 * pr.p[0], e);
    V3Sub(s->x0 + 3 * pr.p[3], s->x0 + 3 * pr.p[2], f);
    V3Cross(e, f, c);
    sine = PetscSqrtReal(V3Dot(c, c) / (V3Dot(e, e) * V3Dot(f, f)));
    if (!(sine > SELF_SOLVE_PARALLEL)) return PETSC_FALSE;
  }
  for (PetscInt i = 0; i < 4; i++) gp += pr.w[i] * V3Dot(n, s->x1 + 3 * pr.p[i]);
  if (PetscMin(dist, gp) >= SELF_SOLVE_REACH * H) return PETSC_FALSE;
  sp->pr = pr;
  for (PetscInt d = 0; d < 3; d++) sp->n[d] = n[d];
  sp->rest     = PetscMin(H, dist);
  sp->share    = kind == 0 ? 1 : EdgeShare(&pr, sine);
  sp->active   = (PetscBool) (gp < sp->rest);
  sp->released = PETSC_FALSE;
  return PETSC_TRUE;
}

PetscErrorCode SelfContactSolveBegin(SelfContact sc, PetscReal h, const PetscScalar *x0, const PetscScalar *v0)
{
  SelfSet        *s = &sc->local;
  SelfSolve      *q = &sc->solve;
  const PetscReal H = sc->thickness;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.self_contact, 0, 0, 0, 0));
  q->k = q->k_set > 0 ? q->k_set : SELF_SOLVE_STIFFNESS * q->mass / (h * h);
  for (PetscInt k = 0; k < 3 * s->nown; k++) {
    s->x0[k] = PetscRealPart(x0[k]);
    s->v[k]  = PetscRealPart(v0[k]);
    s->x1[k] = s->x0[k] + h * s->v[k];
  }
  PetscCall(SelfHaloUpdate(sc, s->x0, s->x1, s->v));
  PetscCall(SelfListUpdate(sc, SELF_SOLVE_REACH * H, PETSC_TRUE)); /* the list (and the halo) for this step's free motion */
  if (q->ns != s->n) {
    PetscCall(PetscFree3(q->xs, q->S, q->gid));
    PetscCall(PetscMalloc3(3 * s->n + 1, &q->xs, 9 * s->n + 1, &q->S, s->n + 1, &q->gid));
    q->ns = s->n;
  }
  for (PetscInt k = 0; k < s->n; k++) {
    q->gid[k] = s->gid[k];
    for (PetscInt i = 0; i < 9; i++) q->S[9 * k + i] = i % 4 == 0;
  }
  q->n = 0;
  /* Point-triangle pairs, then (-contact_self_solve_edges) edge-edge pairs whose
   * closest points are inside both edges (at an end, a point-triangle pair has
   * them). A point's pairs whose closest point is the same edge or corner of
   * several triangles are one contact and share the stiffness (FeatureTriangles).
   * An edge-edge pair inside both edges shares its closest points with no other
   * pair, so its share is not counted out among others but set by where they lie
   * (EdgeShare). Sharing it among a particle's edge-edge pairs within reach
   * instead (tried, counts summed over the ranks) left a pair across a one-line
   * crease 1/16 of the stiffness: the 81^2 landing's filter pushes stayed. */
  for (PetscInt kind = 0; kind < (q->edges ? 2 : 1); kind++)
    for (PetscInt c = 0; c < (kind ? s->nee : s->npt); c++) {
      SolvePair sp, *to = NULL;
      if (!SolvePairMake(s, H, kind, c, &sp)) continue;
      if (kind == 0) sp.share = 1 / (PetscReal) FeatureTriangles(sc, &sp.pr);
      PetscCall(SolvePairNew(q, &to));
      *to = sp;
    }
  PetscCall(PetscLogEventEnd(drape_log.self_contact, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSolveSetConstraints(SelfContact sc, const ClothConstraint type[], const PetscReal normal[])
{
  SelfSolve *q = &sc->solve;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < sc->local.nown; k++) {
    PetscReal *S = q->S + 9 * k;
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < 3; j++) {
        if (!type || type[k] == CLOTH_FREE)
          S[3 * i + j] = i == j;
        else if (type[k] == CLOTH_FIXED)
          S[3 * i + j] = 0;
        else
          S[3 * i + j] = (i == j) - normal[3 * k + i] * normal[3 * k + j];
      }
  }
  if (sc->sf) {
    const PetscInt o = 9 * sc->local.nown;
    PetscCall(PetscSFBcastBegin(sc->sf, sc->unit9, q->S, q->S + o, MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(sc->sf, sc->unit9, q->S, q->S + o, MPI_REPLACE));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSolveAddAcceleration(SelfContact sc, const PetscScalar *x, PetscScalar *a)
{
  const SelfSet *s = &sc->local;
  SelfSolve     *q = &sc->solve;

  PetscFunctionBeginUser;
  PetscCall(SolvePositions(sc, x));
  for (PetscInt e = 0; e < q->n; e++) {
    const SolvePair *sp = q->pair + e;
    const Pair      *pr = &sp->pr;
    const PetscReal *n  = sp->n;
    PetscReal        lam;
    if (!sp->active) continue;
    lam = q->k * sp->share * (sp->rest - SolveGap(sp, q->xs));
    for (PetscInt i = 0; i < 4; i++) {
      const PetscInt p = pr->p[i];
      if (p >= s->nown) continue;
      for (PetscInt d = 0; d < 3; d++) a[3 * p + d] += lam * pr->w[i] * n[d] * s->invm[p];
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSolveGetBlocks(SelfContact sc, PetscInt *nb, const PetscInt **rows, const PetscInt **cols, const PetscReal **vals)
{
  const SelfSet *s = &sc->local;
  SelfSolve     *q = &sc->solve;

  PetscFunctionBeginUser;
  q->nb = 0;
  for (PetscInt e = 0; e < q->n; e++) {
    const SolvePair *sp = q->pair + e;
    const Pair      *pr = &sp->pr;
    const PetscReal *n  = sp->n;
    for (PetscInt i = 0; i < 4; i++) {
      const PetscInt a = pr->p[i];
      if (a >= s->nown || s->invm[a] == 0) continue;
      for (PetscInt j = 0; j < 4; j++) {
        const PetscInt   b  = pr->p[j];
        const PetscReal *Sa = q->S + 9 * a, *Sb = q->S + 9 * b;
        PetscReal        u[3] = {0, 0, 0}, t[3] = {0, 0, 0}, *B;
        if (s->invm[b] == 0) continue;
        if (q->nb == q->mb) {
          q->mb = 2 * q->mb + 256;
          PetscCall(PetscRealloc(q->mb * sizeof(*q->brow), &q->brow));
          PetscCall(PetscRealloc(q->mb * sizeof(*q->bcol), &q->bcol));
          PetscCall(PetscRealloc(9 * q->mb * sizeof(*q->bval), &q->bval));
        }
        q->brow[q->nb] = a;
        q->bcol[q->nb] = q->gid[b];
        B              = q->bval + 9 * q->nb++;
        /* S_a (k w_a w_b n n^T) S_b = k w_a w_b (S_a n)(S_b n)^T */
        for (PetscInt r = 0; r < 3; r++)
          for (PetscInt c = 0; c < 3; c++) u[r] += Sa[3 * r + c] * n[c], t[r] += Sb[3 * r + c] * n[c];
        for (PetscInt r = 0; r < 3; r++)
          for (PetscInt c = 0; c < 3; c++) B[3 * r + c] = sp->active ? q->k * sp->share * pr->w[i] * pr->w[j] * u[r] * t[c] : 0;
      }
    }
  }
  *nb   = q->nb;
  *rows = q->brow;
  *cols = q->bcol;
  *vals = q->bval;
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSolveUpdate(SelfContact sc, const PetscScalar *x, PetscBool apply, PetscInt *changes)
{
  const SelfSet  *s         = &sc->local;
  SelfSolve      *q         = &sc->solve;
  const PetscReal tol       = SELF_SOLVE_SHALLOW * sc->thickness;
  PetscInt        counts[2] = {0, 0}, sums[2]; /* changes, active (each pair counted once over the ranks) */

  PetscFunctionBeginUser;
  PetscCall(SolvePositions(sc, x));
  for (PetscInt e = 0; e < q->n; e++) {
    SolvePair      *sp   = q->pair + e;
    const PetscReal C    = SolveGap(sp, q->xs);
    const PetscBool here = PairCountedHere(s, sp->pr.p);
    counts[1] += here && sp->active; /* pressing in the solve just made */
    if (!apply) continue;
    if (sp->active && C > sp->rest && !sp->released) { /* pulled: let go */
      sp->active   = PETSC_FALSE;
      sp->released = PETSC_TRUE;
      counts[0] += here;
    } else if (!sp->active && C < sp->rest - tol) {
      sp->active = PETSC_TRUE;
      counts[0] += here;
    }
  }
  PetscCall(MPIU_Allreduce(counts, sums, 2, MPIU_INT, MPI_SUM, sc->comm));
  *changes                  = sums[0];
  sc->stats.solve_pairs_max = PetscMax(sc->stats.solve_pairs_max, sums[1]);
  PetscFunctionReturn(0);
}
