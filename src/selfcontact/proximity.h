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
