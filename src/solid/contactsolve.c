/* Contact with the solid inside an implicit step: the constraints, their active set,
 * the release test and lagged friction (include/contactsolve.h says what they are;
 * TSDRAPEBE takes them into its residual, its matrix and its step). Every array is
 * of the owned particles; the only communication is the counts' reductions. */
#include <contactsolve.h>
#include <drape.h>
#include <petscviewer.h>

/* A particle that a step carries less than this fraction of the contact thickness
 * into the contact layer is not made a constraint of the step: the projection
 * after the step lifts it back (by at most this much). Such shallow contacts are
 * the particles at the edge of a contact region, which the solve pulls off and
 * pushes on by turns; as constraints they would make the iterations cycle. */
#define CONTACT_SHALLOW 0.1

struct _p_ContactSolve {
  MPI_Comm  comm;
  Contact   contact;
  Cloth     cloth;
  PetscReal stick_velocity; /* -contact_stick_velocity, m/s */
  PetscBool release_next;   /* -contact_release_next: a constraint found pulling is released from the next step on */
  /* from the contact and the cloth at ContactSolveSetUp */
  ContactMode      mode;
  PetscReal        mu, thickness, damping;
  PetscReal        release; /* released when it would lift faster than h release, m/s^2 */
  const PetscReal *mass;
  const PetscBool *pinned;
  PetscInt         m; /* owned particles */
  /* the step: its length, its start (the TS's arrays), the velocity change of the last one */
  PetscReal          h;
  const PetscScalar *x0, *v0;
  PetscScalar       *dvlast;
  PetscScalar       *a; /* work: accelerations at the start (friction) */
  /* constraints of the step, per owned particle */
  ClothConstraint *ctype;
  PetscReal       *cnormal;     /* outward unit normal, 3 each */
  PetscReal       *ctarget;     /* prescribed normal velocity n.v of the step, m/s */
  PetscScalar     *z;           /* the velocity change that gives the prescribed velocity, 3 each */
  PetscInt        *released;    /* times released in this step */
  PetscBool       *lifted;      /* released, and not yet out of the contact layer */
  PetscBool       *lifted_acc;  /* lifted as the last accepted step left it: each try of a step starts from it */
  PetscReal       *clear;       /* a lower bound of the distance to the solid at the start, m */
  ClothConstraint *ctype_pc;    /* the constraints when the preconditioner was last built */
  PetscBool        constrained; /* any constraint on any rank */
  const PetscReal *hdiag;       /* the Cloth's Hessian diagonal blocks of the last assembly */
  /* friction of sliding particles: from the previous step, the normal force, the
   * sliding direction and speed; for this step, the impulse h f = fimp - fblock v */
  PetscReal *fnormal;       /* N */
  PetscReal *fdir, *fspeed; /* 3 each (unit, tangential), m/s */
  PetscReal *fimp, *fblock; /* 3 and 9 each */
  PetscReal  impulse[3];    /* of the last accepted step, owned particles, N s */
  /* what View reports */
  PetscInt constrained_max, joined, nreleased, swept;
};

PetscErrorCode ContactSolveCreate(MPI_Comm comm, Contact contact, Cloth cloth, ContactSolve *solve)
{
  ContactSolve s;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&s));
  s->comm           = comm;
  s->contact        = contact;
  s->cloth          = cloth;
  s->stick_velocity = 1e-5;
  s->release_next   = PETSC_FALSE;
  *solve            = s;
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveSetFromOptions(ContactSolve s)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(s->comm, NULL, "Contact with the solid in the implicit step (-ts_type drapebe)", "Contact");
  PetscCall(PetscOptionsReal("-contact_stick_velocity", "Backward Euler: sliding speed below which friction is static friction smoothed into a viscous force (it creeps at most this fast, m/s)", "ContactSolveSetFromOptions", s->stick_velocity,
                             &s->stick_velocity, NULL));
  PetscCall(PetscOptionsBool("-contact_release_next", "Backward Euler: a constraint whose impulse pulls its particle into the solid is released from the next step on (Baraff & Witkin 1998), not by solving the step again",
                             "ContactSolveSetFromOptions", s->release_next, &s->release_next, NULL));
  PetscOptionsEnd();
  PetscCall(DrapeCheckReal(s->comm, "-contact_stick_velocity", 1, &s->stick_velocity, 1e-12, 1, "m/s"));
  PetscFunctionReturn(0);
}

static PetscErrorCode ContactSolveFree(ContactSolve s)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree4(s->dvlast, s->a, s->z, s->cnormal));
  PetscCall(PetscFree5(s->ctype, s->ctarget, s->released, s->lifted, s->ctype_pc));
  PetscCall(PetscFree5(s->fnormal, s->fdir, s->fspeed, s->fimp, s->fblock));
  PetscCall(PetscFree2(s->clear, s->lifted_acc));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveSetUp(ContactSolve s)
{
  ClothInfo info;
  PetscInt  m;
  PetscReal g;

  PetscFunctionBeginUser;
  PetscCall(ClothGetInfo(s->cloth, &info));
  PetscCall(ClothGetMasses(s->cloth, &s->mass, &s->pinned));
  PetscCall(ContactGetMode(s->contact, &s->mode, &s->mu));
  PetscCall(ContactGetThickness(s->contact, &s->thickness));
  s->m = m   = info.nowned;
  s->damping = info.damping;
  g          = PetscSqrtReal(PetscSqr(info.gravity[0]) + PetscSqr(info.gravity[1]) + PetscSqr(info.gravity[2]));
  /* a particle at the edge of a contact region is pulled off and pushed on by turns:
   * released only when it would lift faster than a tenth of what gravity gives it in
   * a step, such a particle does not make the iterations cycle */
  s->release     = 0.1 * g;
  s->constrained = PETSC_FALSE;
  PetscCall(ContactSolveFree(s));
  PetscCall(PetscCalloc4(3 * m, &s->dvlast, 3 * m, &s->a, 3 * m, &s->z, 3 * m, &s->cnormal));
  PetscCall(PetscCalloc5(m, &s->ctype, m, &s->ctarget, m, &s->released, m, &s->lifted, m, &s->ctype_pc)); /* CLOTH_FREE, PETSC_FALSE */
  PetscCall(PetscCalloc5(m, &s->fnormal, 3 * m, &s->fdir, m, &s->fspeed, 3 * m, &s->fimp, 9 * m, &s->fblock));
  PetscCall(PetscCalloc2(m, &s->clear, m, &s->lifted_acc));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveView(ContactSolve s, PetscViewer viewer)
{
  PetscBool isascii;
  PetscInt  swept;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) viewer, PETSCVIEWERASCII, &isascii));
  if (!isascii) PetscFunctionReturn(0);
  PetscCall(MPIU_Allreduce(&s->swept, &swept, 1, MPIU_INT, MPI_SUM, s->comm));
  PetscCall(PetscViewerASCIIPrintf(viewer, "  contact with the solid as constraints of the step: at most %" PetscInt_FMT " particles constrained in a solve; after solves %" PetscInt_FMT " constraints added, %" PetscInt_FMT " released\n",
                                   s->constrained_max, s->joined, s->nreleased));
  if (swept) PetscCall(PetscViewerASCIIPrintf(viewer, "  %" PetscInt_FMT " landings found along the step, not at its end (through a thin part of the solid)\n", swept));
  if (s->mode == CONTACT_FRICTION) PetscCall(PetscViewerASCIIPrintf(viewer, "  friction lagged by a step, static below %g m/s\n", (double) s->stick_velocity));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveDestroy(ContactSolve *solve)
{
  PetscFunctionBeginUser;
  if (!*solve) PetscFunctionReturn(0);
  PetscCall(ContactSolveFree(*solve));
  PetscCall(PetscFree(*solve));
  PetscFunctionReturn(0);
}

/* The friction of sliding particle k for this step, as the impulse h f(v) = fimp -
 * fblock v: from the previous step's normal force f_n and sliding velocity (speed
 * y, direction t, projected on this step's tangent plane P = I - n n^T),
 *   y >= eps: h f = -h mu f_n (t + (P - t t^T) v / y)  (magnitude mu f_n, direction
 *             linearised about t),
 *   y <  eps: h f = -h mu f_n P v / eps               (static friction, smoothed). */
static void Friction(ContactSolve s, PetscInt k)
{
  const PetscReal *n = s->cnormal + 3 * k, eps = s->stick_velocity;
  const PetscReal  c   = s->h * s->mu * s->fnormal[k];
  PetscReal       *imp = s->fimp + 3 * k, *B = s->fblock + 9 * k, t[3], tn = 0, ln = 0, y = s->fspeed[k];

  for (PetscInt i = 0; i < 3; i++) imp[i] = 0;
  for (PetscInt i = 0; i < 9; i++) B[i] = 0;
  if (s->mode != CONTACT_FRICTION || s->ctype[k] != CLOTH_SLIDE || c <= 0) return;
  for (PetscInt i = 0; i < 3; i++) tn += n[i] * s->fdir[3 * k + i];
  for (PetscInt i = 0; i < 3; i++) {
    t[i] = s->fdir[3 * k + i] - tn * n[i];
    ln += t[i] * t[i];
  }
  ln = PetscSqrtReal(ln);
  if (y < eps || ln < 0.5) { /* sticking (or the surface turned under a slider) */
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < 3; j++) B[3 * i + j] = c / eps * ((i == j) - n[i] * n[j]);
    return;
  }
  for (PetscInt i = 0; i < 3; i++) {
    t[i] /= ln;
    imp[i] = -c * t[i];
  }
  for (PetscInt i = 0; i < 3; i++)
    for (PetscInt j = 0; j < 3; j++) B[3 * i + j] = c / y * ((i == j) - n[i] * n[j] - t[i] * t[j]);
}

/* The constraints of the step: z, the velocity change that gives the constrained
 * particles their prescribed velocity (the normal target along n; nothing else
 * when fixed), and the friction. *pc_changes: particles whose constraint differs
 * from the preconditioner's. Collective. */
static PetscErrorCode ApplyConstraints(ContactSolve s, PetscInt *pc_changes)
{
  PetscInt counts[2] = {0, 0}; /* constrained, different from the preconditioner's */

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < s->m; k++) {
    const PetscReal *nk = s->cnormal + 3 * k, *v = s->v0 + 3 * k, g = s->ctarget[k];
    const PetscReal  vn = nk[0] * v[0] + nk[1] * v[1] + nk[2] * v[2];
    for (PetscInt d = 0; d < 3; d++) {
      if (s->ctype[k] == CLOTH_SLIDE)
        s->z[3 * k + d] = (g - vn) * nk[d];
      else if (s->ctype[k] == CLOTH_FIXED)
        s->z[3 * k + d] = g * nk[d] - v[d];
      else
        s->z[3 * k + d] = 0;
    }
    Friction(s, k);
    counts[0] += s->ctype[k] != CLOTH_FREE;
    counts[1] += s->ctype[k] != s->ctype_pc[k];
  }
  PetscCall(MPIU_Allreduce(MPI_IN_PLACE, counts, 2, MPIU_INT, MPI_SUM, s->comm));
  s->constrained     = (PetscBool) (counts[0] > 0);
  s->constrained_max = PetscMax(s->constrained_max, counts[0]);
  *pc_changes        = counts[1];
  PetscFunctionReturn(0);
}

/* Constrain particle k: normal n, prescribed normal velocity g. */
static inline void Constrain(ContactSolve s, PetscInt k, const PetscReal n[3], PetscReal g)
{
  s->ctype[k]   = s->mode == CONTACT_STICKY ? CLOTH_FIXED : CLOTH_SLIDE;
  s->ctarget[k] = g;
  for (PetscInt d = 0; d < 3; d++) s->cnormal[3 * k + d] = n[d];
}

/* No longer in contact: no constraint, no friction carried on. */
static inline void Unconstrain(ContactSolve s, PetscInt k)
{
  s->ctype[k]   = CLOTH_FREE;
  s->fnormal[k] = 0;
}

/* Friction of a particle in contact at the start of the step that has no history
 * (its first step in contact: no normal force yet) or was sticking: from the forces
 * on it now, a = F(x, v)/m in s->a, the normal force -m n.a, and whether the pull
 * along the surface already overcomes friction (then it starts sliding, along the
 * pull, with exact kinetic friction from this step on). */
static void FrictionStart(ContactSolve s, PetscInt k)
{
  const PetscReal m = s->mass[k], *n = s->cnormal + 3 * k, *a = s->a + 3 * k;
  const PetscReal an = n[0] * a[0] + n[1] * a[1] + n[2] * a[2];
  PetscReal       ft[3], lt = 0;

  if (s->fnormal[k] <= 0) s->fnormal[k] = PetscMax(-m * an, 0);
  if (s->fspeed[k] >= s->stick_velocity) return;
  for (PetscInt d = 0; d < 3; d++) {
    ft[d] = m * (a[d] - an * n[d]);
    lt += ft[d] * ft[d];
  }
  lt = PetscSqrtReal(lt);
  if (lt <= s->mu * s->fnormal[k]) return;
  for (PetscInt d = 0; d < 3; d++) s->fdir[3 * k + d] = ft[d] / lt;
  s->fspeed[k] = PetscMax(s->stick_velocity, s->h * (lt - s->mu * s->fnormal[k]) / m);
}

/* Continuous contact: free particle k's step from x0 to x (its end, predicted or
 * solved), whose end point has distance *dist to the solid and closest-point normal
 * nrm. Where the step enters the solid unseen by the end point (through a thin part
 * of a mesh, or out on its far side), the landing is where it entered: *dist and nrm
 * become the end point's against the plane of the surface there, so that the
 * constraint ends the step on that plane's contact surface. */
static PetscErrorCode LandingSwept(ContactSolve s, PetscInt k, const PetscReal x[3], PetscReal *dist, PetscReal nrm[3])
{
  const PetscReal *x0 = s->x0 + 3 * k;
  PetscReal        q[3], nf[3];
  PetscBool        hit;

  PetscFunctionBeginUser;
  PetscCall(ContactSweep(s->contact, x0, x, s->clear[k], *dist, nrm, s->thickness * (1 - CONTACT_SHALLOW), &hit, q, nf));
  if (!hit) PetscFunctionReturn(0);
  *dist = nf[0] * (x[0] - q[0]) + nf[1] * (x[1] - q[1]) + nf[2] * (x[2] - q[2]);
  for (PetscInt d = 0; d < 3; d++) nrm[d] = nf[d];
  s->swept++;
  PetscFunctionReturn(0);
}

/* The constraints at the start of the step: particles within the contact layer
 * (but those released since they last left it: the edge of a contact region, whose
 * shallow contacts the projection after the step handles), and particles from
 * outside that the step would carry deeper into it at their velocity extrapolated
 * from the last step, v + dv_last (most of a landing, so that few are left for the
 * iterations; not v + h a, which at steps above the explicit limit is no prediction
 * at all, nor v + h g, which at large steps lands every particle that tension holds
 * just above the surface). */
static PetscErrorCode InitialConstraints(ContactSolve s)
{
  const PetscReal h = s->h, tol = s->thickness * (1 + 1e-6) + PETSC_SMALL;

  PetscFunctionBeginUser;
  if (s->mode == CONTACT_FRICTION) PetscCall(ClothComputeAcceleration(s->cloth, s->x0, s->v0, s->a));
  for (PetscInt k = 0; k < s->m; k++) {
    const PetscReal *x = s->x0 + 3 * k;
    PetscReal        dist, nrm[3];
    s->released[k] = 0;
    if (s->pinned[k]) {
      Unconstrain(s, k);
      continue;
    }
    PetscCall(ContactDistance(s->contact, k, s->m, x, &dist, nrm));
    s->clear[k] = PetscMax(dist, 0);
    if (dist <= tol) {
      if (s->lifted[k])
        Unconstrain(s, k);
      else {
        Constrain(s, k, nrm, (s->thickness - dist) / h);
        if (s->mode == CONTACT_FRICTION) FrictionStart(s, k);
      }
    } else {
      const PetscReal *v0 = s->v0 + 3 * k, *dv = s->dvlast + 3 * k;
      const PetscReal  v[3] = {v0[0] + dv[0], v0[1] + dv[1], v0[2] + dv[2]}, xp[3] = {x[0] + h * v[0], x[1] + h * v[1], x[2] + h * v[2]};
      s->lifted[k] = PETSC_FALSE;
      Unconstrain(s, k);
      PetscCall(ContactDistance(s->contact, k, s->m, xp, &dist, nrm));
      PetscCall(LandingSwept(s, k, xp, &dist, nrm));
      if (dist < s->thickness * (1 - CONTACT_SHALLOW)) Constrain(s, k, nrm, nrm[0] * v[0] + nrm[1] * v[1] + nrm[2] * v[2] + (s->thickness - dist) / h);
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveBegin(ContactSolve s, PetscReal h, const PetscScalar *x0, const PetscScalar *v0, PetscInt *pc_changes)
{
  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.contact, 0, 0, 0, 0));
  s->h  = h;
  s->x0 = x0;
  s->v0 = v0;
  /* a step tried again (a failed solve, too much energy added) starts where its
   * first try did, not from what that try's updates decided */
  PetscCall(PetscArraycpy(s->lifted, s->lifted_acc, s->m));
  PetscCall(InitialConstraints(s));
  PetscCall(ApplyConstraints(s, pc_changes));
  PetscCall(PetscLogEventEnd(drape_log.contact, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveGetConstraints(ContactSolve s, const ClothConstraint **type, const PetscReal **normal, const PetscReal **block)
{
  PetscFunctionBeginUser;
  if (type) *type = s->constrained ? s->ctype : NULL;
  if (normal) *normal = s->cnormal;
  if (block) *block = s->mode == CONTACT_FRICTION ? s->fblock : NULL;
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveSetPreconditioned(ContactSolve s)
{
  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < s->m; k++) s->ctype_pc[k] = s->ctype[k];
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveTrialVelocity(ContactSolve s, const PetscScalar *dv, PetscScalar *vt)
{
  PetscFunctionBeginUser;
  if (!s->constrained) PetscFunctionReturn(0);
  for (PetscInt k = 0; k < s->m; k++) {
    const PetscReal *nk = s->cnormal + 3 * k, *w = dv + 3 * k;
    const PetscReal  wn = nk[0] * w[0] + nk[1] * w[1] + nk[2] * w[2];
    if (s->ctype[k] == CLOTH_FREE) continue;
    for (PetscInt d = 0; d < 3; d++) {
      if (s->ctype[k] == CLOTH_SLIDE)
        vt[3 * k + d] -= wn * nk[d];
      else
        vt[3 * k + d] = s->v0[3 * k + d];
      vt[3 * k + d] += s->z[3 * k + d];
    }
  }
  PetscFunctionReturn(0);
}

/* S (R - h f) + (I - S) D w, f the friction of sliding particles, D as in the
 * matrix (the constrained w stay zero, whatever D) */
PetscErrorCode ContactSolveResidual(ContactSolve s, const PetscScalar *dv, const PetscScalar *vt, PetscScalar *r)
{
  PetscFunctionBeginUser;
  if (!s->constrained) PetscFunctionReturn(0);
  for (PetscInt k = 0; k < s->m; k++) {
    const PetscReal *nk = s->cnormal + 3 * k, *w = dv + 3 * k, *B = s->fblock + 9 * k, *v = vt + 3 * k;
    PetscReal       *rk = r + 3 * k, rn, wn, d;
    if (s->ctype[k] == CLOTH_FREE) continue;
    PetscCall(ClothGetConstraintScale(s->cloth, 1 + s->h * s->damping, s->h * s->h, k, &d));
    if (s->ctype[k] == CLOTH_FIXED)
      for (PetscInt i = 0; i < 3; i++) rk[i] = d * w[i];
    else {
      for (PetscInt i = 0; i < 3; i++) rk[i] += B[3 * i] * v[0] + B[3 * i + 1] * v[1] + B[3 * i + 2] * v[2] - s->fimp[3 * k + i];
      rn = nk[0] * rk[0] + nk[1] * rk[1] + nk[2] * rk[2];
      wn = nk[0] * w[0] + nk[1] * w[1] + nk[2] * w[2];
      for (PetscInt i = 0; i < 3; i++) rk[i] += (d * wn - rn) * nk[i];
    }
  }
  PetscFunctionReturn(0);
}

/* Does constrained particle k, released alone, leave the surface? p is the impulse
 * the constraint carried. Released, the particle's velocity changes by
 * dv = -A_kk^{-1} p (A_kk its diagonal block of the unconstrained matrix,
 * (1 + h c) m I + h^2 H_kk): it lifts off when n.dv is positive, by more than a
 * tenth of what gravity gives in a step. Not simply n.p < 0: a large tangential
 * impulse (sticky contact holding the cloth's pull along the surface) turns, through
 * the anisotropic A_kk, into motion into the solid, and such a particle released
 * would come straight back. */
static PetscBool WouldLift(ContactSolve s, PetscInt k, const PetscReal p[3])
{
  const PetscReal *H = s->hdiag + 9 * k, *nk = s->cnormal + 3 * k, a = (1 + s->h * s->damping) * s->mass[k], b = s->h * s->h;
  PetscReal        A[9], y[3], det;

  for (PetscInt i = 0; i < 9; i++) A[i] = b * H[i] + (i % 4 == 0 ? a : 0);
  /* y = A^{-1} n (A symmetric): cofactors */
  {
    const PetscReal c00 = A[4] * A[8] - A[5] * A[7], c01 = A[5] * A[6] - A[3] * A[8], c02 = A[3] * A[7] - A[4] * A[6];
    const PetscReal c11 = A[0] * A[8] - A[2] * A[6], c12 = A[1] * A[6] - A[0] * A[7], c22 = A[0] * A[4] - A[1] * A[3];
    det  = A[0] * c00 + A[1] * c01 + A[2] * c02;
    y[0] = (c00 * nk[0] + c01 * nk[1] + c02 * nk[2]) / det;
    y[1] = (c01 * nk[0] + c11 * nk[1] + c12 * nk[2]) / det;
    y[2] = (c02 * nk[0] + c12 * nk[1] + c22 * nk[2]) / det;
  }
  /* n.dv = -(A^{-1} n).p */
  return (PetscBool) (-(y[0] * p[0] + y[1] * p[1] + y[2] * p[2]) > s->release * s->h);
}

/* The active set's changes after a solve (xt, vt, at its end): kinds[0] new
 * constraints, kinds[1] released ones, kinds[2] those released from the next step
 * on (-contact_release_next: held to the end of this one, so the solve stands), on
 * this rank. */
static PetscErrorCode UpdateActiveSet(ContactSolve s, const PetscScalar *xt, const PetscScalar *vt_all, const PetscScalar *at, PetscInt kinds[3])
{
  const PetscReal h = s->h;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < s->m; k++) {
    const PetscReal m = s->mass[k], *vt = vt_all + 3 * k;
    PetscReal       p[3];
    if (s->pinned[k]) continue;
    if (s->ctype[k] == CLOTH_FREE) {
      PetscReal dist, nrm[3];
      PetscCall(ContactDistance(s->contact, k, s->m, xt + 3 * k, &dist, nrm));
      PetscCall(LandingSwept(s, k, xt + 3 * k, &dist, nrm));
      if (dist < s->thickness * (1 - CONTACT_SHALLOW)) {
        Constrain(s, k, nrm, nrm[0] * vt[0] + nrm[1] * vt[1] + nrm[2] * vt[2] + (s->thickness - dist) / h);
        s->lifted[k] = PETSC_FALSE;
        kinds[0]++;
      }
      continue;
    }
    /* the impulse the solid gave the particle (friction included) */
    for (PetscInt d = 0; d < 3; d++) p[d] = m * (vt[d] - s->v0[3 * k + d] - h * at[3 * k + d]);
    if (!s->released[k] && WouldLift(s, k, p)) {
      s->released[k]++;
      s->lifted[k] = PETSC_TRUE; /* free at the start of a step while it stays in the layer */
      if (s->release_next) {     /* held to the end of this step */
        kinds[2]++;
        continue;
      }
      Unconstrain(s, k);
      kinds[1]++;
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveUpdate(ContactSolve s, const PetscScalar *xt, const PetscScalar *vt, const PetscScalar *at, PetscInt *changes, PetscInt *pc_changes)
{
  PetscInt kinds[3] = {0, 0, 0}, sums[3]; /* new, released, released from the next step */

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.contact, 0, 0, 0, 0));
  PetscCall(ClothGetHessianDiagonal(s->cloth, &s->hdiag));
  PetscCall(UpdateActiveSet(s, xt, vt, at, kinds));
  PetscCall(MPIU_Allreduce(kinds, sums, 3, MPIU_INT, MPI_SUM, s->comm));
  *changes = sums[0] + sums[1];
  s->joined += sums[0];
  s->nreleased += sums[1] + sums[2];
  PetscCall(PetscInfo(NULL, "contact active set: %" PetscInt_FMT " new, %" PetscInt_FMT " released, %" PetscInt_FMT " from the next step\n", sums[0], sums[1], sums[2]));
  *pc_changes = 0;
  if (*changes) PetscCall(ApplyConstraints(s, pc_changes));
  PetscCall(PetscLogEventEnd(drape_log.contact, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveAccept(ContactSolve s, PetscScalar *vt, const PetscScalar *at)
{
  PetscFunctionBeginUser;
  PetscCall(PetscArraycpy(s->lifted_acc, s->lifted, s->m));
  s->impulse[0] = s->impulse[1] = s->impulse[2] = 0;
  for (PetscInt k = 0; k < s->m; k++) {
    PetscReal *v = vt + 3 * k;
    for (PetscInt d = 0; d < 3; d++) s->dvlast[3 * k + d] = v[d] - s->v0[3 * k + d];
    if (s->constrained && s->ctype[k] != CLOTH_FREE) {
      const PetscReal *nk = s->cnormal + 3 * k, vn = nk[0] * v[0] + nk[1] * v[1] + nk[2] * v[2];
      PetscReal        vend[3], lambda = 0, speed = 0;
      for (PetscInt d = 0; d < 3; d++) {
        vend[d] = s->ctype[k] == CLOTH_FIXED ? 0 : v[d] - vn * nk[d];
        lambda += nk[d] * s->mass[k] * (v[d] - s->v0[3 * k + d] - s->h * at[3 * k + d]);
        speed += vend[d] * vend[d];
        s->impulse[d] += s->mass[k] * (vend[d] - s->v0[3 * k + d] - s->h * at[3 * k + d]);
      }
      speed         = PetscSqrtReal(speed);
      s->fnormal[k] = PetscMax(lambda, 0) / s->h;
      s->fspeed[k]  = speed;
      for (PetscInt d = 0; d < 3; d++) {
        s->fdir[3 * k + d] = speed > 0 ? vend[d] / speed : 0;
        v[d]               = vend[d];
      }
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ContactSolveGetImpulse(ContactSolve s, PetscReal impulse[3])
{
  PetscFunctionBeginUser;
  for (PetscInt d = 0; d < 3; d++) impulse[d] = s->impulse[d];
  PetscFunctionReturn(0);
}
