/* The Hessian of the internal energy applied to a vector, matrix-free (element by
 * element): the stability estimate's operator (src/integrate/stability.c). Two ways
 * to the same product: from each element's directional derivatives (kernels.h,
 * "Hessian-vector products"; the estimate's) and from each element's full matrix
 * (ElementHessian; the reference the tests check the first against). */
#include "clothimpl.h"
#include <drape.h>

static PetscErrorCode ClothApplyHessian_Private(Cloth c, PetscBool elementwise, const PetscScalar *x, const PetscScalar *z, PetscScalar *y)
{
  const PetscScalar *xl;
  PetscScalar       *zl, *yl;
  Vec                Zl, Yl;
  PetscReal          H[225];

  PetscFunctionBeginUser;
  PetscCall(ClothSetUpImplicit(c)); /* the ghost scatter, Zl and the ghosts' pins, at the first product */
  Zl = c->Zl;
  PetscCall(VecPlaceArray(c->Xg, z));
  PetscCall(VecScatterBegin(c->ghost, c->Xg, Zl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(c->ghost, c->Xg, Zl, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecResetArray(c->Xg));
  PetscCall(ClothScatterPositions(c, x, &xl));
  PetscCall(VecGetArray(Zl, &zl));
  PetscCall(ClothGetLocalWork(c, &Yl));
  PetscCall(VecGetArray(Yl, &yl));
  PetscCall(PetscArrayzero(yl, 3 * c->nlocal));
  for (PetscInt l = 0; l < c->nlocal; l++)
    if (c->pinned_local[l]) zl[3 * l] = zl[3 * l + 1] = zl[3 * l + 2] = 0;
  for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
    const PetscInt n = KindSize(kind), m = 3 * n;
    if (elementwise || kind == 3) { /* the bending friction (rare) always by its matrix */
      for (PetscInt e = 0; e < KindCount(c, kind); e++) {
        const PetscInt *p = KindParticles(c, kind, e);
        ElementHessian(c, PETSC_FALSE, kind, e, xl, H);
        for (PetscInt i = 0; i < m; i++) {
          PetscReal s = 0;
          for (PetscInt j = 0; j < m; j++) s += H[m * i + j] * zl[3 * p[j / 3] + j % 3];
          yl[3 * p[i / 3] + i % 3] += s;
        }
      }
    } else if (kind == 0) {
      const ClothElements *el = &c->stretch_el;
      for (PetscInt e = 0; e < el->n; e++) {
        const PetscInt *p = el->p + 2 * e;
        KernelStretchHessianVector(xl + 3 * p[0], xl + 3 * p[1], ElemCoef(el, e), ElemRest(el, e), zl + 3 * p[0], zl + 3 * p[1], yl + 3 * p[0], yl + 3 * p[1]);
      }
    } else {
      const ClothElements  *el = KindList(c, kind);
      const KernelAngleKind ak = kind == 1 ? KERNEL_SHEAR : KERNEL_BEND;
      for (PetscInt e = 0; e < el->n; e++) {
        const PetscInt *p = el->p + 3 * e;
        KernelAngleHessianVector(ak, xl + 3 * p[0], xl + 3 * p[1], xl + 3 * p[2], ElemCoef(el, e), ElemLaw(el, e), zl + 3 * p[0], zl + 3 * p[1], zl + 3 * p[2], yl + 3 * p[0], yl + 3 * p[1], yl + 3 * p[2]);
      }
    }
  }
  for (PetscInt k = 0; k < c->nowned; k++)
    for (PetscInt d = 0; d < 3; d++) y[3 * k + d] = c->pinned[k] ? 0 : yl[3 * c->owned_local[k] + d];
  PetscCall(VecRestoreArray(Yl, &yl));
  PetscCall(VecRestoreArray(Zl, &zl));
  PetscCall(ClothEndScatter(c, &xl));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothApplyHessian(Cloth c, const PetscScalar *x, const PetscScalar *z, PetscScalar *y)
{
  PetscFunctionBeginUser;
  PetscCall(ClothApplyHessian_Private(c, PETSC_FALSE, x, z, y));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothApplyHessianElementwise(Cloth c, const PetscScalar *x, const PetscScalar *z, PetscScalar *y)
{
  PetscFunctionBeginUser;
  PetscCall(ClothApplyHessian_Private(c, PETSC_TRUE, x, z, y));
  PetscFunctionReturn(0);
}

/* ---- windows: the operator restricted to a few lattice rectangles ---- */

/* One element of a window as doubles (gathered with one MPI_Allgatherv): kind, its
 * particles' natural indices (-1: none), coefficient, rest length, bending law (n,
 * L, dk, b[]), friction (area, L, hb, K, kp). */
#define WINDOW_ELEMENT  (1 + 5 + 2 + 3 + KERNEL_BEND_LAW_MAX + 5)
#define WINDOW_PARTICLE 6 /* natural index, x, mass, pinned */

struct _p_ClothWindow {
  PetscInt   np, ne;
  PetscReal *part; /* np records of WINDOW_PARTICLE, by natural index          */
  PetscReal *el;   /* ne records of WINDOW_ELEMENT, in a canonical order        */
  PetscInt  *idx;  /* 5 per element: its particles' positions in part (-1: none) */
  PetscReal *x, *mass;
  PetscInt  *nat;
  PetscBool *free; /* in a window and not pinned */
};

static PetscBool InRects(PetscInt nat, PetscInt Mx, PetscInt nrect, const PetscInt rect[], PetscInt grow)
{
  const PetscInt i = nat % Mx, j = nat / Mx;
  for (PetscInt r = 0; r < nrect; r++)
    if (i >= rect[4 * r] - grow && i <= rect[4 * r + 1] + grow && j >= rect[4 * r + 2] - grow && j <= rect[4 * r + 3] + grow) return PETSC_TRUE;
  return PETSC_FALSE;
}

static int CompareRecords(const void *a, const void *b, void *ctx)
{
  const PetscReal *x = (const PetscReal *) a, *y = (const PetscReal *) b;
  const PetscInt   len = *(const PetscInt *) ctx;
  for (PetscInt i = 0; i < len; i++)
    if (x[i] != y[i]) return x[i] < y[i] ? -1 : 1;
  return 0;
}

static PetscErrorCode GatherRecords(MPI_Comm comm, PetscInt len, PetscInt nloc, const PetscReal *loc, PetscInt *n, PetscReal **all)
{
  PetscMPIInt size, cnt = (PetscMPIInt) (len * nloc), *counts, *displs;
  PetscInt    total = 0;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(PetscMalloc2(size, &counts, size, &displs));
  PetscCallMPI(MPI_Allgather(&cnt, 1, MPI_INT, counts, 1, MPI_INT, comm));
  for (PetscMPIInt r = 0; r < size; r++) {
    displs[r] = (PetscMPIInt) total;
    total += counts[r];
  }
  PetscCall(PetscMalloc1(total + 1, all));
  PetscCallMPI(MPI_Allgatherv(loc, cnt, MPIU_REAL, *all, counts, displs, MPIU_REAL, comm));
  PetscCall(PetscFree2(counts, displs));
  *n = total / len;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothWindowCreate(Cloth c, const PetscScalar *x, PetscInt nrect, const PetscInt rect[], ClothWindow *window)
{
  ClothWindow    w;
  PetscReal     *lp, *le;
  PetscInt       nlp = 0, nle = 0, len;
  const PetscInt grow = 2; /* every particle of an element that touches a window */

  unsigned char *inside; /* per local particle: 1 inside a window, 2 near one */

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&w));
  PetscCall(PetscMalloc1(c->nlocal + 1, &inside));
  for (PetscInt l = 0; l < c->nlocal; l++) inside[l] = InRects(c->natural[l], c->Mx, nrect, rect, 0) ? 1 : (InRects(c->natural[l], c->Mx, nrect, rect, grow) ? 2 : 0);
  /* this rank's owned particles near the windows */
  for (PetscInt k = 0; k < c->nowned; k++) nlp += inside[c->owned_local[k]] > 0;
  PetscCall(PetscMalloc1(WINDOW_PARTICLE * nlp + 1, &lp));
  nlp = 0;
  for (PetscInt k = 0; k < c->nowned; k++) {
    const PetscInt nat = c->natural[c->owned_local[k]];
    PetscReal     *r   = lp + WINDOW_PARTICLE * nlp;
    if (!inside[c->owned_local[k]]) continue;
    r[0] = nat;
    for (PetscInt d = 0; d < 3; d++) r[1 + d] = x[3 * k + d];
    r[4] = c->mass[k];
    r[5] = c->pinned[k];
    nlp++;
  }
  /* the elements this rank owns that touch a window */
  PetscCall(PetscMalloc1(1, &le));
  for (PetscInt pass = 0; pass < 2; pass++) {
    nle = 0;
    for (PetscInt kind = 0; kind < CLOTH_KINDS; kind++) {
      const PetscInt n = KindSize(kind);
      for (PetscInt e = 0; e < KindCount(c, kind); e++) {
        const PetscInt      *p   = KindParticles(c, kind, e);
        const unsigned char *own = kind == 3 ? c->friction_el.own : KindList(c, kind)->own;
        PetscBool            hit = PETSC_FALSE;
        if (!own[e]) continue;
        for (PetscInt a = 0; a < n && !hit; a++) hit = (PetscBool) (inside[p[a]] == 1);
        if (!hit) continue;
        if (pass == 1) {
          PetscReal *r = le + WINDOW_ELEMENT * nle;
          PetscCall(PetscArrayzero(r, WINDOW_ELEMENT));
          r[0] = kind;
          for (PetscInt a = 0; a < 5; a++) r[1 + a] = a < n ? c->natural[p[a]] : -1;
          if (kind == 3) {
            const KernelFriction f = FrictionOf(c, &c->friction_el, e);
            r[WINDOW_ELEMENT - 5]  = f.area;
            r[WINDOW_ELEMENT - 4]  = f.L;
            r[WINDOW_ELEMENT - 3]  = f.hb;
            r[WINDOW_ELEMENT - 2]  = f.K;
            r[WINDOW_ELEMENT - 1]  = c->friction_el.kp[e];
          } else {
            const ClothElements *el  = KindList(c, kind);
            const KernelBendLaw *law = ElemLaw(el, e);
            r[6]                     = ElemCoef(el, e);
            r[7]                     = ElemRest(el, e);
            if (law && law->n > 0) {
              r[8]  = law->n;
              r[9]  = law->L;
              r[10] = law->dk;
              for (PetscInt i = 0; i < KERNEL_BEND_LAW_MAX; i++) r[11 + i] = law->b[i];
            }
          }
        }
        nle++;
      }
    }
    if (pass == 0) {
      PetscCall(PetscFree(le));
      PetscCall(PetscMalloc1(WINDOW_ELEMENT * nle + 1, &le));
    }
  }
  PetscCall(PetscFree(inside));
  PetscCall(GatherRecords(c->comm, WINDOW_PARTICLE, nlp, lp, &w->np, &w->part));
  PetscCall(GatherRecords(c->comm, WINDOW_ELEMENT, nle, le, &w->ne, &w->el));
  PetscCall(PetscFree(lp));
  PetscCall(PetscFree(le));
  /* the same order on every rank and partition: by natural index, elements by kind and particles */
  len = 1;
  PetscCall(PetscTimSort(w->np, w->part, WINDOW_PARTICLE * sizeof(PetscReal), CompareRecords, &len));
  len = 6;
  PetscCall(PetscTimSort(w->ne, w->el, WINDOW_ELEMENT * sizeof(PetscReal), CompareRecords, &len));
  PetscCall(PetscMalloc5(3 * w->np + 1, &w->x, w->np + 1, &w->mass, w->np + 1, &w->nat, w->np + 1, &w->free, 5 * w->ne + 1, &w->idx));
  for (PetscInt k = 0; k < w->np; k++) {
    const PetscReal *r = w->part + WINDOW_PARTICLE * k;
    w->nat[k]          = (PetscInt) r[0];
    for (PetscInt d = 0; d < 3; d++) w->x[3 * k + d] = r[1 + d];
    w->mass[k] = r[4];
    w->free[k] = (PetscBool) (r[5] == 0 && InRects(w->nat[k], c->Mx, nrect, rect, 0));
  }
  for (PetscInt e = 0; e < w->ne; e++)
    for (PetscInt a = 0; a < 5; a++) {
      const PetscReal nat = w->el[WINDOW_ELEMENT * e + 1 + a];
      PetscInt        loc = -1;
      if (nat >= 0) PetscCall(PetscFindInt((PetscInt) nat, w->np, w->nat, &loc));
      PetscCheck(nat < 0 || loc >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "window element's particle %" PetscInt_FMT " not gathered", (PetscInt) nat);
      w->idx[5 * e + a] = loc;
    }
  *window = w;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothWindowGetParticles(ClothWindow w, PetscInt *n, const PetscInt **natural, const PetscReal **mass, const PetscBool **free)
{
  PetscFunctionBeginUser;
  *n       = w->np;
  *natural = w->nat;
  *mass    = w->mass;
  *free    = w->free;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothWindowApplyHessian(ClothWindow w, const PetscScalar *z, PetscScalar *y)
{
  PetscReal H[225];

  PetscFunctionBeginUser;
  PetscCall(PetscArrayzero(y, 3 * w->np));
  for (PetscInt e = 0; e < w->ne; e++) {
    const PetscReal *r = w->el + WINDOW_ELEMENT * e;
    const PetscInt  *p = w->idx + 5 * e, kind = (PetscInt) r[0];
    const PetscReal *x = w->x;
    if (kind == 0)
      KernelStretchHessianVector(x + 3 * p[0], x + 3 * p[1], r[6], r[7], z + 3 * p[0], z + 3 * p[1], y + 3 * p[0], y + 3 * p[1]);
    else if (kind < 3) {
      KernelBendLaw law;
      law.n = (PetscInt) r[8];
      if (law.n > 0) {
        law.L  = r[9];
        law.dk = r[10];
        for (PetscInt i = 0; i < KERNEL_BEND_LAW_MAX; i++) law.b[i] = r[11 + i];
      }
      KernelAngleHessianVector(kind == 1 ? KERNEL_SHEAR : KERNEL_BEND, x + 3 * p[0], x + 3 * p[1], x + 3 * p[2], r[6], law.n > 0 ? &law : NULL, z + 3 * p[0], z + 3 * p[1], z + 3 * p[2], y + 3 * p[0], y + 3 * p[1], y + 3 * p[2]);
    } else {
      KernelFriction f;
      f.area = r[WINDOW_ELEMENT - 5];
      f.L    = r[WINDOW_ELEMENT - 4];
      f.hb   = r[WINDOW_ELEMENT - 3];
      f.K    = r[WINDOW_ELEMENT - 2];
      KernelFrictionEnergy(&f, r[WINDOW_ELEMENT - 1], x + 3 * p[0], x + 3 * p[1], x + 3 * p[2], x + 3 * p[3], x + 3 * p[4], NULL, H);
      for (PetscInt i = 0; i < 15; i++) {
        PetscReal s = 0;
        for (PetscInt j = 0; j < 15; j++) s += H[15 * i + j] * z[3 * p[j / 3] + j % 3];
        y[3 * p[i / 3] + i % 3] += s;
      }
    }
  }
  for (PetscInt k = 0; k < w->np; k++)
    if (!w->free[k]) y[3 * k] = y[3 * k + 1] = y[3 * k + 2] = 0;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothWindowDestroy(ClothWindow *w)
{
  PetscFunctionBeginUser;
  if (!*w) PetscFunctionReturn(0);
  PetscCall(PetscFree5((*w)->x, (*w)->mass, (*w)->nat, (*w)->free, (*w)->idx));
  PetscCall(PetscFree((*w)->part));
  PetscCall(PetscFree((*w)->el));
  PetscCall(PetscFree(*w));
  PetscFunctionReturn(0);
}

/* The stretch edge whose stiffness k (1 + max(0, 1 - L/l)) is largest (ties: the
 * smallest natural index), as the natural index of its first particle: where
 * tension stiffens the cloth most. Collective; the same on any partition. */
PetscErrorCode ClothStretchHotSpot(Cloth c, const PetscScalar *x, PetscInt *natural)
{
  const PetscScalar   *xl = NULL, *xg = NULL;
  const ClothElements *el    = &c->stretch_el;
  PetscReal            best  = -1, gbest;
  PetscInt             where = PETSC_MAX_INT, gwhere;

  PetscFunctionBeginUser;
  /* with the lattice kernel, only the ghosts' positions travel: the whole local copy
   * (its vector and scatter, about 85 bytes a particle) is then never made */
  if (c->lattice)
    PetscCall(ClothLatticeGetGhosts(c, x, &xg));
  else
    PetscCall(ClothScatterPositions(c, x, &xl));
  for (PetscInt e = 0; e < el->n; e++) {
    const PetscInt  *p = el->p + 2 * e;
    const PetscReal *a = xl ? xl + 3 * p[0] : (p[0] < c->nowned ? x + 3 * p[0] : xg + 3 * (p[0] - c->nowned));
    const PetscReal *b = xl ? xl + 3 * p[1] : (p[1] < c->nowned ? x + 3 * p[1] : xg + 3 * (p[1] - c->nowned));
    const PetscReal  l = PetscSqrtReal(PetscSqr(b[0] - a[0]) + PetscSqr(b[1] - a[1]) + PetscSqr(b[2] - a[2]));
    const PetscReal  v = ElemCoef(el, e) * (1 + PetscMax(0, 1 - ElemRest(el, e) / l));
    const PetscInt   n = c->natural[p[0]];
    if (v > best || (v == best && n < where)) best = v, where = n;
  }
  if (c->lattice)
    PetscCall(ClothLatticeRestoreGhosts(c, &xg));
  else
    PetscCall(ClothEndScatter(c, &xl));
  PetscCall(MPIU_Allreduce(&best, &gbest, 1, MPIU_REAL, MPIU_MAX, c->comm));
  if (best != gbest) where = PETSC_MAX_INT;
  PetscCall(MPIU_Allreduce(&where, &gwhere, 1, MPIU_INT, MPI_MIN, c->comm));
  *natural = gwhere == PETSC_MAX_INT ? 0 : gwhere;
  PetscFunctionReturn(0);
}
