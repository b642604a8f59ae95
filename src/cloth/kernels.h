/* Element kernels of the paper's three energies, each with its exact gradient
 * and Hessian (paper section 3; the model and its coefficients: docs/model.md).
 *
 * These functions know nothing about lattices, ranks or partitions: they take
 * the coordinates of one element's particles and return its energy, gradient
 * (w.r.t. those coordinates) and Hessian (row-major). A NULL gradient or
 * Hessian pointer skips that work.
 *
 * Stretch edge (a, b):            E = k/2 (|x_b - x_a| - L)^2
 * Angle element (a, b; vertex c): e1 = x_a - x_c, e2 = x_b - x_c and
 *   shear corner:  E = kappa |e1||e2| phi^2,  phi = angle(e1,e2) - pi/2 = -asin(cos)
 *   bending triple: E = kappa (1 + cos(theta)) = 2 kappa cos^2(theta/2)
 * with cos = e1.e2/(|e1||e2|). Both angle energies are functions E(u, w, s) of
 * u = |e1|^2, w = |e2|^2, s = e1.e2, which gives one chain rule for both.
 * A bending triple may carry a law (KernelBendLaw): its rigidity then depends on
 * the triple's curvature, E = kappa G(1 + cos) with G(q) = q for the linear law.
 *
 * The bending friction (KernelFriction, at the end) is a five-particle element with
 * a state.
 *
 * With project = PETSC_TRUE the Hessian is replaced by a positive semi-definite
 * one (docs/model.md, the paragraph on the SPD projection): the stretch factor
 * (1 - L/l) is clamped at 0 and the angle Hessian's two parts (a rank-3 part and
 * an isotropic 2x2 (x) I3 part) each get their negative eigenvalues clamped at 0.
 * Sums of PSD element matrices keep the backward-Euler matrix SPD for CG. */
#pragma once

#include <petscsys.h>

/* Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations; on
 * return A holds A's projection onto the PSD cone (negative eigenvalues -> 0). */
static inline void KernelProjectPSD3(PetscReal A[9])
{
  PetscReal V[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, D[9], lam[3];
  PetscInt  sweep, p, q, r, i;

  for (i = 0; i < 9; i++) D[i] = A[i];
  for (sweep = 0; sweep < 12; sweep++) {
    PetscReal off = D[1] * D[1] + D[2] * D[2] + D[5] * D[5], diag = D[0] * D[0] + D[4] * D[4] + D[8] * D[8];
    if (off <= 1e-30 * diag || off == 0) break;
    for (p = 0; p < 2; p++) {
      for (q = p + 1; q < 3; q++) {
        PetscReal apq = D[3 * p + q], theta, t, c, s;
        if (apq == 0) continue;
        theta = (D[3 * q + q] - D[3 * p + p]) / (2 * apq);
        t     = (theta >= 0 ? 1.0 : -1.0) / (PetscAbsReal(theta) + PetscSqrtReal(theta * theta + 1));
        c     = 1 / PetscSqrtReal(t * t + 1);
        s     = t * c;
        for (r = 0; r < 3; r++) { /* D <- D G (columns p, q) */
          PetscReal drp = D[3 * r + p], drq = D[3 * r + q];
          D[3 * r + p] = c * drp - s * drq;
          D[3 * r + q] = s * drp + c * drq;
        }
        for (r = 0; r < 3; r++) { /* D <- G^T D (rows p, q) */
          PetscReal dpr = D[3 * p + r], dqr = D[3 * q + r];
          D[3 * p + r] = c * dpr - s * dqr;
          D[3 * q + r] = s * dpr + c * dqr;
        }
        for (r = 0; r < 3; r++) { /* V <- V G */
          PetscReal vrp = V[3 * r + p], vrq = V[3 * r + q];
          V[3 * r + p] = c * vrp - s * vrq;
          V[3 * r + q] = s * vrp + c * vrq;
        }
      }
    }
  }
  for (i = 0; i < 3; i++) lam[i] = PetscMax(D[4 * i], 0.0);
  for (p = 0; p < 3; p++)
    for (q = 0; q < 3; q++) A[3 * p + q] = lam[0] * V[3 * p] * V[3 * q] + lam[1] * V[3 * p + 1] * V[3 * q + 1] + lam[2] * V[3 * p + 2] * V[3 * q + 2];
}

/* Is the symmetric 3x3 A positive semi-definite? All seven principal minors
 * nonnegative, up to round-off: each minor may be negative by 1e-14 times the
 * matching power of max|A_ij| (so a "yes" allows an eigenvalue down to about
 * -1e-7 max|A_ij|, far below what could make the implicit matrix indefinite). A
 * cheap test that spares the Jacobi projection for the (most) elements that need
 * none. */
static inline PetscReal KernelPSD3Margin(PetscReal a0, PetscReal a1, PetscReal a2, PetscReal a4, PetscReal a5, PetscReal a8)
{
  /* the seven minors less their bounds (x >= t as x - t >= 0, exact), the least of
   * them: no branch, so that KernelProjectPSD3Lanes's loop vectorises */
  const PetscReal s  = PetscMax(PetscMax(PetscMax(PetscAbsReal(a0), PetscAbsReal(a1)), PetscMax(PetscAbsReal(a2), PetscAbsReal(a4))), PetscMax(PetscAbsReal(a5), PetscAbsReal(a8)));
  const PetscReal t1 = -1e-14 * s, t2 = t1 * s, t3 = t2 * s;
  const PetscReal m1 = PetscMin(PetscMin(a0 - t1, a4 - t1), a8 - t1), m2 = PetscMin(PetscMin(a0 * a4 - a1 * a1 - t2, a0 * a8 - a2 * a2 - t2), a4 * a8 - a5 * a5 - t2);
  const PetscReal m3 = a0 * (a4 * a8 - a5 * a5) - a1 * (a1 * a8 - a5 * a2) + a2 * (a1 * a5 - a4 * a2) - t3;
  return PetscMin(PetscMin(m1, m2), m3);
}

static inline PetscBool KernelIsPSD3(const PetscReal A[9]) { return (PetscBool) (KernelPSD3Margin(A[0], A[1], A[2], A[4], A[5], A[8]) >= 0); }

/* ---- Lanes: up to KERNEL_LANES small problems at once ----
 *
 * The angle elements' Hessians are formed KERNEL_LANES at a time, each number held
 * in structure-of-arrays order (x[i][k]: number i of lane k), by loops over the
 * lanes without branches (selects), which the compiler vectorises. Each lane is
 * computed by the same operations, in the same order, whatever the other lanes hold
 * and whatever their number: an element alone (n = 1) gets the bits it gets in a
 * batch. (Iterations stop per lane: a lane that has converged is frozen, not
 * iterated on.) */
#define KERNEL_LANES 8

/* PSD projection of the symmetric 3x3 matrices of lanes [0, n), given by their six
 * entries A[0..5] = (a00, a01, a02, a11, a12, a22). With test, a lane that
 * KernelIsPSD3 accepts is left as it is. Otherwise, in closed form: the eigenvalues
 * of B = (A - q I) / p, q = tr(A)/3, are the roots of beta^3 - 3 beta - 2 r,
 * r = det(B)/2 in [-1, 1] (Smith 1961), whose largest, in [1, 2], Newton's method
 * finds from 2 (the cubic is increasing and convex above it: monotone convergence),
 * and the other two from the quadratic left; the eigenvector of the single negative
 * (or single positive) eigenvalue is the cross product of two rows of A - lambda I.
 * Where that eigenvector is ill-determined (eigenvalues within 1e-3 p) the lane is
 * left as it was and decline[k] set: KernelProjectPSD3 (Jacobi) does the work. */
static inline void KernelProjectPSD3Lanes(PetscInt n, PetscBool test, PetscReal A[6][KERNEL_LANES], PetscBool decline[KERNEL_LANES])
{
  /* flags are reals, 1 or 0, and every condition a select, so that the loops take
   * no branch and vectorise */
  const PetscReal tested = test ? 1.0 : 0.0;
  PetscReal       q[KERNEL_LANES], p[KERNEL_LANES], r[KERNEL_LANES], beta[KERNEL_LANES], keep[KERNEL_LANES], done[KERNEL_LANES], no[KERNEL_LANES];

  for (PetscInt k = 0; k < n; k++) {
    const PetscReal a0 = A[0][k], a1 = A[1][k], a2 = A[2][k], a4 = A[3][k], a5 = A[4][k], a8 = A[5][k];
    const PetscReal mm = KernelPSD3Margin(a0, a1, a2, a4, a5, a8), minor = mm >= 0 ? 1.0 : 0.0, psd = tested * minor;
    PetscReal       b0, b1, b2, pp;
    q[k] = (a0 + a4 + a8) / 3;
    b0   = a0 - q[k];
    b1   = a4 - q[k];
    b2   = a8 - q[k];
    p[k] = PetscSqrtReal((b0 * b0 + b1 * b1 + b2 * b2 + 2 * (a1 * a1 + a2 * a2 + a5 * a5)) / 6);
    pp   = p[k] > 0 ? p[k] : 1;
    r[k] = (b0 * (b1 * b2 - a5 * a5) - a1 * (a1 * b2 - a5 * a2) + a2 * (a1 * a5 - b1 * a2)) / (2 * pp * pp * pp);
    r[k] = PetscMin(PetscMax(r[k], -1.0), 1.0);
    {
      const PetscReal qpos = q[k] >= 0 ? 1.0 : 0.0, scalar = p[k] == 0 ? 1.0 : 0.0, sq = scalar * qpos;
      keep[k] = psd > 0 ? 1.0 : sq; /* PSD; or A = q I, q >= 0 */
      done[k] = keep[k] > 0 ? 1.0 : scalar;
    }
    beta[k] = 2;
  }
  for (PetscInt it = 0; it < 60; it++) { /* about 5 iterations; near a double root the halving first, to a gap of 1e-3: 15 */
    PetscBool more = PETSC_FALSE;
    for (PetscInt k = 0; k < n; k++) {
      const PetscReal b = beta[k], d = done[k], f = b * (b * b - 3) - 2 * r[k], fp = 3 * (b * b - 1);
      const PetscReal rising = fp > 0 ? 1.0 : 0.0, den = fp > 0 ? fp : 1.0, step = rising * (f / den), size = PetscAbsReal(step), tol = 1e-13 * b;
      const PetscReal converged = size > tol ? 0.0 : 1.0, moved = b - step, nb = d > 0 ? b : moved, nd = d > 0 ? 1.0 : converged;
      beta[k] = nb;
      done[k] = nd;
    }
    for (PetscInt k = 0; k < n; k++) more = (PetscBool) (more || done[k] == 0);
    if (!more) break;
  }
  for (PetscInt k = 0; k < n; k++) {
    const PetscReal a0 = A[0][k], a1 = A[1][k], a2 = A[2][k], a4 = A[3][k], a5 = A[4][k], a8 = A[5][k];
    const PetscReal disc = PetscSqrtReal(PetscMax(12 - 3 * beta[k] * beta[k], 0.0));
    const PetscReal lmax = q[k] + p[k] * beta[k], lmin = q[k] + p[k] * (-beta[k] - disc) / 2, lmid = 3 * q[k] - lmax - lmin;
    const PetscReal scalar = p[k] == 0 ? 1.0 : 0.0, neg = lmax <= 0 ? 1.0 : 0.0, nonneg = lmin >= 0 ? 1.0 : 0.0;
    const PetscReal zero0 = scalar > 0 ? 1.0 : neg, zero = keep[k] > 0 ? 0.0 : zero0, same0 = zero > 0 ? 0.0 : nonneg, same = keep[k] > 0 ? 1.0 : same0;
    const PetscReal pos = lmid < 0 ? 1.0 : 0.0; /* one negative eigenvalue: remove it; two: keep the positive one */
    const PetscReal lam = pos > 0 ? lmax : lmin, d0 = a0 - lam, d4 = a4 - lam, d8 = a8 - lam;
    /* rows (d0, a1, a2), (a1, d4, a5), (a2, a5, d8): their cross products 0 x 1, 1 x 2, 2 x 0 */
    const PetscReal c00 = a1 * a5 - a2 * d4, c01 = a2 * a1 - d0 * a5, c02 = d0 * d4 - a1 * a1, c10 = d4 * d8 - a5 * a5, c11 = a5 * a2 - a1 * d8, c12 = a1 * a5 - d4 * a2;
    const PetscReal c20 = a5 * a2 - d8 * a1, c21 = d8 * d0 - a2 * a2, c22 = a2 * a1 - a5 * d0;
    const PetscReal n0 = c00 * c00 + c01 * c01 + c02 * c02, n1 = c10 * c10 + c11 * c11 + c12 * c12, n2 = c20 * c20 + c21 * c21 + c22 * c22;
    const PetscReal n01 = n1 > n0 ? n1 : n0, best = n2 > n01 ? n2 : n01, bestp = best > 0 ? best : 1, nv = 1 / PetscSqrtReal(bestp);
    const PetscReal w0 = n1 > n0 ? c10 : c00, w1 = n1 > n0 ? c11 : c01, w2 = n1 > n0 ? c12 : c02;
    const PetscReal v0 = (n2 > n01 ? c20 : w0) * nv, v1 = (n2 > n01 ? c21 : w1) * nv, v2 = (n2 > n01 ? c22 : w2) * nv;
    /* the smallest gap between eigenvalues sets how well they and v are determined
     * (v: to about eps p^3/gap^3): below 1e-3 p, Jacobi */
    const PetscReal gap = PetscMin(lmax - lmid, lmid - lmin), narrow = gap < 1e-3 * p[k] ? 1.0 : 0.0, ill = best == 0 ? 1.0 : narrow;
    const PetscReal w = pos > 0 ? lmax : -lmin, base = pos > 0 ? 0.0 : 1.0, other = 1 - same - zero; /* 1: the eigenvector's update */
    const PetscReal x0 = base * a0 + w * v0 * v0, x1 = base * a1 + w * v0 * v1, x2 = base * a2 + w * v0 * v2, x4 = base * a4 + w * v1 * v1, x5 = base * a5 + w * v1 * v2, x8 = base * a8 + w * v2 * v2;
    const PetscReal upd = other * (1 - ill), y0 = upd > 0 ? x0 : a0, y1 = upd > 0 ? x1 : a1, y2 = upd > 0 ? x2 : a2, y4 = upd > 0 ? x4 : a4, y5 = upd > 0 ? x5 : a5, y8 = upd > 0 ? x8 : a8;
    no[k]   = other * ill;
    A[0][k] = zero > 0 ? 0.0 : y0;
    A[1][k] = zero > 0 ? 0.0 : y1;
    A[2][k] = zero > 0 ? 0.0 : y2;
    A[3][k] = zero > 0 ? 0.0 : y4;
    A[4][k] = zero > 0 ? 0.0 : y5;
    A[5][k] = zero > 0 ? 0.0 : y8;
  }
  for (PetscInt k = 0; k < n; k++) decline[k] = (PetscBool) (no[k] > 0);
}

/* PSD projection of the symmetric 3x3 A (full, row-major) in closed form
 * (KernelProjectPSD3Lanes on one lane, without KernelIsPSD3's test). Returns
 * PETSC_FALSE, A untouched, when the eigenvector is ill-determined (eigenvalues too
 * close); KernelProjectPSD3 (Jacobi) then does the work. Otherwise the result agrees
 * with Jacobi's to 1e-8 max|A_ij| (tests/unit/test_kernels.c; the worst case is a
 * double eigenvalue at zero, resolved to about sqrt(eps)). */
static inline PetscBool KernelProjectPSD3Closed(PetscReal A[9])
{
  PetscReal L[6][KERNEL_LANES];
  PetscBool decline[KERNEL_LANES];

  L[0][0] = A[0], L[1][0] = A[1], L[2][0] = A[2], L[3][0] = A[4], L[4][0] = A[5], L[5][0] = A[8];
  KernelProjectPSD3Lanes(1, PETSC_FALSE, L, decline);
  if (decline[0]) return PETSC_FALSE;
  A[0] = L[0][0], A[1] = A[3] = L[1][0], A[2] = A[6] = L[2][0], A[4] = L[3][0], A[5] = A[7] = L[4][0], A[8] = L[5][0];
  return PETSC_TRUE;
}

/* The stretch edge's Hessian block h (3 x 3): the element's is [[h, -h], [-h, h]]
 * (KernelStretch, the same formula). */
static inline void KernelStretchHessianBlock(const PetscReal *xa, const PetscReal *xb, PetscReal k, PetscReal L, PetscBool project, PetscReal h[9])
{
  const PetscReal e[3] = {xb[0] - xa[0], xb[1] - xa[1], xb[2] - xa[2]};
  const PetscReal l = PetscSqrtReal(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]), u[3] = {e[0] / l, e[1] / l, e[2] / l};
  PetscReal       s = 1 - L / l;

  if (project && s < 0) s = 0;
  for (PetscInt i = 0; i < 3; i++)
    for (PetscInt j = 0; j < 3; j++) h[3 * i + j] = k * ((1 - s) * u[i] * u[j] + (i == j ? s : 0));
}

static inline PetscReal KernelStretch(const PetscReal *xa, const PetscReal *xb, PetscReal k, PetscReal L, PetscReal *g, PetscReal *H, PetscBool project)
{
  PetscReal e[3] = {xb[0] - xa[0], xb[1] - xa[1], xb[2] - xa[2]};
  PetscReal l = PetscSqrtReal(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]), dl = l - L;

  if (g) {
    PetscReal t = k * dl / l;
    for (PetscInt i = 0; i < 3; i++) {
      g[i]     = -t * e[i];
      g[3 + i] = t * e[i];
    }
  }
  if (H) {
    PetscReal hb[9];
    KernelStretchHessianBlock(xa, xb, k, L, project, hb);
    for (PetscInt i = 0; i < 3; i++) {
      for (PetscInt j = 0; j < 3; j++) {
        PetscReal h            = hb[3 * i + j];
        H[6 * i + j]           = h;
        H[6 * (i + 3) + j + 3] = h;
        H[6 * i + j + 3]       = -h;
        H[6 * (i + 3) + j]     = -h;
      }
    }
  }
  return 0.5 * k * dl * dl;
}

/* Gradients only, for the explicit schemes' force loop: the same formulas as
 * KernelStretch/KernelAngle at order 1, arranged for fewest divisions and square
 * roots (one reciprocal 1/(u w) serves 1/u, 1/w and 1/sqrt(u w)). They are checked
 * against the general kernels in tests/unit/test_kernels.c. g = [g_a, g_b(, g_c)]. */
static inline void KernelStretchGradient(const PetscReal *xa, const PetscReal *xb, PetscReal k, PetscReal L, PetscReal g[6])
{
  const PetscReal e0 = xb[0] - xa[0], e1 = xb[1] - xa[1], e2 = xb[2] - xa[2];
  const PetscReal t = k - k * L / PetscSqrtReal(e0 * e0 + e1 * e1 + e2 * e2);

  g[3] = t * e0;
  g[4] = t * e1;
  g[5] = t * e2;
  g[0] = -g[3];
  g[1] = -g[4];
  g[2] = -g[5];
}

/* asin(x) for |x| <= 1 to 2 ulp, in a form the compiler vectorises (no branch, no
 * table): asin(x) = x + x^3 P(x^2) on |x| <= 1/2, and pi/2 - 2 asin(sqrt((1 - |x|)/2))
 * above. P is a degree-11 polynomial fitted to the relative error of asin on
 * [0, 1/2] (Lawson-weighted least squares in 50-digit arithmetic; approximation
 * error 1.5e-17); against glibc's asin: at most 1 ulp below 1/2, 2 ulp above
 * (tests/unit/test_kernels.c). Used by the shear corners of the force loops; the
 * energies keep the C library's asin. */
static inline PetscReal KernelAsin(PetscReal x)
{
  const PetscReal ax  = PetscAbsReal(x);
  const PetscBool big = (PetscBool) (ax > 0.5);
  const PetscReal z = big ? 0.5 * (1 - ax) : x * x, s = big ? PetscSqrtReal(z) : ax;
  PetscReal       u = 0.03190975805482998;

  u = u * z - 0.01622056329858812;
  u = u * z + 0.019525904250609717;
  u = u * z + 0.006528838282604679;
  u = u * z + 0.012169013109334418;
  u = u * z + 0.013885265313232309;
  u = u * z + 0.01735970181594715;
  u = u * z + 0.022371758237395522;
  u = u * z + 0.030381959129763308;
  u = u * z + 0.04464285682847867;
  u = u * z + 0.07500000000336884;
  u = u * z + 0.16666666666665408;
  u = s + s * z * u;
  u = big ? 1.5707963267948966 - 2 * u : u;
  return x < 0 ? -u : u;
}

/* One shear corner from u = |e1|^2, w = |e2|^2, s = e1.e2: its gradient is
 * g_e1 = q w e1 + beta e2, g_e2 = q u e2 + beta e1 (KernelAngleCoefficients' w =
 * [q w, beta, q u]). */
static inline void KernelShearCorner(PetscReal u, PetscReal w, PetscReal s, PetscReal kappa, PetscReal *q, PetscReal *beta)
{
  const PetscReal inv = 1 / (u * w), iP = PetscSqrtReal(u * w) * inv;
  const PetscReal c = PetscMin(PetscMax(s * iP, -1 + 1e-14), 1 - 1e-14), a = KernelAsin(c), g1 = 2 * a / PetscSqrtReal(1 - c * c);

  *q    = kappa * iP * (a * a - g1 * c);
  *beta = kappa * g1;
}

/* A bending triple's rigidity as a function of its curvature (-cloth_bend_table):
 * the moment is M(k) = B b(k) k, a secant rigidity B b(k) as in ARCSim's
 * bending_stiffness (dde.cpp), with b piecewise linear through b[i] at k = i dk,
 * i < n, b[0] = 1, and held at b[n-1] beyond the last sample. The triple's
 * curvature is k = |e1/|e1| + e2/|e2|| / L = 2 sin(beta/2) / L (beta the turning
 * angle, L the rest length of its two segments): the curvature of the circle through
 * its particles to O(beta^2). With q = 1 + cos = (L k)^2 / 2 the energy is
 *   E = kappa G(q),  G(q) = L^2 int_0^k b(t) t dt,  G'(q) = b(k),
 *   G''(q) = b'(k) / (L^2 k),
 * so M = dE/dk / (kappa L^2) = b(k) k: the same forces as ARCSim's, from an energy
 * (exact gradient and Hessian; a table whose moment falls with k makes E
 * non-convex there, and the projected Hessian drops that part). b = 1 gives
 * G(q) = q, the linear triple. */
#define KERNEL_BEND_LAW_MAX 8
typedef struct {
  PetscInt  n;                      /* samples (0: the linear triple)            */
  PetscReal L, dk;                  /* rest length of the segments (m), 1/m       */
  PetscReal b[KERNEL_BEND_LAW_MAX]; /* relative rigidity at k = i dk, b[0] = 1   */
} KernelBendLaw;

/* G(q), G'(q), G''(q) of the law (see KernelBendLaw). */
static inline void KernelBendLawEval(const KernelBendLaw *law, PetscReal q, PetscReal *G, PetscReal *G1, PetscReal *G2)
{
  const PetscReal k   = PetscSqrtReal(2 * PetscMax(q, 0)) / law->L;
  PetscReal       Phi = 0, b = law->b[law->n - 1], db = 0;
  PetscInt        i;

  /* Phi = int_0^k b(t) t dt over whole segments, then the last part */
  for (i = 0; i + 1 < law->n && (i + 1) * law->dk <= k; i++) {
    const PetscReal k0 = i * law->dk, k1 = k0 + law->dk, s = (law->b[i + 1] - law->b[i]) / law->dk, a = law->b[i] - s * k0;
    Phi += a * (k1 * k1 - k0 * k0) / 2 + s * (k1 * k1 * k1 - k0 * k0 * k0) / 3;
  }
  if (i + 1 < law->n) { /* k inside segment i */
    const PetscReal k0 = i * law->dk, s = (law->b[i + 1] - law->b[i]) / law->dk, a = law->b[i] - s * k0;
    Phi += a * (k * k - k0 * k0) / 2 + s * (k * k * k - k0 * k0 * k0) / 3;
    b  = a + s * k;
    db = s;
  } else
    Phi += b * (k * k - PetscSqr((law->n - 1) * law->dk)) / 2; /* beyond the table */
  *G  = law->L * law->L * Phi;
  *G1 = b;
  *G2 = k > 0 ? db / (law->L * law->L * k) : 0.0;
}

/* The angle gradient in two halves, so that a loop can first compute the
 * coefficients w = [2E_u, E_s, 2E_w] of many elements (independent of each other:
 * their square roots, divisions and asin overlap) and then their gradients
 * g_a = 2E_u e1 + E_s e2, g_b = 2E_w e2 + E_s e1, g_c = -(g_a + g_b). law: a
 * bending triple's law (its kappa G'(1 + cos) for kappa), or NULL (linear; shear
 * takes none). */
static inline void KernelAngleCoefficients(PetscBool bend, const PetscReal *restrict xa, const PetscReal *restrict xb, const PetscReal *restrict xc, PetscReal kappa, const KernelBendLaw *law, PetscReal w[3])
{
  const PetscReal e1[3] = {xa[0] - xc[0], xa[1] - xc[1], xa[2] - xc[2]}, e2[3] = {xb[0] - xc[0], xb[1] - xc[1], xb[2] - xc[2]};
  const PetscReal u = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2], v = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
  const PetscReal s = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];

  if (bend) {
    const PetscReal inv = 1 / (u * v), iP = PetscSqrtReal(u * v) * inv, c = s * iP;
    if (law && law->n > 0) { /* kappa G'(1 + c) for kappa */
      PetscReal G, G1, G2;
      KernelBendLawEval(law, 1 + c, &G, &G1, &G2);
      kappa *= G1;
    }
    w[0] = -kappa * c * v * inv;
    w[2] = -kappa * c * u * inv;
    w[1] = kappa * iP;
  } else {
    PetscReal q;
    KernelShearCorner(u, v, s, kappa, &q, &w[1]);
    w[0] = q * v;
    w[2] = q * u;
  }
}

static inline void KernelAngleGradientFromCoefficients(const PetscReal w[3], const PetscReal *restrict xa, const PetscReal *restrict xb, const PetscReal *restrict xc, PetscReal g[9])
{
  for (PetscInt i = 0; i < 3; i++) {
    const PetscReal e1 = xa[i] - xc[i], e2 = xb[i] - xc[i];
    g[i]     = w[0] * e1 + w[1] * e2;
    g[3 + i] = w[2] * e2 + w[1] * e1;
    g[6 + i] = -g[i] - g[3 + i];
  }
}

/* The four shear corners of a lattice cell together (each with rigidity kappa). The
 * cell's particles are x0 = (i,j), x1 = (i+1,j), x2 = (i,j+1), x3 = (i+1,j+1); its
 * edges A = x1 - x0, B = x2 - x0, C = x3 - x2, D = x3 - x1. The corner at x0 has
 * e1 = A, e2 = B; at x1 -A, D; at x2 C, -B; at x3 -D, -C. Each edge is shared by two
 * corners, so the energy's gradient with respect to the edges is
 *   g_A = w0 A + w4 B - w5 D,   g_B = w1 B + w4 A - w6 C,
 *   g_C = w2 C + w7 D - w6 B,   g_D = w3 D - w5 A + w7 C,
 * with w0..w3 the summed length terms of the two corners at each edge and w4..w7
 * the corners' cross terms beta (x0, x1, x2, x3). */
static inline void KernelShearCellCoefficients(const PetscReal *restrict x0, const PetscReal *restrict x1, const PetscReal *restrict x2, const PetscReal *restrict x3, PetscReal kappa, PetscReal w[8])
{
  PetscReal uA = 0, uB = 0, uC = 0, uD = 0, sAB = 0, sAD = 0, sCB = 0, sDC = 0, q[4];

  for (PetscInt i = 0; i < 3; i++) {
    const PetscReal A = x1[i] - x0[i], B = x2[i] - x0[i], C = x3[i] - x2[i], D = x3[i] - x1[i];
    uA += A * A;
    uB += B * B;
    uC += C * C;
    uD += D * D;
    sAB += A * B;
    sAD += A * D;
    sCB += C * B;
    sDC += D * C;
  }
  KernelShearCorner(uA, uB, sAB, kappa, &q[0], &w[4]);
  KernelShearCorner(uA, uD, -sAD, kappa, &q[1], &w[5]);
  KernelShearCorner(uC, uB, -sCB, kappa, &q[2], &w[6]);
  KernelShearCorner(uD, uC, sDC, kappa, &q[3], &w[7]);
  w[0] = q[0] * uB + q[1] * uD;
  w[1] = q[0] * uA + q[2] * uC;
  w[2] = q[3] * uD + q[2] * uB;
  w[3] = q[1] * uA + q[3] * uC;
}

/* The cell's shear gradient g = [g_0, g_1, g_2, g_3] from its coefficients w. */
static inline void KernelShearCellGradient(const PetscReal w[8], const PetscReal *restrict x0, const PetscReal *restrict x1, const PetscReal *restrict x2, const PetscReal *restrict x3, PetscReal g[12])
{
  for (PetscInt i = 0; i < 3; i++) {
    const PetscReal A = x1[i] - x0[i], B = x2[i] - x0[i], C = x3[i] - x2[i], D = x3[i] - x1[i];
    const PetscReal gA = w[0] * A + w[4] * B - w[5] * D, gB = w[1] * B + w[4] * A - w[6] * C;
    const PetscReal gC = w[2] * C + w[7] * D - w[6] * B, gD = w[3] * D - w[5] * A + w[7] * C;
    g[i]     = -gA - gB;
    g[3 + i] = gA - gD;
    g[6 + i] = gB - gC;
    g[9 + i] = gC + gD;
  }
}

/* Shear (bend = PETSC_FALSE) or bending gradient g = [g_a, g_b, g_c]. */
static inline void KernelAngleGradient(PetscBool bend, const PetscReal *xa, const PetscReal *xb, const PetscReal *xc, PetscReal kappa, const KernelBendLaw *law, PetscReal g[9])
{
  PetscReal w[3];

  KernelAngleCoefficients(bend, xa, xb, xc, kappa, law, w);
  KernelAngleGradientFromCoefficients(w, xa, xb, xc, g);
}

/* First and second partials of an angle energy E(u, w, s). */
typedef struct {
  PetscReal E, Eu, Ew, Es, Euu, Eww, Ess, Euw, Eus, Ews;
} KernelAnglePartials;

/* cos = s / sqrt(u w) and its partials. */
typedef struct {
  PetscReal c, cu, cw, cs, cuu, cww, cuw, cus, cws;
} KernelCos;

static inline void KernelCosine(PetscReal u, PetscReal w, PetscReal s, PetscInt order, KernelCos *k)
{
  PetscReal P = PetscSqrtReal(u * w);
  k->c        = s / P;
  if (order < 1) return;
  k->cs = 1 / P;
  k->cu = -k->c / (2 * u);
  k->cw = -k->c / (2 * w);
  if (order < 2) return;
  k->cuu = 3 * k->c / (4 * u * u);
  k->cww = 3 * k->c / (4 * w * w);
  k->cuw = k->c / (4 * u * w);
  k->cus = -1 / (2 * u * P);
  k->cws = -1 / (2 * w * P);
}

/* A shear corner's cosine c = s / sqrt(u w) (as KernelCosine), clamped inside (-1, 1):
 * what its asin is taken of. */
static inline PetscReal KernelShearClamp(PetscReal c) { return PetscMin(PetscMax(c, -1 + 1e-14), 1 - 1e-14); }
static inline PetscReal KernelShearCosine(PetscReal u, PetscReal w, PetscReal s) { return KernelShearClamp(s / PetscSqrtReal(u * w)); }

/* Shear corner: E = kappa sqrt(u w) asin(c)^2, given a = asin(KernelShearCosine(u, w, s)). */
static inline void KernelShearPartialsAt(PetscReal kappa, PetscReal u, PetscReal w, PetscReal s, PetscReal a, PetscInt order, KernelAnglePartials *d)
{
  KernelCos C = {0};
  PetscReal P, r, g, g1 = 0, g2 = 0, Pu, Pw, Puu, Pww, Puw;

  KernelCosine(u, w, s, order, &C);
  C.c  = KernelShearClamp(C.c);
  P    = PetscSqrtReal(u * w);
  g    = a * a;
  d->E = kappa * P * g;
  if (order < 1) return;
  r     = PetscSqrtReal(1 - C.c * C.c);
  g1    = 2 * a / r;
  Pu    = P / (2 * u);
  Pw    = P / (2 * w);
  d->Eu = kappa * (Pu * g + P * g1 * C.cu);
  d->Ew = kappa * (Pw * g + P * g1 * C.cw);
  d->Es = kappa * (P * g1 * C.cs);
  if (order < 2) return;
  g2     = 2 / (r * r) + 2 * a * C.c / (r * r * r);
  Puu    = -P / (4 * u * u);
  Pww    = -P / (4 * w * w);
  Puw    = P / (4 * u * w);
  d->Euu = kappa * (Puu * g + 2 * Pu * g1 * C.cu + P * (g2 * C.cu * C.cu + g1 * C.cuu));
  d->Eww = kappa * (Pww * g + 2 * Pw * g1 * C.cw + P * (g2 * C.cw * C.cw + g1 * C.cww));
  d->Euw = kappa * (Puw * g + Pu * g1 * C.cw + Pw * g1 * C.cu + P * (g2 * C.cu * C.cw + g1 * C.cuw));
  d->Ess = kappa * (P * g2 * C.cs * C.cs);
  d->Eus = kappa * (Pu * g1 * C.cs + P * (g2 * C.cu * C.cs + g1 * C.cus));
  d->Ews = kappa * (Pw * g1 * C.cs + P * (g2 * C.cw * C.cs + g1 * C.cws));
}

/* Shear corner: E = kappa sqrt(u w) asin(c)^2. */
static inline void KernelShearPartials(PetscReal kappa, PetscReal u, PetscReal w, PetscReal s, PetscInt order, KernelAnglePartials *d) { KernelShearPartialsAt(kappa, u, w, s, PetscAsinReal(KernelShearCosine(u, w, s)), order, d); }

/* Bending triple: E = kappa G(1 + c), G(q) = q without a law (law = NULL). */
static inline void KernelBendPartials(PetscReal kappa, const KernelBendLaw *law, PetscReal u, PetscReal w, PetscReal s, PetscInt order, KernelAnglePartials *d)
{
  KernelCos C = {0};
  PetscReal G, G1 = 1, G2 = 0;

  KernelCosine(u, w, s, order, &C);
  if (law && law->n > 0)
    KernelBendLawEval(law, 1 + C.c, &G, &G1, &G2);
  else
    G = 1 + C.c;
  d->E = kappa * G;
  if (order < 1) return;
  d->Eu = kappa * G1 * C.cu;
  d->Ew = kappa * G1 * C.cw;
  d->Es = kappa * G1 * C.cs;
  if (order < 2) return;
  d->Euu = kappa * (G1 * C.cuu + G2 * C.cu * C.cu);
  d->Eww = kappa * (G1 * C.cww + G2 * C.cw * C.cw);
  d->Euw = kappa * (G1 * C.cuw + G2 * C.cu * C.cw);
  d->Ess = kappa * G2 * C.cs * C.cs;
  d->Eus = kappa * (G1 * C.cus + G2 * C.cu * C.cs);
  d->Ews = kappa * (G1 * C.cws + G2 * C.cw * C.cs);
}

/* The inputs of KernelAngleHessian6Lanes: each lane's partials and edges. */
typedef struct {
  PetscReal Eu[KERNEL_LANES], Ew[KERNEL_LANES], Es[KERNEL_LANES];
  PetscReal E2[6][KERNEL_LANES]; /* (Euu, Euw, Eus, Eww, Ews, Ess) */
  PetscReal e1[3][KERNEL_LANES], e2[3][KERNEL_LANES];
} KernelAngleLanes;

/* Lane k's partials from d (its edges are set by whoever fills L). */
static inline void KernelAngleLanesSet(KernelAngleLanes *L, PetscInt k, const KernelAnglePartials *d)
{
  L->Eu[k]    = d->Eu;
  L->Ew[k]    = d->Ew;
  L->Es[k]    = d->Es;
  L->E2[0][k] = d->Euu;
  L->E2[1][k] = d->Euw;
  L->E2[2][k] = d->Eus;
  L->E2[3][k] = d->Eww;
  L->E2[4][k] = d->Ews;
  L->E2[5][k] = d->Ess;
}

/* The angle Hessian with respect to (e1, e2), 6 x 6 (H6[6 i + j][k] for lane k), of
 * lanes [0, n) from their partials: H6 = J^T E2 J + [[2Eu, Es], [Es, 2Ew]] (x) I3,
 * J = [grad u; grad w; grad s] = [[2 e1, 0], [0, 2 e2], [e2, e1]]; with project, each
 * part's negative eigenvalues clamped at 0 (E2 by KernelProjectPSD3Lanes, or Jacobi
 * where it declines; the 2 x 2 in closed form). J's zero entries are left out of the
 * products. The element's 9 x 9 Hessian is H9 = B^T H6 B, B = [[I, 0, -I], [0, I, -I]]:
 * its blocks are h11, h12, -(h11 + h12); h21, h22, -(h21 + h22); -(h11 + h21),
 * -(h12 + h22), h11 + h12 + h21 + h22 with h11, h12, h21, h22 the 3 x 3 blocks of H6
 * (KernelAngle, ClothAssembleMatrix). L's E2 is overwritten by its projection. */
static inline void KernelAngleHessian6Lanes(PetscInt n, KernelAngleLanes *L, PetscBool project, PetscReal H6[36][KERNEL_LANES])
{
  static const PetscInt S[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
  PetscReal             a[KERNEL_LANES], b[KERNEL_LANES], c[KERNEL_LANES];

  for (PetscInt k = 0; k < n; k++) a[k] = 2 * L->Eu[k], b[k] = L->Es[k], c[k] = 2 * L->Ew[k];
  if (project) {
    PetscBool decline[KERNEL_LANES];
    KernelProjectPSD3Lanes(n, PETSC_TRUE, L->E2, decline);
    for (PetscInt k = 0; k < n; k++)
      if (decline[k]) { /* rare: eigenvalues within 1e-3 of their spread */
        PetscReal A[9];
        for (PetscInt i = 0; i < 3; i++)
          for (PetscInt j = 0; j < 3; j++) A[3 * i + j] = L->E2[S[i][j]][k];
        KernelProjectPSD3(A);
        for (PetscInt i = 0; i < 3; i++)
          for (PetscInt j = i; j < 3; j++) L->E2[S[i][j]][k] = A[3 * i + j];
      }
    for (PetscInt k = 0; k < n; k++) { /* [[a, b], [b, c]]: PSD, or its positive eigenvalue's part, or 0 */
      const PetscReal ak = a[k], bk = b[k], ck = c[k], m = 0.5 * (ak + ck), r = PetscSqrtReal(0.25 * (ak - ck) * (ak - ck) + bk * bk), l1 = m + r, l2 = m - r;
      const PetscReal babs = PetscAbsReal(bk), first = ak >= ck ? 1.0 : 0.0, last = 1 - first, l1a = l1 - ak, x = babs > 0 ? bk : first, y = babs > 0 ? l1a : last, nn = x * x + y * y;
      const PetscReal pa = l1 * x * x / nn, pb = l1 * x * y / nn, pc = l1 * y * y / nn, za = l1 <= 0 ? 0.0 : pa, zb = l1 <= 0 ? 0.0 : pb, zc = l1 <= 0 ? 0.0 : pc;
      const PetscReal na = l2 >= 0 ? ak : za, nb = l2 >= 0 ? bk : zb, nc = l2 >= 0 ? ck : zc;
      a[k] = na;
      b[k] = nb;
      c[k] = nc;
    }
  }
  for (PetscInt i = 0; i < 3; i++) {
    PetscReal t[2][3][KERNEL_LANES]; /* rows i and 3 + i of (E2 J)^T */
    for (PetscInt q = 0; q < 3; q++)
      for (PetscInt k = 0; k < n; k++) {
        t[0][q][k] = L->E2[S[q][0]][k] * (2 * L->e1[i][k]) + L->E2[S[q][2]][k] * L->e2[i][k];
        t[1][q][k] = L->E2[S[q][1]][k] * (2 * L->e2[i][k]) + L->E2[S[q][2]][k] * L->e1[i][k];
      }
    for (PetscInt h = 0; h < 2; h++)
      for (PetscInt j = 0; j < 3; j++)
        for (PetscInt k = 0; k < n; k++) {
          H6[6 * (3 * h + i) + j][k]     = t[h][0][k] * (2 * L->e1[j][k]) + t[h][2][k] * L->e2[j][k];
          H6[6 * (3 * h + i) + 3 + j][k] = t[h][1][k] * (2 * L->e2[j][k]) + t[h][2][k] * L->e1[j][k];
        }
  }
  for (PetscInt i = 0; i < 3; i++)
    for (PetscInt k = 0; k < n; k++) {
      H6[6 * i + i][k] += a[k];
      H6[6 * i + 3 + i][k] += b[k];
      H6[6 * (3 + i) + i][k] += b[k];
      H6[6 * (3 + i) + 3 + i][k] += c[k];
    }
}

/* One element's H6 (row-major 6 x 6): KernelAngleHessian6Lanes on one lane. */
static inline void KernelAngleHessian6(const KernelAnglePartials *d, const PetscReal e1[3], const PetscReal e2[3], PetscBool project, PetscReal H6[36])
{
  KernelAngleLanes L;
  PetscReal        H[36][KERNEL_LANES];

  for (PetscInt i = 0; i < 3; i++) L.e1[i][0] = e1[i], L.e2[i][0] = e2[i];
  KernelAngleLanesSet(&L, 0, d);
  KernelAngleHessian6Lanes(1, &L, project, H);
  for (PetscInt i = 0; i < 36; i++) H6[i] = H[i][0];
}

typedef enum {
  KERNEL_SHEAR,
  KERNEL_BEND
} KernelAngleKind;

/* Angle element on particles (a, b, c), c the vertex; x = [x_a, x_b, x_c]; law:
 * a bending triple's law, or NULL (linear; shear takes none). */
static inline PetscReal KernelAngle(KernelAngleKind kind, const PetscReal *xa, const PetscReal *xb, const PetscReal *xc, PetscReal kappa, const KernelBendLaw *law, PetscReal *g, PetscReal *H, PetscBool project)
{
  PetscReal           e1[3] = {xa[0] - xc[0], xa[1] - xc[1], xa[2] - xc[2]}, e2[3] = {xb[0] - xc[0], xb[1] - xc[1], xb[2] - xc[2]};
  PetscReal           u = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2], w = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2];
  PetscReal           s     = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
  PetscInt            order = H ? 2 : (g ? 1 : 0);
  KernelAnglePartials d     = {0};

  if (kind == KERNEL_SHEAR)
    KernelShearPartials(kappa, u, w, s, order, &d);
  else
    KernelBendPartials(kappa, law, u, w, s, order, &d);
  if (g) {
    for (PetscInt i = 0; i < 3; i++) {
      g[i]     = 2 * d.Eu * e1[i] + d.Es * e2[i];
      g[3 + i] = 2 * d.Ew * e2[i] + d.Es * e1[i];
      g[6 + i] = -g[i] - g[3 + i];
    }
  }
  if (H) {
    PetscReal H6[36];
    KernelAngleHessian6(&d, e1, e2, project, H6);
    /* H9 = B^T H6 B with B = [[I, 0, -I], [0, I, -I]] */
    for (PetscInt i = 0; i < 3; i++) {
      for (PetscInt j = 0; j < 3; j++) {
        PetscReal h11 = H6[6 * i + j], h12 = H6[6 * i + 3 + j], h21 = H6[6 * (3 + i) + j], h22 = H6[6 * (3 + i) + 3 + j];
        H[9 * i + j]           = h11;
        H[9 * i + 3 + j]       = h12;
        H[9 * i + 6 + j]       = -(h11 + h12);
        H[9 * (3 + i) + j]     = h21;
        H[9 * (3 + i) + 3 + j] = h22;
        H[9 * (3 + i) + 6 + j] = -(h21 + h22);
        H[9 * (6 + i) + j]     = -(h11 + h21);
        H[9 * (6 + i) + 3 + j] = -(h12 + h22);
        H[9 * (6 + i) + 6 + j] = h11 + h12 + h21 + h22;
      }
    }
  }
  return d.E;
}

/* The partials of the angle elements in L's lanes [0, n), whose edges L->e1, L->e2
 * hold (the element on (a, b; c): e1 = x_a - x_c, e2 = x_b - x_c), coefficients
 * kappa and (bending) laws law (NULL: linear; all NULL: law may be NULL): what
 * KernelAngleHessian6Lanes makes their H6 (KernelAngle's H) from. The bending
 * triples without a law take a loop without a branch (it vectorises); a shear
 * corner's asin is a call. */
static inline void KernelAngleLanesPartials(KernelAngleKind kind, PetscInt n, const PetscReal kappa[KERNEL_LANES], const KernelBendLaw *const *law, KernelAngleLanes *L)
{
  PetscReal u[KERNEL_LANES], w[KERNEL_LANES], s[KERNEL_LANES], a[KERNEL_LANES];

  for (PetscInt k = 0; k < n; k++) {
    u[k] = L->e1[0][k] * L->e1[0][k] + L->e1[1][k] * L->e1[1][k] + L->e1[2][k] * L->e1[2][k];
    w[k] = L->e2[0][k] * L->e2[0][k] + L->e2[1][k] * L->e2[1][k] + L->e2[2][k] * L->e2[2][k];
    s[k] = L->e1[0][k] * L->e2[0][k] + L->e1[1][k] * L->e2[1][k] + L->e1[2][k] * L->e2[2][k];
  }
  if (kind == KERNEL_SHEAR) {
    for (PetscInt k = 0; k < n; k++) a[k] = KernelShearCosine(u[k], w[k], s[k]);
    for (PetscInt k = 0; k < n; k++) a[k] = PetscAsinReal(a[k]); /* a call: the loops around it vectorise */
  }
  for (PetscInt k = 0; k < n; k++) {
    KernelAnglePartials d = {0};

    if (kind == KERNEL_SHEAR)
      KernelShearPartialsAt(kappa[k], u[k], w[k], s[k], a[k], 2, &d);
    else
      KernelBendPartials(kappa[k], law ? law[k] : NULL, u[k], w[k], s[k], 2, &d);
    KernelAngleLanesSet(L, k, &d);
  }
}

/* Bending friction (-cloth_bend_hysteresis). The yarns of a bent fabric slide on
 * each other; KES-F measures the moment this takes per unit width, HB, as half the
 * width 2HB of the bending hysteresis loop (Grosberg's elastic-frictional law,
 * M = B k + HB sign(dk/dt) once the fabric slides). It is regularised as an
 * elastic-perfectly plastic element beside the elastic bending: a spring of
 * stiffness K per unit width in series with a slider that carries at most HB.
 * With a thread triple's signed curvature k = theta / L and the slider's curvature
 * kp (the plastic curvature: a state, updated after every step by
 * KernelFrictionReturn), the triple stores A psi(k - kp), A the area it stands for
 * and psi Huber's function
 *   psi(z) = K z^2 / 2 for |z| <= ky = HB / K,  HB (|z| - ky / 2) beyond,
 * whose derivative, K z clamped to [-HB, HB], is the friction moment. With kp fixed
 * through a step this is backward Euler's incremental potential of the plasticity,
 * and the return mapping after the step is exact. The matrix takes the
 * Gauss-Newton part A psi''(z) grad k grad k^T (PSD): psi'' = K in the stick range
 * with its boundary, 0 beyond it. A triple that slid in the last step starts the
 * next on the boundary (the return mapping leaves it there), so backward Euler's
 * single linearisation sees the spring: should the triple slide on, the step
 * overestimates the friction moment by K times its curvature change (dissipative:
 * a viscosity of K h in curvature rate); should it turn back, the spring unloads as
 * it must. Taking the boundary as sliding instead (moment HB held through the step,
 * no stiffness) pushes a triple that turns back on with the full HB: energy put in,
 * a Cusick drape that never came to rest (measured).
 *
 * theta is the signed turning angle of triple (a, b; vertex c) about the direction
 * of the crossing thread (a0 -> a1), the axis an out-of-plane bend of the thread
 * turns it about: with t1 = x_c - x_a, t2 = x_b - x_c, A = (x_a1 - x_a0)/|x_a1 - x_a0|,
 *   theta = atan2((t1 x t2).A, t1.t2). */
typedef struct {
  PetscReal area; /* A: the area the triple stands for, m^2 */
  PetscReal L;    /* rest length of its segments, m           */
  PetscReal hb;   /* HB, N m/m                                */
  PetscReal K;    /* stick stiffness per unit width, N m      */
} KernelFriction;

/* theta of triple (a, b; c) about the axis a0 -> a1, and its gradient g (15: a, b,
 * c, a0, a1; may be NULL). */
static inline PetscReal KernelTurning(const PetscReal *xa, const PetscReal *xb, const PetscReal *xc, const PetscReal *x0, const PetscReal *x1, PetscReal *g)
{
  const PetscReal t1[3] = {xc[0] - xa[0], xc[1] - xa[1], xc[2] - xa[2]}, t2[3] = {xb[0] - xc[0], xb[1] - xc[1], xb[2] - xc[2]}, d[3] = {x1[0] - x0[0], x1[1] - x0[1], x1[2] - x0[2]};
  const PetscReal ld = PetscSqrtReal(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), A[3] = {d[0] / ld, d[1] / ld, d[2] / ld};
  const PetscReal n[3] = {t1[1] * t2[2] - t1[2] * t2[1], t1[2] * t2[0] - t1[0] * t2[2], t1[0] * t2[1] - t1[1] * t2[0]};
  const PetscReal s = n[0] * A[0] + n[1] * A[1] + n[2] * A[2], co = t1[0] * t2[0] + t1[1] * t2[1] + t1[2] * t2[2], r2 = s * s + co * co;

  if (g) {
    /* d theta = (co ds - s dco) / r2; ds/dt1 = t2 x A, ds/dt2 = A x t1, ds/dd = (n - s A)/|d| */
    const PetscReal t2A[3] = {t2[1] * A[2] - t2[2] * A[1], t2[2] * A[0] - t2[0] * A[2], t2[0] * A[1] - t2[1] * A[0]};
    const PetscReal At1[3] = {A[1] * t1[2] - A[2] * t1[1], A[2] * t1[0] - A[0] * t1[2], A[0] * t1[1] - A[1] * t1[0]};
    const PetscReal ir     = r2 > 0 ? 1 / r2 : 0;
    for (PetscInt i = 0; i < 3; i++) {
      const PetscReal g1 = (co * t2A[i] - s * t2[i]) * ir, g2 = (co * At1[i] - s * t1[i]) * ir, gd = co * (n[i] - s * A[i]) * ir / ld;
      g[i]      = -g1;     /* a  */
      g[3 + i]  = g2;      /* b  */
      g[6 + i]  = g1 - g2; /* c  */
      g[9 + i]  = -gd;     /* a0 */
      g[12 + i] = gd;      /* a1 */
    }
  }
  return PetscAtan2Real(s, co);
}

/* Friction energy A psi(theta/L - kp) of one triple, its gradient g (15) and the
 * Gauss-Newton Hessian H (15 x 15, row-major); g and H may be NULL. */
static inline PetscReal KernelFrictionEnergy(const KernelFriction *f, PetscReal kp, const PetscReal *xa, const PetscReal *xb, const PetscReal *xc, const PetscReal *x0, const PetscReal *x1, PetscReal *g, PetscReal *H)
{
  PetscReal       gt[15];
  const PetscReal k = KernelTurning(xa, xb, xc, x0, x1, (g || H) ? gt : NULL) / f->L, z = k - kp, ky = f->hb / f->K;
  const PetscBool stick = (PetscBool) (PetscAbsReal(z) <= ky * (1 + 1e-9)); /* the boundary: round-off of the return mapping */
  const PetscReal m     = stick ? f->K * z : (z > 0 ? f->hb : -f->hb);

  if (g)
    for (PetscInt i = 0; i < 15; i++) g[i] = f->area * m / f->L * gt[i];
  if (H) {
    const PetscReal c = stick ? f->area * f->K / (f->L * f->L) : 0;
    for (PetscInt i = 0; i < 15; i++)
      for (PetscInt j = i; j < 15; j++) H[15 * i + j] = H[15 * j + i] = c * gt[i] * gt[j]; /* exactly symmetric */
  }
  return f->area * (PetscAbsReal(z) <= ky ? 0.5 * f->K * z * z : f->hb * (PetscAbsReal(z) - 0.5 * ky));
}

/* The return mapping: the plastic curvature after a step that ended at curvature k
 * from plastic curvature kp (the slider moves by what the spring cannot carry). */
static inline PetscReal KernelFrictionReturn(const KernelFriction *f, PetscReal k, PetscReal kp)
{
  const PetscReal ky = f->hb / f->K, z = k - kp;
  return z > ky ? k - ky : (z < -ky ? k + ky : kp);
}

/* ---- Hessian-vector products (the stability estimate, src/cloth/hessian.c) ----
 *
 * y += H z for one element without forming its matrix: the exact Hessian (as
 * KernelStretch/KernelAngle with project = PETSC_FALSE) applied to z = [z_a, z_b(,
 * z_c)] through directional derivatives. For an angle energy E(u, w, s) with
 * d1 = z_a - z_c, d2 = z_b - z_c, du = 2 e1.d1, dw = 2 e2.d2, ds = e1.d2 + e2.d1 and
 * dE_u = E_uu du + E_uw dw + E_us ds (and so on):
 *   h1 = 2 dE_u e1 + dE_s e2 + 2 E_u d1 + E_s d2,  h2 = 2 dE_w e2 + dE_s e1 + 2 E_w d2 + E_s d1,
 * y_a += h1, y_b += h2, y_c -= h1 + h2: about 60 flops besides the partials, where
 * the 9 x 9 matrix and its product take some 400. */
static inline void KernelStretchHessianVector(const PetscReal *xa, const PetscReal *xb, PetscReal k, PetscReal L, const PetscReal *za, const PetscReal *zb, PetscReal *ya, PetscReal *yb)
{
  const PetscReal e[3] = {xb[0] - xa[0], xb[1] - xa[1], xb[2] - xa[2]}, d[3] = {zb[0] - za[0], zb[1] - za[1], zb[2] - za[2]};
  const PetscReal l2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2], il = 1 / PetscSqrtReal(l2);
  const PetscReal s = k * (1 - L * il), t = k * L * il * (e[0] * d[0] + e[1] * d[1] + e[2] * d[2]) / l2; /* H = k (L/l) u u^T + k (1 - L/l) I */

  for (PetscInt i = 0; i < 3; i++) {
    const PetscReal h = t * e[i] + s * d[i];
    yb[i] += h;
    ya[i] -= h;
  }
}

static inline void KernelAngleHessianVector(KernelAngleKind kind, const PetscReal *xa, const PetscReal *xb, const PetscReal *xc, PetscReal kappa, const KernelBendLaw *law, const PetscReal *za, const PetscReal *zb, const PetscReal *zc, PetscReal *ya,
                                            PetscReal *yb, PetscReal *yc)
{
  const PetscReal     e1[3] = {xa[0] - xc[0], xa[1] - xc[1], xa[2] - xc[2]}, e2[3] = {xb[0] - xc[0], xb[1] - xc[1], xb[2] - xc[2]};
  const PetscReal     d1[3] = {za[0] - zc[0], za[1] - zc[1], za[2] - zc[2]}, d2[3] = {zb[0] - zc[0], zb[1] - zc[1], zb[2] - zc[2]};
  const PetscReal     u = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2], w = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2], s = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
  const PetscReal     du = 2 * (e1[0] * d1[0] + e1[1] * d1[1] + e1[2] * d1[2]), dw = 2 * (e2[0] * d2[0] + e2[1] * d2[1] + e2[2] * d2[2]);
  const PetscReal     ds = e1[0] * d2[0] + e1[1] * d2[1] + e1[2] * d2[2] + e2[0] * d1[0] + e2[1] * d1[1] + e2[2] * d1[2];
  KernelAnglePartials p  = {0};
  PetscReal           dEu, dEw, dEs;

  if (kind == KERNEL_SHEAR)
    KernelShearPartials(kappa, u, w, s, 2, &p);
  else
    KernelBendPartials(kappa, law, u, w, s, 2, &p);
  dEu = p.Euu * du + p.Euw * dw + p.Eus * ds;
  dEw = p.Euw * du + p.Eww * dw + p.Ews * ds;
  dEs = p.Eus * du + p.Ews * dw + p.Ess * ds;
  for (PetscInt i = 0; i < 3; i++) {
    const PetscReal h1 = 2 * dEu * e1[i] + dEs * e2[i] + 2 * p.Eu * d1[i] + p.Es * d2[i];
    const PetscReal h2 = 2 * dEw * e2[i] + dEs * e1[i] + 2 * p.Ew * d2[i] + p.Es * d1[i];
    ya[i] += h1;
    yb[i] += h2;
    yc[i] -= h1 + h2;
  }
}
