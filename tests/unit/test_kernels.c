static const char help[] = "Unit tests of the element kernels in src/cloth/kernels.h (KernelStretch, KernelAngle):\n"
                           "Taylor tests of gradient and Hessian, symmetry, PSD projection, invariance, known values.\n"
                           "Options: -seed <int> (random configurations)\n\n";

#include <petscsys.h>
#include <cloth/kernels.h>

/* Every check group that passes is counted here; the first failing check raises
 * an error (PETSC_ERR_PLIB) with a message that names the element and the numbers. */
static PetscInt npassed = 0;

#define NCFG_MAX 16
#define NEPS     6 /* eps = 1e-2 * 2^-k, k = 0..NEPS-1 */
#define EPS0     1e-2

typedef enum {
  ELEM_STRETCH,
  ELEM_SHEAR,
  ELEM_BEND
} ElemKind;
static const char *const ElemKindNames[] = {"stretch", "shear", "bend"};

typedef struct {
  ElemKind      kind;
  PetscInt      n;      /* number of coordinates: 6 (edge) or 9 (angle) */
  PetscReal     x[9];   /* [x_a, x_b] or [x_a, x_b, x_c] (c the vertex) */
  PetscReal     k, L;   /* stretch */
  PetscReal     kappa;  /* shear, bend */
  KernelBendLaw law;    /* bend: law of curvature (n = 0: linear) */
  PetscReal     ell;    /* length scale: shortest edge */
  PetscReal     escale; /* energy scale, for round-off estimates */
  PetscBool     compressed;
  char          label[96];
} Elem;

/* ---------------------------------------------------------------- helpers */

static PetscErrorCode ElemEval(const Elem *el, const PetscReal *x, PetscReal *E, PetscReal *g, PetscReal *H, PetscBool project)
{
  PetscFunctionBeginUser;
  if (el->kind == ELEM_STRETCH)
    *E = KernelStretch(x, x + 3, el->k, el->L, g, H, project);
  else
    *E = KernelAngle(el->kind == ELEM_SHEAR ? KERNEL_SHEAR : KERNEL_BEND, x, x + 3, x + 6, el->kappa, el->law.n ? &el->law : NULL, g, H, project);
  PetscFunctionReturn(0);
}

static PetscErrorCode Norm(PetscInt n, const PetscReal *v, PetscReal *nrm)
{
  PetscReal s = 0;

  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < n; i++) s += v[i] * v[i];
  *nrm = PetscSqrtReal(s);
  PetscFunctionReturn(0);
}

static PetscErrorCode MaxAbs(PetscInt n, const PetscReal *v, PetscReal *m)
{
  PetscFunctionBeginUser;
  *m = 0;
  for (PetscInt i = 0; i < n; i++) *m = PetscMax(*m, PetscAbsReal(v[i]));
  PetscFunctionReturn(0);
}

/* max|a - ref| / max|ref| over n entries. */
static PetscErrorCode MaxRelDiff(PetscInt n, const PetscReal *a, const PetscReal *ref, PetscReal *rel)
{
  PetscReal m, diff = 0;

  PetscFunctionBeginUser;
  PetscCall(MaxAbs(n, ref, &m));
  for (PetscInt i = 0; i < n; i++) diff = PetscMax(diff, PetscAbsReal(a[i] - ref[i]));
  *rel = diff / m;
  PetscFunctionReturn(0);
}

static PetscErrorCode Cross(const PetscReal a[3], const PetscReal b[3], PetscReal c[3])
{
  PetscFunctionBeginUser;
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
  PetscFunctionReturn(0);
}

/* uniform in [lo, hi); the PetscRandom has interval [0, 1) */
static PetscErrorCode Uniform(PetscRandom rnd, PetscReal lo, PetscReal hi, PetscReal *v)
{
  PetscReal r;

  PetscFunctionBeginUser;
  PetscCall(PetscRandomGetValueReal(rnd, &r));
  *v = lo + (hi - lo) * r;
  PetscFunctionReturn(0);
}

static PetscErrorCode RandomUnit(PetscRandom rnd, PetscReal v[3])
{
  PetscReal nrm = 0;

  PetscFunctionBeginUser;
  while (nrm < 0.1 || nrm > 1) {
    for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -1, 1, &v[i]));
    PetscCall(Norm(3, v, &nrm));
  }
  for (PetscInt i = 0; i < 3; i++) v[i] /= nrm;
  PetscFunctionReturn(0);
}

/* random unit vector orthogonal to the unit vector a */
static PetscErrorCode RandomUnitOrthogonal(PetscRandom rnd, const PetscReal a[3], PetscReal v[3])
{
  PetscReal nrm = 0, p;

  PetscFunctionBeginUser;
  while (nrm < 0.1) {
    PetscCall(RandomUnit(rnd, v));
    p = v[0] * a[0] + v[1] * a[1] + v[2] * a[2];
    for (PetscInt i = 0; i < 3; i++) v[i] -= p * a[i];
    PetscCall(Norm(3, v, &nrm));
  }
  for (PetscInt i = 0; i < 3; i++) v[i] /= nrm;
  PetscFunctionReturn(0);
}

/* random rotation (from a random unit quaternion) */
static PetscErrorCode RandomRotation(PetscRandom rnd, PetscReal R[9])
{
  PetscReal q[4], nrm = 0, w, x, y, z;

  PetscFunctionBeginUser;
  while (nrm < 0.1 || nrm > 1) {
    for (PetscInt i = 0; i < 4; i++) PetscCall(Uniform(rnd, -1, 1, &q[i]));
    PetscCall(Norm(4, q, &nrm));
  }
  w    = q[0] / nrm;
  x    = q[1] / nrm;
  y    = q[2] / nrm;
  z    = q[3] / nrm;
  R[0] = 1 - 2 * (y * y + z * z);
  R[1] = 2 * (x * y - w * z);
  R[2] = 2 * (x * z + w * y);
  R[3] = 2 * (x * y + w * z);
  R[4] = 1 - 2 * (x * x + z * z);
  R[5] = 2 * (y * z - w * x);
  R[6] = 2 * (x * z - w * y);
  R[7] = 2 * (y * z + w * x);
  R[8] = 1 - 2 * (x * x + y * y);
  PetscFunctionReturn(0);
}

/* Extreme eigenvalues of the symmetric part of the n x n row-major H (n <= 9) by
 * cyclic Jacobi rotations; the eigenvalues are checked against the invariants
 * trace and Frobenius norm. */
static PetscErrorCode SymEigMinMax(PetscInt n, const PetscReal *H, PetscReal *lmin, PetscReal *lmax)
{
  PetscReal A[81], tr = 0, fro = 0, sl = 0, sl2 = 0, scale;

  PetscFunctionBeginUser;
  PetscCheck(n <= 9, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "SymEigMinMax: n = %" PetscInt_FMT " > 9", n);
  for (PetscInt i = 0; i < n; i++)
    for (PetscInt j = 0; j < n; j++) A[n * i + j] = 0.5 * (H[n * i + j] + H[n * j + i]);
  for (PetscInt i = 0; i < n; i++) tr += A[n * i + i];
  for (PetscInt i = 0; i < n * n; i++) fro += A[i] * A[i];
  for (PetscInt sweep = 0; sweep < 100; sweep++) {
    PetscReal off = 0;
    for (PetscInt p = 0; p < n; p++)
      for (PetscInt q = p + 1; q < n; q++) off += A[n * p + q] * A[n * p + q];
    if (off <= 1e-34 * fro || off == 0) break;
    for (PetscInt p = 0; p < n; p++) {
      for (PetscInt q = p + 1; q < n; q++) {
        PetscReal apq = A[n * p + q], theta, t, c, s;
        if (apq == 0) continue;
        theta = (A[n * q + q] - A[n * p + p]) / (2 * apq);
        t     = (theta >= 0 ? 1.0 : -1.0) / (PetscAbsReal(theta) + PetscSqrtReal(theta * theta + 1));
        c     = 1 / PetscSqrtReal(t * t + 1);
        s     = t * c;
        for (PetscInt r = 0; r < n; r++) { /* columns p, q */
          PetscReal arp = A[n * r + p], arq = A[n * r + q];
          A[n * r + p] = c * arp - s * arq;
          A[n * r + q] = s * arp + c * arq;
        }
        for (PetscInt r = 0; r < n; r++) { /* rows p, q */
          PetscReal apr = A[n * p + r], aqr = A[n * q + r];
          A[n * p + r] = c * apr - s * aqr;
          A[n * q + r] = s * apr + c * aqr;
        }
      }
    }
  }
  *lmin = PETSC_MAX_REAL;
  *lmax = PETSC_MIN_REAL;
  for (PetscInt i = 0; i < n; i++) {
    PetscReal l = A[n * i + i];
    *lmin       = PetscMin(*lmin, l);
    *lmax       = PetscMax(*lmax, l);
    sl += l;
    sl2 += l * l;
  }
  scale = PetscSqrtReal(fro);
  PetscCheck(PetscAbsReal(sl - tr) <= 1e-12 * scale + 1e-300 && PetscAbsReal(sl2 - fro) <= 1e-12 * fro + 1e-300, PETSC_COMM_SELF, PETSC_ERR_PLIB, "test's Jacobi eigen-solver did not converge (trace %g vs %g, |A|_F^2 %g vs %g)", (double) sl,
             (double) tr, (double) sl2, (double) fro);
  PetscFunctionReturn(0);
}

/* ---------------------------------------------------------------- elements */

static PetscErrorCode SetStretch(Elem *el, const PetscReal xa[3], const PetscReal u[3], PetscReal len, PetscReal L, PetscReal k)
{
  PetscFunctionBeginUser;
  PetscCall(PetscMemzero(el, sizeof(*el)));
  el->kind = ELEM_STRETCH;
  el->n    = 6;
  for (PetscInt i = 0; i < 3; i++) {
    el->x[i]     = xa[i];
    el->x[3 + i] = xa[i] + len * u[i];
  }
  el->k          = k;
  el->L          = L;
  el->ell        = len;
  el->escale     = k * L * L;
  el->compressed = (PetscBool) (len < L);
  PetscCall(PetscSNPrintf(el->label, sizeof(el->label), "stretch l/L = %.4f (%s)", (double) (len / L), len < L ? "compressed" : "extended"));
  PetscFunctionReturn(0);
}

/* angle element with vertex xc, e1 = l1 a, e2 = l2 (cos(th) a + sin(th) nrm), a and nrm orthonormal */
static PetscErrorCode SetAngle(Elem *el, ElemKind kind, const PetscReal xc[3], const PetscReal a[3], const PetscReal nrm[3], PetscReal l1, PetscReal l2, PetscReal th, PetscReal kappa)
{
  PetscFunctionBeginUser;
  PetscCall(PetscMemzero(el, sizeof(*el)));
  el->kind = kind;
  el->n    = 9;
  for (PetscInt i = 0; i < 3; i++) {
    el->x[i]     = xc[i] + l1 * a[i];
    el->x[3 + i] = xc[i] + l2 * (PetscCosReal(th) * a[i] + PetscSinReal(th) * nrm[i]);
    el->x[6 + i] = xc[i];
  }
  el->kappa  = kappa;
  el->ell    = PetscMin(l1, l2);
  el->escale = kind == ELEM_SHEAR ? kappa * l1 * l2 : kappa;
  PetscCall(PetscSNPrintf(el->label, sizeof(el->label), "%s theta = %.4f (pi - theta = %.4f), |e1| = %.3f, |e2| = %.3f", ElemKindNames[kind], (double) th, (double) (PETSC_PI - th), (double) l1, (double) l2));
  PetscFunctionReturn(0);
}

static PetscErrorCode RandomStretch(PetscRandom rnd, PetscReal fmin, PetscReal fmax, Elem *el)
{
  PetscReal xa[3], u[3], L = 1, f = 1, k = 1;

  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -1, 1, &xa[i]));
  PetscCall(RandomUnit(rnd, u));
  PetscCall(Uniform(rnd, 0.5, 2, &L));
  PetscCall(Uniform(rnd, fmin, fmax, &f));
  PetscCall(Uniform(rnd, 0.5, 5, &k));
  PetscCall(SetStretch(el, xa, u, f * L, L, k));
  PetscFunctionReturn(0);
}

static PetscErrorCode RandomAngle(PetscRandom rnd, ElemKind kind, PetscReal thmin, PetscReal thmax, Elem *el)
{
  PetscReal xc[3], a[3], nrm[3], l1 = 1, l2 = 1, th = 1, kappa = 1;

  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -1, 1, &xc[i]));
  PetscCall(RandomUnit(rnd, a));
  PetscCall(RandomUnitOrthogonal(rnd, a, nrm));
  PetscCall(Uniform(rnd, 0.5, 2, &l1));
  PetscCall(Uniform(rnd, 0.5, 2, &l2));
  PetscCall(Uniform(rnd, thmin, thmax, &th));
  PetscCall(Uniform(rnd, 0.5, 3, &kappa));
  PetscCall(SetAngle(el, kind, xc, a, nrm, l1, l2, th, kappa));
  PetscFunctionReturn(0);
}

/* Random configurations: stretched and compressed edges; shear corners away from
 * 0 and pi (acute, near right, obtuse); bending triples nearly flat (theta close
 * to, but not at, pi), moderately and strongly bent. */
static PetscErrorCode MakeConfigs(PetscRandom rnd, ElemKind kind, Elem el[], PetscInt *n)
{
  PetscFunctionBeginUser;
  *n = 0;
  switch (kind) {
  case ELEM_STRETCH:
    for (PetscInt i = 0; i < 3; i++) PetscCall(RandomStretch(rnd, 0.6, 0.95, &el[(*n)++]));
    PetscCall(RandomStretch(rnd, 0.3, 0.5, &el[(*n)++]));
    for (PetscInt i = 0; i < 3; i++) PetscCall(RandomStretch(rnd, 1.05, 1.6, &el[(*n)++]));
    PetscCall(RandomStretch(rnd, 2.0, 3.0, &el[(*n)++]));
    break;
  case ELEM_SHEAR:
    for (PetscInt i = 0; i < 2; i++) PetscCall(RandomAngle(rnd, kind, 0.35, 1.2, &el[(*n)++]));
    for (PetscInt i = 0; i < 2; i++) PetscCall(RandomAngle(rnd, kind, 1.45, 1.7, &el[(*n)++]));
    for (PetscInt i = 0; i < 2; i++) PetscCall(RandomAngle(rnd, kind, 1.9, 2.8, &el[(*n)++]));
    break;
  case ELEM_BEND:
    for (PetscInt i = 0; i < 3; i++) PetscCall(RandomAngle(rnd, kind, PETSC_PI - 0.15, PETSC_PI - 0.03, &el[(*n)++]));
    for (PetscInt i = 0; i < 2; i++) PetscCall(RandomAngle(rnd, kind, 1.6, 2.6, &el[(*n)++]));
    for (PetscInt i = 0; i < 3; i++) PetscCall(RandomAngle(rnd, kind, 0.4, 1.4, &el[(*n)++]));
    /* with a law of curvature (KernelBendLaw, L = 1): rising to 2.2 at k = 1.3,
     * held beyond; the turning angles put k = 2 sin(beta/2) well inside the first
     * segment (0.03-0.15, 0.5-1.0) or beyond the table (1.9-2.6), away from the
     * kinks, where the Taylor tests see the smooth law */
    for (PetscInt i = 0; i < 4; i++) {
      const PetscReal lo[] = {0.03, 0.5, 1.9, 1.9}, hi[] = {0.15, 1.0, 2.6, 2.6};
      Elem           *e = &el[(*n)++];
      PetscCall(RandomAngle(rnd, kind, PETSC_PI - hi[i], PETSC_PI - lo[i], e));
      e->law = (KernelBendLaw){.n = 2, .L = 1, .dk = 1.3, .b = {1, 2.2}};
      PetscCall(PetscStrlcat(e->label, ", law b = 1 .. 2.2 at k = 1.3", sizeof e->label));
    }
    break;
  }
  PetscFunctionReturn(0);
}

/* ---------------------------------------------------------------- Taylor tests */

/* random direction with |d| = ell (the element's shortest edge) */
static PetscErrorCode RandomDirection(PetscRandom rnd, const Elem *el, PetscReal d[])
{
  PetscReal nrm = 0;

  PetscFunctionBeginUser;
  while (nrm < 0.1) {
    for (PetscInt i = 0; i < el->n; i++) PetscCall(Uniform(rnd, -1, 1, &d[i]));
    PetscCall(Norm(el->n, d, &nrm));
  }
  for (PetscInt i = 0; i < el->n; i++) d[i] *= el->ell / nrm;
  PetscFunctionReturn(0);
}

/* Best of four random directions by the size of the second difference of E
 * (second = FALSE) or of g (second = TRUE) at step EPS0: keeps the eps^2 term of
 * the Taylor remainder away from an accidental zero. Uses only E resp. g, never
 * the derivative under test. */
static PetscErrorCode PickDirection(PetscRandom rnd, const Elem *el, PetscBool second, PetscReal d[])
{
  PetscReal best = -1, dt[9], xp[9], xm[9], E0, Ep, Em, g0[9], gp[9], gm[9], q;

  PetscFunctionBeginUser;
  PetscCall(ElemEval(el, el->x, &E0, g0, NULL, PETSC_FALSE));
  for (PetscInt t = 0; t < 4; t++) {
    PetscCall(RandomDirection(rnd, el, dt));
    for (PetscInt i = 0; i < el->n; i++) {
      xp[i] = el->x[i] + EPS0 * dt[i];
      xm[i] = el->x[i] - EPS0 * dt[i];
    }
    PetscCall(ElemEval(el, xp, &Ep, gp, NULL, PETSC_FALSE));
    PetscCall(ElemEval(el, xm, &Em, gm, NULL, PETSC_FALSE));
    if (!second)
      q = PetscAbsReal(Ep - 2 * E0 + Em);
    else {
      for (PetscInt i = 0; i < el->n; i++) gp[i] = gp[i] - 2 * g0[i] + gm[i];
      PetscCall(Norm(el->n, gp, &q));
    }
    if (q > best) {
      best = q;
      for (PetscInt i = 0; i < el->n; i++) d[i] = dt[i];
    }
  }
  PetscFunctionReturn(0);
}

typedef struct {
  PetscReal omin, omax;
  PetscInt  nclean, ngood, ncfg;
} OrderStats;

/* Orders log2(r(eps)/r(eps/2)) over the halvings before round-off (r above its
 * noise estimate); most of them (all but at most one, and at least 3) must lie
 * in [1.8, 2.2]. */
static PetscErrorCode CheckOrders(const Elem *el, const char *what, const PetscReal r[], const PetscReal noise[], OrderStats *st)
{
  PetscInt  nclean = 0, ngood = 0;
  PetscReal ord[NEPS - 1];
  char      buf[512];
  size_t    len;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < NEPS - 1; k++) {
    if (r[k] <= noise[k] || r[k + 1] <= noise[k + 1]) break;
    ord[nclean] = PetscLog2Real(r[k] / r[k + 1]);
    if (ord[nclean] >= 1.8 && ord[nclean] <= 2.2) ngood++;
    nclean++;
  }
  PetscCall(PetscSNPrintf(buf, sizeof(buf), "orders"));
  for (PetscInt k = 0; k < nclean; k++) {
    PetscCall(PetscStrlen(buf, &len));
    PetscCall(PetscSNPrintf(buf + len, sizeof(buf) - len, " %.3f", (double) ord[k]));
  }
  PetscCall(PetscStrlen(buf, &len));
  PetscCall(PetscSNPrintf(buf + len, sizeof(buf) - len, "; r(eps) for eps = 1e-2 * 2^-k:"));
  for (PetscInt k = 0; k < NEPS; k++) {
    PetscCall(PetscStrlen(buf, &len));
    PetscCall(PetscSNPrintf(buf + len, sizeof(buf) - len, " %.3e", (double) r[k]));
  }
  PetscCall(PetscStrlen(buf, &len));
  PetscCall(PetscSNPrintf(buf + len, sizeof(buf) - len, " (round-off level %.1e)", (double) noise[NEPS - 1]));
  PetscCheck(nclean >= 3 && ngood >= nclean - 1, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED %s Taylor test on [%s]: %" PetscInt_FMT " of %" PetscInt_FMT " clean halvings have order in [1.8, 2.2]; %s", what, el->label, ngood, nclean, buf);
  for (PetscInt k = 0; k < nclean; k++) {
    st->omin = PetscMin(st->omin, ord[k]);
    st->omax = PetscMax(st->omax, ord[k]);
  }
  st->nclean += nclean;
  st->ngood += ngood;
  st->ncfg++;
  PetscFunctionReturn(0);
}

/* |E(x + eps d) - E(x) - eps g.d| = O(eps^2) */
static PetscErrorCode TaylorGradient(PetscRandom rnd, const Elem *el, OrderStats *st)
{
  PetscReal d[9], x[9], g[9], E0, E1, gd = 0, r[NEPS], noise[NEPS], eps = EPS0;
  char      what[64];

  PetscFunctionBeginUser;
  PetscCall(PickDirection(rnd, el, PETSC_FALSE, d));
  PetscCall(ElemEval(el, el->x, &E0, g, NULL, PETSC_FALSE));
  for (PetscInt i = 0; i < el->n; i++) gd += g[i] * d[i];
  for (PetscInt k = 0; k < NEPS; k++, eps *= 0.5) {
    for (PetscInt i = 0; i < el->n; i++) x[i] = el->x[i] + eps * d[i];
    PetscCall(ElemEval(el, x, &E1, NULL, NULL, PETSC_FALSE));
    r[k]     = PetscAbsReal(E1 - E0 - eps * gd);
    noise[k] = 1e3 * PETSC_MACHINE_EPSILON * (PetscAbsReal(E0) + PetscAbsReal(E1) + eps * PetscAbsReal(gd) + el->escale);
  }
  PetscCall(PetscSNPrintf(what, sizeof(what), "%s gradient", ElemKindNames[el->kind]));
  PetscCall(CheckOrders(el, what, r, noise, st));
  PetscFunctionReturn(0);
}

/* |g(x + eps d) - g(x) - eps H d| = O(eps^2), H the exact Hessian */
static PetscErrorCode TaylorHessian(PetscRandom rnd, const Elem *el, OrderStats *st)
{
  PetscReal d[9], x[9], g0[9], g1[9], H[81], Hd[9], res[9], E, r[NEPS], noise[NEPS], eps = EPS0, ng0, ng1, nHd;
  PetscInt  n = el->n;
  char      what[64];

  PetscFunctionBeginUser;
  PetscCall(PickDirection(rnd, el, PETSC_TRUE, d));
  PetscCall(ElemEval(el, el->x, &E, g0, H, PETSC_FALSE));
  for (PetscInt i = 0; i < n; i++) {
    Hd[i] = 0;
    for (PetscInt j = 0; j < n; j++) Hd[i] += H[n * i + j] * d[j];
  }
  PetscCall(Norm(n, g0, &ng0));
  PetscCall(Norm(n, Hd, &nHd));
  for (PetscInt k = 0; k < NEPS; k++, eps *= 0.5) {
    for (PetscInt i = 0; i < n; i++) x[i] = el->x[i] + eps * d[i];
    PetscCall(ElemEval(el, x, &E, g1, NULL, PETSC_FALSE));
    for (PetscInt i = 0; i < n; i++) res[i] = g1[i] - g0[i] - eps * Hd[i];
    PetscCall(Norm(n, res, &r[k]));
    PetscCall(Norm(n, g1, &ng1));
    noise[k] = 1e3 * PETSC_MACHINE_EPSILON * (ng0 + ng1 + eps * nHd + el->escale / el->ell);
  }
  PetscCall(PetscSNPrintf(what, sizeof(what), "%s exact Hessian", ElemKindNames[el->kind]));
  PetscCall(CheckOrders(el, what, r, noise, st));
  PetscFunctionReturn(0);
}

/* ---------------------------------------------------------------- Hessian structure */

static PetscErrorCode Asymmetry(PetscInt n, const PetscReal *H, PetscReal *rel)
{
  PetscReal m, a = 0;

  PetscFunctionBeginUser;
  PetscCall(MaxAbs(n * n, H, &m));
  for (PetscInt i = 0; i < n; i++)
    for (PetscInt j = i + 1; j < n; j++) a = PetscMax(a, PetscAbsReal(H[n * i + j] - H[n * j + i]));
  *rel = m > 0 ? a / m : a;
  PetscFunctionReturn(0);
}

static PetscErrorCode CheckSymmetry(const Elem *el, PetscReal *worst)
{
  PetscReal H[81], E, rel;

  PetscFunctionBeginUser;
  for (PetscInt p = 0; p < 2; p++) {
    PetscBool project = p ? PETSC_TRUE : PETSC_FALSE;
    PetscCall(ElemEval(el, el->x, &E, NULL, H, project));
    PetscCall(Asymmetry(el->n, H, &rel));
    PetscCheck(rel <= 1e-12, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED symmetry of the %s Hessian on [%s]: max|H - H^T| / max|H| = %g > 1e-12", project ? "projected" : "exact", el->label, (double) rel);
    *worst = PetscMax(*worst, rel);
  }
  PetscFunctionReturn(0);
}

/* projected Hessian PSD; returns lambda_min / max|H| of projected and exact Hessians */
static PetscErrorCode CheckPSD(const Elem *el, PetscReal *proj_rel, PetscReal *exact_rel)
{
  PetscReal H[81], E, m, lmin, lmax;

  PetscFunctionBeginUser;
  PetscCall(ElemEval(el, el->x, &E, NULL, H, PETSC_TRUE));
  PetscCall(MaxAbs(el->n * el->n, H, &m));
  PetscCall(SymEigMinMax(el->n, H, &lmin, &lmax));
  PetscCheck(m > 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: projected %s Hessian is identically zero on [%s]", ElemKindNames[el->kind], el->label);
  PetscCheck(lmin >= -1e-10 * m, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: projected %s Hessian is not PSD on [%s]: lambda_min = %g, max|H| = %g, ratio %g < -1e-10", ElemKindNames[el->kind], el->label, (double) lmin, (double) m, (double) (lmin / m));
  *proj_rel = lmin / m;
  PetscCall(ElemEval(el, el->x, &E, NULL, H, PETSC_FALSE));
  PetscCall(MaxAbs(el->n * el->n, H, &m));
  PetscCall(SymEigMinMax(el->n, H, &lmin, &lmax));
  *exact_rel = m > 0 ? lmin / m : 0;
  PetscFunctionReturn(0);
}

/* ---------------------------------------------------------------- invariance */

typedef struct {
  PetscReal energy, energyraw, grot, gsum, torque;
} InvStats;

static PetscErrorCode CheckInvariance(PetscRandom rnd, const Elem *el, InvStats *st)
{
  PetscReal R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, t[3], y[9], E0, E1, g0[9], g1[9], Rg[9], sum[3], tq[3], c[3], ng, scale, tscale, err, nrm, nx, ngi;
  PetscInt  np   = el->n / 3;

  PetscFunctionBeginUser;
  PetscCall(RandomRotation(rnd, R));
  for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -1, 1, &t[i]));
  for (PetscInt p = 0; p < np; p++)
    for (PetscInt i = 0; i < 3; i++) y[3 * p + i] = R[3 * i] * el->x[3 * p] + R[3 * i + 1] * el->x[3 * p + 1] + R[3 * i + 2] * el->x[3 * p + 2] + t[i];
  PetscCall(ElemEval(el, el->x, &E0, g0, NULL, PETSC_FALSE));
  PetscCall(ElemEval(el, y, &E1, g1, NULL, PETSC_FALSE));

  /* energy: 1e-12 relative to |E|, with |E| floored at 1e-2 of the element's
   * energy scale: a nearly flat bend has E = kappa (1 + cos) ~ 1e-4 kappa, and the
   * cancellation in 1 + cos alone costs ~1e-16 kappa, i.e. ~1e-12 relative to E */
  err = PetscAbsReal(E1 - E0) / PetscMax(PetscAbsReal(E0), 1e-2 * el->escale);
  PetscCheck(err <= 1e-12, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED rigid-motion invariance of the %s energy on [%s]: E = %.17g, E(R x + t) = %.17g, relative change %g > 1e-12", ElemKindNames[el->kind], el->label, (double) E0, (double) E1,
             (double) err);
  st->energy    = PetscMax(st->energy, err);
  st->energyraw = PetscMax(st->energyraw, PetscAbsReal(E1 - E0) / PetscAbsReal(E0));

  /* gradient is covariant: g(R x + t) = R g(x) */
  PetscCall(Norm(el->n, g0, &ng));
  for (PetscInt p = 0; p < np; p++)
    for (PetscInt i = 0; i < 3; i++) Rg[3 * p + i] = g1[3 * p + i] - (R[3 * i] * g0[3 * p] + R[3 * i + 1] * g0[3 * p + 1] + R[3 * i + 2] * g0[3 * p + 2]);
  PetscCall(Norm(el->n, Rg, &nrm));
  err = ng > 0 ? nrm / ng : nrm;
  PetscCheck(err <= 1e-10, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: %s gradient does not rotate with the element on [%s]: |g(Rx+t) - R g(x)| / |g| = %g > 1e-10", ElemKindNames[el->kind], el->label, (double) err);
  st->grot = PetscMax(st->grot, err);

  /* translation invariance: sum_i g_i = 0; rotation invariance: sum_i x_i x g_i = 0 (at both placements) */
  for (PetscInt pass = 0; pass < 2; pass++) {
    const PetscReal *x = pass ? y : el->x, *g = pass ? g1 : g0;
    scale  = 0;
    tscale = 0;
    for (PetscInt i = 0; i < 3; i++) sum[i] = tq[i] = 0;
    for (PetscInt p = 0; p < np; p++) {
      PetscCall(Cross(&x[3 * p], &g[3 * p], c));
      PetscCall(Norm(3, &x[3 * p], &nx));
      PetscCall(Norm(3, &g[3 * p], &ngi));
      for (PetscInt i = 0; i < 3; i++) {
        sum[i] += g[3 * p + i];
        tq[i] += c[i];
      }
      scale += ngi;
      tscale += nx * ngi;
    }
    PetscCall(Norm(3, sum, &nrm));
    err = scale > 0 ? nrm / scale : nrm;
    PetscCheck(err <= 1e-10, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED translation invariance of the %s gradient on [%s]: |sum_i g_i| / sum_i |g_i| = %g > 1e-10", ElemKindNames[el->kind], el->label, (double) err);
    st->gsum = PetscMax(st->gsum, err);
    PetscCall(Norm(3, tq, &nrm));
    err = tscale > 0 ? nrm / tscale : nrm;
    PetscCheck(err <= 1e-10, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED rotation invariance of the %s gradient on [%s]: |sum_i x_i x g_i| / sum_i |x_i||g_i| = %g > 1e-10", ElemKindNames[el->kind], el->label, (double) err);
    st->torque = PetscMax(st->torque, err);
  }
  PetscFunctionReturn(0);
}

/* ---------------------------------------------------------------- check groups */

static PetscErrorCode GroupsForKind(PetscRandom rnd, ElemKind kind, PetscReal exact_rel[], Elem el[], PetscInt *ncfg)
{
  OrderStats  st;
  InvStats    inv  = {0, 0, 0, 0, 0};
  PetscReal   asym = 0, pmin = PETSC_MAX_REAL, emin = PETSC_MAX_REAL, prel = 0;
  const char *name = ElemKindNames[kind];
  PetscInt    n;

  PetscFunctionBeginUser;
  PetscCall(MakeConfigs(rnd, kind, el, &n));
  *ncfg = n;

  st.omin = PETSC_MAX_REAL, st.omax = PETSC_MIN_REAL, st.nclean = st.ngood = st.ncfg = 0;
  for (PetscInt c = 0; c < n; c++) PetscCall(TaylorGradient(rnd, &el[c], &st));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS %-7s gradient Taylor test: %" PetscInt_FMT " configs, %" PetscInt_FMT "/%" PetscInt_FMT " halvings with order in [1.8, 2.2], observed orders %.3f .. %.3f\n", name, st.ncfg, st.ngood, st.nclean,
                        (double) st.omin, (double) st.omax));
  npassed++;

  st.omin = PETSC_MAX_REAL, st.omax = PETSC_MIN_REAL, st.nclean = st.ngood = st.ncfg = 0;
  for (PetscInt c = 0; c < n; c++) PetscCall(TaylorHessian(rnd, &el[c], &st));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS %-7s exact Hessian Taylor test: %" PetscInt_FMT " configs, %" PetscInt_FMT "/%" PetscInt_FMT " halvings with order in [1.8, 2.2], observed orders %.3f .. %.3f\n", name, st.ncfg, st.ngood, st.nclean,
                        (double) st.omin, (double) st.omax));
  npassed++;

  for (PetscInt c = 0; c < n; c++) PetscCall(CheckSymmetry(&el[c], &asym));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS %-7s Hessian symmetry (exact and projected): max |H - H^T| / max|H| = %.2e (tol 1e-12)\n", name, (double) asym));
  npassed++;

  for (PetscInt c = 0; c < n; c++) {
    PetscCall(CheckPSD(&el[c], &prel, &exact_rel[c]));
    pmin = PetscMin(pmin, prel);
    emin = PetscMin(emin, exact_rel[c]);
  }
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS %-7s projected Hessian PSD: min lambda_min / max|H| = %.2e (tol -1e-10); exact Hessian: min lambda_min / max|H| = %.3f\n", name, (double) pmin, (double) emin));
  npassed++;

  for (PetscInt c = 0; c < n; c++) PetscCall(CheckInvariance(rnd, &el[c], &inv));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS %-7s rigid-motion invariance: max rel. energy change %.2e (%.2e vs |E| alone), |g(Rx+t) - Rg| %.2e, |sum g| %.2e, |sum x cross g| %.2e\n", name, (double) inv.energy, (double) inv.energyraw,
                        (double) inv.grot, (double) inv.gsum, (double) inv.torque));
  npassed++;
  PetscFunctionReturn(0);
}

/* The projection matters: the exact Hessian is clearly indefinite for every
 * compressed edge and for at least one shear or bend configuration. */
static PetscErrorCode GroupIndefinite(const Elem st[], const PetscReal st_rel[], PetscInt nst, const PetscReal sh_rel[], PetscInt nsh, const PetscReal be_rel[], PetscInt nbe)
{
  PetscInt  ncomp = 0, nsh_neg = 0, nbe_neg = 0;
  PetscReal worst = PETSC_MIN_REAL, sh_min = PETSC_MAX_REAL, be_min = PETSC_MAX_REAL;

  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < nst; c++) {
    if (!st[c].compressed) continue;
    ncomp++;
    PetscCheck(st_rel[c] < -1e-2, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: exact stretch Hessian of a compressed edge [%s] has no clearly negative eigenvalue: lambda_min / max|H| = %g (expected 2 (1 - L/l) < 0)", st[c].label, (double) st_rel[c]);
    worst = PetscMax(worst, st_rel[c]);
  }
  PetscCheck(ncomp > 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "test setup: no compressed stretch configuration");
  for (PetscInt c = 0; c < nsh; c++) {
    if (sh_rel[c] < -1e-2) nsh_neg++;
    sh_min = PetscMin(sh_min, sh_rel[c]);
  }
  for (PetscInt c = 0; c < nbe; c++) {
    if (be_rel[c] < -1e-2) nbe_neg++;
    be_min = PetscMin(be_min, be_rel[c]);
  }
  PetscCheck(nsh_neg + nbe_neg > 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: no shear or bend configuration has an exact Hessian with a clearly negative eigenvalue (min lambda_min / max|H|: shear %g, bend %g)", (double) sh_min, (double) be_min);
  PetscCall(PetscPrintf(PETSC_COMM_WORLD,
                        "PASS exact Hessians are indefinite (projection matters): %" PetscInt_FMT "/%" PetscInt_FMT " compressed edges (lambda_min / max|H| <= %.3f), shear %" PetscInt_FMT "/%" PetscInt_FMT " (min %.3f), bend %" PetscInt_FMT
                        "/%" PetscInt_FMT " (min %.3f)\n",
                        ncomp, ncomp, (double) worst, nsh_neg, nsh, (double) sh_min, nbe_neg, nbe, (double) be_min));
  npassed++;
  PetscFunctionReturn(0);
}

/* For an extended edge (l > L) the exact stretch Hessian is PSD and the projection leaves it alone. */
static PetscErrorCode GroupProjectedEqualsExact(const Elem st[], PetscInt nst)
{
  PetscReal He[36], Hp[36], E, m, diff, worst = 0;
  PetscInt  next = 0;

  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < nst; c++) {
    if (st[c].compressed) continue;
    next++;
    PetscCall(ElemEval(&st[c], st[c].x, &E, NULL, He, PETSC_FALSE));
    PetscCall(ElemEval(&st[c], st[c].x, &E, NULL, Hp, PETSC_TRUE));
    PetscCall(MaxAbs(36, He, &m));
    diff = 0;
    for (PetscInt i = 0; i < 36; i++) diff = PetscMax(diff, PetscAbsReal(He[i] - Hp[i]));
    PetscCheck(diff <= 1e-14 * m, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: projected and exact stretch Hessians differ on the extended edge [%s]: max|Hp - H| / max|H| = %g", st[c].label, (double) (diff / m));
    worst = PetscMax(worst, diff / m);
  }
  PetscCheck(next > 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "test setup: no extended stretch configuration");
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS stretch projected == exact Hessian on %" PetscInt_FMT " extended edges (l > L): max|Hp - H| / max|H| = %.2e\n", next, (double) worst));
  npassed++;
  PetscFunctionReturn(0);
}

/* The force loop's gradient-only kernels give the general kernels' gradient to
 * round-off on every configuration (they are the same formula, rearranged). */
static PetscErrorCode GroupGradientKernels(const Elem *sets[], const PetscInt nset[])
{
  PetscReal worst = 0;
  PetscInt  count = 0;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < 3; k++) {
    for (PetscInt c = 0; c < nset[k]; c++) {
      const Elem *el = &sets[k][c];
      PetscReal   g[9], gf[9], E, rel;
      PetscCall(ElemEval(el, el->x, &E, g, NULL, PETSC_FALSE));
      if (el->kind == ELEM_STRETCH)
        KernelStretchGradient(el->x, el->x + 3, el->k, el->L, gf);
      else
        KernelAngleGradient(el->kind == ELEM_BEND ? PETSC_TRUE : PETSC_FALSE, el->x, el->x + 3, el->x + 6, el->kappa, el->law.n ? &el->law : NULL, gf);
      PetscCall(MaxRelDiff(el->n, gf, g, &rel));
      PetscCheck(rel <= 1e-12, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: gradient-only %s kernel differs from the general kernel [%s]: max|g_fast - g| / max|g| = %g", ElemKindNames[el->kind], el->label, (double) rel);
      worst = PetscMax(worst, rel);
      count++;
    }
  }
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS gradient-only kernels == general kernels on %" PetscInt_FMT " configurations: max rel. difference %.2e (tol 1e-12)\n", count, (double) worst));
  npassed++;
  PetscFunctionReturn(0);
}

/* The force loop's shear cell (four corners sharing four edges) gives the sum of
 * its four corners' gradients, corner by corner as cloth.c lists them, to round-off:
 * on random sheared, stretched, bent and folded cells (angles 1 to 179 degrees). */
static PetscErrorCode GroupShearCell(PetscRandom rnd)
{
  PetscReal worst = 0;
  PetscInt  count = 0;

  PetscFunctionBeginUser;
  for (PetscInt t = 0; t < 2000; t++) {
    /* x0 at the origin, x1 along a, x2 at an angle th from a, x3 = x1 + x2 - x0 + noise */
    PetscReal x[12], a[3], n[3], b[3], l1 = 0, l2 = 0, th = 0, kappa = 0, lam = 0, w[8], g[12], gs[12] = {0}, gc[9], rel;
    PetscCall(RandomUnit(rnd, a));
    PetscCall(RandomUnitOrthogonal(rnd, a, n));
    PetscCall(Cross(n, a, b));
    PetscCall(Uniform(rnd, 0.5, 2.0, &l1));
    PetscCall(Uniform(rnd, 0.5, 2.0, &l2));
    PetscCall(Uniform(rnd, PETSC_PI / 180, PETSC_PI * 179 / 180, &th));
    PetscCall(Uniform(rnd, 0.1, 10, &kappa));
    for (PetscInt d = 0; d < 3; d++) {
      x[d]     = 0;
      x[3 + d] = l1 * a[d];
      x[6 + d] = l2 * (PetscCosReal(th) * a[d] + PetscSinReal(th) * b[d]);
    }
    for (PetscInt d = 0; d < 3; d++) {
      PetscCall(Uniform(rnd, -0.3, 0.3, &lam));
      x[9 + d] = x[3 + d] + x[6 + d] + lam * PetscMin(l1, l2);
    }
    {
      /* corners (a, b, vertex) as cloth.c builds them, particle numbers 0..3 */
      const PetscInt corner[4][3] = {{1, 2, 0}, {0, 3, 1}, {3, 0, 2}, {2, 1, 3}};
      for (PetscInt k = 0; k < 4; k++) {
        KernelAngleGradient(PETSC_FALSE, x + 3 * corner[k][0], x + 3 * corner[k][1], x + 3 * corner[k][2], kappa, NULL, gc);
        for (PetscInt q = 0; q < 3; q++)
          for (PetscInt d = 0; d < 3; d++) gs[3 * corner[k][q] + d] += gc[3 * q + d];
      }
    }
    KernelShearCellCoefficients(x, x + 3, x + 6, x + 9, kappa, w);
    KernelShearCellGradient(w, x, x + 3, x + 6, x + 9, g);
    PetscCall(MaxRelDiff(12, g, gs, &rel));
    PetscCheck(rel <= 1e-12, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: shear cell gradient differs from its four corners' (cell %" PetscInt_FMT ", angle %g deg): max|g_cell - g| / max|g| = %g", t, (double) (th * 180 / PETSC_PI), (double) rel);
    worst = PetscMax(worst, rel);
    count++;
  }
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS shear cell gradient == sum of its four corners on %" PetscInt_FMT " cells: max rel. difference %.2e (tol 1e-12)\n", count, (double) worst));
  npassed++;
  PetscFunctionReturn(0);
}

/* KernelIsPSD3 on A = R diag(l) R^T: "yes" for every l_min >= 1e-9 max|l| and for
 * rank-deficient PSD matrices (exact zeros blurred by round-off), "no" for every
 * l_min <= -1e-6 max|l|; and the projection it spares is then the identity. */
static PetscErrorCode GroupPSDTest(PetscRandom rnd)
{
  PetscInt yes = 0, no = 0;

  PetscFunctionBeginUser;
  for (PetscInt t = 0; t < 3000; t++) {
    PetscReal R[9], l[3], A[9], P[9], scale, expo = 0, lmin, diff = 0;
    PetscCall(RandomRotation(rnd, R));
    PetscCall(Uniform(rnd, -6, 6, &expo));
    scale = PetscPowReal(10, expo);
    for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -1, 1, &l[i]));
    if (t % 3 == 0) l[0] = l[1] = 0, l[2] = 1; /* rank 1, PSD */
    lmin = PetscMin(l[0], PetscMin(l[1], l[2]));
    if (lmin > -1e-6 && lmin < 1e-9 && t % 3) continue; /* the undecided band */
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < 3; j++) A[3 * i + j] = scale * (R[3 * i] * l[0] * R[3 * j] + R[3 * i + 1] * l[1] * R[3 * j + 1] + R[3 * i + 2] * l[2] * R[3 * j + 2]);
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < i; j++) A[3 * i + j] = A[3 * j + i];
    if (lmin >= 0 || t % 3 == 0) {
      PetscCheck(KernelIsPSD3(A), PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: KernelIsPSD3 rejects a PSD matrix with eigenvalues %g %g %g (x %g)", (double) l[0], (double) l[1], (double) l[2], (double) scale);
      PetscCall(PetscArraycpy(P, A, 9));
      KernelProjectPSD3(P);
      for (PetscInt i = 0; i < 9; i++) diff = PetscMax(diff, PetscAbsReal(P[i] - A[i]));
      PetscCheck(diff <= 1e-12 * scale, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: the projection of a PSD matrix moved it by %g (x %g)", (double) (diff / scale), (double) scale);
      yes++;
    } else {
      PetscCheck(!KernelIsPSD3(A), PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: KernelIsPSD3 accepts a matrix with eigenvalues %g %g %g (x %g)", (double) l[0], (double) l[1], (double) l[2], (double) scale);
      no++;
    }
  }
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS PSD test of 3x3 blocks: %" PetscInt_FMT " PSD (incl. rank 1) accepted, %" PetscInt_FMT " with lambda_min <= -1e-6 max|lambda| refused\n", yes, no));
  npassed++;
  PetscFunctionReturn(0);
}

/* The closed-form projection agrees with the Jacobi one on random symmetric
 * matrices of every inertia, including near-double eigenvalues (where it declines
 * and Jacobi is used): max difference 1e-8 max|A_ij| (eigenvalues within about sqrt(eps) of a double one
 * at zero are resolved only that well; physically they are zero either way). */
static PetscErrorCode GroupClosedProjection(PetscRandom rnd)
{
  PetscInt  done = 0, declined = 0;
  PetscReal worst = 0;

  PetscFunctionBeginUser;
  for (PetscInt t = 0; t < 20000; t++) {
    PetscReal R[9], l[3], A[9], J[9], scale = 0, u = 0;
    PetscCall(RandomRotation(rnd, R));
    for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -1, 1, &l[i]));
    PetscCall(Uniform(rnd, 0, 1, &u));
    if (u < 0.2) l[1] = l[0] + (u - 0.1) * 1e-6;             /* near-double eigenvalue */
    if (u < 0.05) l[0] = -0.5 * (l[1] = (u - 0.025) * 1e-5); /* ... straddling zero: declined */
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < 3; j++) A[3 * i + j] = R[3 * i] * l[0] * R[3 * j] + R[3 * i + 1] * l[1] * R[3 * j + 1] + R[3 * i + 2] * l[2] * R[3 * j + 2];
    for (PetscInt i = 0; i < 3; i++)
      for (PetscInt j = 0; j < i; j++) A[3 * i + j] = A[3 * j + i];
    for (PetscInt i = 0; i < 9; i++) scale = PetscMax(scale, PetscAbsReal(A[i]));
    PetscCall(PetscArraycpy(J, A, 9));
    KernelProjectPSD3(J);
    if (!KernelProjectPSD3Closed(A)) {
      declined++;
      continue;
    }
    for (PetscInt i = 0; i < 9; i++) worst = PetscMax(worst, PetscAbsReal(A[i] - J[i]) / scale);
    done++;
  }
  PetscCheck(worst <= 1e-8, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: closed-form and Jacobi PSD projections differ by %g max|A_ij|", (double) worst);
  PetscCheck(declined > 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "test setup: no near-double case reached the fallback");
  PetscCheck(done > 15000, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: the closed-form projection declined %" PetscInt_FMT " of 20000 matrices", declined);
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS closed-form PSD projection == Jacobi on %" PetscInt_FMT " random 3x3 (max diff %.1e max|A_ij|); declined %" PetscInt_FMT " near-double cases to Jacobi\n", done, (double) worst, declined));
  npassed++;
  PetscFunctionReturn(0);
}

/* The lanes give each lane the bits it gets alone: KernelProjectPSD3Lanes on batches
 * of 1 to 8 random matrices (PSD ones, near-double eigenvalues that decline, A = q I,
 * the zero matrix) against each matrix on one lane, to the bit, decline flags too;
 * and the angle Hessian's lanes (partials, projections, products) on batches of
 * random shear corners and bending triples against KernelAngle's H, one element at
 * a time, to the bit. Were a lane's result to depend on its neighbours (a shared
 * iteration count, a vector reduction), the assembled matrix would depend on how
 * elements fall into batches. */
static PetscErrorCode GroupLanes(PetscRandom rnd)
{
  PetscInt checked = 0, declined = 0, angles = 0;

  PetscFunctionBeginUser;
  for (PetscInt t = 0; t < 2000; t++) {
    PetscReal A[6][KERNEL_LANES] = {{0}}, B[6][KERNEL_LANES], u = 1;
    PetscBool dec[KERNEL_LANES], dec1[KERNEL_LANES];
    PetscInt  n;
    PetscCall(Uniform(rnd, 1, KERNEL_LANES + 1, &u));
    n = PetscMin((PetscInt) u, KERNEL_LANES);
    for (PetscInt k = 0; k < n; k++) {
      PetscReal R[9], l[3], M[9], kind = 1;
      PetscCall(RandomRotation(rnd, R));
      for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -1, 1, &l[i]));
      PetscCall(Uniform(rnd, 0, 1, &kind));
      if (kind < 0.2)
        l[1] = l[0] + (kind - 0.1) * 1e-6; /* near-double: may decline */
      else if (kind < 0.3)
        l[0] = PetscAbsReal(l[0]), l[1] = PetscAbsReal(l[1]), l[2] = PetscAbsReal(l[2]); /* PSD */
      else if (kind < 0.35)
        l[1] = l[2] = l[0]; /* A = q I (up to round-off) */
      else if (kind < 0.37)
        l[0] = l[1] = l[2] = 0; /* zero */
      for (PetscInt i = 0; i < 3; i++)
        for (PetscInt j = 0; j < 3; j++) M[3 * i + j] = R[3 * i] * l[0] * R[3 * j] + R[3 * i + 1] * l[1] * R[3 * j + 1] + R[3 * i + 2] * l[2] * R[3 * j + 2];
      A[0][k] = M[0], A[1][k] = M[1], A[2][k] = M[2], A[3][k] = M[4], A[4][k] = M[5], A[5][k] = M[8];
    }
    PetscCall(PetscArraycpy(&B[0][0], &A[0][0], 6 * KERNEL_LANES));
    KernelProjectPSD3Lanes(n, PETSC_TRUE, A, dec);
    for (PetscInt k = 0; k < n; k++) {
      PetscReal one[6][KERNEL_LANES];
      for (PetscInt i = 0; i < 6; i++) one[i][0] = B[i][k];
      KernelProjectPSD3Lanes(1, PETSC_TRUE, one, dec1);
      PetscCheck(dec1[0] == dec[k], PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: lane %" PetscInt_FMT " of %" PetscInt_FMT " declines %d in the batch, %d alone", k, n, (int) dec[k], (int) dec1[0]);
      for (PetscInt i = 0; i < 6; i++)
        PetscCheck(one[i][0] == A[i][k], PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: lane %" PetscInt_FMT " of %" PetscInt_FMT ", entry %" PetscInt_FMT ": %.17g in the batch, %.17g alone", k, n, i, (double) A[i][k], (double) one[i][0]);
      declined += dec[k];
      checked++;
    }
  }
  for (PetscInt t = 0; t < 200; t++) {
    const KernelAngleKind kind = t % 2 ? KERNEL_BEND : KERNEL_SHEAR;
    KernelAngleLanes      L;
    PetscReal             kappa[KERNEL_LANES], x[KERNEL_LANES][9], H6[36][KERNEL_LANES];
    for (PetscInt k = 0; k < KERNEL_LANES; k++) {
      for (PetscInt i = 0; i < 9; i++) PetscCall(Uniform(rnd, -1, 1, &x[k][i]));
      PetscCall(Uniform(rnd, 0.1, 2, &kappa[k]));
      for (PetscInt i = 0; i < 3; i++) L.e1[i][k] = x[k][i] - x[k][6 + i], L.e2[i][k] = x[k][3 + i] - x[k][6 + i];
    }
    KernelAngleLanesPartials(kind, KERNEL_LANES, kappa, NULL, &L);
    KernelAngleHessian6Lanes(KERNEL_LANES, &L, PETSC_TRUE, H6);
    for (PetscInt k = 0; k < KERNEL_LANES; k++) {
      PetscReal H[81];
      KernelAngle(kind, x[k], x[k] + 3, x[k] + 6, kappa[k], NULL, NULL, H, PETSC_TRUE);
      for (PetscInt i = 0; i < 3; i++)
        for (PetscInt j = 0; j < 3; j++) {
          PetscCheck(H[9 * i + j] == H6[6 * i + j][k] && H[9 * i + 3 + j] == H6[6 * i + 3 + j][k] && H[9 * (3 + i) + j] == H6[6 * (3 + i) + j][k] && H[9 * (3 + i) + 3 + j] == H6[6 * (3 + i) + 3 + j][k], PETSC_COMM_SELF, PETSC_ERR_PLIB,
                     "FAILED: %s lane %" PetscInt_FMT ": the lanes' H6 differs from KernelAngle's H at block entry (%" PetscInt_FMT ", %" PetscInt_FMT ")", kind == KERNEL_SHEAR ? "shear" : "bending", k, i, j);
        }
      angles++;
    }
  }
  PetscCheck(declined > 0 && declined < checked / 2, PETSC_COMM_SELF, PETSC_ERR_PLIB, "test setup: %" PetscInt_FMT " of %" PetscInt_FMT " lanes declined", declined, checked);
  PetscCall(PetscPrintf(PETSC_COMM_WORLD,
                        "PASS lanes: %" PetscInt_FMT " 3x3 projections in batches of 1-8 equal to the bit to each alone (%" PetscInt_FMT " declined alike); %" PetscInt_FMT " angle elements' H6 from the lanes equal to KernelAngle's H\n", checked,
                        declined, angles));
  npassed++;
  PetscFunctionReturn(0);
}

/* E = 0.25 and g = (-u, +u) for l = 1.5, L = 1, k = 2 */
static PetscErrorCode GroupKnownStretch(PetscRandom rnd)
{
  PetscReal xa[3] = {0, 0, 0}, u[3] = {1, 0, 0}, g[6], E, eE = 0, eg = 0;
  Elem      el;

  PetscFunctionBeginUser;
  for (PetscInt t = 0; t < 5; t++) {
    if (t > 0) {
      for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -1, 1, &xa[i]));
      PetscCall(RandomUnit(rnd, u));
    }
    PetscCall(SetStretch(&el, xa, u, 1.5, 1.0, 2.0));
    PetscCall(ElemEval(&el, el.x, &E, g, NULL, PETSC_FALSE));
    PetscCheck(PetscAbsReal(E - 0.25) <= 1e-12, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: stretch l = 1.5, L = 1, k = 2 gives E = %.17g, expected 0.25", (double) E);
    eE = PetscMax(eE, PetscAbsReal(E - 0.25));
    for (PetscInt i = 0; i < 3; i++) {
      PetscReal da = PetscAbsReal(g[i] + u[i]), db = PetscAbsReal(g[3 + i] - u[i]);
      PetscCheck(da <= 1e-12 && db <= 1e-12, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: stretch l = 1.5, L = 1, k = 2, edge direction (%g, %g, %g): gradient (%g, %g, %g | %g, %g, %g), expected (-u | +u)", (double) u[0], (double) u[1],
                 (double) u[2], (double) g[0], (double) g[1], (double) g[2], (double) g[3], (double) g[4], (double) g[5]);
      eg = PetscMax(eg, PetscMax(da, db));
    }
  }
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS stretch known values (l = 1.5, L = 1, k = 2, 5 placements): |E - 0.25| <= %.2e, |g - (-u, +u)| <= %.2e\n", (double) eE, (double) eg));
  npassed++;
  PetscFunctionReturn(0);
}

/* A random vertex, two orthonormal directions, edge lengths and coefficient. */
static PetscErrorCode RandomPlacement(PetscRandom rnd, PetscReal xc[3], PetscReal a[3], PetscReal nrm[3], PetscReal *l1, PetscReal *l2, PetscReal *kappa)
{
  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -1, 1, &xc[i]));
  PetscCall(RandomUnit(rnd, a));
  PetscCall(RandomUnitOrthogonal(rnd, a, nrm));
  PetscCall(Uniform(rnd, 0.5, 2, l1));
  PetscCall(Uniform(rnd, 0.5, 2, l2));
  PetscCall(Uniform(rnd, 0.5, 3, kappa));
  PetscFunctionReturn(0);
}

/* right angle: E = 0, g = 0; unit edges at pi/2 + 0.1: E = kappa * 0.01 */
static PetscErrorCode GroupKnownShear(PetscRandom rnd)
{
  PetscReal xc[3], a[3], nrm[3], l1 = 1, l2 = 1, kappa = 1, E, g[9], ng, e0 = 0, eg0 = 0, e1 = 0;
  Elem      el;

  PetscFunctionBeginUser;
  for (PetscInt t = 0; t < 5; t++) {
    PetscCall(RandomPlacement(rnd, xc, a, nrm, &l1, &l2, &kappa));
    /* right angle, e2 = l2 nrm exactly */
    PetscCall(SetAngle(&el, ELEM_SHEAR, xc, a, nrm, l1, l2, PETSC_PI / 2, kappa));
    for (PetscInt i = 0; i < 3; i++) el.x[3 + i] = xc[i] + l2 * nrm[i];
    PetscCall(ElemEval(&el, el.x, &E, g, NULL, PETSC_FALSE));
    PetscCall(Norm(9, g, &ng));
    PetscCheck(PetscAbsReal(E) <= 1e-14 * el.escale, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: shear corner at a right angle [%s] has E = %g, expected 0", el.label, (double) E);
    PetscCheck(ng <= 1e-12 * el.escale / el.ell, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: shear corner at a right angle [%s] has |g| = %g, expected 0", el.label, (double) ng);
    e0  = PetscMax(e0, PetscAbsReal(E) / el.escale);
    eg0 = PetscMax(eg0, ng * el.ell / el.escale);
    /* unit edges at pi/2 + 0.1 */
    PetscCall(SetAngle(&el, ELEM_SHEAR, xc, a, nrm, 1.0, 1.0, PETSC_PI / 2 + 0.1, kappa));
    PetscCall(ElemEval(&el, el.x, &E, NULL, NULL, PETSC_FALSE));
    PetscCheck(PetscAbsReal(E - kappa * 0.01) <= 1e-12 * kappa * 0.01, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: shear corner, unit edges at pi/2 + 0.1, kappa = %g: E = %.17g, expected kappa * 0.01 = %.17g", (double) kappa, (double) E,
               (double) (kappa * 0.01));
    e1 = PetscMax(e1, PetscAbsReal(E - kappa * 0.01) / (kappa * 0.01));
  }
  PetscCall(
    PetscPrintf(PETSC_COMM_WORLD, "PASS shear known values (5 placements): right angle |E| / (kappa|e1||e2|) <= %.2e, |g| ell / (kappa|e1||e2|) <= %.2e; pi/2 + 0.1 rel. error of E = 0.01 kappa <= %.2e\n", (double) e0, (double) eg0, (double) e1));
  npassed++;
  PetscFunctionReturn(0);
}

/* straight triple: E = 0 (and g = 0); angle theta: E = kappa (1 + cos theta) */
static PetscErrorCode GroupKnownBend(PetscRandom rnd)
{
  const PetscReal ths[] = {PETSC_PI / 6, PETSC_PI / 3, PETSC_PI / 2, 2 * PETSC_PI / 3, 5 * PETSC_PI / 6, 3.0, 3.1};
  PetscReal       xc[3], a[3], nrm[3], l1 = 1, l2 = 1, kappa = 1, E, g[9], ng, e0 = 0, eg0 = 0, eth = 0, Eref;
  Elem            el;

  PetscFunctionBeginUser;
  for (PetscInt t = 0; t < 5; t++) {
    PetscCall(RandomPlacement(rnd, xc, a, nrm, &l1, &l2, &kappa));
    /* straight, e2 = -l2 a exactly */
    PetscCall(SetAngle(&el, ELEM_BEND, xc, a, nrm, l1, l2, PETSC_PI, kappa));
    for (PetscInt i = 0; i < 3; i++) el.x[3 + i] = xc[i] - l2 * a[i];
    PetscCall(ElemEval(&el, el.x, &E, g, NULL, PETSC_FALSE));
    PetscCall(Norm(9, g, &ng));
    PetscCheck(PetscAbsReal(E) <= 1e-14 * kappa, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: straight bending triple [%s] has E = %g, expected 0", el.label, (double) E);
    PetscCheck(ng <= 1e-10 * kappa / el.ell, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: straight bending triple [%s] has |g| = %g, expected 0 (minimum)", el.label, (double) ng);
    e0  = PetscMax(e0, PetscAbsReal(E) / kappa);
    eg0 = PetscMax(eg0, ng * el.ell / kappa);
    for (size_t j = 0; j < sizeof(ths) / sizeof(ths[0]); j++) {
      PetscCall(SetAngle(&el, ELEM_BEND, xc, a, nrm, l1, l2, ths[j], kappa));
      PetscCall(ElemEval(&el, el.x, &E, NULL, NULL, PETSC_FALSE));
      Eref = kappa * (1 + PetscCosReal(ths[j]));
      PetscCheck(PetscAbsReal(E - Eref) <= 1e-12 * kappa, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: bending triple [%s]: E = %.17g, expected kappa (1 + cos theta) = %.17g", el.label, (double) E, (double) Eref);
      eth = PetscMax(eth, PetscAbsReal(E - Eref) / kappa);
    }
  }
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS bend known values (5 placements): straight |E| / kappa <= %.2e, |g| ell / kappa <= %.2e; 7 angles |E - kappa (1 + cos theta)| / kappa <= %.2e\n", (double) e0, (double) eg0, (double) eth));
  npassed++;
  PetscFunctionReturn(0);
}

/* A triple under a law of curvature: b(t) = 1 + sigma t up to k1 = dk, b(k1) beyond.
 * With k = 2 sin(beta/2) / L: E = kappa L^2 (k^2/2 + sigma k^3/3) inside, and
 * kappa L^2 (k1^2/2 + sigma k1^3/3 + b(k1) (k^2 - k1^2)/2) beyond; a straight
 * triple has E = 0 and g = 0. */
static PetscErrorCode GroupKnownBendLaw(PetscRandom rnd)
{
  const PetscReal betas[] = {1e-3, 0.05, 0.3, 0.7, 1.2, 2.0, 3.0};
  PetscReal       xc[3], a[3], nrm[3], l1 = 1, l2 = 1, kappa = 1, E, g[9], ng, worst = 0;
  Elem            el;

  PetscFunctionBeginUser;
  for (PetscInt t = 0; t < 5; t++) {
    const PetscReal L = 0.01 + 0.02 * t, k1 = 0.6 / L, sigma = (t % 2 ? -0.6 : 1.5) / k1; /* b(k1) = 0.4 or 2.5; the kink at beta ~ 0.6 */
    PetscCall(RandomPlacement(rnd, xc, a, nrm, &l1, &l2, &kappa));
    for (size_t j = 0; j < sizeof(betas) / sizeof(betas[0]); j++) {
      const PetscReal k = 2 * PetscSinReal(betas[j] / 2) / L, b1 = 1 + sigma * k1;
      PetscReal       Eref;
      PetscCall(SetAngle(&el, ELEM_BEND, xc, a, nrm, l1, l2, PETSC_PI - betas[j], kappa));
      el.law = (KernelBendLaw){.n = 2, .L = L, .dk = k1, .b = {1, b1}};
      PetscCall(ElemEval(&el, el.x, &E, NULL, NULL, PETSC_FALSE));
      Eref = k <= k1 ? kappa * L * L * (k * k / 2 + sigma * k * k * k / 3) : kappa * L * L * (k1 * k1 / 2 + sigma * k1 * k1 * k1 / 3 + b1 * (k * k - k1 * k1) / 2);
      /* 1 + cos carries round-off of 1e-16 (as for the linear triple): an absolute tolerance */
      PetscCheck(PetscAbsReal(E - Eref) <= 1e-12 * kappa * (1 + PetscAbsReal(b1)), PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: bending triple under a law [%s, L %g, sigma %g]: E = %.17g, expected %.17g", el.label, (double) L,
                 (double) sigma, (double) E, (double) Eref);
      worst = PetscMax(worst, PetscAbsReal(E - Eref) / (kappa * (1 + PetscAbsReal(b1))));
    }
    PetscCall(SetAngle(&el, ELEM_BEND, xc, a, nrm, l1, l2, PETSC_PI, kappa));
    for (PetscInt i = 0; i < 3; i++) el.x[3 + i] = xc[i] - l2 * a[i];
    el.law = (KernelBendLaw){.n = 2, .L = L, .dk = k1, .b = {1, 1 + sigma * k1}};
    PetscCall(ElemEval(&el, el.x, &E, g, NULL, PETSC_FALSE));
    PetscCall(Norm(9, g, &ng));
    PetscCheck(PetscAbsReal(E) <= 1e-14 * kappa && ng <= 1e-10 * kappa / el.ell, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: straight bending triple under a law [%s] has E = %g, |g| = %g, expected 0", el.label, (double) E, (double) ng);
  }
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "PASS bend law known values (5 placements, rising and falling tables, 7 angles inside and beyond): max |E - E_ref| / (kappa (1 + |b(k1)|)) %.2e (tol 1e-12); straight triple E = 0, g = 0\n", (double) worst));
  npassed++;
  PetscFunctionReturn(0);
}

/* ---------------------------------------------------------------- bending friction */

/* A thread triple (a, b; c) turned by beta about the crossing thread's direction
 * (a0 -> a1), then rotated by R and moved by o: x holds a, b, c, a0, a1 (15). With
 * the thread along t, the plane's normal n and the axis A = n x t: theta = beta.
 * tilt leans the axis out of the plane and skews it in it (a sheared, bent sheet). */
static void FrictionTriple(PetscReal beta, PetscReal l1, PetscReal l2, PetscReal la, const PetscReal tilt[2], const PetscReal R[9], const PetscReal o[3], PetscReal x[15])
{
  const PetscReal loc[5][3] = {{-l1, 0, 0}, {l2 * PetscCosReal(beta), 0, l2 * PetscSinReal(beta)}, {0, 0, 0}, {-la * tilt[1], -la, -la * tilt[0]}, {la * tilt[1], la, la * tilt[0]}};
  /* t = e_x, n = e_z, A = n x t = e_y: t1 x t2 = l1 l2 (0, -sin, 0)... so b bends
   * towards -z for theta > 0 */
  for (PetscInt p = 0; p < 5; p++) {
    PetscReal y[3] = {loc[p][0], loc[p][1], p == 1 ? -loc[p][2] : loc[p][2]};
    for (PetscInt i = 0; i < 3; i++) x[3 * p + i] = o[i] + R[3 * i] * y[0] + R[3 * i + 1] * y[1] + R[3 * i + 2] * y[2];
  }
}

/* KernelTurning and KernelFrictionEnergy: theta's known values and invariance, its
 * gradient's Taylor order, Huber's known values, the energy's gradient (stick and
 * slide) and Gauss-Newton Hessian (exact where the spring is unloaded) by Taylor
 * tests, the Hessian's symmetry and PSD, the return mapping. */
static PetscErrorCode GroupFriction(PetscRandom rnd)
{
  const PetscReal betas[] = {-2.8, -1.0, -0.2, -1e-3, 0, 1e-3, 0.3, 1.2, 3.0};
  PetscReal       worst = 0, omin = 10, omax = 0, R[9], o[3], x[15], y[15], g[15], d[15], H[225] = {0};
  PetscInt        ntaylor = 0;

  PetscFunctionBeginUser;
  for (PetscInt t = 0; t < 6; t++) {
    PetscReal l1 = 1, l2 = 1, la = 1, tilt[2] = {0, 0};
    PetscCall(Uniform(rnd, 0.5, 2, &l1));
    PetscCall(Uniform(rnd, 0.5, 2, &l2));
    PetscCall(Uniform(rnd, 0.5, 2, &la));
    PetscCall(RandomRotation(rnd, R));
    for (PetscInt i = 0; i < 3; i++) PetscCall(Uniform(rnd, -5, 5, &o[i]));
    for (size_t j = 0; j < sizeof(betas) / sizeof(betas[0]); j++) {
      PetscReal th;
      FrictionTriple(betas[j], l1, l2, la, tilt, R, o, x);
      th = KernelTurning(x, x + 3, x + 6, x + 9, x + 12, NULL);
      PetscCheck(PetscAbsReal(th - betas[j]) <= 1e-13, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: turning angle of a triple bent by %g (segments %g, %g) is %.17g", (double) betas[j], (double) l1, (double) l2, (double) th);
      worst = PetscMax(worst, PetscAbsReal(th - betas[j]));
      /* scaled about c: the same angle */
      for (PetscInt i = 0; i < 15; i++) y[i] = x[6 + i % 3] + 3.7 * (x[i] - x[6 + i % 3]);
      PetscCheck(PetscAbsReal(KernelTurning(y, y + 3, y + 6, y + 9, y + 12, NULL) - th) <= 1e-13, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED invariance: the turning angle changes when the triple is scaled");
    }
    /* Taylor: theta's gradient, then the energy's gradient (stick, slide) and the
     * Gauss-Newton Hessian where the spring is unloaded (psi' = 0: it is exact) */
    PetscCall(Uniform(rnd, -0.3, 0.3, &tilt[0]));
    PetscCall(Uniform(rnd, -0.3, 0.3, &tilt[1]));
    FrictionTriple(0.4 + 0.3 * t, l1, l2, la, tilt, R, o, x);
    for (PetscInt i = 0; i < 15; i++) PetscCall(Uniform(rnd, -1, 1, &d[i]));
    for (PetscInt test = 0; test < 4; test++) {
      const PetscReal th0 = KernelTurning(x, x + 3, x + 6, x + 9, x + 12, NULL), L = 0.7;
      KernelFriction  f = {.area = 1.3, .L = L, .hb = 2.0, .K = 5.0}; /* stick range 0.4 */
      /* kp: the angle itself (unloaded), inside the range, beyond it (sliding) */
      const PetscReal kp = test == 0 ? th0 / L : (test == 1 ? th0 / L - 0.15 : (test == 2 ? th0 / L + 1.5 : th0 / L - 1.5));
      PetscReal       r[NEPS], rh[NEPS], E0 = 0, gd = 0, Hd[15], eps = EPS0;
      if (test == 0) { /* theta itself: E = theta */
        E0 = KernelTurning(x, x + 3, x + 6, x + 9, x + 12, g);
      } else
        E0 = KernelFrictionEnergy(&f, kp, x, x + 3, x + 6, x + 9, x + 12, g, H);
      for (PetscInt i = 0; i < 15; i++) gd += g[i] * d[i];
      if (test == 1) {
        PetscReal lmin = 0;
        for (PetscInt i = 0; i < 15; i++)
          for (PetscInt j = 0; j < i; j++) PetscCheck(H[15 * i + j] == H[15 * j + i], PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED symmetry of the friction Hessian at (%" PetscInt_FMT ", %" PetscInt_FMT ")", i, j);
        for (PetscInt i = 0; i < 15; i++) { /* H = c g g^T: d^T H d >= 0 for every d, = c (g.d)^2 */
          PetscReal s = 0;
          for (PetscInt j = 0; j < 15; j++) s += H[15 * i + j] * d[j];
          lmin += d[i] * s;
        }
        PetscCheck(lmin >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED PSD: d^T H d = %g < 0 for the friction Hessian", (double) lmin);
      }
      for (PetscInt i = 0; i < 15; i++) {
        Hd[i] = 0;
        for (PetscInt j = 0; j < 15; j++) Hd[i] += H[15 * i + j] * d[j];
      }
      for (PetscInt k = 0; k < NEPS; k++, eps *= 0.5) {
        PetscReal E1, g1[15], res = 0;
        for (PetscInt i = 0; i < 15; i++) y[i] = x[i] + eps * d[i];
        if (test == 0)
          E1 = KernelTurning(y, y + 3, y + 6, y + 9, y + 12, NULL);
        else {
          /* the unloaded spring: kp = theta(x)/L, so psi'(x) = 0 and H is the exact Hessian */
          KernelFriction fu = f;
          E1                = KernelFrictionEnergy(&f, kp, y, y + 3, y + 6, y + 9, y + 12, NULL, NULL);
          KernelFrictionEnergy(&fu, th0 / L, y, y + 3, y + 6, y + 9, y + 12, g1, NULL);
        }
        r[k] = PetscAbsReal(E1 - E0 - eps * gd);
        if (test == 1) {
          PetscReal g0[15], Hu[225];
          KernelFrictionEnergy(&f, th0 / L, x, x + 3, x + 6, x + 9, x + 12, g0, Hu);
          for (PetscInt i = 0; i < 15; i++) {
            PetscReal hd = 0;
            for (PetscInt j = 0; j < 15; j++) hd += Hu[15 * i + j] * d[j];
            res += PetscSqr(g1[i] - g0[i] - eps * hd);
          }
          rh[k] = PetscSqrtReal(res);
        }
      }
      for (PetscInt k = 2; k + 1 < NEPS; k++) { /* the first halvings are not yet asymptotic at eps = 1e-2 */
        const PetscReal ord = PetscLog2Real(r[k] / r[k + 1]);
        PetscCheck(ord >= 1.8 && ord <= 2.2, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED friction Taylor test (%s): order %.3f at halving %" PetscInt_FMT " (r = %.3e, %.3e)",
                   test == 0 ? "turning angle" : (test == 1 ? "energy, stick" : "energy, sliding"), (double) ord, k, (double) r[k], (double) r[k + 1]);
        omin = PetscMin(omin, ord);
        omax = PetscMax(omax, ord);
        if (test == 1) {
          const PetscReal oh = PetscLog2Real(rh[k] / rh[k + 1]);
          PetscCheck(oh >= 1.8 && oh <= 2.2, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED friction Hessian Taylor test (unloaded spring): order %.3f at halving %" PetscInt_FMT, (double) oh, k);
          omin = PetscMin(omin, oh);
          omax = PetscMax(omax, oh);
        }
      }
      ntaylor++;
      if (test >= 2) { /* sliding: the moment is HB, the matrix has nothing */
        PetscReal hn = 0;
        for (PetscInt i = 0; i < 225; i++) hn += PetscAbsReal(H[i]);
        PetscCheck(hn == 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED: a sliding friction element puts %g into the matrix", (double) hn);
      }
    }
  }
  {                                                                          /* Huber's known values and the return mapping; straight triple: theta = 0 */
    const KernelFriction f  = {.area = 2.0, .L = 0.5, .hb = 3.0, .K = 10.0}; /* ky = 0.3 */
    const PetscReal      ky = 0.3, zs[] = {0, 0.1, -0.2, 0.3, 0.5, -1.1};
    const PetscReal      zero[2] = {0, 0}, Id[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, oo[3] = {0, 0, 0};
    FrictionTriple(0, 1, 1, 1, zero, Id, oo, x);
    for (size_t j = 0; j < sizeof(zs) / sizeof(zs[0]); j++) {
      const PetscReal z = zs[j], E = KernelFrictionEnergy(&f, -z, x, x + 3, x + 6, x + 9, x + 12, NULL, NULL);
      const PetscReal Eref = f.area * (PetscAbsReal(z) <= ky ? 0.5 * f.K * z * z : f.hb * (PetscAbsReal(z) - 0.5 * ky));
      const PetscReal kp = KernelFrictionReturn(&f, 0, -z), kpref = PetscAbsReal(z) <= ky ? -z : (z > 0 ? -ky : ky);
      PetscCheck(PetscAbsReal(E - Eref) <= 1e-14 * (1 + Eref), PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED known value: friction energy at z = %g is %.17g, expected %.17g", (double) z, (double) E, (double) Eref);
      PetscCheck(PetscAbsReal(kp - kpref) <= 1e-15, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED return mapping at z = %g: kp = %.17g, expected %.17g", (double) z, (double) kp, (double) kpref);
    }
  }
  PetscCall(PetscPrintf(PETSC_COMM_WORLD,
                        "PASS bending friction: turning angle known to %.1e over 6 placements x 9 angles (scaling-invariant); %" PetscInt_FMT
                        " Taylor tests (angle, energy stick/sliding, Gauss-Newton Hessian where unloaded) orders %.3f-%.3f; Hessian symmetric, PSD, 0 when sliding; Huber values and return mapping known\n",
                        (double) worst, ntaylor, (double) omin, (double) omax));
  npassed++;
  PetscFunctionReturn(0);
}

/* KernelAsin, the force loops' asin, against the C library's: at most 1 ulp apart on
 * |x| <= 1/2, 2 ulp above, odd, exact at 0 and +-1. */
static PetscErrorCode GroupAsin(PetscRandom rnd)
{
  PetscReal worst[2] = {0, 0};

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < 400000; k++) {
    PetscReal x = 0, ref, ulp;
    PetscCall(Uniform(rnd, -1, 1, &x));
    if (k % 2) x *= 0.5;
    ref = PetscAsinReal(x);
    ulp = nextafter(PetscAbsReal(ref), PETSC_INFINITY) - PetscAbsReal(ref);
    if (ref != 0) worst[PetscAbsReal(x) > 0.5] = PetscMax(worst[PetscAbsReal(x) > 0.5], PetscAbsReal(KernelAsin(x) - ref) / ulp);
    PetscCheck(KernelAsin(-x) == -KernelAsin(x), PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED KernelAsin is not odd at %.17g", (double) x);
  }
  PetscCheck(worst[0] <= 1 && worst[1] <= 2, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED KernelAsin: %g ulp from asin on |x| <= 1/2 (at most 1), %g above (at most 2)", (double) worst[0], (double) worst[1]);
  PetscCheck(KernelAsin(0) == 0 && KernelAsin(1) == PETSC_PI / 2 && KernelAsin(-1) == -PETSC_PI / 2 && KernelAsin(1e-300) == 1e-300, PETSC_COMM_SELF, PETSC_ERR_PLIB, "FAILED KernelAsin at 0, 1e-300 or +-1");
  npassed++;
  PetscFunctionReturn(0);
}

static PetscErrorCode Run(void)
{
  PetscRandom rnd;
  PetscInt    seed = 20240613, nst, nsh, nbe;
  Elem        est[NCFG_MAX], esh[NCFG_MAX], ebe[NCFG_MAX];
  PetscReal   rst[NCFG_MAX], rsh[NCFG_MAX], rbe[NCFG_MAX];

  PetscFunctionBeginUser;
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-seed", &seed, NULL));
  PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
  PetscCall(PetscRandomSetInterval(rnd, 0.0, 1.0));
  PetscCall(PetscRandomSetSeed(rnd, (unsigned long) seed));
  PetscCall(PetscRandomSeed(rnd));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "test_kernels: seed %" PetscInt_FMT "\n", seed));

  PetscCall(GroupsForKind(rnd, ELEM_STRETCH, rst, est, &nst));
  PetscCall(GroupsForKind(rnd, ELEM_SHEAR, rsh, esh, &nsh));
  PetscCall(GroupsForKind(rnd, ELEM_BEND, rbe, ebe, &nbe));
  PetscCall(GroupIndefinite(est, rst, nst, rsh, nsh, rbe, nbe));
  PetscCall(GroupProjectedEqualsExact(est, nst));
  {
    const Elem    *sets[3] = {est, esh, ebe};
    const PetscInt nset[3] = {nst, nsh, nbe};
    PetscCall(GroupGradientKernels(sets, nset));
  }
  PetscCall(GroupShearCell(rnd));
  PetscCall(GroupAsin(rnd));
  PetscCall(GroupPSDTest(rnd));
  PetscCall(GroupClosedProjection(rnd));
  PetscCall(GroupLanes(rnd));
  PetscCall(GroupKnownStretch(rnd));
  PetscCall(GroupKnownShear(rnd));
  PetscCall(GroupKnownBend(rnd));
  PetscCall(GroupKnownBendLaw(rnd));
  PetscCall(GroupFriction(rnd));

  PetscCall(PetscRandomDestroy(&rnd));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "%" PetscInt_FMT " passed, 0 failed\n", npassed));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr;

  PetscCall(PetscInitialize(&argc, &argv, NULL, help));
  ierr = Run();
  if (ierr) PetscCall(PetscPrintf(PETSC_COMM_WORLD, "%" PetscInt_FMT " passed, 1 failed\n", npassed));
  PetscCall(PetscFinalize());
  return ierr ? 1 : 0;
}
