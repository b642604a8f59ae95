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
#define SELF_SOLVE_FEATURE   1e-6

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
  for (PetscInt a = sc->tri_ptr[f[0]]; a < sc->tri_ptr[f[0] + 1]; a++) {
    const PetscInt *T = sc->mesh.tri + 3 * sc->tri_adj[a];
    if (nf == 1 || T[0] == f[1] || T[1] == f[1] || T[2] == f[1]) count++;
  }
  return PetscMax(count, 1);
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
  PetscCall(SelfListUpdate(sc)); /* the list (and the halo) for this step's free motion */
  if (q->ns != s->n) {
    PetscCall(PetscFree3(q->xs, q->S, q->gid));
    PetscCall(PetscMalloc3(3 * s->n + 1, &q->xs, 9 * s->n + 1, &q->S, s->n + 1, &q->gid));
    q->ns = s->n;
  }
  for (PetscInt k = 0; k < s->n; k++) {
    const PetscInt p = s->nat[k];
    q->gid[k]        = sc->gstart[sc->owner[p]] + sc->owner_idx[p];
    for (PetscInt i = 0; i < 9; i++) q->S[9 * k + i] = i % 4 == 0;
  }
  q->n = 0;
  {
    const PetscInt kind = 0; /* point-triangle pairs (below) */
    for (PetscInt c = 0; c < s->npt; c++) {
      Pair      pr;
      PetscReal n[3], dist, gp = 0, share;
      PairParticles(s, kind, c, pr.p);
      if (s->invm[pr.p[0]] == 0 && s->invm[pr.p[1]] == 0 && s->invm[pr.p[2]] == 0 && s->invm[pr.p[3]] == 0) continue;
      dist = PairClosest(kind, s->x0, &pr, n);
      if (!(dist > 0)) continue; /* touching: no normal (the filter's fail-safe takes it) */
      for (PetscInt i = 0; i < 4; i++) gp += pr.w[i] * V3Dot(n, s->x1 + 3 * pr.p[i]);
      if (PetscMin(dist, gp) >= SELF_SOLVE_REACH * H) continue;
      share = 1 / (PetscReal) FeatureTriangles(sc, &pr);
      if (q->n == q->m) {
        q->m = 2 * q->m + 64;
        PetscCall(PetscRealloc(q->m * sizeof(*q->pair), &q->pair));
      }
      {
        SolvePair *sp = q->pair + q->n++;
        sp->pr        = pr;
        for (PetscInt d = 0; d < 3; d++) sp->n[d] = n[d];
        sp->rest     = PetscMin(H, dist);
        sp->share    = share;
        sp->active   = (PetscBool) (gp < sp->rest);
        sp->released = PETSC_FALSE;
      }
    }
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
