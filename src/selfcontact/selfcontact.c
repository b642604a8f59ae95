/* Self-contact of the cloth: the post-step filter of include/selfcontact.h.
 *
 * Why a velocity filter after the step (Bridson, Fedkiw & Anderson 2002) rather than
 * an IPC barrier (Li et al. 2020) inside the solve: it acts the same way after every
 * scheme drape has (explicit, symplectic and backward Euler, whatever TS takes the
 * step), it needs no change to the matrix's sparsity (a pair couples four particles
 * that the lattice does not), and with continuous collision detection and a
 * fail-safe it guarantees by construction what the tests assert: a step that starts
 * without crossings ends without them. Its cost is a broad phase and a pass over
 * the close pairs per step; an IPC barrier needs line searches bounded by
 * collision-free step sizes inside every Newton iteration. */
#include "selfcontactimpl.h"
#include "proximity.h"
#include <drape.h>
#include <petscviewer.h>

/* A point within this fraction of the thickness of a triangle at a time its four
 * points are coplanar (or two edges within it) collides. */
#define SELF_CCD_TOL 1e-3
/* The position correction towards the thickness per step, as a fraction of it. */
#define SELF_PUSH_MAX 0.25
/* A candidate list's boxes also cover this many more steps of each particle's
 * motion, so that a cloth moving steadily keeps its list for as many steps. */
#define SELF_PREDICT_STEPS 2

struct _p_SelfContact {
  MPI_Comm         comm;
  Cloth            cloth;
  PetscBool        enabled;
  PetscReal        thickness, mu;
  PetscInt         its;
  PetscReal        margin; /* of the Verlet list, in thicknesses */
  PetscBool        hash;   /* broad phase by the spatial hash (else CGAL) */
  SelfMesh         mesh;
  PetscInt         N, nowned;
  PetscMPIInt     *counts3, *displs3, *counts6, *displs6; /* Allgatherv layouts, reals */
  PetscInt        *gather_nat;                            /* natural index of each gathered particle */
  PetscReal       *invm;                                  /* 1/m, 0 pinned (natural) */
  PetscReal       *x0, *x1, *v;                           /* natural, 3 each */
  PetscReal       *lo, *hi;                               /* each particle's sweep at the last broad phase */
  PetscReal       *send, *recv;
  PetscBool        zones;              /* fail-safe by rigid impact zones (else stop the particles) */
  PetscInt         npt, nee, *pt, *ee; /* candidate pairs */
  SelfContactStats stats;
};

PetscErrorCode SelfContactCreate(MPI_Comm comm, Cloth cloth, SelfContact *self)
{
  SelfContact sc;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&sc));
  sc->comm   = comm;
  sc->cloth  = cloth;
  sc->mu     = 0.3;
  sc->its    = 8;
  sc->margin = 1;
  sc->hash   = PETSC_TRUE;
  sc->zones  = PETSC_TRUE;
  *self      = sc;
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSetFromOptions(SelfContact sc)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(sc->comm, NULL, "Self-contact of the cloth", "SelfContact");
  PetscCall(PetscOptionsBool("-contact_self", "The cloth does not pass through itself (proximity impulses, continuous collisions, fail-safe)", "SelfContactSetFromOptions", sc->enabled, &sc->enabled, NULL));
  PetscCall(PetscOptionsReal("-contact_self_thickness", "Distance the cloth keeps from itself (m; 0: a quarter of the lattice spacing)", "SelfContactSetFromOptions", sc->thickness, &sc->thickness, NULL));
  PetscCall(PetscOptionsReal("-contact_self_friction", "Coulomb friction coefficient between layers of the cloth", "SelfContactSetFromOptions", sc->mu, &sc->mu, NULL));
  PetscCall(PetscOptionsReal("-contact_self_margin", "Candidate pairs are kept while no particle moved more than this many thicknesses beyond its sweep when they were found", "SelfContactSetFromOptions", sc->margin, &sc->margin, NULL));
  {
    const char *const kinds[] = {"cgal", "hash"};
    PetscInt          kind    = sc->hash;
    PetscCall(PetscOptionsEList("-contact_self_broad_phase", "Broad phase: CGAL's box intersection or a uniform spatial hash (the same pairs)", "SelfContactSetFromOptions", kinds, 2, kinds[kind], &kind, NULL));
    sc->hash = (PetscBool) (kind == 1);
  }
  {
    const char *const kinds[] = {"freeze", "zones"};
    PetscInt          kind    = sc->zones;
    PetscCall(
      PetscOptionsEList("-contact_self_failsafe", "Fail-safe for pairs still colliding after the collision passes: rigid impact zones, or stop the particles at the start of the step", "SelfContactSetFromOptions", kinds, 2, kinds[kind], &kind, NULL));
    sc->zones = (PetscBool) (kind == 1);
  }
  PetscCall(PetscOptionsInt("-contact_self_its", "Passes of collision impulses before the fail-safe takes the pairs still colliding", "SelfContactSetFromOptions", sc->its, &sc->its, NULL));
  PetscOptionsEnd();
  PetscCall(DrapeCheckReal(sc->comm, "-contact_self_thickness", 1, &sc->thickness, 0, 1, "m (0: a quarter of the lattice spacing)"));
  PetscCall(DrapeCheckReal(sc->comm, "-contact_self_friction", 1, &sc->mu, 0, 10, ""));
  PetscCall(DrapeCheckReal(sc->comm, "-contact_self_margin", 1, &sc->margin, 0, 100, "thicknesses"));
  PetscCall(DrapeCheckIntOption(sc->comm, "-contact_self_its"));
  PetscCall(DrapeCheckInt(sc->comm, "-contact_self_its", sc->its, 0, 1000));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactEnabled(SelfContact sc, PetscBool *enabled)
{
  PetscFunctionBeginUser;
  *enabled = sc->enabled;
  PetscFunctionReturn(0);
}

/* The cloth's surface: two triangles per lattice cell whose four corners are cloth;
 * their edges once (warp, weft and the cell's diagonal). */
static PetscErrorCode SelfMeshCreate(Cloth cloth, PetscInt Mx, PetscInt My, SelfMesh *m)
{
  PetscInt  nc = 0, *isvert, ne = 0;
  PetscInt *edges;

  PetscFunctionBeginUser;
  for (PetscInt j = 0; j + 1 < My; j++)
    for (PetscInt i = 0; i + 1 < Mx; i++)
      if (ClothIsActive(cloth, i, j) && ClothIsActive(cloth, i + 1, j) && ClothIsActive(cloth, i, j + 1) && ClothIsActive(cloth, i + 1, j + 1)) nc++;
  m->nt = 2 * nc;
  PetscCall(PetscMalloc1(3 * m->nt + 1, &m->tri));
  PetscCall(PetscMalloc1(10 * nc + 1, &edges));
  PetscCall(PetscCalloc1(Mx * My, &isvert));
  nc = 0;
  for (PetscInt j = 0; j + 1 < My; j++)
    for (PetscInt i = 0; i + 1 < Mx; i++) {
      const PetscInt a = j * Mx + i, b = a + 1, c = a + Mx, d = c + 1; /* (i,j) (i+1,j) (i,j+1) (i+1,j+1) */
      if (!(ClothIsActive(cloth, i, j) && ClothIsActive(cloth, i + 1, j) && ClothIsActive(cloth, i, j + 1) && ClothIsActive(cloth, i + 1, j + 1))) continue;
      const PetscInt t[6] = {a, b, d, a, d, c}, e[10] = {a, b, a, c, a, d, c, d, b, d};
      for (PetscInt k = 0; k < 6; k++) m->tri[6 * nc + k] = t[k];
      for (PetscInt k = 0; k < 10; k++) edges[ne * 2 + k] = e[k];
      ne += 5;
      isvert[a] = isvert[b] = isvert[c] = isvert[d] = 1;
      nc++;
    }
  /* unique edges: an edge is shared by at most two cells; key min * N + max */
  {
    PetscInt64 *key;
    PetscInt    n = 0;
    PetscCall(PetscMalloc1(ne + 1, &key));
    for (PetscInt k = 0; k < ne; k++) key[k] = (PetscInt64) PetscMin(edges[2 * k], edges[2 * k + 1]) * (Mx * My) + PetscMax(edges[2 * k], edges[2 * k + 1]);
    PetscCall(PetscSortInt64(ne, key));
    for (PetscInt k = 0; k < ne; k++)
      if (k == 0 || key[k] != key[k - 1]) {
        edges[2 * n]     = (PetscInt) (key[k] / (Mx * My));
        edges[2 * n + 1] = (PetscInt) (key[k] % (Mx * My));
        n++;
      }
    m->ne   = n;
    m->edge = edges;
    PetscCall(PetscFree(key));
  }
  m->nv = 0;
  for (PetscInt p = 0; p < Mx * My; p++) m->nv += isvert[p];
  PetscCall(PetscMalloc1(m->nv + 1, &m->vert));
  m->nv = 0;
  for (PetscInt p = 0; p < Mx * My; p++)
    if (isvert[p]) m->vert[m->nv++] = p;
  PetscCall(PetscFree(isvert));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSetUp(SelfContact sc)
{
  ClothInfo        info;
  const PetscInt  *natural;
  const PetscReal *mass;
  const PetscBool *pinned;
  PetscMPIInt      size, nown;
  PetscMPIInt     *counts1, *displs1;
  PetscReal       *mp;

  PetscFunctionBeginUser;
  if (!sc->enabled) PetscFunctionReturn(0);
  PetscCall(ClothGetInfo(sc->cloth, &info));
  PetscCall(ClothGetNatural(sc->cloth, &natural));
  PetscCall(ClothGetMasses(sc->cloth, &mass, &pinned));
  if (sc->thickness == 0) sc->thickness = 0.25 * PetscMin(info.spacing[0], info.spacing[1]);
  sc->stats.thickness = sc->thickness;
  sc->N               = info.nparticles;
  sc->nowned          = info.nowned;
  PetscCheck(6 * (PetscInt64) sc->N < PETSC_MPI_INT_MAX, sc->comm, PETSC_ERR_SUP, "-contact_self gathers the whole cloth on every rank; %" PetscInt_FMT " particles are more than one MPI message holds (at most %d)", sc->N, PETSC_MPI_INT_MAX / 6);
  PetscCallMPI(MPI_Comm_size(sc->comm, &size));
  PetscCall(PetscMPIIntCast(sc->nowned, &nown));
  PetscCall(PetscMalloc4(size, &sc->counts3, size, &sc->displs3, size, &sc->counts6, size, &sc->displs6));
  PetscCall(PetscMalloc2(size, &counts1, size, &displs1));
  PetscCallMPI(MPI_Allgather(&nown, 1, MPI_INT, counts1, 1, MPI_INT, sc->comm));
  displs1[0] = 0;
  for (PetscMPIInt r = 0; r < size; r++) {
    if (r > 0) displs1[r] = displs1[r - 1] + counts1[r - 1];
    sc->counts3[r] = 3 * counts1[r];
    sc->displs3[r] = 3 * displs1[r];
    sc->counts6[r] = 6 * counts1[r];
    sc->displs6[r] = 6 * displs1[r];
  }
  PetscCall(PetscMalloc1(sc->N, &sc->gather_nat));
  PetscCallMPI(MPI_Allgatherv(natural, nown, MPIU_INT, sc->gather_nat, counts1, displs1, MPIU_INT, sc->comm));
  /* 1/m by natural index (0: pinned, never moved by an impulse) */
  PetscCall(PetscMalloc2(6 * sc->N, &sc->recv, 6 * sc->nowned + 1, &sc->send));
  PetscCall(PetscMalloc1(sc->N, &sc->invm));
  mp = sc->send;
  for (PetscInt k = 0; k < sc->nowned; k++) mp[k] = pinned[k] || mass[k] <= 0 ? 0 : 1 / mass[k];
  PetscCallMPI(MPI_Allgatherv(mp, nown, MPIU_REAL, sc->recv, counts1, displs1, MPIU_REAL, sc->comm));
  for (PetscInt k = 0; k < sc->N; k++) sc->invm[sc->gather_nat[k]] = sc->recv[k];
  PetscCall(PetscFree2(counts1, displs1));
  PetscCall(PetscMalloc5(3 * sc->N, &sc->x0, 3 * sc->N, &sc->x1, 3 * sc->N, &sc->v, 3 * sc->N, &sc->lo, 3 * sc->N, &sc->hi));
  PetscCall(SelfMeshCreate(sc->cloth, info.Mx, info.My, &sc->mesh));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactView(SelfContact sc, PetscViewer viewer)
{
  PetscFunctionBeginUser;
  if (!sc->enabled) PetscFunctionReturn(0);
  PetscCall(PetscViewerASCIIPrintf(viewer, "Self-contact: thickness %g m, friction mu = %g, %" PetscInt_FMT " triangles, %" PetscInt_FMT " edges (the whole cloth on every rank)\n", (double) sc->thickness, (double) sc->mu, sc->mesh.nt, sc->mesh.ne));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactDestroy(SelfContact *self)
{
  SelfContact sc = *self;

  PetscFunctionBeginUser;
  if (!sc) PetscFunctionReturn(0);
  PetscCall(PetscFree4(sc->counts3, sc->displs3, sc->counts6, sc->displs6));
  PetscCall(PetscFree(sc->gather_nat));
  PetscCall(PetscFree2(sc->recv, sc->send));
  PetscCall(PetscFree(sc->invm));
  PetscCall(PetscFree5(sc->x0, sc->x1, sc->v, sc->lo, sc->hi));
  PetscCall(PetscFree(sc->pt));
  PetscCall(PetscFree(sc->ee));
  PetscCall(PetscFree(sc->mesh.vert));
  PetscCall(PetscFree(sc->mesh.tri));
  PetscCall(PetscFree(sc->mesh.edge));
  PetscCall(PetscFree(*self));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactGetStats(SelfContact sc, SelfContactStats *stats)
{
  PetscFunctionBeginUser;
  *stats = sc->stats;
  PetscFunctionReturn(0);
}

/* Owned positions (and velocities) -> natural-order copies on every rank. */
static PetscErrorCode Gather(SelfContact sc, const PetscScalar *x, const PetscScalar *v, PetscReal *X, PetscReal *V)
{
  const PetscInt nper = v ? 6 : 3;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < sc->nowned; k++)
    for (PetscInt d = 0; d < 3; d++) {
      sc->send[nper * k + d] = PetscRealPart(x[3 * k + d]);
      if (v) sc->send[nper * k + 3 + d] = PetscRealPart(v[3 * k + d]);
    }
  PetscCallMPI(MPI_Allgatherv(sc->send, (PetscMPIInt) (nper * sc->nowned), MPIU_REAL, sc->recv, v ? sc->counts6 : sc->counts3, v ? sc->displs6 : sc->displs3, MPIU_REAL, sc->comm));
  for (PetscInt k = 0; k < sc->N; k++) {
    const PetscInt p = sc->gather_nat[k];
    for (PetscInt d = 0; d < 3; d++) {
      X[3 * p + d] = sc->recv[nper * k + d];
      if (v) V[3 * p + d] = sc->recv[nper * k + 3 + d];
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactBeginStep(SelfContact sc, const PetscScalar *x)
{
  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.self_contact, 0, 0, 0, 0));
  PetscCall(Gather(sc, x, NULL, sc->x0, NULL));
  PetscCall(PetscLogEventEnd(drape_log.self_contact, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

/* ---- the filter, on the natural-order copies (the same on every rank) ---- */

typedef struct {
  PetscInt  p[4]; /* particles                                                  */
  PetscReal w[4]; /* weights: the pair's gap along n is sum_i w_i x_i . n        */
} Pair;

/* Do the boxes of the pair's two primitives (particles p[0..na) and p[na..4)) over
 * the positions of X and Y overlap when grown by tol? */
static PetscBool PairBoxesOverlap(const PetscInt p[4], PetscInt na, const PetscReal *X, const PetscReal *Y, PetscReal tol)
{
  for (PetscInt d = 0; d < 3; d++) {
    PetscReal alo = PETSC_MAX_REAL, ahi = -PETSC_MAX_REAL, blo = PETSC_MAX_REAL, bhi = -PETSC_MAX_REAL;
    for (PetscInt i = 0; i < 4; i++) {
      const PetscReal a = X[3 * p[i] + d], b = Y[3 * p[i] + d];
      if (i < na)
        alo = PetscMin(alo, PetscMin(a, b)), ahi = PetscMax(ahi, PetscMax(a, b));
      else
        blo = PetscMin(blo, PetscMin(a, b)), bhi = PetscMax(bhi, PetscMax(a, b));
    }
    if (alo > bhi + tol || blo > ahi + tol) return PETSC_FALSE;
  }
  return PETSC_TRUE;
}

/* The particles of candidate (kind, k): the point and the triangle's three, or the two edges'. */
static void PairParticles(const SelfContact sc, PetscInt kind, PetscInt k, PetscInt p[4])
{
  if (kind == 0) {
    const PetscInt v = sc->mesh.vert[sc->pt[2 * k]], *T = sc->mesh.tri + 3 * sc->pt[2 * k + 1];
    p[0] = v, p[1] = T[0], p[2] = T[1], p[3] = T[2];
  } else {
    const PetscInt *e = sc->mesh.edge + 2 * sc->ee[2 * k], *f = sc->mesh.edge + 2 * sc->ee[2 * k + 1];
    p[0] = e[0], p[1] = e[1], p[2] = f[0], p[3] = f[1];
  }
}

static inline void WeightsPT(Pair *pr, const PetscReal w[3]) { pr->w[0] = 1, pr->w[1] = -w[0], pr->w[2] = -w[1], pr->w[3] = -w[2]; }
static inline void WeightsEE(Pair *pr, PetscReal s, PetscReal u) { pr->w[0] = -(1 - s), pr->w[1] = -s, pr->w[2] = 1 - u, pr->w[3] = u; }

/* The pair's closest points at positions X (its particles set by PairParticles):
 * the weights, the unit normal from the first primitive (triangle, first edge) to
 * the second (point, second edge) and the distance. */
static PetscReal PairClosest(PetscInt kind, const PetscReal *X, Pair *pr, PetscReal n[3])
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

/* The pair's relative displacement over the step along n. */
static PetscReal PairDisplacement(const SelfContact sc, const Pair *pr, const PetscReal n[3])
{
  PetscReal g = 0;
  for (PetscInt i = 0; i < 4; i++)
    for (PetscInt d = 0; d < 3; d++) g += pr->w[i] * (sc->x1[3 * pr->p[i] + d] - sc->x0[3 * pr->p[i] + d]) * n[d];
  return g;
}

/* The impulse along the unit direction n that changes the pair's relative
 * displacement by dg (m): particle i moves by w_i/m_i lambda n (pinned: not at all);
 * with h > 0 its velocity changes by that over h. */
static PetscBool PairPush(SelfContact sc, const Pair *pr, const PetscReal n[3], PetscReal dg, PetscReal h)
{
  PetscReal den = 0, lam;
  for (PetscInt i = 0; i < 4; i++) den += pr->w[i] * pr->w[i] * sc->invm[pr->p[i]];
  if (den <= 0) return PETSC_FALSE;
  lam = dg / den;
  for (PetscInt i = 0; i < 4; i++) {
    const PetscInt  p = pr->p[i];
    const PetscReal s = lam * pr->w[i] * sc->invm[p];
    for (PetscInt d = 0; d < 3; d++) {
      sc->x1[3 * p + d] += s * n[d];
      if (h > 0) sc->v[3 * p + d] += s * n[d] / h;
    }
  }
  return PETSC_TRUE;
}

/* Proximity at the start of the step: stop the approach of every pair closer than
 * the thickness (friction bounded by the normal impulse), then push it apart in
 * position towards the thickness. Returns the number of such pairs. */
static PetscInt Proximity(SelfContact sc, PetscReal h)
{
  const PetscReal H     = sc->thickness;
  PetscInt        close = 0;

  for (PetscInt kind = 0; kind < 2; kind++)
    for (PetscInt k = 0; k < (kind ? sc->nee : sc->npt); k++) {
      Pair      pr;
      PetscReal n[3], dist, disp;
      PairParticles(sc, kind, k, pr.p);
      if (!PairBoxesOverlap(pr.p, kind == 0 ? 1 : 2, sc->x0, sc->x0, H)) continue;
      dist = PairClosest(kind, sc->x0, &pr, n);
      if (dist >= H || dist <= 0) continue; /* dist 0: touching at the start, no direction: the collision pass sees it */
      close++;
      disp = PairDisplacement(sc, &pr, n);
      if (disp < 0 && PairPush(sc, &pr, n, -disp, h)) {
        /* Coulomb: the relative tangential velocity drops by at most mu times the
         * normal velocity change -disp/h */
        PetscReal vr[3] = {0, 0, 0}, vn, vt[3], lt;
        for (PetscInt i = 0; i < 4; i++)
          for (PetscInt d = 0; d < 3; d++) vr[d] += pr.w[i] * sc->v[3 * pr.p[i] + d];
        vn = V3Dot(vr, n);
        for (PetscInt d = 0; d < 3; d++) vt[d] = vr[d] - vn * n[d];
        lt = V3Norm(vt);
        if (lt > 0) {
          const PetscReal dvt = PetscMin(lt, sc->mu * (-disp / h));
          for (PetscInt d = 0; d < 3; d++) vt[d] /= lt;
          PairPush(sc, &pr, vt, -dvt * h, h);
        }
        disp = PairDisplacement(sc, &pr, n);
      }
      if (dist + disp < H) PairPush(sc, &pr, n, PetscMin(H - dist - disp, SELF_PUSH_MAX * H), 0);
    }
  return close;
}

/* Continuous collision of candidate (kind, k) over the step from x0 to x1: the pair,
 * its unit normal at the collision oriented by the start (the gap sum w_i x0_i . n
 * is positive); PETSC_FALSE if it does not collide. */
static PetscBool Collides(SelfContact sc, PetscInt kind, PetscInt k, Pair *pr, PetscReal n[3])
{
  const PetscReal tol = SELF_CCD_TOL * sc->thickness;
  PetscReal       D[4][3], X[4][3], t, gap0 = 0;

  PairParticles(sc, kind, k, pr->p);
  if (!PairBoxesOverlap(pr->p, kind == 0 ? 1 : 2, sc->x0, sc->x1, tol)) return PETSC_FALSE; /* most candidates of a kept list */
  for (PetscInt i = 0; i < 4; i++) V3Sub(sc->x1 + 3 * pr->p[i], sc->x0 + 3 * pr->p[i], D[i]);
  {
    const PetscReal *x0 = sc->x0;
    const PetscInt  *p  = pr->p;
    if (kind == 0) {
      PetscReal w[3];
      if (!PointTriangleCollision(x0 + 3 * p[0], D[0], x0 + 3 * p[1], D[1], x0 + 3 * p[2], D[2], x0 + 3 * p[3], D[3], tol, &t, w)) return PETSC_FALSE;
      WeightsPT(pr, w);
    } else {
      PetscReal s, u;
      if (!EdgeEdgeCollision(x0 + 3 * p[0], D[0], x0 + 3 * p[1], D[1], x0 + 3 * p[2], D[2], x0 + 3 * p[3], D[3], tol, &t, &s, &u)) return PETSC_FALSE;
      WeightsEE(pr, s, u);
    }
    for (PetscInt i = 0; i < 4; i++) V3At(x0 + 3 * p[i], D[i], t, X[i]);
  }
  {
    /* the normal at the collision: the triangle's, or the two edges' common normal */
    PetscReal e1[3], e2[3], len;
    if (kind == 0) {
      V3Sub(X[2], X[1], e1);
      V3Sub(X[3], X[1], e2);
    } else {
      V3Sub(X[1], X[0], e1);
      V3Sub(X[3], X[2], e2);
    }
    V3Cross(e1, e2, n);
    len = V3Norm(n);
    if (len <= 1e-12 * V3Norm(e1) * V3Norm(e2)) { /* parallel edges (or a degenerate triangle): the direction at the start */
      for (PetscInt d = 0; d < 3; d++) n[d] = 0;
      for (PetscInt i = 0; i < 4; i++)
        for (PetscInt d = 0; d < 3; d++) n[d] += pr->w[i] * sc->x0[3 * pr->p[i] + d];
      len = V3Norm(n);
      if (len == 0) return PETSC_FALSE;
    }
    for (PetscInt d = 0; d < 3; d++) n[d] /= len;
  }
  for (PetscInt i = 0; i < 4; i++)
    for (PetscInt d = 0; d < 3; d++) gap0 += pr->w[i] * sc->x0[3 * pr->p[i] + d] * n[d];
  if (gap0 < 0)
    for (PetscInt d = 0; d < 3; d++) n[d] = -n[d];
  return PETSC_TRUE;
}

/* The candidate pairs (a Verlet list): boxes of the sweep x0 -> x1, extended by
 * SELF_PREDICT_STEPS more steps of the same motion, grown by half the thickness and
 * a margin of one thickness. While no particle's start or end position is more than
 * the margin outside its box at the last broad phase, the list holds every pair
 * closer than the thickness at the start and every pair that can collide: it is
 * kept across impulses and steps, and rebuilt only when a particle moved further
 * (every third step or so while the cloth falls steadily; never while it rests).
 * Extra candidates do nothing (the passes act on close or colliding pairs, in the
 * sorted order), so the list's extent changes the cost, not the result. */

static PetscErrorCode BroadPhase(SelfContact sc)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree(sc->pt));
  PetscCall(PetscFree(sc->ee));
  for (PetscInt k = 0; k < 3 * sc->N; k++) {
    /* a non-finite box has no cells (the hash) or no order (CGAL) */
    PetscCheck(!PetscIsInfOrNanReal(sc->x0[k]) && !PetscIsInfOrNanReal(sc->x1[k]), PETSC_COMM_SELF, PETSC_ERR_FP, "Self-contact: a particle's position is not finite (the step diverged); reduce -ts_dt or use -ts_type drapebe");
    const PetscReal ahead = sc->x1[k] + SELF_PREDICT_STEPS * (sc->x1[k] - sc->x0[k]);
    sc->lo[k]             = PetscMin(PetscMin(sc->x0[k], sc->x1[k]), ahead);
    sc->hi[k]             = PetscMax(PetscMax(sc->x0[k], sc->x1[k]), ahead);
  }
  PetscCall(PetscLogEventBegin(drape_log.self_broad, 0, 0, 0, 0));
  PetscCall((sc->hash ? SelfBroadPhaseHash : SelfBroadPhase)(&sc->mesh, sc->lo, sc->hi, (0.5 + sc->margin) * sc->thickness, &sc->npt, &sc->pt, &sc->nee, &sc->ee));
  PetscCall(PetscLogEventEnd(drape_log.self_broad, 0, 0, 0, 0));
  sc->stats.broad_phases++;
  PetscFunctionReturn(0);
}

static PetscErrorCode BroadPhaseIfMoved(SelfContact sc)
{
  const PetscReal m     = sc->margin * sc->thickness;
  PetscBool       valid = sc->pt ? PETSC_TRUE : PETSC_FALSE;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < 3 * sc->N && valid; k++)
    if (PetscMin(sc->x0[k], sc->x1[k]) < sc->lo[k] - m || PetscMax(sc->x0[k], sc->x1[k]) > sc->hi[k] + m) valid = PETSC_FALSE;
  if (!valid) PetscCall(BroadPhase(sc));
  PetscFunctionReturn(0);
}

/* ---- rigid impact zones (Provot 1997; Bridson, Fedkiw & Anderson 2002, 7.4) ----
 * The particles of pairs that still collide are merged into zones (union-find, the
 * root the zone's smallest particle: the same zones in any order), and each zone
 * moves rigidly over the step: the translation and rotation that keep the linear
 * and angular momentum of its particles' displacements. Straight-line
 * interpolation of a rotation by less than pi is an invertible affine map, so a
 * zone, collision-free at the start, does not collide with itself; zones that
 * collide with each other merge, until none does (at worst the whole cloth moves
 * rigidly). A zone holding a pinned particle stays where it was. */

static PetscInt ZoneRoot(PetscInt *parent, PetscInt p)
{
  while (parent[p] != p) {
    parent[p] = parent[parent[p]];
    p         = parent[p];
  }
  return p;
}

/* Put the pair's particles in one zone; PETSC_TRUE if that changed any zone. */
static PetscBool ZoneMerge(PetscInt *parent, const PetscInt p[4])
{
  PetscBool changed = PETSC_FALSE;
  PetscInt  r;

  for (PetscInt i = 0; i < 4; i++)
    if (parent[p[i]] < 0) parent[p[i]] = p[i], changed = PETSC_TRUE;
  r = ZoneRoot(parent, p[0]);
  for (PetscInt i = 1; i < 4; i++) {
    const PetscInt q = ZoneRoot(parent, p[i]);
    if (q == r) continue;
    parent[PetscMax(q, r)] = PetscMin(q, r);
    r                      = PetscMin(q, r);
    changed                = PETSC_TRUE;
  }
  return changed;
}

/* Rodrigues: R a for the rotation vector th */
static void Rotate(const PetscReal th[3], const PetscReal a[3], PetscReal Ra[3])
{
  const PetscReal ang = V3Norm(th);
  PetscReal       k[3], kxa[3], c, s, ka;

  if (ang == 0) {
    for (PetscInt d = 0; d < 3; d++) Ra[d] = a[d];
    return;
  }
  for (PetscInt d = 0; d < 3; d++) k[d] = th[d] / ang;
  V3Cross(k, a, kxa);
  c = PetscCosReal(ang), s = PetscSinReal(ang), ka = V3Dot(k, a);
  for (PetscInt d = 0; d < 3; d++) Ra[d] = a[d] * c + kxa[d] * s + k[d] * ka * (1 - c);
}

/* Move every zone rigidly (see above) from the end positions xs the step had when
 * the fail-safe began (not from a previous round's rigid motion, which would lose a
 * little rotation at every round); returns the number of particles in zones. work:
 * 16 N reals, pinned: N flags; zone: the union-find parents (-1 outside a zone). */
static PetscErrorCode ZonesRigidify(SelfContact sc, PetscReal h, PetscInt *zone, const PetscReal *xs, PetscReal *work, PetscBool *pinned, PetscInt *inzones)
{
  const PetscInt N = sc->N;
  /* per root: mass, mass-weighted start and displacement, then centre, translation, angular momentum (then rotation), inertia */
  PetscReal *m = work, *c = m + N, *u = c + 3 * N, *L = u + 3 * N, *In = L + 3 * N;

  PetscFunctionBeginUser;
  PetscCall(PetscArrayzero(work, 16 * N));
  PetscCall(PetscArrayzero(pinned, N));
  *inzones = 0;
  for (PetscInt p = 0; p < N; p++) {
    PetscInt r;
    if (zone[p] < 0) continue;
    r = ZoneRoot(zone, p);
    (*inzones)++;
    if (sc->invm[p] == 0) {
      pinned[r] = PETSC_TRUE;
      continue;
    }
    m[r] += 1 / sc->invm[p];
    for (PetscInt d = 0; d < 3; d++) {
      c[3 * r + d] += sc->x0[3 * p + d] / sc->invm[p];
      u[3 * r + d] += (xs[3 * p + d] - sc->x0[3 * p + d]) / sc->invm[p];
    }
  }
  for (PetscInt r = 0; r < N; r++)
    if (m[r] > 0)
      for (PetscInt d = 0; d < 3; d++) c[3 * r + d] /= m[r], u[3 * r + d] /= m[r];
  for (PetscInt p = 0; p < N; p++) {
    PetscInt  r;
    PetscReal rp[3], up[3], l[3], mp;
    if (zone[p] < 0 || sc->invm[p] == 0) continue;
    r = ZoneRoot(zone, p);
    if (pinned[r]) continue;
    mp = 1 / sc->invm[p];
    for (PetscInt d = 0; d < 3; d++) rp[d] = sc->x0[3 * p + d] - c[3 * r + d], up[d] = xs[3 * p + d] - sc->x0[3 * p + d] - u[3 * r + d];
    V3Cross(rp, up, l);
    for (PetscInt d = 0; d < 3; d++) L[3 * r + d] += mp * l[d];
    /* inertia: m (|r|^2 1 - r r^T), upper triangle xx xy xz yy yz zz */
    In[6 * r + 0] += mp * (rp[1] * rp[1] + rp[2] * rp[2]);
    In[6 * r + 1] -= mp * rp[0] * rp[1];
    In[6 * r + 2] -= mp * rp[0] * rp[2];
    In[6 * r + 3] += mp * (rp[0] * rp[0] + rp[2] * rp[2]);
    In[6 * r + 4] -= mp * rp[1] * rp[2];
    In[6 * r + 5] += mp * (rp[0] * rp[0] + rp[1] * rp[1]);
  }
  /* the rotation over the step: theta = I^-1 L (by cofactors). Translation only (the
   * angular momentum not kept) if I is singular, a zone of collinear particles, or
   * the angle reaches pi/2. The velocity set after is the rigid motion's at the end,
   * u/h + omega x R r: to second order in the angle the displacement over h. */
  for (PetscInt r = 0; r < N; r++) {
    const PetscReal *A = In + 6 * r;
    PetscReal        cof[6], det, th[3];
    if (!(m[r] > 0) || pinned[r]) continue;
    cof[0] = A[3] * A[5] - A[4] * A[4];
    cof[1] = A[2] * A[4] - A[1] * A[5];
    cof[2] = A[1] * A[4] - A[2] * A[3];
    cof[3] = A[0] * A[5] - A[2] * A[2];
    cof[4] = A[1] * A[2] - A[0] * A[4];
    cof[5] = A[0] * A[3] - A[1] * A[1];
    det    = A[0] * cof[0] + A[1] * cof[1] + A[2] * cof[2];
    th[0] = th[1] = th[2] = 0;
    if (det > 1e-12 * PetscPowReal(A[0] + A[3] + A[5], 3)) {
      const PetscReal *l = L + 3 * r;
      th[0]              = (cof[0] * l[0] + cof[1] * l[1] + cof[2] * l[2]) / det;
      th[1]              = (cof[1] * l[0] + cof[3] * l[1] + cof[4] * l[2]) / det;
      th[2]              = (cof[2] * l[0] + cof[4] * l[1] + cof[5] * l[2]) / det;
      if (V3Norm(th) >= PETSC_PI / 2) th[0] = th[1] = th[2] = 0;
    }
    for (PetscInt d = 0; d < 3; d++) L[3 * r + d] = th[d]; /* L now holds the rotation */
  }
  for (PetscInt p = 0; p < N; p++) {
    PetscInt  r;
    PetscReal rp[3], Rr[3], w[3], wxr[3];
    if (zone[p] < 0 || sc->invm[p] == 0) continue;
    r = ZoneRoot(zone, p);
    if (pinned[r]) {
      for (PetscInt d = 0; d < 3; d++) sc->x1[3 * p + d] = sc->x0[3 * p + d], sc->v[3 * p + d] = 0;
      continue;
    }
    for (PetscInt d = 0; d < 3; d++) rp[d] = sc->x0[3 * p + d] - c[3 * r + d], w[d] = L[3 * r + d] / h;
    Rotate(L + 3 * r, rp, Rr);
    V3Cross(w, Rr, wxr);
    for (PetscInt d = 0; d < 3; d++) {
      sc->x1[3 * p + d] = c[3 * r + d] + u[3 * r + d] + Rr[d];
      sc->v[3 * p + d]  = u[3 * r + d] / h + wxr[d];
    }
  }
  PetscFunctionReturn(0);
}

/* The fail-safe by impact zones: *count particles in zones. */
static PetscErrorCode FailSafeZones(SelfContact sc, PetscReal h, PetscInt *count)
{
  PetscInt   merged, rounds = 0, *zone;
  PetscReal *xs, *work;
  PetscBool *pinned;

  PetscFunctionBeginUser;
  *count = 0;
  PetscCall(PetscMalloc4(sc->N, &zone, 3 * sc->N, &xs, 16 * sc->N, &work, sc->N, &pinned));
  PetscCall(PetscArraycpy(xs, sc->x1, 3 * sc->N));
  for (PetscInt p = 0; p < sc->N; p++) zone[p] = -1;
  do {
    PetscCall(BroadPhaseIfMoved(sc));
    merged = 0;
    for (PetscInt kind = 0; kind < 2; kind++)
      for (PetscInt k = 0; k < (kind ? sc->nee : sc->npt); k++) {
        Pair      pr;
        PetscReal n[3];
        if (Collides(sc, kind, k, &pr, n) && ZoneMerge(zone, pr.p)) merged++;
      }
    if (merged) PetscCall(ZonesRigidify(sc, h, zone, xs, work, pinned, count));
    /* each round merges zones or adds particles to them: at most 2 N rounds */
    PetscCheck(++rounds <= 2 * sc->N + 1, PETSC_COMM_SELF, PETSC_ERR_PLIB, "Self-contact impact zones did not settle in %" PetscInt_FMT " rounds", rounds);
  } while (merged);
  PetscCall(PetscFree4(zone, xs, work, pinned));
  PetscFunctionReturn(0);
}

/* The fail-safe by stopping: the particles of every pair that still collides stay
 * where they were at the start (collision-free); the ones they now collide with
 * follow. *count particles stopped. */
static PetscErrorCode FailSafeFreeze(SelfContact sc, PetscInt *count)
{
  PetscInt   frozen;
  PetscBool *stopped;

  PetscFunctionBeginUser;
  *count = 0;
  PetscCall(PetscCalloc1(sc->N, &stopped));
  do {
    PetscCall(BroadPhaseIfMoved(sc));
    frozen = 0;
    for (PetscInt kind = 0; kind < 2; kind++)
      for (PetscInt k = 0; k < (kind ? sc->nee : sc->npt); k++) {
        Pair      pr;
        PetscReal n[3];
        if (!Collides(sc, kind, k, &pr, n)) continue;
        for (PetscInt i = 0; i < 4; i++) {
          const PetscInt p = pr.p[i];
          if (stopped[p] || sc->invm[p] == 0) continue;
          stopped[p] = PETSC_TRUE;
          for (PetscInt d = 0; d < 3; d++) {
            sc->x1[3 * p + d] = sc->x0[3 * p + d];
            sc->v[3 * p + d]  = 0;
          }
          frozen++;
        }
      }
    *count += frozen;
  } while (frozen);
  PetscCall(PetscFree(stopped));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactFilter(SelfContact sc, PetscReal h, PetscScalar *x, PetscScalar *v, PetscBool *changed)
{
  PetscInt ncol = 1, ncol_total = 0, failsafe = 0;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.self_contact, 0, 0, 0, 0));
  PetscCall(Gather(sc, x, v, sc->x1, sc->v));
  PetscCall(BroadPhaseIfMoved(sc));
  sc->stats.pairs = Proximity(sc, h);
  for (PetscInt it = 0; it < sc->its && ncol; it++) {
    PetscCall(BroadPhaseIfMoved(sc));
    ncol = 0;
    for (PetscInt kind = 0; kind < 2; kind++)
      for (PetscInt k = 0; k < (kind ? sc->nee : sc->npt); k++) {
        Pair      pr;
        PetscReal n[3], disp;
        if (!Collides(sc, kind, k, &pr, n)) continue;
        disp = PairDisplacement(sc, &pr, n);
        if (disp < 0 && PairPush(sc, &pr, n, -disp, h)) ncol++;
      }
    sc->stats.collisions += ncol;
    ncol_total += ncol;
  }
  if (ncol || sc->its == 0) {
    PetscCall(sc->zones ? FailSafeZones(sc, h, &failsafe) : FailSafeFreeze(sc, &failsafe));
    sc->stats.failsafe += failsafe;
  }
  *changed = (PetscBool) (sc->stats.pairs || ncol_total || failsafe);
  {
    const PetscInt *natural;
    PetscCall(ClothGetNatural(sc->cloth, &natural));
    for (PetscInt k = 0; k < sc->nowned; k++)
      for (PetscInt d = 0; d < 3; d++) {
        x[3 * k + d] = sc->x1[3 * natural[k] + d];
        v[3 * k + d] = sc->v[3 * natural[k] + d];
      }
  }
  PetscCall(PetscLogEventEnd(drape_log.self_contact, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}
