/* Particle-solid contact: projection and velocity constraints after a step (all
 * schemes), and the cached distance queries the implicit step's constraints use
 * (src/solid/contactsolve.c). */
#include <solid.h>
#include <drape.h>
#include <petscviewer.h>

static const char *const mode_names[] = {"sticky", "friction", "frictionless", "ContactMode", "CONTACT_", NULL};

/* Per-particle memory of the last query: the distance to the solid is
 * 1-Lipschitz in the position, so a particle that has moved less than its last
 * clearance minus the thickness cannot be in contact: no query. A particle that
 * has not moved at all (held by sticky contact) reuses its last answer. */
typedef struct {
  PetscInt   n;
  PetscReal *x, *d, *nrm;
} ContactCache;

struct _p_Contact {
  MPI_Comm     comm;
  Solid        solid;
  ContactMode  mode;
  PetscReal    thickness, mu;
  ContactCache owned;      /* one entry per owned particle */
  PetscInt     nprev;      /* particles in prev: 0 before ContactCheckInitial */
  PetscReal   *prev;       /* where ContactProject left each owned particle (start of the next step) */
  PetscReal    prevbox[6]; /* their box, lo and hi (the self-contact filter may move them a fraction of a thickness after) */
};

static PetscErrorCode CacheQuery(Contact c, ContactCache *cache, PetscInt idx, PetscInt n, const PetscReal p[3], PetscReal *dist, PetscReal nrm[3])
{
  PetscFunctionBeginUser;
  if (cache->n != n) {
    PetscCall(PetscFree3(cache->x, cache->d, cache->nrm));
    PetscCall(PetscMalloc3(3 * n, &cache->x, n, &cache->d, 3 * n, &cache->nrm));
    for (PetscInt i = 0; i < n; i++) cache->d[i] = -1; /* unknown */
    cache->n = n;
  }
  if (cache->d[idx] >= 0) {
    const PetscReal *q     = cache->x + 3 * idx;
    PetscReal        moved = PetscSqrtReal(PetscSqr(p[0] - q[0]) + PetscSqr(p[1] - q[1]) + PetscSqr(p[2] - q[2]));
    if (moved == 0) {
      *dist = cache->d[idx];
      for (PetscInt d = 0; d < 3; d++) nrm[d] = cache->nrm[3 * idx + d];
      PetscFunctionReturn(0);
    }
    if (cache->d[idx] - moved > 2 * c->thickness) {
      *dist = cache->d[idx] - moved; /* a lower bound: far enough, no normal needed */
      PetscFunctionReturn(0);
    }
  }
  PetscCall(SolidQuery(c->solid, p, dist, nrm));
  for (PetscInt d = 0; d < 3; d++) {
    cache->x[3 * idx + d]   = p[d];
    cache->nrm[3 * idx + d] = nrm[d];
  }
  cache->d[idx] = PetscMax(*dist, 0);
  PetscFunctionReturn(0);
}

/* A lower bound of particle idx's distance to the solid at p, from its last query
 * (the distance is 1-Lipschitz); 0 when unknown. */
static PetscReal CacheClearance(const ContactCache *cache, PetscInt idx, PetscInt n, const PetscReal p[3])
{
  const PetscReal *q = cache->x + 3 * idx;

  if (cache->n != n || cache->d[idx] < 0) return 0;
  return PetscMax(cache->d[idx] - PetscSqrtReal(PetscSqr(p[0] - q[0]) + PetscSqr(p[1] - q[1]) + PetscSqr(p[2] - q[2])), 0);
}

/* Where the next step starts from: the sweep's first ends, in the box [lo, hi]
 * (NULL: found here). */
static PetscErrorCode ContactSetStart(Contact c, PetscInt n, const PetscScalar *x, const PetscReal lo[3], const PetscReal hi[3])
{
  PetscFunctionBeginUser;
  for (PetscInt d = 0; d < 3; d++) {
    c->prevbox[d]     = lo ? lo[d] : PETSC_MAX_REAL;
    c->prevbox[3 + d] = hi ? hi[d] : -PETSC_MAX_REAL;
  }
  for (PetscInt k = 0; !lo && k < n; k++)
    for (PetscInt d = 0; d < 3; d++) {
      c->prevbox[d]     = PetscMin(c->prevbox[d], x[3 * k + d]);
      c->prevbox[3 + d] = PetscMax(c->prevbox[3 + d], x[3 * k + d]);
    }
  if (c->nprev != n) {
    PetscCall(PetscFree(c->prev));
    PetscCall(PetscMalloc1(3 * n, &c->prev));
    c->nprev = n;
  }
  PetscCall(PetscArraycpy(c->prev, x, 3 * n));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactCreate(MPI_Comm comm, Solid solid, Contact *contact)
{
  Contact c;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&c));
  c->comm      = comm;
  c->solid     = solid;
  c->mode      = CONTACT_STICKY;
  c->thickness = 2e-3;
  c->mu        = 0.3;
  *contact     = c;
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSetFromOptions(Contact c)
{
  PetscInt imode = (PetscInt) c->mode;

  PetscFunctionBeginUser;
  PetscOptionsBegin(c->comm, NULL, "Contact with the solid", "Contact");
  PetscCall(PetscOptionsEList("-contact_mode", "sticky (the paper: v = 0 on the surface), friction (Coulomb), frictionless", "ContactSetFromOptions", mode_names, 3, mode_names[imode], &imode, NULL));
  PetscCall(PetscOptionsReal("-contact_thickness", "Distance from the solid at which particles are in contact (m)", "ContactSetFromOptions", c->thickness, &c->thickness, NULL));
  PetscCall(PetscOptionsReal("-contact_friction", "Coulomb friction coefficient mu (static = kinetic)", "ContactSetFromOptions", c->mu, &c->mu, NULL));
  PetscOptionsEnd();
  c->mode = (ContactMode) imode;
  /* the layer is the fabric's thickness (the distance the cloth keeps from the solid):
   * a metre floated the cloth a metre above it, and moved a cloth that started within
   * it there in one step */
  PetscCall(DrapeCheckReal(c->comm, "-contact_thickness", 1, &c->thickness, 0, 0.05, "m (the distance the cloth keeps from the solid, a fabric's thickness)"));
  PetscCall(DrapeCheckReal(c->comm, "-contact_friction", 1, &c->mu, 0, 10, ""));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactView(Contact c, PetscViewer viewer)
{
  PetscFunctionBeginUser;
  PetscCall(PetscViewerASCIIPrintf(viewer, "Contact: %s, thickness %g m", mode_names[c->mode], (double) c->thickness));
  if (c->mode == CONTACT_FRICTION) PetscCall(PetscViewerASCIIPrintf(viewer, ", mu = %g", (double) c->mu));
  PetscCall(PetscViewerASCIIPrintf(viewer, "\n"));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactDestroy(Contact *c)
{
  PetscFunctionBeginUser;
  if (!*c) PetscFunctionReturn(0);
  PetscCall(PetscFree3((*c)->owned.x, (*c)->owned.d, (*c)->owned.nrm));
  PetscCall(PetscFree((*c)->prev));
  PetscCall(PetscFree(*c));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactGetMode(Contact c, ContactMode *mode, PetscReal *mu)
{
  PetscFunctionBeginUser;
  if (mode) *mode = c->mode;
  if (mu) *mu = c->mode == CONTACT_FRICTION ? c->mu : 0;
  PetscFunctionReturn(0);
}

/* Velocity after contact: the normal component into the solid is removed; the
 * tangential part follows the mode (Coulomb: the normal impulse dvn bounds the
 * tangential one). */
static void ContactVelocity(ContactMode mode, PetscReal mu, const PetscReal n[3], PetscReal v[3])
{
  PetscReal vn = v[0] * n[0] + v[1] * n[1] + v[2] * n[2], dvn = vn < 0 ? -vn : 0, vt[3], lt;

  if (mode == CONTACT_STICKY) {
    v[0] = v[1] = v[2] = 0;
    return;
  }
  for (PetscInt d = 0; d < 3; d++) {
    v[d] += dvn * n[d];
    vt[d] = v[d] - (vn + dvn) * n[d];
  }
  if (mode == CONTACT_FRICTIONLESS) return;
  lt = PetscSqrtReal(vt[0] * vt[0] + vt[1] * vt[1] + vt[2] * vt[2]);
  for (PetscInt d = 0; d < 3; d++) v[d] -= (lt <= mu * dvn ? 1 : mu * dvn / lt) * vt[d];
}

PetscErrorCode ContactSweep(Contact c, const PetscReal p0[3], const PetscReal p1[3], PetscReal clear, PetscReal dist, const PetscReal normal[3], PetscReal limit, PetscBool *hit, PetscReal q[3], PetscReal nf[3])
{
  const PetscReal L = PetscSqrtReal(PetscSqr(p1[0] - p0[0]) + PetscSqr(p1[1] - p0[1]) + PetscSqr(p1[2] - p0[2]));
  PetscReal       t;
  PetscBool       crossed;

  PetscFunctionBeginUser;
  *hit = PETSC_FALSE;
  if (L == 0 || clear > L + c->thickness) PetscFunctionReturn(0); /* the step cannot reach the solid */
  if (dist >= limit && clear + dist > L) PetscFunctionReturn(0);  /* nor here: the distance is 1-Lipschitz, at least (clear + dist - L)/2 along it */
  if (dist < limit) {
    /* the end point's answer (back along the closest point's normal) is right unless it
     * puts the particle behind a mesh face it crossed (through a thin part); a convex
     * primitive or the plane cannot be passed that way */
    const PetscReal back[3] = {p1[0] + (c->thickness - dist) * normal[0], p1[1] + (c->thickness - dist) * normal[1], p1[2] + (c->thickness - dist) * normal[2]};
    PetscCall(SolidSweep(c->solid, p0, back, PETSC_TRUE, &t, nf, &crossed));
    if (!crossed) PetscFunctionReturn(0);
  }
  PetscCall(SolidSweep(c->solid, p0, p1, PETSC_FALSE, &t, nf, &crossed));
  if (!crossed) PetscFunctionReturn(0);
  *hit = PETSC_TRUE;
  for (PetscInt d = 0; d < 3; d++) q[d] = p0[d] + t * (p1[d] - p0[d]);
  PetscFunctionReturn(0);
}

/* Project the owned particles that reached the solid back onto its contact
 * surface and constrain their velocity; impulse[3] (local, not summed over ranks)
 * gains the impulse the solid gave them, sum of m (v_after - v_before). */
PetscErrorCode ContactProject(Contact c, PetscInt n, PetscScalar *x, PetscScalar *v, const PetscReal *mass, const PetscBool *pinned, PetscReal h, PetscReal *depth, PetscInt *ncontact, PetscReal impulse[3], PetscBool *held)
{
  PetscReal lo[3] = {PETSC_MAX_REAL, PETSC_MAX_REAL, PETSC_MAX_REAL}, hi[3] = {-PETSC_MAX_REAL, -PETSC_MAX_REAL, -PETSC_MAX_REAL};
  PetscReal deepest = 0, grow = c->thickness;
  PetscInt  count = 0;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.contact, 0, 0, 0, 0));
  if (held)
    for (PetscInt k = 0; k < n; k++) held[k] = PETSC_FALSE;
  const PetscBool swept = (PetscBool) (c->nprev == n); /* the steps' start known */
  PetscReal       box[6];                              /* of the steps: from their starts' box to their ends' */
  for (PetscInt k = 0; k < n; k++)
    for (PetscInt d = 0; d < 3; d++) {
      lo[d] = PetscMin(lo[d], x[3 * k + d]);
      hi[d] = PetscMax(hi[d], x[3 * k + d]);
    }
  for (PetscInt d = 0; d < 3; d++) {
    box[d]     = swept ? PetscMin(lo[d], c->prevbox[d]) : lo[d];
    box[3 + d] = swept ? PetscMax(hi[d], c->prevbox[3 + d]) : hi[d];
  }
  if (n > 0 && SolidBoxNear(c->solid, box, box + 3, grow)) {
    for (PetscInt k = 0; k < n; k++) {
      PetscReal *p = x + 3 * k, dist = c->thickness, nrm[3] = {0, 0, 1}; /* outside the box grown by the thickness: at least that far */
      PetscBool  near, hit = PETSC_FALSE, queried = PETSC_FALSE;
      if (pinned && pinned[k]) continue;
      near = SolidBoxNear(c->solid, p, p, grow);
      if (swept) {
        /* continuous contact: the step from where the last projection left the
         * particle, against the solid; where it entered the solid unseen by the end
         * point (through a thin part), the plane of the face it entered replaces the
         * closest point's */
        const PetscReal *p0 = c->prev + 3 * k, lo0[3] = {PetscMin(p0[0], p[0]), PetscMin(p0[1], p[1]), PetscMin(p0[2], p[2])}, hi0[3] = {PetscMax(p0[0], p[0]), PetscMax(p0[1], p[1]), PetscMax(p0[2], p[2])};
        if ((p0[0] != p[0] || p0[1] != p[1] || p0[2] != p[2]) && (near || SolidBoxNear(c->solid, lo0, hi0, grow))) { /* moved (sticky contact holds many still) */
          const PetscReal L2 = PetscSqr(p[0] - p0[0]) + PetscSqr(p[1] - p0[1]) + PetscSqr(p[2] - p0[2]);
          PetscReal       q[3], nf[3];
          if (near) PetscCall(CacheQuery(c, &c->owned, k, n, p, &dist, nrm));
          queried = near;
          /* ContactSweep's first test, without the square roots: a step shorter than the clearance at its end cannot reach the solid */
          if (dist < c->thickness || dist * dist <= L2) PetscCall(ContactSweep(c, p0, p, CacheClearance(&c->owned, k, n, p0), dist, nrm, c->thickness, &hit, q, nf));
          if (hit) {
            dist = nf[0] * (p[0] - q[0]) + nf[1] * (p[1] - q[1]) + nf[2] * (p[2] - q[2]);
            for (PetscInt d = 0; d < 3; d++) nrm[d] = nf[d];
          }
        }
      }
      if (!near && !hit) continue;
      if (!queried && !hit) PetscCall(CacheQuery(c, &c->owned, k, n, p, &dist, nrm));
      if (held && c->mode == CONTACT_STICKY && dist <= 2 * c->thickness && v[3 * k] == 0 && v[3 * k + 1] == 0 && v[3 * k + 2] == 0)
        held[k] = PETSC_TRUE; /* drapebe's fixed constraints: v = 0, on the surface's plane (a faceted surface can be a hair further) */
      if (dist > c->thickness * (1 + 1e-6) + PETSC_SMALL) continue;
      count++;
      if (held && c->mode == CONTACT_STICKY) held[k] = PETSC_TRUE; /* in the layer: v = 0 below */
      if (dist >= c->thickness) continue;
      PetscReal vold[3] = {v[3 * k], v[3 * k + 1], v[3 * k + 2]}, dx[3];
      deepest           = PetscMax(deepest, c->thickness - dist);
      ContactVelocity(c->mode, c->mu, nrm, v + 3 * k);
      /* position: back onto the contact surface, and along the corrected velocity */
      for (PetscInt d = 0; d < 3; d++) {
        dx[d] = h * (v[3 * k + d] - vold[d]);
        impulse[d] += mass[k] * (v[3 * k + d] - vold[d]);
      }
      {
        PetscReal dxn = dx[0] * nrm[0] + dx[1] * nrm[1] + dx[2] * nrm[2];
        for (PetscInt d = 0; d < 3; d++) {
          p[d] += dx[d] - dxn * nrm[d] + (c->thickness - dist) * nrm[d];
          lo[d] = PetscMin(lo[d], p[d]); /* the next steps' starts */
          hi[d] = PetscMax(hi[d], p[d]);
        }
      }
    }
  }
  PetscCall(ContactSetStart(c, n, x, lo, hi));
  PetscCall(MPIU_Allreduce(&deepest, depth, 1, MPIU_REAL, MPI_MAX, c->comm));
  PetscCall(MPIU_Allreduce(&count, ncontact, 1, MPIU_INT, MPI_SUM, c->comm));
  PetscCall(PetscLogEventEnd(drape_log.contact, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactGetThickness(Contact c, PetscReal *thickness)
{
  PetscFunctionBeginUser;
  *thickness = c->thickness;
  PetscFunctionReturn(0);
}

PetscErrorCode ContactDistance(Contact c, PetscInt k, PetscInt n, const PetscReal x[3], PetscReal *dist, PetscReal normal[3])
{
  PetscFunctionBeginUser;
  if (!SolidBoxNear(c->solid, x, x, 2 * c->thickness)) {
    *dist = 2 * c->thickness; /* a lower bound */
    PetscFunctionReturn(0);
  }
  PetscCall(CacheQuery(c, &c->owned, k, n, x, dist, normal));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactCheckInitial(Contact c, PetscInt n, const PetscScalar *x)
{
  PetscInt  inside = 0, total;
  PetscReal dist, nrm[3];

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < n; k++) {
    if (!SolidBoxNear(c->solid, x + 3 * k, x + 3 * k, 0)) continue;
    PetscCall(SolidQuery(c->solid, x + 3 * k, &dist, nrm));
    if (dist < 0) inside++;
  }
  PetscCall(MPIU_Allreduce(&inside, &total, 1, MPIU_INT, MPI_SUM, c->comm));
  PetscCall(ContactSetStart(c, n, x, NULL, NULL));
  PetscCheck(!total, c->comm, PETSC_ERR_USER_INPUT, "The initial cloth has %" PetscInt_FMT " particles inside the solid; place it outside (-cloth_center, -cloth_orientation) or move the solid (-solid_translate, -solid_floor, -solid_plane)", total);
  PetscFunctionReturn(0);
}
