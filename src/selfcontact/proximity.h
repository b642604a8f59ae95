/* Narrow phase of self-contact: closest points and continuous collision times of
 * a point and a triangle, and of two segments (Ericson, Real-Time Collision
 * Detection, 5.1.5 and 5.1.9; the coplanarity cubic of Provot 1997 and Bridson,
 * Fedkiw & Anderson 2002). Pure functions of coordinates: no particle indices, no
 * partition. Vertices move linearly over the step, x(t) = x0 + t d, t in [0, 1]. */
#pragma once

#include <petscsys.h>

static inline void V3Sub(const PetscReal a[3], const PetscReal b[3], PetscReal c[3])
{
  c[0] = a[0] - b[0];
  c[1] = a[1] - b[1];
  c[2] = a[2] - b[2];
}
static inline PetscReal V3Dot(const PetscReal a[3], const PetscReal b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static inline void      V3Cross(const PetscReal a[3], const PetscReal b[3], PetscReal c[3])
{
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}
static inline PetscReal V3Norm(const PetscReal a[3]) { return PetscSqrtReal(V3Dot(a, a)); }
/* x0 + t d */
static inline void V3At(const PetscReal x0[3], const PetscReal d[3], PetscReal t, PetscReal x[3])
{
  x[0] = x0[0] + t * d[0];
  x[1] = x0[1] + t * d[1];
  x[2] = x0[2] + t * d[2];
}

/* Closest point of triangle (a, b, c) to p, as barycentric weights w (w[0] a + w[1]
 * b + w[2] c); returns the distance. */
static inline PetscReal PointTriangleClosest(const PetscReal p[3], const PetscReal a[3], const PetscReal b[3], const PetscReal c[3], PetscReal w[3])
{
  PetscReal ab[3], ac[3], ap[3], bp[3], cp[3], q[3], d1, d2, d3, d4, d5, d6, va, vb, vc, s, t;

  V3Sub(b, a, ab);
  V3Sub(c, a, ac);
  V3Sub(p, a, ap);
  d1 = V3Dot(ab, ap);
  d2 = V3Dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) { /* vertex a */
    w[0] = 1, w[1] = 0, w[2] = 0;
    goto done;
  }
  V3Sub(p, b, bp);
  d3 = V3Dot(ab, bp);
  d4 = V3Dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) { /* vertex b */
    w[0] = 0, w[1] = 1, w[2] = 0;
    goto done;
  }
  vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) { /* edge ab */
    s    = d1 / (d1 - d3);
    w[0] = 1 - s, w[1] = s, w[2] = 0;
    goto done;
  }
  V3Sub(p, c, cp);
  d5 = V3Dot(ab, cp);
  d6 = V3Dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) { /* vertex c */
    w[0] = 0, w[1] = 0, w[2] = 1;
    goto done;
  }
  vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) { /* edge ac */
    t    = d2 / (d2 - d6);
    w[0] = 1 - t, w[1] = 0, w[2] = t;
    goto done;
  }
  va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) { /* edge bc */
    t    = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    w[0] = 0, w[1] = 1 - t, w[2] = t;
    goto done;
  }
  { /* interior */
    PetscReal den = 1 / (va + vb + vc);
    s             = vb * den;
    t             = vc * den;
    w[0] = 1 - s - t, w[1] = s, w[2] = t;
  }
done:
  for (PetscInt d = 0; d < 3; d++) q[d] = p[d] - (w[0] * a[d] + w[1] * b[d] + w[2] * c[d]);
  return V3Norm(q);
}

/* Closest points a + s (b - a) and c + t (d - c) of segments ab and cd; returns
 * their distance. */
static inline PetscReal SegmentSegmentClosest(const PetscReal a[3], const PetscReal b[3], const PetscReal c[3], const PetscReal d[3], PetscReal *s_, PetscReal *t_)
{
  PetscReal       d1[3], d2[3], r[3], q[3], A, E, F, s, t;
  const PetscReal tiny = 1e-300;

  V3Sub(b, a, d1);
  V3Sub(d, c, d2);
  V3Sub(a, c, r);
  A = V3Dot(d1, d1);
  E = V3Dot(d2, d2);
  F = V3Dot(d2, r);
  if (A <= tiny && E <= tiny)
    s = t = 0;
  else if (A <= tiny) {
    s = 0;
    t = PetscClipInterval(F / E, 0, 1);
  } else {
    PetscReal C = V3Dot(d1, r);
    if (E <= tiny) {
      t = 0;
      s = PetscClipInterval(-C / A, 0, 1);
    } else {
      PetscReal B = V3Dot(d1, d2), den = A * E - B * B;
      s = den > 1e-14 * A * E ? PetscClipInterval((B * F - C * E) / den, 0, 1) : 0; /* parallel: any s */
      t = (B * s + F) / E;
      if (t < 0) {
        t = 0;
        s = PetscClipInterval(-C / A, 0, 1);
      } else if (t > 1) {
        t = 1;
        s = PetscClipInterval((B - C) / A, 0, 1);
      }
    }
  }
  for (PetscInt k = 0; k < 3; k++) q[k] = (c[k] + t * d2[k]) - (a[k] + s * d1[k]);
  *s_ = s;
  *t_ = t;
  return V3Norm(q);
}

/* The two distances above in lanes: SELF_LANES pairs at a time, their coordinates
 * by lane (P[k][d][l]: point k of the pair, direction d, lane l), in loops without a
 * branch that a compiler vectorises (every region's value computed, the region
 * chosen by selects in the order of the branches above). Each lane gives the bits
 * of the scalar function: the same operations on the same values, in the same order
 * (no contraction into fused multiply-adds: ISO C's -ffp-contract=off). */
#define SELF_LANES 8

/* |p - closest point of triangle (a, b, c)|: P[0] = p, P[1..3] = a, b, c. */
static inline void PointTriangleDistanceLanes(int n, const PetscReal P[4][3][SELF_LANES], PetscReal dist[SELF_LANES])
{
  PetscReal       d1[SELF_LANES], d2[SELF_LANES], d3[SELF_LANES], d4[SELF_LANES], d5[SELF_LANES], d6[SELF_LANES], va[SELF_LANES], vb[SELF_LANES], vc[SELF_LANES];
  PetscReal       w0[SELF_LANES], w1[SELF_LANES], w2[SELF_LANES], u[SELF_LANES], v[SELF_LANES];
  const PetscReal zero = 0, one = 1;

  for (int l = 0; l < n; l++) {
    const PetscReal ab[3] = {P[2][0][l] - P[1][0][l], P[2][1][l] - P[1][1][l], P[2][2][l] - P[1][2][l]};
    const PetscReal ac[3] = {P[3][0][l] - P[1][0][l], P[3][1][l] - P[1][1][l], P[3][2][l] - P[1][2][l]};
    const PetscReal ap[3] = {P[0][0][l] - P[1][0][l], P[0][1][l] - P[1][1][l], P[0][2][l] - P[1][2][l]};
    const PetscReal bp[3] = {P[0][0][l] - P[2][0][l], P[0][1][l] - P[2][1][l], P[0][2][l] - P[2][2][l]};
    const PetscReal cp[3] = {P[0][0][l] - P[3][0][l], P[0][1][l] - P[3][1][l], P[0][2][l] - P[3][2][l]};
    d1[l] = V3Dot(ab, ap), d2[l] = V3Dot(ac, ap), d3[l] = V3Dot(ab, bp), d4[l] = V3Dot(ac, bp), d5[l] = V3Dot(ab, cp), d6[l] = V3Dot(ac, cp);
    vc[l] = d1[l] * d4[l] - d3[l] * d2[l];
    vb[l] = d5[l] * d2[l] - d1[l] * d6[l];
    va[l] = d3[l] * d6[l] - d5[l] * d4[l];
  }
  /* the interior, then each region of the branches from the last to the first: the first that holds is chosen */
  for (int l = 0; l < n; l++) {
    const PetscReal den = 1 / (va[l] + vb[l] + vc[l]);
    u[l]                = vb[l] * den;
    v[l]                = vc[l] * den;
    w0[l] = 1 - u[l] - v[l], w1[l] = u[l], w2[l] = v[l];
  }
  for (int l = 0; l < n; l++) { /* edge bc */
    const PetscReal e = d4[l] - d3[l], f = d5[l] - d6[l], t = e / (e + f);
    const int       m = (va[l] <= 0) & (e >= 0) & (f >= 0);
    w0[l]             = m ? zero : w0[l];
    w1[l]             = m ? 1 - t : w1[l];
    w2[l]             = m ? t : w2[l];
  }
  for (int l = 0; l < n; l++) { /* edge ac */
    const PetscReal t = d2[l] / (d2[l] - d6[l]);
    const int       m = (vb[l] <= 0) & (d2[l] >= 0) & (d6[l] <= 0);
    w0[l]             = m ? 1 - t : w0[l];
    w1[l]             = m ? zero : w1[l];
    w2[l]             = m ? t : w2[l];
  }
  for (int l = 0; l < n; l++) { /* vertex c */
    const int m = (d6[l] >= 0) & (d5[l] <= d6[l]);
    w0[l]       = m ? zero : w0[l];
    w1[l]       = m ? zero : w1[l];
    w2[l]       = m ? one : w2[l];
  }
  for (int l = 0; l < n; l++) { /* edge ab */
    const PetscReal t = d1[l] / (d1[l] - d3[l]);
    const int       m = (vc[l] <= 0) & (d1[l] >= 0) & (d3[l] <= 0);
    w0[l]             = m ? 1 - t : w0[l];
    w1[l]             = m ? t : w1[l];
    w2[l]             = m ? zero : w2[l];
  }
  for (int l = 0; l < n; l++) { /* vertex b */
    const int m = (d3[l] >= 0) & (d4[l] <= d3[l]);
    w0[l]       = m ? zero : w0[l];
    w1[l]       = m ? one : w1[l];
    w2[l]       = m ? zero : w2[l];
  }
  for (int l = 0; l < n; l++) { /* vertex a */
    const int m = (d1[l] <= 0) & (d2[l] <= 0);
    w0[l]       = m ? one : w0[l];
    w1[l]       = m ? zero : w1[l];
    w2[l]       = m ? zero : w2[l];
  }
  for (int l = 0; l < n; l++) {
    PetscReal q[3];
    for (int d = 0; d < 3; d++) q[d] = P[0][d][l] - (w0[l] * P[1][d][l] + w1[l] * P[2][d][l] + w2[l] * P[3][d][l]);
    dist[l] = PetscSqrtReal(V3Dot(q, q));
  }
}

/* PetscClipInterval(x, 0, 1) in lanes, one select a statement (what GCC vectorises). */
static inline void ClipUnitLanes(int n, PetscReal x[SELF_LANES])
{
  const PetscReal zero = 0, one = 1;
  for (int l = 0; l < n; l++) {
    const PetscReal a = x[l];
    x[l]              = a < one ? a : one;
  }
  for (int l = 0; l < n; l++) {
    const PetscReal a = x[l];
    x[l]              = zero < a ? a : zero;
  }
}

/* The distance of segments ab and cd: P[0..3] = a, b, c, d. */
static inline void SegmentSegmentDistanceLanes(int n, const PetscReal P[4][3][SELF_LANES], PetscReal dist[SELF_LANES])
{
  PetscReal       A[SELF_LANES], B[SELF_LANES], C[SELF_LANES], E[SELF_LANES], F[SELF_LANES], s[SELF_LANES], t[SELF_LANES], sg[SELF_LANES], tg[SELF_LANES];
  PetscReal       lo[SELF_LANES], hi[SELF_LANES], pt[SELF_LANES];
  const PetscReal tiny = 1e-300, zero = 0, one = 1;

  for (int l = 0; l < n; l++) {
    const PetscReal d1[3] = {P[1][0][l] - P[0][0][l], P[1][1][l] - P[0][1][l], P[1][2][l] - P[0][2][l]};
    const PetscReal d2[3] = {P[3][0][l] - P[2][0][l], P[3][1][l] - P[2][1][l], P[3][2][l] - P[2][2][l]};
    const PetscReal r[3]  = {P[0][0][l] - P[2][0][l], P[0][1][l] - P[2][1][l], P[0][2][l] - P[2][2][l]};
    A[l] = V3Dot(d1, d1), E[l] = V3Dot(d2, d2), F[l] = V3Dot(d2, r), C[l] = V3Dot(d1, r), B[l] = V3Dot(d1, d2);
  }
  /* both long: s from the lines (0 if parallel), t from s; each clipped */
  for (int l = 0; l < n; l++) sg[l] = (B[l] * F[l] - C[l] * E[l]) / (A[l] * E[l] - B[l] * B[l]);
  ClipUnitLanes(n, sg);
  for (int l = 0; l < n; l++) {
    const PetscReal x = sg[l];
    const int       m = A[l] * E[l] - B[l] * B[l] > 1e-14 * A[l] * E[l];
    sg[l]             = m ? x : zero;
  }
  for (int l = 0; l < n; l++) tg[l] = (B[l] * sg[l] + F[l]) / E[l];
  for (int l = 0; l < n; l++) lo[l] = -C[l] / A[l], hi[l] = (B[l] - C[l]) / A[l], pt[l] = F[l] / E[l];
  ClipUnitLanes(n, lo);
  ClipUnitLanes(n, hi);
  ClipUnitLanes(n, pt);
  for (int l = 0; l < n; l++) {
    const PetscReal x = hi[l], y = sg[l];
    s[l] = tg[l] > 1 ? x : y;
  }
  for (int l = 0; l < n; l++) {
    const PetscReal x = lo[l], y = s[l];
    s[l] = tg[l] < 0 ? x : y;
  }
  for (int l = 0; l < n; l++) {
    const PetscReal y = tg[l];
    t[l]              = y > 1 ? one : y;
  }
  for (int l = 0; l < n; l++) {
    const PetscReal y = t[l];
    t[l]              = tg[l] < 0 ? zero : y;
  }
  for (int l = 0; l < n; l++) { /* cd a point (ab not): t = 0, s = lo */
    const PetscReal x = lo[l], y = s[l], z = t[l];
    const int       m = (A[l] > tiny) & (E[l] <= tiny);
    s[l]              = m ? x : y;
    t[l]              = m ? zero : z;
  }
  for (int l = 0; l < n; l++) { /* ab a point: s = 0, t = pt (both points: 0) */
    const PetscReal x = pt[l], y = s[l], z = t[l];
    const int       m = A[l] <= tiny, both = (A[l] <= tiny) & (E[l] <= tiny);
    s[l] = m ? zero : y;
    t[l] = m ? x : z;
    t[l] = both ? zero : t[l];
  }
  for (int l = 0; l < n; l++) {
    PetscReal q[3];
    for (int d = 0; d < 3; d++) {
      const PetscReal d1 = P[1][d][l] - P[0][d][l], d2 = P[3][d][l] - P[2][d][l];
      q[d] = (P[2][d][l] + t[l] * d2) - (P[0][d][l] + s[l] * d1);
    }
    dist[l] = PetscSqrtReal(V3Dot(q, q));
  }
}

/* Coefficients of f(t) = ((e1 + t D1) x (e2 + t D2)) . (q + t Dq), c[0] + c[1] t +
 * c[2] t^2 + c[3] t^3, and a scale of its terms (for "f vanishes identically"). */
static inline PetscReal TripleCubic(const PetscReal e1[3], const PetscReal D1[3], const PetscReal e2[3], const PetscReal D2[3], const PetscReal q[3], const PetscReal Dq[3], PetscReal c[4])
{
  PetscReal n0[3], n1a[3], n1b[3], n1[3], n2[3];

  V3Cross(e1, e2, n0);
  V3Cross(e1, D2, n1a);
  V3Cross(D1, e2, n1b);
  for (PetscInt d = 0; d < 3; d++) n1[d] = n1a[d] + n1b[d];
  V3Cross(D1, D2, n2);
  c[0] = V3Dot(n0, q);
  c[1] = V3Dot(n0, Dq) + V3Dot(n1, q);
  c[2] = V3Dot(n1, Dq) + V3Dot(n2, q);
  c[3] = V3Dot(n2, Dq);
  return (V3Norm(e1) + V3Norm(D1)) * (V3Norm(e2) + V3Norm(D2)) * (V3Norm(q) + V3Norm(Dq));
}

static inline PetscReal CubicEval(const PetscReal c[4], PetscReal t) { return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]; }

/* The roots of the cubic c in [0, 1], ascending (at most 3): the interval is cut at
 * the critical points into pieces where f is monotone, and each piece with a sign
 * change is bisected to round-off. */
static inline PetscInt CubicRootsUnit(const PetscReal c[4], PetscReal roots[3])
{
  PetscReal cut[4] = {0, 1, 1, 1};
  PetscInt  ncut = 1, nroot = 0;
  {
    const PetscReal A = 3 * c[3], B = 2 * c[2], C = c[1]; /* f' = A t^2 + B t + C */
    PetscReal       r[2];
    PetscInt        nr = 0;
    if (A != 0) {
      PetscReal disc = B * B - 4 * A * C;
      if (disc >= 0) {
        PetscReal sq = PetscSqrtReal(disc), qq = -0.5 * (B + (B >= 0 ? sq : -sq));
        r[nr++] = qq / A;
        if (qq != 0) r[nr++] = C / qq;
      }
    } else if (B != 0)
      r[nr++] = -C / B;
    if (nr == 2 && r[0] > r[1]) {
      PetscReal tmp = r[0];
      r[0]          = r[1];
      r[1]          = tmp;
    }
    for (PetscInt k = 0; k < nr; k++)
      if (r[k] > 0 && r[k] < 1) cut[ncut++] = r[k];
    cut[ncut++] = 1;
  }
  for (PetscInt k = 0; k + 1 < ncut; k++) {
    PetscReal lo = cut[k], hi = cut[k + 1], flo = CubicEval(c, lo), fhi = CubicEval(c, hi);
    if (flo == 0) {
      if (nroot == 0 || roots[nroot - 1] < lo) roots[nroot++] = lo;
      continue;
    }
    if (fhi == 0) {
      roots[nroot++] = hi;
      continue;
    }
    if ((flo < 0) == (fhi < 0)) continue;
    for (PetscInt it = 0; it < 80 && hi - lo > 1e-15; it++) {
      PetscReal mid = 0.5 * (lo + hi), fm = CubicEval(c, mid);
      if ((fm < 0) == (flo < 0))
        lo = mid, flo = fm;
      else
        hi = mid;
    }
    roots[nroot++] = 0.5 * (lo + hi);
  }
  return nroot;
}

/* The times to test for a collision: the roots of the coplanarity cubic, or, when
 * the four points stay coplanar the whole step (f vanishes to round-off: a flat sheet
 * moving in its plane), nine times spread over the step. */
static inline PetscInt CollisionTimes(const PetscReal c[4], PetscReal scale, PetscReal times[9])
{
  PetscReal m = PetscMax(PetscMax(PetscAbsReal(c[0]), PetscAbsReal(c[1])), PetscMax(PetscAbsReal(c[2]), PetscAbsReal(c[3])));
  if (m <= 1e-12 * scale) {
    for (PetscInt k = 0; k < 9; k++) times[k] = k / 8.0;
    return 9;
  }
  return CubicRootsUnit(c, times);
}

/* The times at which points a, b, c, d (from x0 by d over the step) may be coplanar:
 * those of the signed volume (b - a) x (c - a) . (d - a), a cubic in t. A point and a
 * triangle, and two edges, can only meet at such a time. */
static inline PetscInt CoplanarTimes(const PetscReal a0[3], const PetscReal da[3], const PetscReal b0[3], const PetscReal db[3], const PetscReal c0[3], const PetscReal dc[3], const PetscReal d0[3], const PetscReal dd[3], PetscReal times[9])
{
  PetscReal e1[3], D1[3], e2[3], D2[3], q[3], Dq[3], c[4], scale;

  V3Sub(b0, a0, e1);
  V3Sub(db, da, D1);
  V3Sub(c0, a0, e2);
  V3Sub(dc, da, D2);
  V3Sub(d0, a0, q);
  V3Sub(dd, da, Dq);
  scale = TripleCubic(e1, D1, e2, D2, q, Dq, c);
  return CollisionTimes(c, scale, times);
}

/* First time t in [0, 1] at which point p comes within tol of triangle (a, b, c),
 * each vertex moving from x0 by d over the step; w: barycentric weights there.
 * Returns PETSC_FALSE when they do not. */
static inline PetscBool PointTriangleCollision(const PetscReal p0[3], const PetscReal dp[3], const PetscReal a0[3], const PetscReal da[3], const PetscReal b0[3], const PetscReal db[3], const PetscReal c0[3], const PetscReal dc[3], PetscReal tol,
                                               PetscReal *t, PetscReal w[3])
{
  PetscReal times[9];
  PetscInt  n = CoplanarTimes(a0, da, b0, db, c0, dc, p0, dp, times);

  for (PetscInt k = 0; k < n; k++) {
    PetscReal p[3], a[3], b[3], cc[3];
    V3At(p0, dp, times[k], p);
    V3At(a0, da, times[k], a);
    V3At(b0, db, times[k], b);
    V3At(c0, dc, times[k], cc);
    if (PointTriangleClosest(p, a, b, cc, w) <= tol) {
      *t = times[k];
      return PETSC_TRUE;
    }
  }
  return PETSC_FALSE;
}

/* First time t in [0, 1] at which segments ab and cd come within tol, each vertex
 * moving from x0 by d; s, u: the closest points' parameters there. */
static inline PetscBool EdgeEdgeCollision(const PetscReal a0[3], const PetscReal da[3], const PetscReal b0[3], const PetscReal db[3], const PetscReal c0[3], const PetscReal dc[3], const PetscReal d0[3], const PetscReal dd[3], PetscReal tol,
                                          PetscReal *t, PetscReal *s, PetscReal *u)
{
  PetscReal times[9];
  PetscInt  n = CoplanarTimes(a0, da, b0, db, c0, dc, d0, dd, times);

  for (PetscInt k = 0; k < n; k++) {
    PetscReal a[3], b[3], cc[3], d[3];
    V3At(a0, da, times[k], a);
    V3At(b0, db, times[k], b);
    V3At(c0, dc, times[k], cc);
    V3At(d0, dd, times[k], d);
    if (SegmentSegmentClosest(a, b, cc, d, s, u) <= tol) {
      *t = times[k];
      return PETSC_TRUE;
    }
  }
  return PETSC_FALSE;
}
