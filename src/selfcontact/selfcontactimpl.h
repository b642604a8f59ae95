/* Private to src/selfcontact/: the cloth's surface as triangles of lattice
 * particles, named by natural lattice index (j Mx + i). No rank holds the whole
 * surface: its primitives are functions of (i, j) and of which particles are cloth
 * (ClothIsActive), named by keys in the order of the lattice:
 *   vertex p                       key p (a particle of some cloth cell)
 *   triangle s of the cell at a    key 2 a + s: s = 0 (a, a + 1, a + Mx + 1),
 *                                  s = 1 (a, a + Mx + 1, a + Mx); a = j Mx + i its
 *                                  corner (i, j), the cell's four corners cloth
 *   edge (a, a + o)                key 3 a + code: o = 1, Mx, Mx + 1 for code 0, 1, 2
 * So the keys order the primitives as the natural order of their first particle (the
 * order every rank and partition agrees on), and are at most 3 N: within PetscInt
 * wherever the lattice is (3 N unknowns), and exact as reals when gathered. */
#pragma once

#include <selfcontact.h>
#include "proximity.h"
#include <petscsf.h>
#include <petsc/private/hashmapi.h>

typedef struct {
  PetscInt  nv, nt, ne;
  PetscInt *vert; /* particles that belong to a triangle               */
  PetscInt *tri;  /* 3 particles each: two per lattice cell of the cloth */
  PetscInt *edge; /* 2 particles each: the triangles' edges, once       */
} SelfMesh;

/* CGAL's box intersection (broadphase.cxx). Candidate pairs whose boxes (start and end positions, grown by r) overlap, sorted,
 * none sharing a particle: point-triangle (vertex, triangle) and edge-edge (e, f), e < f.
 * The pair arrays are PetscMalloc'ed (2 entries per pair). Not collective. */
PETSC_EXTERN PetscErrorCode SelfBroadPhase(const SelfMesh *, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscInt *npt, PetscInt **pt, PetscInt *nee, PetscInt **ee);
/* The same pairs, in the same order, by a uniform spatial hash (hashgrid.c). */
PETSC_EXTERN PetscErrorCode SelfBroadPhaseHash(const SelfMesh *, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscInt *npt, PetscInt **pt, PetscInt *nee, PetscInt **ee);
/* The same pairs, in the same order, by the hash over tiles of the lattice (hashgrid.c): nat, the natural index of each particle, Mx the lattice's row. */
PETSC_EXTERN PetscErrorCode SelfBroadPhaseTiles(const SelfMesh *, const PetscInt *nat, PetscInt Mx, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscInt *npt, PetscInt **pt, PetscInt *nee, PetscInt **ee);

/* Particles the filter acts on, their copy of the state, their primitives and the
 * candidate pairs among them: a rank's own particles and its halo; or (only state
 * and 1/m) the particles of the contacts gathered from every rank. */
typedef struct {
  PetscInt   n, nown;                  /* particles; the first nown are the rank's own (gathered: all) */
  PetscInt  *nat;                      /* natural index of each */
  PetscInt  *gid;                      /* global block number of each (the cloth's and the implicit matrix's; local set only) */
  PetscReal *invm0;                    /* the cloth's 1/m of each, 0 pinned (local set only) */
  PetscReal *invm, *x0, *x1, *v;       /* 1/m (0 pinned or held), start, end, velocity: 3 each */
  PetscReal *lo, *hi;                  /* each particle's box at the last broad phase */
  SelfMesh   mesh;                     /* primitives (indices into this set) in natural order */
  PetscInt  *vid, *tid, *eid;          /* their keys (the whole cloth's order) */
  PetscInt   ncpt, ncee, *cpt, *cee;   /* candidate pairs (the broad phase's) with one of the first nown particles */
  PetscInt   nnpt, nnee, *npt_, *nee_; /* the near list: the candidates closer than SelfNearRadius at xr */
  PetscReal *xr;                       /* the local set's positions when the near list was made (3 each) */
  PetscInt   nxr;                      /* entries xr holds */
  PetscBool  listed, has_near;         /* a candidate list exists; a near list is made from it */
  PetscReal *dc;                       /* has_near: every candidate's distance at xr (point-triangle, then edge-edge) */
  PetscReal *ndc;                      /* has_near: the near list's distances at xr (point-triangle from 0, edge-edge from ncpt) */
  PetscInt   nlpt, nlee, *lpt_, *lee_; /* the live list: the candidates (or the near list's pairs) that distance and the motion since xr leave within reach (NearLive, NearWithin) */
  PetscBool  near_taken;               /* the last list update took the near list's pairs within reach (NearWithin), by ... */
  PetscReal  near_delta[3];            /* ... this bound on the motion since xr (NearHolds') */
  PetscReal *dr;                       /* work: x0 - xr and x1 - xr, 6 each (nxr / 3 particles) */
  PetscReal *dm;                       /* work: each triangle's, then edge's, mean of dr and its particles' largest distance from it (NearLive), 9 each */
  PetscInt   ndm;                      /* entries dm holds */
  PetscInt   npt, nee, *pt, *ee;       /* the pairs the passes take: the near list, or every candidate */
} SelfSet;

typedef struct {
  PetscInt  p[4]; /* particles                                                  */
  PetscReal w[4]; /* weights: the pair's gap along n is sum_i w_i x_i . n        */
} Pair;

/* Self-contact inside the implicit step (implicit.c): the step's close pairs as
 * one-sided penalties. */
typedef struct {
  Pair      pr;    /* particles (local set) and weights at the step's start */
  PetscReal n[3];  /* unit normal at the step's start */
  PetscReal rest;  /* rest gap, m */
  PetscReal share; /* of the stiffness */
  PetscBool active;
  PetscBool released; /* let go once in this step */
} SolvePair;

enum {
  SELF_BROAD_CGAL,
  SELF_BROAD_HASH,
  SELF_BROAD_TILES
};

/* The lattice's tiles for the lists' tests patch by patch (patches.c): square blocks of side particles, nx by ny. */
typedef struct {
  PetscInt   side, nx, ny, n;
  PetscInt  *of;         /* the tile of each own particle */
  PetscReal *list_box;   /* each patch's box (-lo, hi) when the candidate list was made: 6 a tile */
  PetscReal *near_box;   /* each patch's box of xr when the near list was made */
  PetscReal *work, *ext; /* 18 a tile */
} SelfPatches;

typedef struct {
  PetscBool  enabled;  /* -contact_self_solve (taken only by a scheme that calls SelfContactSolveBegin) */
  PetscBool  edges;    /* -contact_self_solve_edges: edge-edge pairs too */
  PetscReal  k, k_set; /* penalty stiffness of the step; -contact_self_stiffness (0: SELF_SOLVE_STIFFNESS m / h^2), N/m */
  PetscReal  mass;     /* mean particle mass, kg */
  PetscInt   n, m;     /* the step's pairs, allocated */
  SolvePair *pair;
  PetscInt   ns;     /* local-set particles the arrays below hold */
  PetscReal *xs;     /* trial positions over the local set */
  PetscReal *S;      /* each local-set particle's free-direction projector (solid contact), 9 each */
  PetscInt  *gid;    /* global block index of each local-set particle in the implicit matrix */
  PetscInt   nb, mb; /* matrix blocks, allocated */
  PetscInt  *brow, *bcol;
  PetscReal *bval;
} SelfSolve;
struct _p_SelfContact {
  MPI_Comm         comm;
  PetscMPIInt      rank, size;
  Cloth            cloth;
  PetscBool        enabled;
  PetscReal        thickness, mu;
  PetscInt         its;
  PetscReal        margin; /* of the Verlet list, in thicknesses */
  PetscReal        near;   /* radius of the near list, in thicknesses (0: none) */
  PetscInt         broad;  /* broad phase: SELF_BROAD_CGAL, _HASH, _TILES */
  PetscBool        zones;  /* fail-safe by rigid impact zones (else stop the particles) */
  PetscInt         Mx, My, N, nowned;
  PetscInt         nt, ne;          /* the whole cloth's triangles and edges (counts) */
  PetscHMapI       local_of;        /* natural -> index in the local set (absent: -1) */
  PetscInt         dir_start, *dir; /* a directory: global number of naturals dir_start + k (PETSc's split of N), -1 none */
  PetscLayout      dir_layout;
  PetscReal       *invm_own; /* 1/m of the own particles, 0 pinned */
  PetscBool       *held;     /* owned particles the solid holds in this filter (SelfContactSetHeld) */
  PetscBool        use_held; /* held given for the filter under way */
  PetscInt         nh1, *h1; /* the halo's fixed part: other ranks' particles of own particles' triangles */
  SelfSet          local;    /* the rank's own particles and its halo */
  PetscSF          sf;       /* own particles (roots) -> the local set's halo (leaves) */
  MPI_Datatype     unit3;    /* 3 reals */
  PetscInt        *uf;       /* union-find parents over the local set (-1: not in an active pair) */
  PetscBool       *bnd;      /* a group of active pairs reaches the halo (by root) */
  PetscInt        *gstart;   /* global block index of each rank's first particle (size + 1) */
  MPI_Datatype     unit9;    /* 9 reals */
  SelfSolve        solve;
  SelfPatches      patches;
  PetscBool        implicit;    /* SelfContactSetImplicit: the candidate list is not tested patch by patch */
  PetscBool        use_patches; /* -contact_self_patches */
  SelfContactStats stats;
};

/* The lattice cell at a = j Mx + i (corners (i, j) to (i + 1, j + 1)) is cloth. */
PETSC_INTERN PetscBool SelfCellIsCloth(SelfContact, PetscInt a);
/* The keys of the triangles that hold particle p, ascending (at most 6). */
PETSC_INTERN PetscInt SelfParticleTriangles(SelfContact, PetscInt p, PetscInt key[6]);
/* The particles of triangle `key`. */
static inline void SelfTriangleParticles(PetscInt Mx, PetscInt key, PetscInt T[3])
{
  const PetscInt a = key / 2;
  T[0]             = a;
  T[1]             = key % 2 ? a + Mx + 1 : a + 1;
  T[2]             = key % 2 ? a + Mx : a + Mx + 1;
}

/* The particles of candidate (kind, k): the point and the triangle's three, or the two edges'. */
static inline void PairParticles(const SelfSet *s, PetscInt kind, PetscInt k, PetscInt p[4])
{
  if (kind == 0) {
    const PetscInt v = s->mesh.vert[s->pt[2 * k]], *T = s->mesh.tri + 3 * s->pt[2 * k + 1];
    p[0] = v, p[1] = T[0], p[2] = T[1], p[3] = T[2];
  } else {
    const PetscInt *e = s->mesh.edge + 2 * s->ee[2 * k], *f = s->mesh.edge + 2 * s->ee[2 * k + 1];
    p[0] = e[0], p[1] = e[1], p[2] = f[0], p[3] = f[1];
  }
}

/* Is one of the particles p[0..4) among the set's own? */
static inline PetscBool PairIsOwn(const SelfSet *s, const PetscInt p[4]) { return (PetscBool) (p[0] < s->nown || p[1] < s->nown || p[2] < s->nown || p[3] < s->nown); }

/* Does this rank count the pair (its particle of smallest natural index is its own)?
 * Every pair is counted once over the ranks. */
static inline PetscBool PairCountedHere(const SelfSet *s, const PetscInt p[4])
{
  PetscInt first = 0;
  for (PetscInt i = 1; i < 4; i++)
    if (s->nat[p[i]] < s->nat[p[first]]) first = i;
  return (PetscBool) (p[first] < s->nown);
}

static inline void WeightsPT(Pair *pr, const PetscReal w[3]) { pr->w[0] = 1, pr->w[1] = -w[0], pr->w[2] = -w[1], pr->w[3] = -w[2]; }
static inline void WeightsEE(Pair *pr, PetscReal s, PetscReal u) { pr->w[0] = -(1 - s), pr->w[1] = -s, pr->w[2] = 1 - u, pr->w[3] = u; }

/* The pair's closest points at positions X (its particles set by PairParticles):
 * the weights, the unit normal from the first primitive (triangle, first edge) to
 * the second (point, second edge) and the distance. */
static inline PetscReal PairClosest(PetscInt kind, const PetscReal *X, Pair *pr, PetscReal n[3])
{
  const PetscInt *p = pr->p;
  PetscReal       dist;

  if (kind == 0) {
    PetscReal w[3];
    dist = PointTriangleClosest(X + 3 * p[0], X + 3 * p[1], X + 3 * p[2], X + 3 * p[3], w);
    WeightsPT(pr, w);
  } else {
    PetscReal s, u;
    dist = SegmentSegmentClosest(X + 3 * p[0], X + 3 * p[1], X + 3 * p[2], X + 3 * p[3], &s, &u);
    WeightsEE(pr, s, u);
  }
  for (PetscInt d = 0; d < 3; d++) n[d] = 0;
  for (PetscInt i = 0; i < 4; i++)
    for (PetscInt d = 0; d < 3; d++) n[d] += pr->w[i] * X[3 * p[i] + d];
  if (dist > 0)
    for (PetscInt d = 0; d < 3; d++) n[d] /= dist;
  return dist;
}

/* The distances of candidates [0, n) of kind (0 point-triangle, 1 edge-edge; s->pt or
 * s->ee set) at positions X, each PairClosest's to the bit, in lanes (nearlanes.c). */
PETSC_INTERN void SelfNearDistances(const SelfSet *, PetscInt, PetscInt, const PetscReal *, PetscReal *);
/* The motion of particles [0, n) since the lists were made, in one pass: the largest
 * x - hi and lo - x at x0 and x1 (12; lo given), the largest and smallest x0 - xr,
 * x1 - xr and x1 - x0 (18; xr given), and a sum of 0 * every coordinate (nearlanes.c). */
PETSC_INTERN void SelfMotionMaxima(PetscInt, const PetscReal *, const PetscReal *, const PetscReal *, const PetscReal *, const PetscReal *, PetscReal[12], PetscReal[18], PetscReal *);
/* The halo's copies of x0, x1 and v (any may be NULL; arrays over the local set)
 * from their owners. Collective. */
PETSC_INTERN PetscErrorCode SelfHaloUpdate(SelfContact, PetscReal *, PetscReal *, PetscReal *);
/* The local set's candidate list for its present x0 and x1, rebuilt (with the halo)
 * when a particle of any rank moved beyond the margin, and the pairs the passes
 * take (pt, ee): every candidate that may come within reach (m) at x0 or collide
 * over the step x0 -> x1, or (gap_at_end) whose gap at x1 along the normal at x0
 * may be below reach. Collective. */
PETSC_INTERN PetscErrorCode SelfListUpdate(SelfContact, PetscReal, PetscBool);
/* Does one translation keep every particle within the margin m of its box, given per
 * position (start, end) and direction the largest x - hi and the largest lo - x
 * (g[6 j + d], g[6 j + 3 + d]) over the particles in question? (SetListValid) */
static inline PetscBool SelfListTranslates(const PetscReal g[12], PetscReal m)
{
  for (PetscInt j = 0; j < 2; j++)
    for (PetscInt d = 0; d < 3; d++)
      if (!(g[6 * j + d] + g[6 * j + 3 + d] <= 2 * m)) return PETSC_FALSE;
  return PETSC_TRUE;
}
/* The half-diagonals delta of the boxes of x0 - xr, x1 - xr and x1 - x0 from their
 * largest and minus their smallest entries g (over the particles in question). */
static inline void SelfNearDelta(const PetscReal g[18], PetscReal delta[3])
{
  for (PetscInt j = 0; j < 3; j++) {
    PetscReal sq = 0;
    for (PetscInt d = 0; d < 3; d++) sq += PetscSqr(PetscMax(0, 0.5 * (g[6 * j + d] + g[6 * j + 3 + d])));
    delta[j] = PetscSqrtReal(sq);
  }
}
/* Does a near list of radius R hold every pair within reach, when every particle's
 * displacement since it was made, less one translation, is at most delta[0] (at the
 * start), delta[1] (at the end), and its motion over the step less another at most
 * delta[2]? (selfcontact.c, "the near list") */
static inline PetscBool SelfNearHolds(PetscReal R, const PetscReal delta[3], PetscReal reach, PetscBool gap_at_end)
{
  R *= 1 - 1e-9; /* less what rounding of the distances may take */
  if (!(R - 2 * PetscMax(delta[0], delta[1]) > reach)) return PETSC_FALSE;
  return (PetscBool) (!gap_at_end || R - 2 * delta[0] - 2 * delta[2] > reach);
}
/* The patches (patches.c): set up from the own particles' natural indices, freed; the
 * patches' boxes over the own particles' boxes lo .. hi; the candidate list's test
 * and the near list's, patch by patch. Collective. */
PETSC_INTERN PetscErrorCode SelfPatchesSetUp(SelfContact, const PetscInt *);
PETSC_INTERN PetscErrorCode SelfPatchesDestroy(SelfContact);
PETSC_INTERN PetscErrorCode SelfPatchesBoxes(SelfContact, const PetscReal *, const PetscReal *, PetscReal *);
PETSC_INTERN PetscErrorCode SelfPatchesListValid(SelfContact, const PetscReal *, const PetscReal *, const PetscReal *, const PetscReal *, PetscReal, PetscReal, PetscBool *);
PETSC_INTERN PetscErrorCode SelfPatchesNearHolds(SelfContact, const PetscReal *, const PetscReal *, const PetscReal *, PetscReal, PetscReal, PetscBool, PetscBool *);
/* Frees the implicit step's arrays (implicit.c). */
PETSC_INTERN PetscErrorCode SelfSolveDestroy(SelfContact);
