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
 * collision-free step sizes inside every Newton iteration.
 *
 * On many ranks (a geometric halo). Each rank holds its own particles and a halo:
 * the particles of every cloth triangle whose box (the sweep of the step, grown for
 * the candidate list) reaches the box of the rank's own triangles. The halo is
 * found from boxes exchanged between ranks and moved with a PetscSF; it is rebuilt
 * with the candidate list, only when a particle moved more than the list's margin.
 * A rank evaluates every candidate pair with one of its own particles, from the
 * same inputs as every other rank that holds the pair. How the passes stay those
 * of one rank is said at Pass() below; no step gathers the whole cloth. */
#include "selfcontactimpl.h"
#include "proximity.h"
#include <drape.h>
#include <petscsf.h>
#include <petscviewer.h>
#include <stdlib.h> /* qsort */

/* A point within this fraction of the thickness of a triangle at a time its four
 * points are coplanar (or two edges within it) collides. */
#define SELF_CCD_TOL 1e-3
/* The position correction towards the thickness per step, as a fraction of it. */
#define SELF_PUSH_MAX 0.25
/* The largest change of a pair's relative position (in thicknesses) a collision
 * impulse makes; a faster impact goes to the fail-safe's impact zones. An impulse
 * moves the pair's particles against their lattice neighbours by what it takes
 * from the pair's approach: a sheet folding into itself at five to ten
 * thicknesses a step, stopped pair by pair, gained 0.42 J of stretch energy in
 * the impact step while its kinetic energy fell by 0.02 J (strain 37 %), and blew
 * up at 3, 4.2, 4.5 and 5 ms steps of backward Euler; with this bound it does not
 * (tests/test_self_contact.py). */
#define SELF_IMPULSE_MAX 1.0
/* A candidate list's boxes also cover this many more steps of each particle's
 * motion, so that a cloth moving steadily keeps its list for as many steps; and,
 * while that motion is shorter than the margin, up to SELF_PREDICT_MAX steps as
 * long as they stay within the margin (a skin sized from the particle's motion).
 * The stiff sphere drop at 64^2 and 0.1 ms (symplectic Euler), whose list lived
 * about 27 steps, made 111 lists with 2 steps, 83 with up to 10 (3.38 -> 3.10 CPU
 * s), 79 with 15 and 76 with 25, whose longer boxes cost more than they saved; with
 * every particle's box grown by a margin ahead (not capped in steps) 73 lists cost
 * 3.57 s. A step longer than half the margin (drapebe's) keeps 2. */
#define SELF_PREDICT_STEPS 2
#define SELF_PREDICT_MAX   10
/* Two patches whose pairs the candidate list may leave out (patches.c) are further
 * apart than this many thicknesses (a pair the list's test leaves out is further
 * apart than one thickness; rounding's slack). */
#define SELF_PATCH_APART (1 + 1e-6)
/* The near list's radius (-contact_self_near_radius), in thicknesses: past the
 * implicit solve's reach (2) by half a thickness, and below the 2.83 at which a
 * flat lattice at the default thickness (a quarter of the spacing) has the
 * triangles across a cell's diagonal from a particle. */
#define SELF_NEAR_RADIUS 2.5

PetscErrorCode SelfContactCreate(MPI_Comm comm, Cloth cloth, SelfContact *self)
{
  SelfContact sc;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&sc));
  sc->comm          = comm;
  sc->cloth         = cloth;
  sc->mu            = 0.3;
  sc->its           = 8;
  sc->margin        = 0.5;
  sc->near          = SELF_NEAR_RADIUS;
  sc->broad         = SELF_BROAD_TILES;
  sc->zones         = PETSC_TRUE;
  sc->unit3         = MPI_DATATYPE_NULL;
  sc->unit9         = MPI_DATATYPE_NULL;
  sc->solve.enabled = PETSC_TRUE;
  sc->use_patches   = PETSC_TRUE;
  sc->solve.edges   = PETSC_TRUE;
  *self             = sc;
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
  PetscCall(PetscOptionsReal("-contact_self_near_radius", "The passes take the candidates closer than this many thicknesses while no particle moved far enough to bring another within reach (0: every candidate, every pass)",
                             "SelfContactSetFromOptions", sc->near, &sc->near, NULL));
  {
    const char *const kinds[] = {"cgal", "hash", "tiles"};
    PetscInt          kind    = sc->broad;
    PetscCall(
      PetscOptionsEList("-contact_self_broad_phase", "Broad phase: CGAL's box intersection, a uniform spatial hash of the primitives, or of the lattice's tiles (the same pairs)", "SelfContactSetFromOptions", kinds, 3, kinds[kind], &kind, NULL));
    sc->broad = kind;
  }
  {
    const char *const kinds[] = {"freeze", "zones"};
    PetscInt          kind    = sc->zones;
    PetscCall(
      PetscOptionsEList("-contact_self_failsafe", "Fail-safe for pairs still colliding after the collision passes: rigid impact zones, or stop the particles at the start of the step", "SelfContactSetFromOptions", kinds, 2, kinds[kind], &kind, NULL));
    sc->zones = (PetscBool) (kind == 1);
  }
  PetscCall(PetscOptionsBool("-contact_self_solve", "In backward Euler (drapebe): the close pairs enter the step's solve as stiff one-sided penalties (the filter after the step stays)", "SelfContactSetFromOptions", sc->solve.enabled,
                             &sc->solve.enabled, NULL));
  PetscCall(PetscOptionsBool("-contact_self_solve_edges", "With -contact_self_solve: the close edge-edge pairs whose closest points are inside both edges enter the solve too (else point-triangle pairs only)", "SelfContactSetFromOptions",
                             sc->solve.edges, &sc->solve.edges, NULL));
  PetscCall(PetscOptionsReal("-contact_self_stiffness", "Stiffness of a pair's penalty in the solve (N/m; 0: 10 m/h^2, m the mean particle mass: a pair approaching by a thickness a step sinks by a tenth of it)", "SelfContactSetFromOptions",
                             sc->solve.k_set, &sc->solve.k_set, NULL));
  PetscCall(PetscOptionsBool("-contact_self_patches", "Where no one translation of the cloth keeps the candidate and near lists, test them patch by patch of the lattice (0: remake them then; the same pairs either way)", "SelfContactSetFromOptions",
                             sc->use_patches, &sc->use_patches, NULL));
  PetscCall(PetscOptionsInt("-contact_self_its", "Passes of collision impulses before the fail-safe takes the pairs still colliding", "SelfContactSetFromOptions", sc->its, &sc->its, NULL));
  PetscOptionsEnd();
  PetscCall(DrapeCheckReal(sc->comm, "-contact_self_thickness", 1, &sc->thickness, 0, 1, "m (0: a quarter of the lattice spacing)"));
  PetscCall(DrapeCheckReal(sc->comm, "-contact_self_friction", 1, &sc->mu, 0, 10, ""));
  PetscCall(DrapeCheckReal(sc->comm, "-contact_self_stiffness", 1, &sc->solve.k_set, 0, 1e12, "N/m (0: 10 m/h^2)"));
  PetscCall(DrapeCheckReal(sc->comm, "-contact_self_margin", 1, &sc->margin, 0, 100, "thicknesses"));
  PetscCall(DrapeCheckReal(sc->comm, "-contact_self_near_radius", 1, &sc->near, 0, 100, "thicknesses (0: no near list)"));
  PetscCall(DrapeCheckIntOption(sc->comm, "-contact_self_its"));
  PetscCall(DrapeCheckInt(sc->comm, "-contact_self_its", sc->its, 0, 1000));
  PetscFunctionReturn(0);
}
/* The list's margin is half a thickness in every scheme. An implicit step scans its
 * candidate list at every solve and every filter: the Cusick scene at 161^2 (denim,
 * drapebe, to rest), margin one thickness against a half, side by side:
 * self-contact 31.2 against 22.7 s of the first second (-log_view), 227 against 338
 * broad phases; a quarter took 24.1 s. An explicit step's passes take only the near
 * list's pairs within reach (NearWithin), so there too a shorter candidate list (its
 * near lists made from fewer candidates) pays for more broad phases: the stiff
 * symplectic sphere drop at 64^2 to 1 s, 7.4 CPU s at one thickness, 6.6 at a half,
 * 6.8 at three quarters, 7.7 at a quarter (BENCHMARKS.md). */
PetscErrorCode SelfContactSetImplicit(SelfContact sc, PetscBool implicit)
{
  PetscFunctionBeginUser;
  sc->implicit = implicit;
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactEnabled(SelfContact sc, PetscBool *enabled)
{
  PetscFunctionBeginUser;
  *enabled = sc->enabled;
  PetscFunctionReturn(0);
}

/* The cloth's surface: two triangles per lattice cell whose four corners are cloth,
 * their edges (warp, weft and the cell's diagonal) and their particles, named by
 * keys (selfcontactimpl.h) and found from (i, j), never listed for the whole cloth. */
static PetscBool CellAt(SelfContact sc, PetscInt i, PetscInt j)
{
  if (i < 0 || j < 0 || i + 1 >= sc->Mx || j + 1 >= sc->My) return PETSC_FALSE;
  return (PetscBool) (ClothIsActive(sc->cloth, i, j) && ClothIsActive(sc->cloth, i + 1, j) && ClothIsActive(sc->cloth, i, j + 1) && ClothIsActive(sc->cloth, i + 1, j + 1));
}

PetscBool SelfCellIsCloth(SelfContact sc, PetscInt a) { return CellAt(sc, a % sc->Mx, a / sc->Mx); }

/* The cells with corner p: at (i - 1, j - 1), (i, j - 1), (i - 1, j), (i, j). */
static void CellsAround(SelfContact sc, PetscInt p, PetscBool cell[4])
{
  const PetscInt i = p % sc->Mx, j = p / sc->Mx;
  cell[0] = CellAt(sc, i - 1, j - 1), cell[1] = CellAt(sc, i, j - 1), cell[2] = CellAt(sc, i - 1, j), cell[3] = CellAt(sc, i, j);
}

PetscInt SelfParticleTriangles(SelfContact sc, PetscInt p, PetscInt key[6])
{
  const PetscInt Mx = sc->Mx;
  PetscBool      cell[4];
  PetscInt       n = 0;

  CellsAround(sc, p, cell);
  if (cell[0]) key[n++] = 2 * (p - Mx - 1), key[n++] = 2 * (p - Mx - 1) + 1; /* p its far corner: both */
  if (cell[1]) key[n++] = 2 * (p - Mx) + 1;                                  /* p its corner (i, j + 1): the second */
  if (cell[2]) key[n++] = 2 * (p - 1);                                       /* p its corner (i + 1, j): the first */
  if (cell[3]) key[n++] = 2 * p, key[n++] = 2 * p + 1;
  return n;
}

static inline void EdgeParticles(PetscInt Mx, PetscInt key, PetscInt E[2])
{
  const PetscInt code = key % 3;
  E[0]                = key / 3;
  E[1]                = E[0] + (code == 0 ? 1 : code == 1 ? Mx : Mx + 1);
}

/* The keys of the triangles (tri) or edges whose first particle (smallest natural
 * index) is p, ascending: each primitive has one. */
static PetscInt FirstPrimitives(SelfContact sc, PetscBool tri, PetscInt p, PetscInt key[3])
{
  PetscBool cell[4];
  PetscInt  n = 0;

  if (tri) {
    if (CellAt(sc, p % sc->Mx, p / sc->Mx)) key[n++] = 2 * p, key[n++] = 2 * p + 1;
    return n;
  }
  CellsAround(sc, p, cell);
  if (cell[1] || cell[3]) key[n++] = 3 * p;
  if (cell[2] || cell[3]) key[n++] = 3 * p + 1;
  if (cell[3]) key[n++] = 3 * p + 2;
  return n;
}

/* Is particle p a corner of a cell of the cloth? */
static PetscBool IsVertex(SelfContact sc, PetscInt p)
{
  PetscBool cell[4];
  CellsAround(sc, p, cell);
  return (PetscBool) (cell[0] || cell[1] || cell[2] || cell[3]);
}

/* Index in the local set of natural particle nat, -1 if it is not there. */
static inline PetscInt LocalOf(SelfContact sc, PetscInt nat)
{
  const khiter_t it = kh_get(HMapI, sc->local_of, nat);
  return it != kh_end(sc->local_of) ? kh_val(sc->local_of, it) : -1;
}

/* ---- the local set: the rank's own particles with their halo ---- */

static PetscErrorCode SetFreeList(SelfSet *s)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree(s->cpt));
  PetscCall(PetscFree(s->cee));
  PetscCall(PetscFree(s->npt_));
  PetscCall(PetscFree(s->nee_));
  PetscCall(PetscFree4(s->dc, s->ndc, s->lpt_, s->lee_));
  s->ncpt = s->ncee = s->nnpt = s->nnee = s->npt = s->nee = s->nlpt = s->nlee = 0;
  s->pt = s->ee = NULL;
  s->listed = s->has_near = PETSC_FALSE;
  PetscFunctionReturn(0);
}

static PetscErrorCode SetFreeMesh(SelfMesh *m)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree(m->vert));
  PetscCall(PetscFree(m->tri));
  PetscCall(PetscFree(m->edge));
  PetscFunctionReturn(0);
}

/* The triangles (tri) or edges of the local set's particles whose particles are all
 * in the set: their keys, ascending, and their particles as indices into the set. */
static PetscErrorCode LocalPrimitives(SelfContact sc, PetscBool tri, PetscInt *n, PetscInt **out, PetscInt **gid)
{
  const SelfSet *s    = &sc->local;
  const PetscInt nper = tri ? 3 : 2;
  PetscInt       m    = 0, *ids, *loc;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc1(3 * s->n + 1, &ids));
  for (PetscInt k = 0; k < s->n; k++) { /* each primitive from its first particle: once */
    PetscInt key[3], nk = FirstPrimitives(sc, tri, s->nat[k], key);
    for (PetscInt a = 0; a < nk; a++) {
      PetscInt  P[3];
      PetscBool all = PETSC_TRUE;
      if (tri)
        SelfTriangleParticles(sc->Mx, key[a], P);
      else
        EdgeParticles(sc->Mx, key[a], P);
      for (PetscInt c = 1; c < nper; c++) all = (PetscBool) (all && LocalOf(sc, P[c]) >= 0);
      if (all) ids[m++] = key[a];
    }
  }
  PetscCall(PetscSortInt(m, ids));
  PetscCall(PetscMalloc1(nper * m + 1, &loc));
  for (PetscInt i = 0; i < m; i++) {
    PetscInt P[3];
    if (tri)
      SelfTriangleParticles(sc->Mx, ids[i], P);
    else
      EdgeParticles(sc->Mx, ids[i], P);
    for (PetscInt c = 0; c < nper; c++) loc[nper * i + c] = LocalOf(sc, P[c]);
  }
  *n   = m;
  *out = loc;
  *gid = ids;
  PetscFunctionReturn(0);
}

/* The global numbers gid[0..n) of natural particles nat[0..n) (other ranks' too),
 * from the directory (its part of the naturals on each rank). Collective. */
static PetscErrorCode DirectoryLookup(SelfContact sc, PetscInt n, const PetscInt *nat, PetscInt *gid)
{
  PetscSF sf;

  PetscFunctionBeginUser;
  PetscCall(PetscSFCreate(sc->comm, &sf));
  PetscCall(PetscSFSetGraphLayout(sf, sc->dir_layout, n, NULL, PETSC_COPY_VALUES, nat));
  PetscCall(PetscSFBcastBegin(sf, MPIU_INT, sc->dir, gid, MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sf, MPIU_INT, sc->dir, gid, MPI_REPLACE));
  PetscCall(PetscSFDestroy(&sf));
  for (PetscInt k = 0; k < n; k++) PetscCheck(gid[k] >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "Self-contact: particle %" PetscInt_FMT " has no owner", nat[k]);
  PetscFunctionReturn(0);
}

/* The rank that owns global number g, and g's index there. */
static void OwnerOf(SelfContact sc, PetscInt g, PetscInt *rank, PetscInt *index)
{
  PetscInt lo = 0, hi = sc->size - 1; /* the last r with gstart[r] <= g */
  while (lo < hi) {
    const PetscInt mid = (lo + hi + 1) / 2;
    if (sc->gstart[mid] <= g)
      lo = mid;
    else
      hi = mid - 1;
  }
  *rank  = lo;
  *index = g - sc->gstart[lo];
}

/* The local set: the own particles (their state kept) and the halo halo[0..nhalo)
 * (natural indices, sorted; state still to be moved in by HaloUpdate), the PetscSF
 * that moves it, the primitives among them. */
static PetscErrorCode LocalSetBuild(SelfContact sc, PetscInt nhalo, const PetscInt *halo)
{
  SelfSet        *s    = &sc->local;
  const PetscInt  nown = sc->nowned, n = nown + nhalo;
  const PetscInt *natural;
  PetscInt       *nat, *gid, *vert, nvert = 0;
  PetscReal      *invm0, *invm, *x0, *x1, *v, *lo, *hi;
  PetscSFNode    *remote;

  PetscFunctionBeginUser;
  PetscCall(ClothGetNatural(sc->cloth, &natural));
  PetscCall(PetscMalloc7(n + 1, &nat, n + 1, &invm, 3 * n + 1, &x0, 3 * n + 1, &x1, 3 * n + 1, &v, 3 * n + 1, &lo, 3 * n + 1, &hi));
  PetscCall(PetscMalloc2(n + 1, &gid, n + 1, &invm0));
  if (s->x0) {
    PetscCall(PetscArraycpy(x0, s->x0, 3 * nown));
    PetscCall(PetscArraycpy(x1, s->x1, 3 * nown));
    PetscCall(PetscArraycpy(v, s->v, 3 * nown));
  }
  PetscCall(PetscFree7(s->nat, s->invm, s->x0, s->x1, s->v, s->lo, s->hi));
  PetscCall(PetscFree2(s->gid, s->invm0));
  s->nat = nat, s->invm = invm, s->x0 = x0, s->x1 = x1, s->v = v, s->lo = lo, s->hi = hi, s->gid = gid, s->invm0 = invm0;
  s->n = n, s->nown = nown;
  for (PetscInt k = 0; k < nown; k++) nat[k] = natural[k];
  for (PetscInt k = 0; k < nhalo; k++) nat[nown + k] = halo[k];
  PetscCall(PetscHMapIClear(sc->local_of));
  PetscCall(PetscHMapIResize(sc->local_of, n));
  for (PetscInt k = 0; k < n; k++) PetscCall(PetscHMapISet(sc->local_of, nat[k], k));
  for (PetscInt k = 0; k < nown; k++) gid[k] = sc->gstart[sc->rank] + k, invm0[k] = sc->invm_own[k];
  if (sc->size > 1) {
    /* the halo's owners from the directory, then the SF from them */
    PetscCall(DirectoryLookup(sc, nhalo, nat + nown, gid + nown));
    PetscCall(PetscSFDestroy(&sc->sf));
    PetscCall(PetscMalloc1(nhalo + 1, &remote));
    for (PetscInt k = 0; k < nhalo; k++) OwnerOf(sc, gid[nown + k], &remote[k].rank, &remote[k].index);
    PetscCall(PetscSFCreate(sc->comm, &sc->sf));
    PetscCall(PetscSFSetGraph(sc->sf, nown, nhalo, NULL, PETSC_COPY_VALUES, remote, PETSC_OWN_POINTER));
    PetscCall(PetscSFSetUp(sc->sf));
    PetscCall(PetscSFBcastBegin(sc->sf, MPIU_REAL, invm0, invm0 + nown, MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(sc->sf, MPIU_REAL, invm0, invm0 + nown, MPI_REPLACE));
  }
  for (PetscInt k = 0; k < n; k++) invm[k] = invm0[k];
  PetscCall(SetFreeMesh(&s->mesh));
  PetscCall(PetscFree(s->vid));
  PetscCall(PetscFree(s->tid));
  PetscCall(PetscFree(s->eid));
  PetscCall(SetFreeList(s));
  PetscCall(LocalPrimitives(sc, PETSC_TRUE, &s->mesh.nt, &s->mesh.tri, &s->tid));
  PetscCall(LocalPrimitives(sc, PETSC_FALSE, &s->mesh.ne, &s->mesh.edge, &s->eid));
  /* vertices in the order of the whole cloth's (their natural indices) */
  PetscCall(PetscMalloc1(n + 1, &s->vid));
  for (PetscInt k = 0; k < n; k++)
    if (IsVertex(sc, nat[k])) s->vid[nvert++] = nat[k];
  PetscCall(PetscSortInt(nvert, s->vid));
  PetscCall(PetscMalloc1(nvert + 1, &vert));
  for (PetscInt i = 0; i < nvert; i++) vert[i] = LocalOf(sc, s->vid[i]);
  s->mesh.nv   = nvert;
  s->mesh.vert = vert;
  PetscCall(PetscFree2(sc->uf, sc->bnd));
  PetscCall(PetscMalloc2(n + 1, &sc->uf, n + 1, &sc->bnd));
  for (PetscInt k = 0; k < n; k++) sc->uf[k] = -1, sc->bnd[k] = PETSC_FALSE;
  PetscFunctionReturn(0);
}

/* The halo's copies of x0, x1 and v (any may be NULL) from their owners. */
PetscErrorCode SelfHaloUpdate(SelfContact sc, PetscReal *x0, PetscReal *x1, PetscReal *v)
{
  PetscReal     *a[3] = {x0, x1, v};
  const PetscInt o    = 3 * sc->local.nown;

  PetscFunctionBeginUser;
  if (!sc->sf) PetscFunctionReturn(0);
  for (PetscInt i = 0; i < 3; i++)
    if (a[i]) PetscCall(PetscSFBcastBegin(sc->sf, sc->unit3, a[i], a[i] + o, MPI_REPLACE));
  for (PetscInt i = 0; i < 3; i++)
    if (a[i]) PetscCall(PetscSFBcastEnd(sc->sf, sc->unit3, a[i], a[i] + o, MPI_REPLACE));
  PetscFunctionReturn(0);
}

/* The local set's 1/m for the filter: 0 for the particles the solid holds (own from
 * sc->held, the halo's from their owners), or back to the cloth's (restore). */
static PetscErrorCode SetHeldMasses(SelfContact sc, PetscBool restore)
{
  SelfSet *s = &sc->local;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < s->n; k++) s->invm[k] = s->invm0[k];
  if (restore || !sc->use_held) PetscFunctionReturn(0);
  for (PetscInt k = 0; k < s->nown; k++)
    if (sc->held[k]) s->invm[k] = 0;
  if (sc->sf) {
    PetscCall(PetscSFBcastBegin(sc->sf, MPIU_REAL, s->invm, s->invm + s->nown, MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(sc->sf, MPIU_REAL, s->invm, s->invm + s->nown, MPI_REPLACE));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSetHeld(SelfContact sc, const PetscBool held[])
{
  PetscFunctionBeginUser;
  sc->use_held = (PetscBool) (held != NULL);
  if (!held) PetscFunctionReturn(0);
  if (!sc->held) PetscCall(PetscMalloc1(sc->nowned + 1, &sc->held));
  PetscCall(PetscArraycpy(sc->held, held, sc->nowned));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactSetUp(SelfContact sc)
{
  ClothInfo        info;
  const PetscInt  *natural;
  const PetscReal *mass;
  const PetscBool *pinned;
  PetscInt         count[2] = {0, 0};

  PetscFunctionBeginUser;
  if (!sc->enabled) PetscFunctionReturn(0);
  PetscCall(ClothGetInfo(sc->cloth, &info));
  PetscCall(ClothGetNatural(sc->cloth, &natural));
  PetscCall(ClothGetMasses(sc->cloth, &mass, &pinned));
  if (sc->thickness == 0) sc->thickness = 0.25 * PetscMin(info.spacing[0], info.spacing[1]);
  sc->solve.mass      = info.mass / info.nparticles;
  sc->stats.thickness = sc->thickness;
  sc->Mx              = info.Mx;
  sc->My              = info.My;
  sc->N               = info.nparticles;
  sc->nowned          = info.nowned;
  /* particles and primitives (keys up to 3 N) travel as reals when contacts are gathered */
  PetscCheck(3 * (PetscReal) sc->N < 1 / PETSC_MACHINE_EPSILON, sc->comm, PETSC_ERR_SUP, "-contact_self sends particle indices as reals: %" PetscInt_FMT " particles are more than this precision counts exactly (at most %g)", sc->N,
             (double) (1 / (3 * PETSC_MACHINE_EPSILON)));
  PetscCallMPI(MPI_Comm_rank(sc->comm, &sc->rank));
  PetscCallMPI(MPI_Comm_size(sc->comm, &sc->size));
  /* each rank's first global number (the cloth numbers each rank's particles in a row) */
  PetscCall(PetscMalloc1(sc->size + 1, &sc->gstart));
  sc->gstart[0] = 0;
  PetscCallMPI(MPI_Allgather(&sc->nowned, 1, MPIU_INT, sc->gstart + 1, 1, MPIU_INT, sc->comm));
  for (PetscMPIInt r = 0; r < sc->size; r++) sc->gstart[r + 1] += sc->gstart[r];
  /* the directory: the global number of each natural index, PETSc's split of them
   * over the ranks, so that a rank finds its halo's owners without an array of the
   * whole lattice */
  if (sc->size > 1) {
    PetscSF   sf;
    PetscInt *gid, nd;
    PetscCall(PetscLayoutCreateFromSizes(sc->comm, PETSC_DECIDE, sc->N, 1, &sc->dir_layout));
    PetscCall(PetscLayoutGetRange(sc->dir_layout, &sc->dir_start, &nd));
    nd -= sc->dir_start;
    PetscCall(PetscMalloc1(nd + 1, &sc->dir));
    for (PetscInt k = 0; k < nd; k++) sc->dir[k] = -1;
    PetscCall(PetscMalloc1(sc->nowned + 1, &gid));
    for (PetscInt k = 0; k < sc->nowned; k++) gid[k] = sc->gstart[sc->rank] + k;
    PetscCall(PetscSFCreate(sc->comm, &sf));
    PetscCall(PetscSFSetGraphLayout(sf, sc->dir_layout, sc->nowned, NULL, PETSC_COPY_VALUES, natural));
    PetscCall(PetscSFReduceBegin(sf, MPIU_INT, gid, sc->dir, MPI_REPLACE));
    PetscCall(PetscSFReduceEnd(sf, MPIU_INT, gid, sc->dir, MPI_REPLACE));
    PetscCall(PetscSFDestroy(&sf));
    PetscCall(PetscFree(gid));
  }
  /* 1/m of the own particles (0: pinned, never moved by an impulse) */
  PetscCall(PetscMalloc1(sc->nowned + 1, &sc->invm_own));
  for (PetscInt k = 0; k < sc->nowned; k++) sc->invm_own[k] = pinned[k] || mass[k] <= 0 ? 0 : 1 / mass[k];
  /* the whole cloth's triangles and edges, counted by the rank of their first particle */
  for (PetscInt k = 0; k < sc->nowned; k++) {
    PetscInt key[3];
    count[0] += FirstPrimitives(sc, PETSC_TRUE, natural[k], key);
    count[1] += FirstPrimitives(sc, PETSC_FALSE, natural[k], key);
  }
  PetscCall(MPIU_Allreduce(MPI_IN_PLACE, count, 2, MPIU_INT, MPI_SUM, sc->comm));
  sc->nt = count[0], sc->ne = count[1];
  /* the fixed part of the halo: the other ranks' particles of the own particles' triangles */
  PetscCall(PetscHMapICreate(&sc->local_of));
  for (PetscInt k = 0; k < sc->nowned; k++) PetscCall(PetscHMapISet(sc->local_of, natural[k], k));
  {
    PetscInt m = 0;
    PetscCall(PetscMalloc1(18 * sc->nowned + 1, &sc->h1));
    for (PetscInt k = 0; k < sc->nowned; k++) {
      PetscInt key[6], nt = SelfParticleTriangles(sc, natural[k], key);
      for (PetscInt a = 0; a < nt; a++) {
        PetscInt T[3];
        SelfTriangleParticles(sc->Mx, key[a], T);
        for (PetscInt c = 0; c < 3; c++)
          if (LocalOf(sc, T[c]) < 0) sc->h1[m++] = T[c];
      }
    }
    sc->nh1 = m;
    PetscCall(PetscSortRemoveDupsInt(&sc->nh1, sc->h1));
  }
  PetscCallMPI(MPI_Type_contiguous(3, MPIU_REAL, &sc->unit3));
  PetscCallMPI(MPI_Type_commit(&sc->unit3));
  PetscCallMPI(MPI_Type_contiguous(9, MPIU_REAL, &sc->unit9));
  PetscCallMPI(MPI_Type_commit(&sc->unit9));
  PetscCall(LocalSetBuild(sc, sc->nh1, sc->h1));
  PetscCall(SelfPatchesSetUp(sc, natural));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactView(SelfContact sc, PetscViewer viewer)
{
  PetscFunctionBeginUser;
  if (!sc->enabled) PetscFunctionReturn(0);
  PetscCall(PetscViewerASCIIPrintf(viewer, "Self-contact: thickness %g m, friction mu = %g, %" PetscInt_FMT " triangles, %" PetscInt_FMT " edges (each rank: its own particles and a halo of the cloth near them)\n", (double) sc->thickness,
                                   (double) sc->mu, sc->nt, sc->ne));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactDestroy(SelfContact *self)
{
  SelfContact sc = *self;

  PetscFunctionBeginUser;
  if (!sc) PetscFunctionReturn(0);
  if (sc->local_of) PetscCall(PetscHMapIDestroy(&sc->local_of));
  PetscCall(PetscFree(sc->dir));
  PetscCall(PetscLayoutDestroy(&sc->dir_layout));
  PetscCall(PetscFree(sc->invm_own));
  PetscCall(PetscFree(sc->held));
  PetscCall(PetscFree(sc->h1));
  PetscCall(PetscFree2(sc->uf, sc->bnd));
  PetscCall(PetscFree(sc->local.vid));
  PetscCall(PetscFree(sc->local.tid));
  PetscCall(PetscFree(sc->local.eid));
  PetscCall(PetscFree7(sc->local.nat, sc->local.invm, sc->local.x0, sc->local.x1, sc->local.v, sc->local.lo, sc->local.hi));
  PetscCall(PetscFree2(sc->local.gid, sc->local.invm0));
  PetscCall(SetFreeMesh(&sc->local.mesh));
  PetscCall(SetFreeList(&sc->local));
  PetscCall(PetscFree(sc->local.xr));
  PetscCall(PetscFree(sc->local.dr));
  PetscCall(PetscFree(sc->local.dm));
  PetscCall(PetscSFDestroy(&sc->sf));
  if (sc->unit3 != MPI_DATATYPE_NULL) PetscCallMPI(MPI_Type_free(&sc->unit3));
  if (sc->unit9 != MPI_DATATYPE_NULL) PetscCallMPI(MPI_Type_free(&sc->unit9));
  PetscCall(PetscFree(sc->gstart));
  PetscCall(SelfSolveDestroy(sc));
  PetscCall(SelfPatchesDestroy(sc));
  PetscCall(PetscFree(*self));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactGetStats(SelfContact sc, SelfContactStats *stats)
{
  PetscFunctionBeginUser;
  *stats = sc->stats;
  if (sc->size > 1) {
    PetscReal sums[2] = {stats->near_pairs, stats->near_within};
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums, 2, MPIU_REAL, MPI_SUM, sc->comm));
    stats->near_pairs = sums[0], stats->near_within = sums[1];
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactBeginStep(SelfContact sc, const PetscScalar *x)
{
  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < 3 * sc->nowned; k++) sc->local.x0[k] = PetscRealPart(x[k]);
  PetscFunctionReturn(0);
}

/* ---- candidate pairs ---- */

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

/* Each particle's box: its start and end positions and more steps of the same
 * motion: SELF_PREDICT_STEPS, or as many as stay within `reach` (the margin), at
 * most SELF_PREDICT_MAX. PETSC_FALSE if a position is not finite. */
static PetscBool SetBoxes(SelfSet *s, PetscReal reach)
{
  for (PetscInt k = 0; k < s->n; k++) {
    PetscReal step = 0, ahead;
    for (PetscInt d = 0; d < 3; d++) step = PetscMax(step, PetscAbsReal(s->x1[3 * k + d] - s->x0[3 * k + d]));
    ahead = step > 0 ? PetscMin(SELF_PREDICT_MAX, PetscMax(SELF_PREDICT_STEPS, reach / step)) : SELF_PREDICT_STEPS;
    for (PetscInt d = 0; d < 3; d++) {
      const PetscInt  i = 3 * k + d;
      const PetscReal a = s->x1[i] + ahead * (s->x1[i] - s->x0[i]);
      if (PetscIsInfOrNanReal(a)) return PETSC_FALSE;
      s->lo[i] = PetscMin(PetscMin(s->x0[i], s->x1[i]), a);
      s->hi[i] = PetscMax(PetscMax(s->x0[i], s->x1[i]), a);
    }
  }
  return PETSC_TRUE;
}

/* The candidate pairs (a Verlet list): boxes of the sweep x0 -> x1, extended by
 * more steps of the same motion (SetBoxes), grown by half the thickness and
 * a margin of one thickness. While no particle's start or end position is more than
 * the margin outside its box at the last broad phase, the list holds every pair
 * closer than the thickness at the start and every pair that can collide: it is
 * kept across impulses and steps, and rebuilt only when a particle moved further
 * (every third step or so while the cloth falls steadily; never while it rests).
 * Extra candidates do nothing (the passes act on close or colliding pairs), so the
 * list's extent changes the cost, not the result. Only pairs with an own particle
 * are kept. The boxes are set (SetBoxes). */
typedef struct {
  SelfContact sc;
  SelfSet    *s;
} BroadCtx;

static PetscErrorCode BroadPhaseRun(void *ctx)
{
  const BroadCtx *b = (const BroadCtx *) ctx;
  SelfSet        *s = b->s;
  const PetscReal r = (0.5 + b->sc->margin) * b->sc->thickness;

  PetscFunctionBeginUser;
  switch (b->sc->broad) {
  case SELF_BROAD_CGAL:
    PetscCall(SelfBroadPhase(&s->mesh, s->lo, s->hi, r, &s->ncpt, &s->cpt, &s->ncee, &s->cee));
    break;
  case SELF_BROAD_HASH:
    PetscCall(SelfBroadPhaseHash(&s->mesh, s->lo, s->hi, r, &s->ncpt, &s->cpt, &s->ncee, &s->cee));
    break;
  default:
    PetscCall(SelfBroadPhaseTiles(&s->mesh, s->nat, b->sc->Mx, s->lo, s->hi, r, &s->ncpt, &s->cpt, &s->ncee, &s->cee));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode SetBroadPhase(SelfContact sc, SelfSet *s)
{
  PetscInt n   = 0;
  BroadCtx ctx = {sc, s};

  PetscFunctionBeginUser;
  PetscCall(SetFreeList(s));
  PetscCall(PetscLogEventBegin(drape_log.self_broad, 0, 0, 0, 0));
  /* its refusals (a runaway coordinate, memory) may come from one rank's part only: raised on every rank */
  PetscCall(DrapeCollective(sc->comm, BroadPhaseRun, &ctx));
  PetscCall(PetscLogEventEnd(drape_log.self_broad, 0, 0, 0, 0));
  if (s->nown < s->n) {
    for (PetscInt kind = 0; kind < 2; kind++) {
      PetscInt *list = kind ? s->cee : s->cpt, *np = kind ? &s->ncee : &s->ncpt;
      n     = 0;
      s->pt = s->cpt, s->ee = s->cee; /* for PairParticles */
      for (PetscInt k = 0; k < *np; k++) {
        PetscInt p[4];
        PairParticles(s, kind, k, p);
        if (!PairIsOwn(s, p)) continue;
        list[2 * n] = list[2 * k], list[2 * n + 1] = list[2 * k + 1];
        n++;
      }
      *np = n;
    }
  }
  PetscCall(SelfPatchesBoxes(sc, s->lo, s->hi, sc->patches.list_box));
  s->listed   = PETSC_TRUE;
  s->has_near = PETSC_FALSE;
  PetscFunctionReturn(0);
}

/* Does the list still hold every pair: is there a translation of the start
 * positions, and one of the end positions, that puts every particle within the
 * margin of its box? A translation changes no distance and no collision (along the
 * step the cloth moves by the interpolated translation): the pairs the list must
 * hold are those of the translated cloth, which it holds; a cloth that falls or
 * slides as a whole keeps its list. Per direction the translation exists iff the
 * largest x - hi and the largest lo - x sum to at most twice the margin. Over every
 * rank; a position that is not finite makes the list invalid (SetBoxes then says
 * so). */
static PetscErrorCode SetListValid(SelfContact sc, const SelfSet *s, const PetscReal g[12], PetscBool *valid)
{
  const PetscReal m = sc->margin * sc->thickness;

  PetscFunctionBeginUser;
  *valid = s->listed; /* the same on every rank */
  if (!*valid) PetscFunctionReturn(0);
  *valid = (PetscBool) (g[0] < PETSC_MAX_REAL && SelfListTranslates(g, m));
  /* Patch by patch only in the explicit schemes (a position not finite fails the
   * test above and is not taken further). The implicit solve takes the candidates
   * within two thicknesses, past the one thickness a list is kept for: which of those
   * between one and two a list still holds depends on when it was made, so a list
   * kept longer changes the solve's penalties (the sphere scene at 2 ms: other
   * frames from t = 0.3 s, though no crossing; the filter's guarantee is the same).
   * So drapebe's lists are made when they were. */
  if (!*valid && sc->use_patches && !sc->implicit && g[0] < PETSC_MAX_REAL) PetscCall(SelfPatchesListValid(sc, s->x0, s->x1, s->lo, s->hi, m, SELF_PATCH_APART * sc->thickness, valid));
  PetscFunctionReturn(0);
}

/* The motion since the lists were made, over the own particles of every rank, in
 * one pass and one reduction: g[0, 12) SetListValid's maxima, start and end, per
 * direction, the largest x - hi and lo - x (g[0] PETSC_MAX_REAL where a position is
 * not finite; when a list exists), and g[12, 30) NearDisplacements' at xr (when a
 * near list exists). */
static PetscErrorCode ListMotion(SelfContact sc, const SelfSet *s, PetscReal g[30])
{
  PetscReal b[30], zero;

  PetscFunctionBeginUser;
  SelfMotionMaxima(s->nown, s->x0, s->x1, s->listed ? s->lo : NULL, s->hi, s->listed && s->has_near ? s->xr : NULL, b, b + 12, &zero);
  if (zero != 0) b[0] = PETSC_MAX_REAL;
  if (sc->size > 1)
    PetscCallMPI(MPI_Allreduce(b, g, 30, MPIU_REAL, MPIU_MAX, sc->comm));
  else
    PetscCall(PetscArraycpy(g, b, 30));
  PetscFunctionReturn(0);
}

static PetscErrorCode CheckFinite(SelfContact sc, PetscBool finite)
{
  PetscFunctionBeginUser;
  /* a non-finite box has no cells (the hash) or no order (CGAL) */
  PetscCheck(finite, sc->comm, PETSC_ERR_FP, "Self-contact: a particle's position is not finite (the step diverged); reduce -ts_dt or use -ts_type drapebe");
  PetscFunctionReturn(0);
}

/* The halo for the present boxes of the local set: every particle of every triangle
 * (of a particle of this rank's) whose box reaches another rank's box goes to it.
 * A rank's box: the boxes of its own particles' triangles, grown by twice the list's
 * radius. A candidate pair with an own particle is a pair of primitives whose boxes,
 * grown by the radius, overlap; the other primitive lies in a triangle of some
 * rank's particle, whose box reaches this rank's box: so both primitives of every
 * pair a rank evaluates are in its local set, and the local list is the whole
 * cloth's list restricted to the pairs with an own particle, in the same order. */
/* The box of the cloth's triangle T (natural indices) over the local set's particle boxes. */
/* The triangles of particle p (natural index), their particles and their boxes
 * (the union of their particles' sweeps); returns how many. */
static PetscInt ParticleTriangleBoxes(const SelfContact sc, PetscInt p, PetscInt T[6][3], PetscReal lo[6][3], PetscReal hi[6][3])
{
  const SelfSet *s = &sc->local;
  PetscInt       tk[6], nt = SelfParticleTriangles(sc, p, tk);

  for (PetscInt a = 0; a < nt; a++) {
    SelfTriangleParticles(sc->Mx, tk[a], T[a]);
    for (PetscInt d = 0; d < 3; d++) lo[a][d] = PETSC_MAX_REAL, hi[a][d] = -PETSC_MAX_REAL;
    for (PetscInt c = 0; c < 3; c++) {
      const PetscInt q = LocalOf(sc, T[a][c]);
      for (PetscInt d = 0; d < 3; d++) lo[a][d] = PetscMin(lo[a][d], s->lo[3 * q + d]), hi[a][d] = PetscMax(hi[a][d], s->hi[3 * q + d]);
    }
  }
  return nt;
}

static PetscErrorCode HaloRebuild(SelfContact sc)
{
  SelfSet *s = &sc->local;
  /* a little more than the broad phase's two radii, so that rounding never drops a pair */
  const PetscReal grow = 2.01 * (0.5 + sc->margin) * sc->thickness;
  PetscReal       mine[6], *boxes;
  PetscInt64     *key  = NULL;
  PetscInt        nkey = 0, mkey = 0, nhalo, *halo, nrecv = 0, *send, *recv;
  PetscMPIInt    *scount, *sdispl, *rcount, *rdispl;

  PetscFunctionBeginUser;
  for (PetscInt d = 0; d < 3; d++) mine[d] = PETSC_MAX_REAL, mine[3 + d] = -PETSC_MAX_REAL;
  for (PetscInt k = 0; k < s->nown; k++) {
    PetscInt  T[6][3];
    PetscReal lo[6][3], hi[6][3];
    PetscInt  nt = ParticleTriangleBoxes(sc, s->nat[k], T, lo, hi);
    for (PetscInt a = 0; a < nt; a++)
      for (PetscInt d = 0; d < 3; d++) mine[d] = PetscMin(mine[d], lo[a][d] - grow), mine[3 + d] = PetscMax(mine[3 + d], hi[a][d] + grow);
  }
  PetscCall(PetscMalloc1(6 * sc->size, &boxes));
  PetscCallMPI(MPI_Allgather(mine, 6, MPIU_REAL, boxes, 6, MPIU_REAL, sc->comm));
  /* (rank, particle) keys to send */
  PetscCall(PetscMalloc4(sc->size, &scount, sc->size, &sdispl, sc->size, &rcount, sc->size, &rdispl));
  for (PetscInt k = 0; k < s->nown; k++) {
    PetscInt  T[6][3];
    PetscReal lo[6][3], hi[6][3];
    PetscInt  nt = ParticleTriangleBoxes(sc, s->nat[k], T, lo, hi);
    for (PetscInt a = 0; a < nt; a++) {
      for (PetscMPIInt r = 0; r < sc->size; r++) {
        const PetscReal *B = boxes + 6 * r;
        if (r == sc->rank || lo[a][0] > B[3] || lo[a][1] > B[4] || lo[a][2] > B[5] || hi[a][0] < B[0] || hi[a][1] < B[1] || hi[a][2] < B[2]) continue;
        if (nkey + 3 > mkey) {
          mkey = 2 * mkey + 64;
          PetscCall(PetscRealloc(mkey * sizeof(*key), &key));
        }
        for (PetscInt c = 0; c < 3; c++) key[nkey++] = (PetscInt64) r * sc->N + T[a][c];
      }
    }
  }
  PetscCall(PetscSortInt64(nkey, key));
  {
    PetscInt u = 0;
    for (PetscInt i = 0; i < nkey; i++)
      if (i == 0 || key[i] != key[i - 1]) key[u++] = key[i];
    nkey = u;
  }
  PetscCall(PetscMalloc1(nkey + 1, &send));
  for (PetscMPIInt r = 0; r < sc->size; r++) scount[r] = 0;
  for (PetscInt i = 0; i < nkey; i++) {
    scount[key[i] / sc->N]++;
    send[i] = (PetscInt) (key[i] % sc->N);
  }
  PetscCallMPI(MPI_Alltoall(scount, 1, MPI_INT, rcount, 1, MPI_INT, sc->comm));
  sdispl[0] = rdispl[0] = 0;
  for (PetscMPIInt r = 0; r < sc->size; r++) {
    if (r > 0) sdispl[r] = sdispl[r - 1] + scount[r - 1], rdispl[r] = rdispl[r - 1] + rcount[r - 1];
    nrecv += rcount[r];
  }
  PetscCall(PetscMalloc1(nrecv + sc->nh1 + 1, &recv));
  PetscCallMPI(MPI_Alltoallv(send, scount, sdispl, MPIU_INT, recv, rcount, rdispl, MPIU_INT, sc->comm));
  /* the halo: the fixed part and what was sent here, not own */
  nhalo = 0;
  halo  = recv;
  for (PetscInt i = 0; i < nrecv; i++)
    if (LocalOf(sc, recv[i]) < 0 || LocalOf(sc, recv[i]) >= s->nown) halo[nhalo++] = recv[i];
  for (PetscInt i = 0; i < sc->nh1; i++) halo[nhalo++] = sc->h1[i];
  PetscCall(PetscSortRemoveDupsInt(&nhalo, halo));
  PetscCall(MPIU_Allreduce(&nhalo, &sc->stats.halo, 1, MPIU_INT, MPI_MAX, sc->comm));
  PetscCall(LocalSetBuild(sc, nhalo, halo));
  PetscCall(SelfHaloUpdate(sc, s->x0, s->x1, s->v));
  PetscCall(PetscFree(recv));
  PetscCall(PetscFree(send));
  PetscCall(PetscFree(key));
  PetscCall(PetscFree4(scount, sdispl, rcount, rdispl));
  PetscCall(PetscFree(boxes));
  PetscFunctionReturn(0);
}

/* ---- the near list: the candidates that can act, by distance ----
 * A list made from boxes holds many pairs that are never close: the triangles
 * across a cell's diagonal from a particle are inside its box but 0.7 spacings
 * away, and a cloth at rest keeps its list for ever. The near list keeps the
 * candidates closer than R (-contact_self_near_radius) at the positions xr it
 * was made at. Let every particle's displacement from xr, less a translation c
 * common to all, be at most delta (x0 - xr, and x1 - xr), and its motion over the
 * step x1 - x0 less another common translation at most D. A translation changes no
 * distance, and a primitive's points are convex combinations of its particles': a
 * candidate left out (distance at least R at xr) is farther than R - 2 delta from
 * its partner all along the step, and its gap at x1 along its normal at x0 is at
 * least R - 2 delta0 - 2 D. While these exceed the reach the passes need (the
 * thickness; the implicit solve's reach), the near list holds every pair they act
 * on, in the candidates' order: the same pairs act, the same frames. delta and D
 * are half-diagonals of the boxes of the displacements over every rank (c their
 * centres). */
/* The half-diagonals of the boxes of x0 - xr, x1 - xr (xr NULL: x0, so 0 and D) and x1 - x0 over the own particles of every rank. */
static PetscErrorCode NearDisplacements(SelfContact sc, const SelfSet *s, const PetscReal *xr, PetscReal delta[3])
{
  PetscReal b[18], g[18], list[12], zero;

  PetscFunctionBeginUser;
  SelfMotionMaxima(s->nown, s->x0, s->x1, NULL, NULL, xr ? xr : s->x0, list, b, &zero);
  if (sc->size > 1)
    PetscCallMPI(MPI_Allreduce(b, g, 18, MPIU_REAL, MPIU_MAX, sc->comm));
  else
    PetscCall(PetscArraycpy(g, b, 18));
  SelfNearDelta(g, delta);
  PetscFunctionReturn(0);
}

/* Does the near list hold every pair the passes need (delta from NearDisplacements)? */
static PetscBool NearHolds(const SelfContact sc, const PetscReal delta[3], PetscReal reach, PetscBool gap_at_end) { return SelfNearHolds(sc->near * sc->thickness, delta, reach, gap_at_end); }

/* The near list at the present x0 (the whole local set's, the halo's included). */
static PetscErrorCode NearMake(SelfContact sc, SelfSet *s)
{
  const PetscReal R = sc->near * sc->thickness;

  PetscFunctionBeginUser;
  if (s->nxr < 3 * s->n) {
    PetscCall(PetscFree(s->xr));
    PetscCall(PetscFree(s->dr));
    PetscCall(PetscMalloc1(3 * s->n, &s->xr));
    PetscCall(PetscMalloc1(6 * s->n, &s->dr));
    s->nxr = 3 * s->n;
  }
  PetscCall(PetscArraycpy(s->xr, s->x0, 3 * s->n));
  PetscCall(SelfPatchesBoxes(sc, s->xr, s->xr, sc->patches.near_box));
  if (!s->dc) { /* (one list's: SetFreeList frees them with it) */
    PetscCall(PetscFree(s->npt_));
    PetscCall(PetscFree(s->nee_));
    PetscCall(PetscMalloc1(2 * s->ncpt + 1, &s->npt_));
    PetscCall(PetscMalloc1(2 * s->ncee + 1, &s->nee_));
    PetscCall(PetscMalloc4(s->ncpt + s->ncee + 1, &s->dc, s->ncpt + s->ncee + 1, &s->ndc, 2 * s->ncpt + 1, &s->lpt_, 2 * s->ncee + 1, &s->lee_));
  }
  s->pt = s->cpt, s->ee = s->cee, s->nnpt = s->nnee = 0;
  for (PetscInt kind = 0; kind < 2; kind++) {
    const PetscInt *from = kind ? s->cee : s->cpt;
    PetscInt       *to = kind ? s->nee_ : s->npt_, *n = kind ? &s->nnee : &s->nnpt;
    PetscReal      *dc = s->dc + (kind ? s->ncpt : 0), *ndc = s->ndc + (kind ? s->ncpt : 0);
    SelfNearDistances(s, kind, kind ? s->ncee : s->ncpt, s->xr, dc);
    for (PetscInt k = 0; k < (kind ? s->ncee : s->ncpt); k++) {
      if (dc[k] >= R) continue; /* (a NaN distance is kept) */
      to[2 * *n] = from[2 * k], to[2 * *n + 1] = from[2 * k + 1];
      ndc[*n] = dc[k];
      (*n)++;
    }
  }
  s->has_near = PETSC_TRUE;
  PetscFunctionReturn(0);
}

/* The mean c of the displacements dr (6 each) of each of the n primitives' particles
 * (stride each, prim), and the largest distance of one of them from it at x0, at x1
 * and over the step: 9 each (c at x0, c at x1, the three distances). */
static void PrimitiveMotion(PetscInt n, PetscInt stride, const PetscInt *prim, const PetscReal *dr, PetscReal *dm)
{
  const PetscReal w = 1.0 / stride; /* (any point serves as c: r is measured from it) */

  for (PetscInt e = 0; e < n; e++) {
    const PetscInt *P = prim + stride * e;
    PetscReal      *m = dm + 9 * e, q[3] = {0, 0, 0};
    for (PetscInt d = 0; d < 6; d++) {
      PetscReal c = 0;
      for (PetscInt i = 0; i < stride; i++) c += dr[6 * P[i] + d];
      m[d] = c * w;
    }
    for (PetscInt i = 0; i < stride; i++) {
      const PetscReal *a  = dr + 6 * P[i];
      PetscReal        r0 = 0, r1 = 0, rD = 0;
      for (PetscInt d = 0; d < 3; d++) {
        const PetscReal e0 = a[d] - m[d], e1 = a[3 + d] - m[3 + d];
        r0 += e0 * e0, r1 += e1 * e1, rD += (e1 - e0) * (e1 - e0);
      }
      q[0] = PetscMax(q[0], r0), q[1] = PetscMax(q[1], r1), q[2] = PetscMax(q[2], rD);
    }
    for (PetscInt d = 0; d < 3; d++) m[6 + d] = PetscSqrtReal(q[d]);
  }
}

/* NearLive's test of the n candidates from of one kind (0 point-triangle, 1
 * edge-edge) with distances dc at xr: those kept go to `to`, in order; returns
 * how many. */
static inline PetscInt LiveOf(const SelfSet *s, PetscInt kind, PetscReal reach, PetscBool gap_at_end, PetscInt n, const PetscInt *restrict from, const PetscReal *restrict dc, PetscInt *restrict to)
{
  const PetscReal *restrict dr = s->dr, *restrict dm = s->dm, *restrict tm = dm + 9 * s->mesh.nt, none[3] = {0, 0, 0};
  const PetscInt *restrict vert = s->mesh.vert;
  PetscInt nkept                = 0;

  for (PetscInt k = 0; k < n; k++) {
    /* with rounding's slack, R = (1 - 1e-9) dc - reach: left out if (1 + 1e-9)
     * max(M0, M1) < R and, with the gap, (1 + 1e-9) (M0 + MD) < R, compared in
     * squares with (x + y)^2 <= 2 (x^2 + y^2) (R (1 - 2e-9) below R / (1 + 1e-9));
     * else if max(m0, m1) < L, half of R / (1 + 1e-9), and m0 + mD < L */
    const PetscReal R = (1 - 1e-9) * dc[k] - reach;
    if (R > 0) { /* (a NaN distance is kept) */
      const PetscReal *a = kind ? tm + 9 * from[2 * k] : dr + 6 * vert[from[2 * k]];
      const PetscReal *b = kind ? tm + 9 * from[2 * k + 1] : dm + 9 * from[2 * k + 1], *ra = kind ? a + 6 : none, *rb = b + 6;
      const PetscReal  Rs = R * (1 - 2e-9), R0 = Rs - ra[0] - rb[0], R1 = Rs - ra[1] - rb[1], RD = R0 - ra[2] - rb[2];
      PetscReal        s0 = 0, s1 = 0, sD = 0;
      for (PetscInt d = 0; d < 3; d++) {
        const PetscReal e0 = a[d] - b[d], e1 = a[3 + d] - b[3 + d];
        s0 += e0 * e0, s1 += e1 * e1, sD += (e1 - e0) * (e1 - e0);
      }
      if (R0 > 0 && R1 > 0 && s0 < R0 * R0 && s1 < R1 * R1 && (!gap_at_end || (RD > 0 && 2 * (s0 + sD) < RD * RD))) continue;
      {
        const PetscReal L = R / (2 * (1 + 1e-9)), L2 = L * L;
        PetscInt        p[4];
        PetscReal       q0 = 0, q1 = 0, qD = 0;
        PairParticles(s, kind, k, p);
        for (PetscInt i = 1; i < 4; i++) {
          const PetscReal *u = dr + 6 * p[i], *w = dr + 6 * p[0];
          PetscReal        r0 = 0, r1 = 0, rD = 0;
          for (PetscInt d = 0; d < 3; d++) {
            const PetscReal e0 = u[d] - w[d], e1 = u[3 + d] - w[3 + d];
            r0 += e0 * e0, r1 += e1 * e1, rD += (e1 - e0) * (e1 - e0);
          }
          q0 = PetscMax(q0, r0), q1 = PetscMax(q1, r1), qD = PetscMax(qD, rD);
        }
        if (q0 < L2 && q1 < L2 && (!gap_at_end || 2 * (q0 + qD) < L2)) continue;
      }
    }
    to[2 * nkept] = from[2 * k], to[2 * nkept + 1] = from[2 * k + 1];
    nkept++;
  }
  return nkept;
}

/* The live list: the candidates that their distance at xr (dc) and the motion
 * since then do not keep beyond reach, in the candidates' order. Where the near
 * list cannot hold (NearHolds: a bound on every particle's displacement, less one
 * translation for the whole cloth), most candidates still can be left out by their
 * own bound: the Cusick scene's skirt swings about a pedestal that holds a third of
 * the cloth, and the diagonal neighbours of a cell (2.83 thicknesses apart at rest)
 * are most of the list. With d_i = x_i - xr_i and a primitive's points convex
 * combinations of its particles', two bounds on how far the motion moved a pair's
 * points apart, each enough to leave it out:
 * - each primitive's mean displacement c and the largest distance r of one of its
 *   particles' from it (PrimitiveMotion): a point of it moved within r of c, so the
 *   pair's distance is at least dc - M, M = |c_A - c_B| + r_A + r_B;
 * - m = max_i |d_i - d_0| over the pair's particles: at least dc - 2 m.
 * The first costs two primitives' records a candidate instead of four particles'
 * and leaves out most of what the second would; the second is taken where the
 * first does not. Along the step (d interpolated) the distance is at least that
 * bound at x0 or at x1, whichever less; and the implicit solve's gap at the end of
 * the free motion (weights w_i summing to 0, |w| to 2; SolveReachable) at least the
 * distance at x0 less the bound on sum_i w_i D_i, D = x1 - x0: M_D (the first) or
 * 2 max_i |D_i - D_0|. A pair left out is one no pass acts on: the same pairs act,
 * in the same order. *nlive: the candidates in the list; *fresh: every d_i at x0
 * is 0 (the distances are those of x0). */
static PetscErrorCode NearLive(SelfSet *s, PetscReal reach, PetscBool gap_at_end, PetscInt *nlive, PetscBool *fresh)
{
  PetscReal *dr = s->dr, zero = 0, *dm;

  PetscFunctionBeginUser;
  if (s->ndm < 9 * (s->mesh.nt + s->mesh.ne)) {
    PetscCall(PetscFree(s->dm));
    s->ndm = 9 * (s->mesh.nt + s->mesh.ne);
    PetscCall(PetscMalloc1(s->ndm + 1, &s->dm));
  }
  dm = s->dm;
  for (PetscInt k = 0; k < s->n; k++)
    for (PetscInt d = 0; d < 3; d++) {
      dr[6 * k + d]     = s->x0[3 * k + d] - s->xr[3 * k + d];
      dr[6 * k + 3 + d] = s->x1[3 * k + d] - s->xr[3 * k + d];
      zero              = PetscMax(zero, PetscAbsReal(dr[6 * k + d]));
    }
  *fresh = (PetscBool) (zero == 0);
  PrimitiveMotion(s->mesh.nt, 3, s->mesh.tri, dr, dm);
  PrimitiveMotion(s->mesh.ne, 2, s->mesh.edge, dr, dm + 9 * s->mesh.nt);
  s->pt = s->cpt, s->ee = s->cee; /* (PairParticles) */
  s->nlpt = LiveOf(s, 0, reach, gap_at_end, s->ncpt, s->cpt, s->dc, s->lpt_);
  s->nlee = LiveOf(s, 1, reach, gap_at_end, s->ncee, s->cee, s->dc + s->ncpt, s->lee_);
  *nlive  = s->nlpt + s->nlee;
  PetscFunctionReturn(0);
}

/* The near list's pairs that the motion since xr may have brought within reach, in
 * the list's order, to the live list's arrays: pair k is left out where NearHolds'
 * test holds for its own distance at xr (ndc) in place of the list's radius, delta
 * bounding every particle's displacement since xr less one translation (and the
 * step's less another): its distance at x0, at x1 and along the step (and its gap
 * at the end) stay beyond reach, so no pass acts on it and the implicit solve takes
 * no penalty of it (SolvePairMake). The same pairs act, in the same order. A list
 * made at x0 has delta (0, D, D), D the step's (delta[2], which does not depend on
 * xr). */
static void NearWithin(SelfSet *s, const PetscReal delta[3], PetscReal reach, PetscBool gap_at_end)
{
  for (PetscInt kind = 0; kind < 2; kind++) {
    const PetscInt *restrict from = kind ? s->nee_ : s->npt_;
    const PetscReal *restrict dc  = s->ndc + (kind ? s->ncpt : 0);
    PetscInt *restrict to         = kind ? s->lee_ : s->lpt_;
    const PetscInt n              = kind ? s->nnee : s->nnpt;
    PetscInt       m              = 0;
    for (PetscInt k = 0; k < n; k++) {
      if (SelfNearHolds(dc[k], delta, reach, gap_at_end)) continue; /* (a NaN distance is kept) */
      to[2 * m] = from[2 * k], to[2 * m + 1] = from[2 * k + 1];
      m++;
    }
    if (kind)
      s->nlee = m;
    else
      s->nlpt = m;
  }
}

/* The pairs the passes take: those of the near list within reach (NearWithin) if
 * the list holds them (made again at x0 if it no longer does and a list made there
 * would), else the live list (NearLive; the distances made again at x0 when more
 * than a quarter of the candidates are live). */
static PetscErrorCode NearSelect(SelfContact sc, SelfSet *s, PetscReal reach, PetscBool gap_at_end, const PetscReal motion[18])
{
  PetscReal delta[3];
  PetscBool use = PETSC_FALSE, live = PETSC_FALSE;

  PetscFunctionBeginUser;
  if (sc->near > 0) { /* (0: no near list) */
    if (s->has_near) {
      SelfNearDelta(motion, delta); /* (ListMotion's, the near list at xr) */
      use = NearHolds(sc, delta, reach, gap_at_end);
      if (!use && sc->use_patches && delta[0] == delta[0] && delta[1] == delta[1]) PetscCall(SelfPatchesNearHolds(sc, s->x0, s->x1, s->xr, sc->near * sc->thickness, reach, gap_at_end, &use));
    }
    if (!use) {
      PetscCall(NearDisplacements(sc, s, NULL, delta));
      if ((use = NearHolds(sc, delta, reach, gap_at_end))) {
        PetscCall(NearMake(sc, s));
        sc->stats.near_lists++;
        delta[0] = 0, delta[1] = delta[2]; /* (at the new xr) */
      } else {
        PetscInt  nlive = 0;
        PetscBool fresh = PETSC_TRUE, remake = (PetscBool) !s->has_near;
        if (s->has_near) {
          PetscCall(NearLive(s, reach, gap_at_end, &nlive, &fresh));
          remake = (PetscBool) (!fresh && 4 * nlive > s->ncpt + s->ncee);
        }
        /* made again on every rank if on one: every rank's xr the same positions,
         * so that the test of the near list (over the own particles of all) bounds
         * the halo's displacements too */
        if (sc->size > 1) PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &remake, 1, MPIU_BOOL, MPI_LOR, sc->comm));
        if (remake) {
          PetscCall(NearMake(sc, s));
          sc->stats.near_lists++;
          PetscCall(NearLive(s, reach, gap_at_end, &nlive, &fresh));
        }
        live = PETSC_TRUE;
        sc->stats.live_lists++;
      }
    }
  }
  s->near_taken = use;
  if (use) {
    NearWithin(s, delta, reach, gap_at_end);
    sc->stats.near_pairs += (PetscReal) (s->nnpt + s->nnee);
    sc->stats.near_within += (PetscReal) (s->nlpt + s->nlee);
    for (PetscInt j = 0; j < 3; j++) s->near_delta[j] = delta[j];
  }
  if (use || live)
    s->pt = s->lpt_, s->npt = s->nlpt, s->ee = s->lee_, s->nee = s->nlee;
  else
    s->pt = s->cpt, s->npt = s->ncpt, s->ee = s->cee, s->nee = s->ncee;
  PetscFunctionReturn(0);
}

/* The pairs a collision pass takes, once SelfListUpdate chose them: of a near list's,
 * only those the same bound on the motion since xr leaves within
 * the collision test's tolerance (Collides: no pair further apart than that along the
 * step collides); of a live list or every candidate, all. */
static void SelfListColliding(SelfContact sc)
{
  SelfSet *s = &sc->local;

  if (!s->near_taken) return;
  NearWithin(s, s->near_delta, SELF_CCD_TOL * sc->thickness, PETSC_FALSE);
  s->pt = s->lpt_, s->npt = s->nlpt, s->ee = s->lee_, s->nee = s->nlee;
}

/* The local set's list, rebuilt (with the halo) when a particle of any rank moved
 * beyond the margin, and the pairs the passes take. Collective. */
PetscErrorCode SelfListUpdate(SelfContact sc, PetscReal reach, PetscBool gap_at_end)
{
  SelfSet    *s = &sc->local;
  PetscMPIInt ok, all;
  PetscBool   valid;
  PetscReal   motion[30];

  PetscFunctionBeginUser;
  PetscCall(ListMotion(sc, s, motion));
  PetscCall(SetListValid(sc, s, motion, &valid));
  if (!valid) {
    ok = SetBoxes(s, sc->margin * sc->thickness);
    if (sc->size > 1) {
      PetscCallMPI(MPI_Allreduce(&ok, &all, 1, MPI_INT, MPI_MIN, sc->comm));
      PetscCall(CheckFinite(sc, (PetscBool) all));
      PetscCall(HaloRebuild(sc));
      (void) SetBoxes(s, sc->margin * sc->thickness);              /* the new halo's */
      if (sc->use_held) PetscCall(SetHeldMasses(sc, PETSC_FALSE)); /* the new halo's 1/m, in a filter */
    } else
      PetscCall(CheckFinite(sc, (PetscBool) ok));
    PetscCall(SetBroadPhase(sc, s));
    sc->stats.broad_phases++;
  }
  PetscCall(NearSelect(sc, s, reach, gap_at_end, motion + 12)); /* (a new list has no near list: its motion is not taken) */
  PetscFunctionReturn(0);
}

/* ---- a pair's corrections ---- */

/* What one pair does to its four particles, from the state at the start of a pass:
 * their 1/m, displacement over the step and velocity, and the pair's corrections. */
typedef struct {
  PetscReal im[4], d[4][3], v[4][3];
  PetscReal dx[4][3], dv[4][3];
} Act;

static void ActInit(const SelfSet *s, const Pair *pr, Act *a)
{
  for (PetscInt i = 0; i < 4; i++) {
    const PetscInt p = pr->p[i];
    a->im[i]         = s->invm[p];
    for (PetscInt d = 0; d < 3; d++) {
      a->d[i][d]  = s->x1[3 * p + d] - s->x0[3 * p + d];
      a->v[i][d]  = s->v[3 * p + d];
      a->dx[i][d] = a->dv[i][d] = 0;
    }
  }
}

/* The pair's relative displacement over the step along n, with its corrections. */
static PetscReal ActDisplacement(const Pair *pr, const Act *a, const PetscReal n[3])
{
  PetscReal g = 0;
  for (PetscInt i = 0; i < 4; i++)
    for (PetscInt d = 0; d < 3; d++) g += pr->w[i] * (a->d[i][d] + a->dx[i][d]) * n[d];
  return g;
}

/* The impulse along the unit direction n that changes the pair's relative
 * displacement by dg (m): particle i moves by w_i/m_i lambda n (pinned: not at all);
 * with h > 0 its velocity changes by that over h. */
static PetscBool ActPush(const Pair *pr, Act *a, const PetscReal n[3], PetscReal dg, PetscReal h)
{
  PetscReal den = 0, lam;
  for (PetscInt i = 0; i < 4; i++) den += pr->w[i] * pr->w[i] * a->im[i];
  if (den <= 0) return PETSC_FALSE;
  lam = dg / den;
  for (PetscInt i = 0; i < 4; i++) {
    const PetscReal s = lam * pr->w[i] * a->im[i];
    for (PetscInt d = 0; d < 3; d++) {
      a->dx[i][d] += s * n[d];
      if (h > 0) a->dv[i][d] += s * n[d] / h;
    }
  }
  return PETSC_TRUE;
}

/* A pair closer than the thickness H at the start (distance dist, unit normal n):
 * stop its approach (friction bounded by the normal impulse), then push it apart in
 * position towards the thickness. PETSC_TRUE if it acted. */
static PetscBool ActProximity(const Pair *pr, Act *a, const PetscReal n[3], PetscReal dist, PetscReal H, PetscReal mu, PetscReal h)
{
  PetscReal disp  = ActDisplacement(pr, a, n);
  PetscBool acted = PETSC_FALSE;

  if (disp < 0 && ActPush(pr, a, n, -disp, h)) {
    /* Coulomb: the relative tangential velocity drops by at most mu times the
     * normal velocity change -disp/h */
    PetscReal vr[3] = {0, 0, 0}, vn, vt[3], lt;
    acted           = PETSC_TRUE;
    for (PetscInt i = 0; i < 4; i++)
      for (PetscInt d = 0; d < 3; d++) vr[d] += pr->w[i] * (a->v[i][d] + a->dv[i][d]);
    vn = V3Dot(vr, n);
    for (PetscInt d = 0; d < 3; d++) vt[d] = vr[d] - vn * n[d];
    lt = V3Norm(vt);
    if (lt > 0) {
      const PetscReal dvt = PetscMin(lt, mu * (-disp / h));
      for (PetscInt d = 0; d < 3; d++) vt[d] /= lt;
      ActPush(pr, a, vt, -dvt * h, h);
    }
    disp = ActDisplacement(pr, a, n);
  }
  if (dist + disp < H && ActPush(pr, a, n, PetscMin(H - dist - disp, SELF_PUSH_MAX * H), 0)) acted = PETSC_TRUE;
  return acted;
}

/* Apply a pair's corrections to the state of its set. */
static void ActApply(SelfSet *s, const Pair *pr, const Act *a)
{
  for (PetscInt i = 0; i < 4; i++)
    for (PetscInt d = 0; d < 3; d++) s->x1[3 * pr->p[i] + d] += a->dx[i][d], s->v[3 * pr->p[i] + d] += a->dv[i][d];
}

/* Continuous collision of the pair of kind kind and particles pr->p in set s over
 * the step from x0 to x1: its weights and unit normal at the collision oriented by
 * the start (the gap sum w_i x0_i . n is positive); PETSC_FALSE if it does not
 * collide. */
static PetscBool Collides(SelfContact sc, const SelfSet *s, PetscInt kind, Pair *pr, PetscReal n[3])
{
  const PetscReal tol = SELF_CCD_TOL * sc->thickness;
  PetscReal       D[4][3], X[4][3], t, gap0 = 0;

  if (!PairBoxesOverlap(pr->p, kind == 0 ? 1 : 2, s->x0, s->x1, tol)) return PETSC_FALSE; /* most candidates of a kept list */
  for (PetscInt i = 0; i < 4; i++) V3Sub(s->x1 + 3 * pr->p[i], s->x0 + 3 * pr->p[i], D[i]);
  {
    const PetscReal *x0 = s->x0;
    const PetscInt  *p  = pr->p;
    if (kind == 0) {
      PetscReal w[3];
      if (!PointTriangleCollision(x0 + 3 * p[0], D[0], x0 + 3 * p[1], D[1], x0 + 3 * p[2], D[2], x0 + 3 * p[3], D[3], tol, &t, w)) return PETSC_FALSE;
      WeightsPT(pr, w);
    } else {
      PetscReal su, u;
      if (!EdgeEdgeCollision(x0 + 3 * p[0], D[0], x0 + 3 * p[1], D[1], x0 + 3 * p[2], D[2], x0 + 3 * p[3], D[3], tol, &t, &su, &u)) return PETSC_FALSE;
      WeightsEE(pr, su, u);
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
        for (PetscInt d = 0; d < 3; d++) n[d] += pr->w[i] * s->x0[3 * pr->p[i] + d];
      len = V3Norm(n);
      if (len == 0) return PETSC_FALSE;
    }
    for (PetscInt d = 0; d < 3; d++) n[d] /= len;
  }
  for (PetscInt i = 0; i < 4; i++)
    for (PetscInt d = 0; d < 3; d++) gap0 += pr->w[i] * s->x0[3 * pr->p[i] + d] * n[d];
  if (gap0 < 0)
    for (PetscInt d = 0; d < 3; d++) n[d] = -n[d];
  return PETSC_TRUE;
}

/* Take one active pair on the present state of its set (proximity: stop its
 * approach and push it towards the thickness; collision: if it still collides, the
 * inelastic impulse that stops its relative normal motion). PETSC_TRUE if it acted. */
static PetscBool PairTake(SelfContact sc, SelfSet *s, PetscInt kind, Pair *pr, PetscBool proximity, PetscReal h)
{
  Act       a;
  PetscReal n[3];

  if (proximity) {
    const PetscReal dist = PairClosest(kind, s->x0, pr, n);
    ActInit(s, pr, &a);
    if (!ActProximity(pr, &a, n, dist, sc->thickness, sc->mu, h)) return PETSC_FALSE;
  } else {
    PetscReal disp;
    if (!Collides(sc, s, kind, pr, n)) return PETSC_FALSE;
    ActInit(s, pr, &a);
    disp = ActDisplacement(pr, &a, n);
    if (!(disp < 0 && -disp <= SELF_IMPULSE_MAX * sc->thickness && ActPush(pr, &a, n, -disp, h))) return PETSC_FALSE;
  }
  ActApply(s, pr, &a);
  return PETSC_TRUE;
}

/* ---- union-find over particles (groups of active pairs; impact zones) ---- */

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

/* ---- the passes: Gauss-Seidel over the active pairs, on any number of ranks ----
 * A pass takes the pairs active at its start (proximity: closer than the thickness
 * at the start of the step; collision: colliding over the step), one after the
 * other in the order of the sorted candidate list (the natural order of the
 * primitives), each on the state the previous ones left. Pairs that share no
 * particle commute, so the active pairs fall into groups, connected by shared
 * particles, that can be taken in any order. A group whose particles are all this
 * rank's own is taken here. A group that reaches into the halo spans ranks: its
 * pairs are gathered on every rank (each sent by the rank of its particle of
 * smallest natural index, with its four particles' state) and taken there in the
 * same order. Every rank so does the same arithmetic on the same values, in the
 * same order, as one rank would: the result is the same on any number of ranks and
 * any partition. The gathered part is the contacts across the partition's cuts. */

#define SELF_PACK 47 /* reals per gathered pair: kind, its two primitives, 4 particles, their x0, x1, v, 1/m */

/* The pair's primitives' indices in the whole cloth. */
static void PairPrimitives(const SelfSet *s, PetscInt kind, PetscInt k, PetscReal g[2])
{
  if (kind == 0) {
    const PetscInt a = s->pt[2 * k], b = s->pt[2 * k + 1];
    g[0] = (PetscReal) s->vid[a], g[1] = (PetscReal) s->tid[b];
  } else {
    const PetscInt a = s->ee[2 * k], b = s->ee[2 * k + 1];
    g[0] = (PetscReal) s->eid[a], g[1] = (PetscReal) s->eid[b];
  }
}

/* A pair packed to be gathered: kind, its primitives (k >= 0), its particles'
 * natural indices and their x0, x1, v. */
static void PackPair(const SelfSet *s, PetscInt kind, PetscInt k, const PetscInt p[4], PetscReal *pk)
{
  pk[0] = (PetscReal) kind;
  if (k >= 0)
    PairPrimitives(s, kind, k, pk + 1);
  else
    pk[1] = pk[2] = 0;
  for (PetscInt i = 0; i < 4; i++) {
    pk[3 + i] = (PetscReal) s->nat[p[i]];
    for (PetscInt d = 0; d < 3; d++) pk[7 + 9 * i + d] = s->x0[3 * p[i] + d], pk[10 + 9 * i + d] = s->x1[3 * p[i] + d], pk[13 + 9 * i + d] = s->v[3 * p[i] + d];
    pk[43 + i] = s->invm[p[i]]; /* 0 also for a particle the solid holds */
  }
}

/* Every rank's packed pairs (here[0] of them, and two counts to sum) on every rank:
 * sums (pairs, and the two counts over the ranks), packs (rank order; PetscFree).
 * Collective. */
static PetscErrorCode GatherPacks(SelfContact sc, const PetscInt here[3], const PetscReal *pack, PetscInt sums[3], PetscReal **packs)
{
  PetscInt    *all;
  PetscMPIInt *counts, *displs;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc3(3 * sc->size, &all, sc->size, &counts, sc->size, &displs));
  PetscCallMPI(MPI_Allgather(here, 3, MPIU_INT, all, 3, MPIU_INT, sc->comm));
  sums[0] = sums[1] = sums[2] = 0;
  for (PetscMPIInt r = 0; r < sc->size; r++) {
    PetscCall(PetscMPIIntCast(SELF_PACK * all[3 * r], &counts[r]));
    PetscCall(PetscMPIIntCast(SELF_PACK * sums[0], &displs[r]));
    for (PetscInt i = 0; i < 3; i++) sums[i] += all[3 * r + i];
  }
  PetscCall(PetscMalloc1(SELF_PACK * sums[0] + 1, packs));
  PetscCallMPI(MPI_Allgatherv(pack, counts[sc->rank], MPIU_REAL, *packs, counts, displs, MPIU_REAL, sc->comm));
  PetscCall(PetscFree3(all, counts, displs));
  PetscFunctionReturn(0);
}

static int PackCompare(const void *a, const void *b)
{
  const PetscReal *x = *(const PetscReal *const *) a, *y = *(const PetscReal *const *) b;
  for (PetscInt i = 0; i < 3; i++)
    if (x[i] != y[i]) return x[i] < y[i] ? -1 : 1;
  return 0;
}

/* Take the gathered pairs (npack of SELF_PACK reals, from every rank) in order on
 * every rank, and copy the state of the particles this rank holds back to its set.
 * *nacted: how many acted. */
static PetscErrorCode TakeGathered(SelfContact sc, PetscBool proximity, PetscReal h, PetscInt npack, const PetscReal *packs, PetscInt *nacted)
{
  SelfSet          *s    = &sc->local;
  SelfSet           mini = {0};
  PetscInt         *nat, m = 4 * npack;
  const PetscReal **order;

  PetscFunctionBeginUser;
  *nacted = 0;
  PetscCall(PetscMalloc2(m + 1, &nat, npack + 1, &order));
  for (PetscInt j = 0; j < npack; j++)
    for (PetscInt i = 0; i < 4; i++) nat[4 * j + i] = (PetscInt) packs[SELF_PACK * j + 3 + i];
  PetscCall(PetscSortRemoveDupsInt(&m, nat));
  PetscCall(PetscMalloc4(m + 1, &mini.invm, 3 * m + 1, &mini.x0, 3 * m + 1, &mini.x1, 3 * m + 1, &mini.v));
  mini.n = mini.nown = m;
  for (PetscInt j = 0; j < npack; j++) {
    const PetscReal *pk = packs + SELF_PACK * j;
    order[j]            = pk;
    for (PetscInt i = 0; i < 4; i++) {
      PetscInt q;
      PetscCall(PetscFindInt((PetscInt) pk[3 + i], m, nat, &q));
      mini.invm[q] = pk[43 + i];
      for (PetscInt d = 0; d < 3; d++) mini.x0[3 * q + d] = pk[7 + 9 * i + d], mini.x1[3 * q + d] = pk[10 + 9 * i + d], mini.v[3 * q + d] = pk[13 + 9 * i + d];
    }
  }
  qsort(order, (size_t) npack, sizeof(*order), PackCompare);
  for (PetscInt j = 0; j < npack; j++) {
    const PetscReal *pk   = order[j];
    const PetscInt   kind = (PetscInt) pk[0];
    Pair             pr;
    for (PetscInt i = 0; i < 4; i++) PetscCall(PetscFindInt((PetscInt) pk[3 + i], m, nat, &pr.p[i]));
    if (PairTake(sc, &mini, kind, &pr, proximity, h)) (*nacted)++;
  }
  for (PetscInt q = 0; q < m; q++) {
    const PetscInt l = LocalOf(sc, nat[q]);
    if (l < 0) continue;
    for (PetscInt d = 0; d < 3; d++) s->x1[3 * l + d] = mini.x1[3 * q + d], s->v[3 * l + d] = mini.v[3 * q + d];
  }
  PetscCall(PetscFree4(mini.invm, mini.x0, mini.x1, mini.v));
  PetscCall(PetscFree2(nat, order));
  PetscFunctionReturn(0);
}

/* One pass (proximity, or collision) over the local set. *nactive: the pairs active
 * at its start, *nacted: those that acted (over all ranks). Collective. */
static PetscErrorCode Pass(SelfContact sc, PetscBool proximity, PetscReal h, PetscInt *nactive, PetscInt *nacted)
{
  SelfSet        *s  = &sc->local;
  const PetscReal H  = sc->thickness;
  PetscInt        na = 0, *act, here[3] = {0, 0, 0}; /* pairs gathered from here, active, acted (counted here) */
  PetscReal      *pack;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc1(s->npt + s->nee + 1, &act));
  for (PetscInt kind = 0; kind < 2; kind++)
    for (PetscInt k = 0; k < (kind ? s->nee : s->npt); k++) {
      Pair      pr;
      PetscReal n[3];
      PairParticles(s, kind, k, pr.p);
      if (proximity) {
        PetscReal dist;
        if (!PairBoxesOverlap(pr.p, kind == 0 ? 1 : 2, s->x0, s->x0, H)) continue;
        dist = PairClosest(kind, s->x0, &pr, n);
        if (dist >= H || dist <= 0) continue; /* dist 0: touching at the start, no direction: the collision pass sees it */
      } else if (!Collides(sc, s, kind, &pr, n))
        continue;
      act[na++] = kind ? s->npt + k : k;
      if (PairCountedHere(s, pr.p)) here[1]++;
      (void) ZoneMerge(sc->uf, pr.p);
    }
  for (PetscInt j = 0; j < na; j++) {
    const PetscInt kind = act[j] >= s->npt, k = kind ? act[j] - s->npt : act[j];
    PetscInt       p[4];
    PairParticles(s, kind, k, p);
    for (PetscInt i = 0; i < 4; i++)
      if (p[i] >= s->nown) sc->bnd[ZoneRoot(sc->uf, p[i])] = PETSC_TRUE;
  }
  /* the groups of this rank's own particles here; the others' pairs packed */
  PetscCall(PetscMalloc1(SELF_PACK * na + 1, &pack));
  for (PetscInt j = 0; j < na; j++) {
    const PetscInt kind = act[j] >= s->npt, k = kind ? act[j] - s->npt : act[j];
    Pair           pr;
    PetscReal     *pk = pack + SELF_PACK * here[0];
    PairParticles(s, kind, k, pr.p);
    if (!sc->bnd[ZoneRoot(sc->uf, pr.p[0])]) {
      if (PairTake(sc, s, kind, &pr, proximity, h)) here[2]++;
      continue;
    }
    if (!PairCountedHere(s, pr.p)) continue;
    PackPair(s, kind, k, pr.p, pk);
    here[0]++;
  }
  for (PetscInt j = 0; j < na; j++) {
    const PetscInt kind = act[j] >= s->npt, k = kind ? act[j] - s->npt : act[j];
    PetscInt       p[4];
    PairParticles(s, kind, k, p);
    for (PetscInt i = 0; i < 4; i++) sc->uf[p[i]] = -1, sc->bnd[p[i]] = PETSC_FALSE;
  }
  PetscCall(PetscFree(act));
  *nactive = here[1];
  *nacted  = here[2];
  if (sc->size > 1) {
    PetscInt   sums[3], nb;
    PetscReal *packs;
    PetscCall(GatherPacks(sc, here, pack, sums, &packs));
    *nactive = sums[1];
    *nacted  = sums[2];
    if (sums[0]) {
      PetscCall(TakeGathered(sc, proximity, h, sums[0], packs, &nb));
      sc->stats.gathered += sums[0];
      *nacted += nb;
    }
    PetscCall(PetscFree(packs));
  }
  PetscCall(PetscFree(pack));
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
static PetscErrorCode ZonesRigidify(SelfSet *s, PetscReal h, PetscInt *zone, const PetscReal *xs, PetscReal *work, PetscBool *pinned, PetscInt *inzones)
{
  const PetscInt N = s->n;
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
    if (s->invm[p] == 0) {
      pinned[r] = PETSC_TRUE;
      continue;
    }
    m[r] += 1 / s->invm[p];
    for (PetscInt d = 0; d < 3; d++) {
      c[3 * r + d] += s->x0[3 * p + d] / s->invm[p];
      u[3 * r + d] += (xs[3 * p + d] - s->x0[3 * p + d]) / s->invm[p];
    }
  }
  for (PetscInt r = 0; r < N; r++)
    if (m[r] > 0)
      for (PetscInt d = 0; d < 3; d++) c[3 * r + d] /= m[r], u[3 * r + d] /= m[r];
  for (PetscInt p = 0; p < N; p++) {
    PetscInt  r;
    PetscReal rp[3], up[3], l[3], mp;
    if (zone[p] < 0 || s->invm[p] == 0) continue;
    r = ZoneRoot(zone, p);
    if (pinned[r]) continue;
    mp = 1 / s->invm[p];
    for (PetscInt d = 0; d < 3; d++) rp[d] = s->x0[3 * p + d] - c[3 * r + d], up[d] = xs[3 * p + d] - s->x0[3 * p + d] - u[3 * r + d];
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
    if (zone[p] < 0 || s->invm[p] == 0) continue;
    r = ZoneRoot(zone, p);
    if (pinned[r]) {
      for (PetscInt d = 0; d < 3; d++) s->x1[3 * p + d] = s->x0[3 * p + d], s->v[3 * p + d] = 0;
      continue;
    }
    for (PetscInt d = 0; d < 3; d++) rp[d] = s->x0[3 * p + d] - c[3 * r + d], w[d] = L[3 * r + d] / h;
    Rotate(L + 3 * r, rp, Rr);
    V3Cross(w, Rr, wxr);
    for (PetscInt d = 0; d < 3; d++) {
      s->x1[3 * p + d] = c[3 * r + d] + u[3 * r + d] + Rr[d];
      s->v[3 * p + d]  = u[3 * r + d] / h + wxr[d];
    }
  }
  PetscFunctionReturn(0);
}

/* The fail-safe by impact zones: *count particles in zones. Each round every rank
 * finds the pairs of its list that still collide; they are gathered on every rank
 * with their particles' state (the zones' particles, in natural order, the same on
 * every rank), the zones merged and moved there, and the ranks copy the moved
 * particles back. Collective. */
static PetscErrorCode FailSafeZones(SelfContact sc, PetscReal h, PetscInt *count)
{
  SelfSet   *s = &sc->local, z = {0}; /* z: the zones' particles */
  PetscInt   npairs = 0, *pairs = NULL, rounds = 0, cap = 0, *nat = NULL;
  PetscReal *xs = NULL, *pack = NULL;

  PetscFunctionBeginUser;
  *count = 0;
  for (;;) {
    PetscInt   here[3] = {0, 0, 0}, sums[3], m, *zone, mnew;
    PetscReal *packs, *work;
    PetscBool *pinned, merged = PETSC_FALSE;

    PetscCall(SelfListUpdate(sc, sc->thickness, PETSC_FALSE));
    SelfListColliding(sc);
    for (PetscInt kind = 0; kind < 2; kind++)
      for (PetscInt k = 0; k < (kind ? s->nee : s->npt); k++) {
        Pair      pr;
        PetscReal n[3];
        PairParticles(s, kind, k, pr.p);
        if (!PairCountedHere(s, pr.p) || !Collides(sc, s, kind, &pr, n)) continue;
        if (here[0] == cap) {
          cap = 2 * cap + 16;
          PetscCall(PetscRealloc(SELF_PACK * cap * sizeof(*pack), &pack));
        }
        PackPair(s, kind, -1, pr.p, pack + SELF_PACK * here[0]++);
      }
    PetscCall(GatherPacks(sc, here, pack, sums, &packs));
    if (!sums[0]) {
      PetscCall(PetscFree(packs));
      break;
    }
    /* the zones' particles: the ones they had (their state kept) and the new pairs' */
    {
      PetscInt  *nn, nold = z.n;
      PetscReal *ox0 = z.x0, *oxs = xs, *ox1 = z.x1, *ov = z.v, *oim = z.invm;
      PetscInt  *onat = nat;
      PetscCall(PetscMalloc1(nold + 4 * sums[0] + 1, &nn));
      PetscCall(PetscArraycpy(nn, nat, nold));
      for (PetscInt j = 0; j < 4 * sums[0]; j++) nn[nold + j] = (PetscInt) packs[SELF_PACK * (j / 4) + 3 + j % 4];
      mnew = nold + 4 * sums[0];
      PetscCall(PetscSortRemoveDupsInt(&mnew, nn));
      PetscCall(PetscMalloc5(mnew + 1, &z.invm, 3 * mnew + 1, &z.x0, 3 * mnew + 1, &z.x1, 3 * mnew + 1, &z.v, 3 * mnew + 1, &xs));
      for (PetscInt q = 0; q < mnew; q++) {
        PetscInt o = -1;
        if (nold) PetscCall(PetscFindInt(nn[q], nold, onat, &o));
        if (o >= 0) z.invm[q] = oim[o];
        if (o >= 0)
          for (PetscInt d = 0; d < 3; d++) z.x0[3 * q + d] = ox0[3 * o + d], xs[3 * q + d] = oxs[3 * o + d], z.x1[3 * q + d] = ox1[3 * o + d], z.v[3 * q + d] = ov[3 * o + d];
      }
      for (PetscInt j = 0; j < sums[0]; j++) {
        const PetscReal *pk = packs + SELF_PACK * j;
        for (PetscInt i = 0; i < 4; i++) {
          PetscInt q, o = -1;
          PetscCall(PetscFindInt((PetscInt) pk[3 + i], mnew, nn, &q));
          if (nold) PetscCall(PetscFindInt(nn[q], nold, onat, &o));
          if (o >= 0) continue; /* in a zone already: its state is the zone's */
          z.invm[q] = pk[43 + i];
          for (PetscInt d = 0; d < 3; d++) z.x0[3 * q + d] = pk[7 + 9 * i + d], xs[3 * q + d] = z.x1[3 * q + d] = pk[10 + 9 * i + d], z.v[3 * q + d] = pk[13 + 9 * i + d];
        }
      }
      PetscCall(PetscFree5(oim, ox0, ox1, ov, oxs));
      PetscCall(PetscFree(onat));
      nat = nn;
      z.n = z.nown = mnew;
    }
    /* the pairs (natural indices) */
    {
      PetscInt *more;
      PetscCall(PetscMalloc1(4 * (npairs + sums[0]) + 1, &more));
      PetscCall(PetscArraycpy(more, pairs, 4 * npairs));
      for (PetscInt j = 0; j < 4 * sums[0]; j++) more[4 * npairs + j] = (PetscInt) packs[SELF_PACK * (j / 4) + 3 + j % 4];
      PetscCall(PetscFree(pairs));
      pairs = more;
    }
    PetscCall(PetscFree(packs));
    /* the zones: union-find over the zones' particles (root: the smallest natural index) */
    m = z.n;
    PetscCall(PetscMalloc3(m, &zone, 16 * m, &work, m, &pinned));
    for (PetscInt q = 0; q < m; q++) zone[q] = -1;
    for (PetscInt j = 0; j < npairs + sums[0]; j++) {
      PetscInt p[4];
      for (PetscInt i = 0; i < 4; i++) PetscCall(PetscFindInt(pairs[4 * j + i], m, nat, &p[i]));
      if (ZoneMerge(zone, p) && j >= npairs) merged = PETSC_TRUE;
    }
    npairs += sums[0];
    if (merged) {
      PetscCall(ZonesRigidify(&z, h, zone, xs, work, pinned, count));
      for (PetscInt q = 0; q < m; q++) {
        const PetscInt l = LocalOf(sc, nat[q]);
        if (l < 0) continue;
        for (PetscInt d = 0; d < 3; d++) s->x1[3 * l + d] = z.x1[3 * q + d], s->v[3 * l + d] = z.v[3 * q + d];
      }
    }
    PetscCall(PetscFree3(zone, work, pinned));
    if (!merged) break;
    /* each round merges zones or adds particles to them: at most 2 N rounds */
    PetscCheck(++rounds <= 2 * sc->N + 1, PETSC_COMM_SELF, PETSC_ERR_PLIB, "Self-contact impact zones did not settle in %" PetscInt_FMT " rounds", rounds);
  }
  PetscCall(PetscFree5(z.invm, z.x0, z.x1, z.v, xs));
  PetscCall(PetscFree(nat));
  PetscCall(PetscFree(pairs));
  PetscCall(PetscFree(pack));
  PetscFunctionReturn(0);
}

/* The fail-safe by stopping: the particles of every pair that still collides stay
 * where they were at the start (collision-free); the ones they then collide with
 * follow, round after round (every rank its own particles, from the state at the
 * start of the round). *count particles stopped. Collective. */
static PetscErrorCode FailSafeFreeze(SelfContact sc, PetscInt *count)
{
  SelfSet   *s = &sc->local;
  PetscInt   frozen;
  PetscBool *stopped, *stop;

  PetscFunctionBeginUser;
  *count = 0;
  PetscCall(PetscCalloc2(s->nown + 1, &stopped, s->nown + 1, &stop));
  do {
    PetscInt mine = 0;
    PetscCall(SelfListUpdate(sc, sc->thickness, PETSC_FALSE));
    SelfListColliding(sc);
    for (PetscInt kind = 0; kind < 2; kind++)
      for (PetscInt k = 0; k < (kind ? s->nee : s->npt); k++) {
        Pair      pr;
        PetscReal n[3];
        PairParticles(s, kind, k, pr.p);
        if (!Collides(sc, s, kind, &pr, n)) continue;
        for (PetscInt i = 0; i < 4; i++)
          if (pr.p[i] < s->nown) stop[pr.p[i]] = PETSC_TRUE;
      }
    for (PetscInt p = 0; p < s->nown; p++) {
      if (!stop[p]) continue;
      stop[p] = PETSC_FALSE;
      if (stopped[p] || s->invm[p] == 0) continue;
      stopped[p] = PETSC_TRUE;
      for (PetscInt d = 0; d < 3; d++) s->x1[3 * p + d] = s->x0[3 * p + d], s->v[3 * p + d] = 0;
      mine++;
    }
    PetscCall(MPIU_Allreduce(&mine, &frozen, 1, MPIU_INT, MPI_SUM, sc->comm));
    *count += frozen;
    if (frozen) PetscCall(SelfHaloUpdate(sc, NULL, s->x1, s->v));
  } while (frozen);
  PetscCall(PetscFree2(stopped, stop));
  PetscFunctionReturn(0);
}

PetscErrorCode SelfContactFilter(SelfContact sc, PetscReal h, PetscScalar *x, PetscScalar *v, PetscBool *changed)
{
  SelfSet *s    = &sc->local;
  PetscInt ncol = 0, ncol_total = 0, failsafe = 0, close, active = 1;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.self_contact, 0, 0, 0, 0));
  for (PetscInt k = 0; k < 3 * s->nown; k++) s->x1[k] = PetscRealPart(x[k]), s->v[k] = PetscRealPart(v[k]);
  PetscCall(SelfHaloUpdate(sc, s->x0, s->x1, s->v));
  if (sc->use_held) PetscCall(SetHeldMasses(sc, PETSC_FALSE));
  PetscCall(SelfListUpdate(sc, sc->thickness, PETSC_FALSE));
  PetscCall(Pass(sc, PETSC_TRUE, h, &sc->stats.pairs, &close));
  if (close) PetscCall(SelfHaloUpdate(sc, NULL, s->x1, s->v)); /* close: pairs that acted, on any rank */
  for (PetscInt it = 0; it < sc->its && active; it++) {
    if (it > 0 || close) PetscCall(SelfListUpdate(sc, sc->thickness, PETSC_FALSE)); /* (else nothing moved since the last) */
    SelfListColliding(sc);
    PetscCall(Pass(sc, PETSC_FALSE, h, &active, &ncol));
    if (ncol) PetscCall(SelfHaloUpdate(sc, NULL, s->x1, s->v));
    sc->stats.collisions += ncol;
    ncol_total += ncol;
    if (!ncol) break; /* nothing changed: the same pairs still collide */
  }
  if (active) {
    PetscCall(sc->zones ? FailSafeZones(sc, h, &failsafe) : FailSafeFreeze(sc, &failsafe));
    sc->stats.failsafe += failsafe;
    sc->stats.failsafe_steps++;
  }
  if (sc->use_held) PetscCall(SetHeldMasses(sc, PETSC_TRUE));
  sc->use_held = PETSC_FALSE; /* given again for each filter */
  *changed     = (PetscBool) (sc->stats.pairs || ncol_total || failsafe);
  for (PetscInt k = 0; k < 3 * s->nown; k++) x[k] = s->x1[k], v[k] = s->v[k];
  PetscCall(PetscLogEventEnd(drape_log.self_contact, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}
