/* Stability limits of the explicit schemes from Omega_max (paper section 4).
 *
 * Omega_max^2 = lambda_max(M^-1 H), H the exact Hessian of the internal energy with
 * pins removed, by the Lanczos process on M^-1 H (self-adjoint in the M inner
 * product), matrix-free: each step one product H z from the elements' directional
 * derivatives (ClothApplyHessian) and three M-inner products, nothing stored but
 * three vectors; the top eigenvalue of the small tridiagonal matrix by bisection.
 * The start vector holds what the top mode of a lattice looks like: in each of the
 * three directions, the three sign patterns (-1)^i, (-1)^j, (-1)^(i+j) (the corners
 * of the lattice's Brillouin zone, where a stretch, shear or bending chain is
 * stiffest) under the lowest envelope of the lattice box, plus a pseudo-random part
 * for whatever else the top mode is; all from each particle's lattice index, so the
 * same on any partition.
 *
 * For the top mode x'' = -Omega^2 x - c x':
 *   symplectic Euler  h <= (sqrt(c^2 + 4 Omega^2) - c) / Omega^2   (2/Omega at c = 0)
 *   explicit Euler    h <= c / Omega^2 if the top mode is underdamped (c < 2 Omega),
 *                     h <= 2 / (c/2 + sqrt(c^2/4 - Omega^2)) otherwise; no step at c = 0.
 */
#include <stability.h>
#include <drape.h>

#ifndef STABILITY_RTOL
#define STABILITY_RTOL 1e-4
#endif
#ifndef STABILITY_WINDOW
#define STABILITY_WINDOW 24 /* half-width of a window, particles */
#endif
#define STABILITY_WINDOWS 2

/* Largest eigenvalue of the symmetric tridiagonal matrix (diagonal a[0..k-1],
 * off-diagonal b[0..k-2]) by bisection on the Sturm sequence count. */
static PetscReal TridiagonalMax(PetscInt k, const PetscReal *a, const PetscReal *b)
{
  PetscReal lo = PETSC_MAX_REAL, hi = -PETSC_MAX_REAL;

  for (PetscInt i = 0; i < k; i++) { /* Gershgorin interval */
    const PetscReal r = (i > 0 ? PetscAbsReal(b[i - 1]) : 0) + (i < k - 1 ? PetscAbsReal(b[i]) : 0);
    lo                = PetscMin(lo, a[i] - r);
    hi                = PetscMax(hi, a[i] + r);
  }
  for (PetscInt it = 0; it < 200 && hi - lo > 1e-15 * PetscMax(PetscAbsReal(lo), PetscAbsReal(hi)); it++) {
    const PetscReal mid   = 0.5 * (lo + hi);
    PetscReal       q     = 1;
    PetscInt        above = 0; /* eigenvalues above mid */
    for (PetscInt i = 0; i < k; i++) {
      q = a[i] - mid - (i > 0 ? b[i - 1] * b[i - 1] / q : 0);
      if (q == 0) q = -1e-300;
      if (q > 0) above++;
    }
    if (above > 0)
      lo = mid;
    else
      hi = mid;
  }
  return hi;
}

/* The start vector (see the top of the file): lattice index -> value, the same on
 * any partition; the envelope of the rectangle (i0, i1, j0, j1) a particle is in. */
static void StartVector(PetscInt Mx, PetscInt nrect, const PetscInt rect[], PetscInt np, const PetscInt *natural, const PetscBool *fixed, PetscScalar *z)
{
  /* weights of the patterns (-1)^i, (-1)^j, (-1)^(i+j) in each direction: generic, so
   * that no polarisation of a tilted sheet is missed */
  const PetscReal c[3][3] = {{1.0, 0.43, 0.71}, {0.57, 1.0, 0.83}, {0.61, 0.37, 1.0}}, noise = 0.2;

  for (PetscInt k = 0; k < np; k++) {
    const PetscInt  i = natural[k] % Mx, j = natural[k] / Mx;
    const PetscReal si = i % 2 ? -1 : 1, sj = j % 2 ? -1 : 1;
    PetscReal       env = 0;
    for (PetscInt r = 0; r < nrect; r++) {
      const PetscInt *b = rect + 4 * r;
      if (i >= b[0] && i <= b[1] && j >= b[2] && j <= b[3]) env = PetscMax(env, PetscSinReal(PETSC_PI * (i - b[0] + 1) / (b[1] - b[0] + 2)) * PetscSinReal(PETSC_PI * (j - b[2] + 1) / (b[3] - b[2] + 2)));
    }
    for (PetscInt d = 0; d < 3; d++) {
      const PetscReal h = PetscSinReal(12.9898 * (3 * natural[k] + d) + 78.233) * 43758.5453, r = 2 * (h - PetscFloorReal(h)) - 1;
      z[3 * k + d] = fixed[k] ? 0 : env * (c[d][0] * si + c[d][1] * sj + c[d][2] * si * sj) + noise * r;
    }
  }
}

typedef PetscErrorCode (*HessianProduct)(void *, const PetscScalar *, PetscScalar *);

/* lambda_max(M^-1 H) by Lanczos on np particles (fixed ones take no part): at most
 * maxit steps, fewer once a step raises the estimate by less than STABILITY_RTOL
 * (early) or an invariant subspace is found. Collective on comm. */
static PetscErrorCode Lanczos(MPI_Comm comm, PetscInt np, const PetscInt *natural, const PetscReal *mass, const PetscBool *fixed, PetscInt Mx, PetscInt nrect, const PetscInt rect[], HessianProduct apply, void *ctx, PetscInt maxit, PetscBool early,
                              PetscReal *lambda, PetscInt *steps)
{
  const PetscInt n = 3 * np;
  PetscScalar   *work[3], *p, *q, *r, *t;
  PetscReal     *alpha, *beta, loc, sum, nrm;

  PetscFunctionBeginUser;
  *lambda = 0;
  *steps  = 0;
  PetscCall(PetscMalloc3(n + 1, &work[0], n + 1, &work[1], n + 1, &work[2]));
  PetscCall(PetscMalloc2(maxit + 1, &alpha, maxit + 1, &beta));
  p = work[0], q = work[1], r = work[2];
  StartVector(Mx, nrect, rect, np, natural, fixed, q);
  /* Lanczos on A = M^-1 H in the M inner product: q the current vector, p the last */
  loc = 0;
  for (PetscInt k = 0; k < np; k++)
    for (PetscInt d = 0; d < 3; d++) loc += mass[k] * q[3 * k + d] * q[3 * k + d];
  PetscCall(MPIU_Allreduce(&loc, &nrm, 1, MPIU_REAL, MPI_SUM, comm));
  nrm = PetscSqrtReal(nrm);
  for (PetscInt i = 0; i < n; i++) {
    q[i] = nrm > 0 ? q[i] / nrm : 0;
    p[i] = 0;
  }
  for (PetscInt it = 0; it < maxit && nrm > 0; it++) {
    const PetscReal prev = *lambda;
    PetscCall(apply(ctx, q, r));
    loc = 0;
    for (PetscInt i = 0; i < n; i++) loc += q[i] * r[i]; /* q.Hq = <q, M^-1 H q>_M */
    PetscCall(MPIU_Allreduce(&loc, &sum, 1, MPIU_REAL, MPI_SUM, comm));
    alpha[it] = sum;
    loc       = 0;
    for (PetscInt k = 0; k < np; k++)
      for (PetscInt d = 0; d < 3; d++) {
        const PetscInt i = 3 * k + d;
        r[i]             = (fixed[k] ? 0 : r[i] / mass[k]) - alpha[it] * q[i] - (it > 0 ? beta[it - 1] * p[i] : 0);
        loc += mass[k] * r[i] * r[i];
      }
    PetscCall(MPIU_Allreduce(&loc, &sum, 1, MPIU_REAL, MPI_SUM, comm));
    beta[it] = PetscSqrtReal(sum);
    *steps   = it + 1;
    *lambda  = TridiagonalMax(*steps, alpha, beta);
    PetscCall(PetscInfo(NULL, "Lanczos step %" PetscInt_FMT ": Omega_max = %.10e rad/s\n", *steps, (double) PetscSqrtReal(PetscMax(*lambda, 0))));
    if (beta[it] <= 1e-14 * PetscAbsReal(*lambda)) break; /* an invariant subspace */
    if (early && it > 0 && *lambda - prev <= STABILITY_RTOL * *lambda) break;
    for (PetscInt i = 0; i < n; i++) r[i] /= beta[it];
    t = p, p = q, q = r, r = t; /* p <- q <- r */
  }
  PetscCall(PetscFree2(alpha, beta));
  PetscCall(PetscFree3(work[0], work[1], work[2]));
  PetscFunctionReturn(0);
}

typedef struct {
  Cloth              cloth;
  const PetscScalar *x;
  PetscBool          elementwise;
} LatticeProduct;

static PetscErrorCode ApplyLattice(void *ctx, const PetscScalar *z, PetscScalar *y)
{
  LatticeProduct *lp = (LatticeProduct *) ctx;

  PetscFunctionBeginUser;
  if (lp->elementwise)
    PetscCall(ClothApplyHessianElementwise(lp->cloth, lp->x, z, y));
  else
    PetscCall(ClothApplyHessian(lp->cloth, lp->x, z, y));
  PetscFunctionReturn(0);
}

static PetscErrorCode ApplyWindow(void *ctx, const PetscScalar *z, PetscScalar *y)
{
  PetscFunctionBeginUser;
  PetscCall(ClothWindowApplyHessian((ClothWindow) ctx, z, y));
  PetscFunctionReturn(0);
}

PetscErrorCode StabilityEstimate(Cloth cloth, const PetscScalar *x, PetscInt iterations, StabilityLimits *lim)
{
  ClothInfo info;
  PetscReal lambda = 0, c, Om2;
  PetscInt  steps  = 0;
  MPI_Comm  comm;

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.stability, 0, 0, 0, 0));
  PetscCall(ClothGetInfo(cloth, &info));
  {
    DM da;
    PetscCall(ClothGetDM(cloth, &da));
    comm = PetscObjectComm((PetscObject) da);
  }
  if (lim->reference || (PetscInt64) info.Mx * info.My <= STABILITY_WINDOWS * PetscSqr(2 * STABILITY_WINDOW + 1)) { /* the whole lattice */
    const PetscReal *mass;
    const PetscBool *pinned;
    const PetscInt  *natural, rect[4] = {0, info.Mx - 1, 0, info.My - 1};
    LatticeProduct   lp = {cloth, x, lim->reference};
    PetscCall(ClothGetMasses(cloth, &mass, &pinned));
    PetscCall(ClothGetNatural(cloth, &natural));
    PetscCall(Lanczos(comm, info.nowned, natural, mass, pinned, info.Mx, 1, rect, ApplyLattice, &lp, iterations, (PetscBool) !lim->reference, &lambda, &steps));
  } else { /* windows: the lattice's centre and where tension stiffens it most */
    ClothWindow      w;
    PetscInt         hot, np, rect[4 * STABILITY_WINDOWS], centre[2 * STABILITY_WINDOWS];
    const PetscInt  *natural;
    const PetscReal *mass;
    const PetscBool *free;
    PetscBool       *fixed;
    PetscCall(ClothStretchHotSpot(cloth, x, &hot));
    centre[0] = info.Mx / 2, centre[1] = info.My / 2, centre[2] = hot % info.Mx, centre[3] = hot / info.Mx;
    for (PetscInt r = 0; r < STABILITY_WINDOWS; r++) {
      const PetscInt i0 = PetscMin(PetscMax(centre[2 * r] - STABILITY_WINDOW, 0), info.Mx - 1 - 2 * STABILITY_WINDOW);
      const PetscInt j0 = PetscMin(PetscMax(centre[2 * r + 1] - STABILITY_WINDOW, 0), info.My - 1 - 2 * STABILITY_WINDOW);
      rect[4 * r] = PetscMax(i0, 0), rect[4 * r + 1] = PetscMin(i0 + 2 * STABILITY_WINDOW, info.Mx - 1);
      rect[4 * r + 2] = PetscMax(j0, 0), rect[4 * r + 3] = PetscMin(j0 + 2 * STABILITY_WINDOW, info.My - 1);
    }
    PetscCall(PetscInfo(NULL, "windows around (%" PetscInt_FMT ", %" PetscInt_FMT ") and (%" PetscInt_FMT ", %" PetscInt_FMT ")\n", centre[0], centre[1], centre[2], centre[3]));
    PetscCall(ClothWindowCreate(cloth, x, STABILITY_WINDOWS, rect, &w));
    PetscCall(ClothWindowGetParticles(w, &np, &natural, &mass, &free));
    PetscCall(PetscMalloc1(np + 1, &fixed));
    for (PetscInt k = 0; k < np; k++) fixed[k] = (PetscBool) !free[k];
    PetscCall(Lanczos(PETSC_COMM_SELF, np, natural, mass, fixed, info.Mx, STABILITY_WINDOWS, rect, ApplyWindow, w, iterations, PETSC_TRUE, &lambda, &steps));
    PetscCall(PetscFree(fixed));
    PetscCall(ClothWindowDestroy(&w));
  }
  c               = info.damping;
  Om2             = PetscMax(lambda, 0);
  lim->omega      = PetscSqrtReal(Om2);
  lim->iterations = steps;
  if (Om2 > 0) {
    lim->symplectic = (PetscSqrtReal(c * c + 4 * Om2) - c) / Om2;
    if (c <= 0)
      lim->euler = 0;
    else if (c < 2 * lim->omega)
      lim->euler = c / Om2;
    else
      lim->euler = 2 / (0.5 * c + PetscSqrtReal(0.25 * c * c - Om2));
  } else {
    lim->symplectic = PETSC_INFINITY;
    lim->euler      = c > 0 ? 2 / c : PETSC_INFINITY;
  }
  PetscCall(PetscLogEventEnd(drape_log.stability, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode StabilityView(const StabilityLimits *lim, PetscReal damping, Report r, PetscViewer viewer)
{
  PetscFunctionBeginUser;
  if (viewer) PetscCall(PetscViewerASCIIPrintf(viewer, "Stability (estimated at t = 0, %" PetscInt_FMT " Lanczos steps):", lim->iterations));
  PetscCall(ReportViewReal(r, viewer, "omega_max", " Omega_max = %.4e rad/s\n", lim->omega));
  PetscCall(ReportViewReal(r, viewer, "symplectic_limit", "  symplectic Euler: stable for h < %.4e s (2/Omega_max, reduced by damping)\n", lim->symplectic));
  PetscCall(ReportViewReal(r, lim->euler > 0 ? viewer : NULL, "euler_limit", "  explicit Euler: stable for h < %.4e s", lim->euler)); /* 0: unstable at every step */
  if (!viewer) PetscFunctionReturn(0);
  if (lim->euler > 0)
    PetscCall(PetscViewerASCIIPrintf(viewer, " at damping %g 1/s (c/Omega_max^2)\n", (double) damping));
  else
    PetscCall(PetscViewerASCIIPrintf(viewer, "  explicit Euler: unstable at every step without damping (energy grows by 1 + (Omega h)^2 per step)\n"));
  PetscCall(PetscViewerASCIIPrintf(viewer, "  backward Euler: no step limit for the linearised problem (a single linearisation, -snes_type ksponly, can still fail at very large steps on stiff fabric)\n"));
  PetscFunctionReturn(0);
}
