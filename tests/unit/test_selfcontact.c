static const char help[] = "Unit tests of the self-contact narrow phase (src/selfcontact/proximity.h): closest points of a point\n"
                           "and a triangle and of two segments against brute force, cubic roots, continuous collision times with\n"
                           "known answers, random sweeps checked against a dense sampling of the motion, and the near list's\n"
                           "distances in lanes equal to the bit to the scalar ones in every region and degenerate case.\n";

#include <petscsys.h>
#include <selfcontact/selfcontactimpl.h>

static PetscInt npassed = 0;

#define CHECK(cond, ...)                                                                                                                                                                                                                                 \
  do {                                                                                                                                                                                                                                                   \
    PetscCheck(cond, PETSC_COMM_SELF, PETSC_ERR_PLIB, __VA_ARGS__);                                                                                                                                                                                      \
  } while (0)

/* point-triangle and segment-segment distances against a fine brute-force search */
static PetscErrorCode GroupClosest(PetscRandom rnd)
{
  PetscFunctionBeginUser;
  for (PetscInt cfg = 0; cfg < 200; cfg++) {
    PetscReal x[12], w[3], best = PETSC_MAX_REAL, d, s, u;
    for (PetscInt k = 0; k < 12; k++) PetscCall(PetscRandomGetValueReal(rnd, &x[k]));
    d = PointTriangleClosest(x, x + 3, x + 6, x + 9, w);
    CHECK(w[0] >= -1e-14 && w[1] >= -1e-14 && w[2] >= -1e-14 && PetscAbsReal(w[0] + w[1] + w[2] - 1) < 1e-12, "barycentric weights %g %g %g", (double) w[0], (double) w[1], (double) w[2]);
    for (PetscInt i = 0; i <= 200; i++)
      for (PetscInt j = 0; i + j <= 200; j++) {
        PetscReal a = i / 200.0, b = j / 200.0, q[3];
        for (PetscInt k = 0; k < 3; k++) q[k] = x[k] - ((1 - a - b) * x[3 + k] + a * x[6 + k] + b * x[9 + k]);
        best = PetscMin(best, V3Norm(q));
      }
    CHECK(d <= best + 1e-12 && d >= best - 2e-2, "point-triangle distance %g, brute force %g", (double) d, (double) best);
    best = PETSC_MAX_REAL;
    d    = SegmentSegmentClosest(x, x + 3, x + 6, x + 9, &s, &u);
    for (PetscInt i = 0; i <= 400; i++)
      for (PetscInt j = 0; j <= 400; j++) {
        PetscReal a = i / 400.0, b = j / 400.0, q[3];
        for (PetscInt k = 0; k < 3; k++) q[k] = (x[6 + k] + b * (x[9 + k] - x[6 + k])) - (x[k] + a * (x[3 + k] - x[k]));
        best = PetscMin(best, V3Norm(q));
      }
    CHECK(d <= best + 1e-12 && d >= best - 1e-2, "segment-segment distance %g, brute force %g", (double) d, (double) best);
  }
  { /* parallel overlapping segments: distance is the offset */
    PetscReal a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0.5, 0.1, 0}, d[3] = {2, 0.1, 0}, s, u;
    CHECK(PetscAbsReal(SegmentSegmentClosest(a, b, c, d, &s, &u) - 0.1) < 1e-14, "parallel segments");
  }
  npassed++;
  PetscFunctionReturn(0);
}

/* cubic roots in [0, 1]: (t - r1)(t - r2)(t - r3) with known roots; two roots 1e-9
 * apart (a grazing contact) may be found as one, but the first is found */
static PetscErrorCode GroupCubic(void)
{
  const PetscReal cases[][3] = {{0.1, 0.5, 0.9}, {0.25, 1.5, -2}, {-0.5, 0.75, 0.7501}, {0.3, 0.3 + 1e-9, 2}};
  const PetscInt  expect[]   = {3, 1, 2, 2};

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < 4; k++) {
    const PetscReal *r = cases[k];
    PetscReal        c[4], roots[3];
    PetscInt         n;
    c[3] = 1;
    c[2] = -(r[0] + r[1] + r[2]);
    c[1] = r[0] * r[1] + r[0] * r[2] + r[1] * r[2];
    c[0] = -r[0] * r[1] * r[2];
    n    = CubicRootsUnit(c, roots);
    CHECK(n == expect[k] || (k == 3 && n == 1), "cubic %" PetscInt_FMT ": %" PetscInt_FMT " roots in [0, 1], expected %" PetscInt_FMT, k, n, expect[k]);
    for (PetscInt i = 0; i < n; i++) {
      PetscReal dmin = PETSC_MAX_REAL;
      for (PetscInt j = 0; j < 3; j++) dmin = PetscMin(dmin, PetscAbsReal(roots[i] - r[j]));
      CHECK(dmin < 1e-8, "cubic %" PetscInt_FMT ": root %g is none of the known ones", k, (double) roots[i]);
      CHECK(i == 0 || roots[i] > roots[i - 1], "roots not ascending");
    }
  }
  npassed++;
  PetscFunctionReturn(0);
}

/* A point falling through a still triangle, a triangle swept over a still point, two
 * crossing edges: the collision time is where the motion puts them together. */
static PetscErrorCode GroupKnownCollisions(void)
{
  const PetscReal a0[3] = {0, 0, 0}, b0[3] = {1, 0, 0}, c0[3] = {0, 1, 0}, zero[3] = {0, 0, 0};
  PetscReal       t, w[3], s, u;

  PetscFunctionBeginUser;
  { /* p from z = 0.3 to z = -0.1 over (0.2, 0.3): crosses at t = 0.75 */
    const PetscReal p0[3] = {0.2, 0.3, 0.3}, dp[3] = {0, 0, -0.4};
    CHECK(PointTriangleCollision(p0, dp, a0, zero, b0, zero, c0, zero, 1e-9, &t, w), "falling point missed");
    CHECK(PetscAbsReal(t - 0.75) < 1e-12 && PetscAbsReal(w[1] - 0.2) < 1e-12 && PetscAbsReal(w[2] - 0.3) < 1e-12, "falling point: t = %g, w = %g %g %g", (double) t, (double) w[0], (double) w[1], (double) w[2]);
  }
  { /* the same point passing beside the triangle (x + y > 1): no collision */
    const PetscReal p0[3] = {0.7, 0.6, 0.3}, dp[3] = {0, 0, -0.4};
    CHECK(!PointTriangleCollision(p0, dp, a0, zero, b0, zero, c0, zero, 1e-9, &t, w), "a point beside the triangle collided");
  }
  { /* the triangle rises through a still point at z = 0.5 (reached at t = 0.5) */
    const PetscReal p0[3] = {0.25, 0.25, 0.5}, up[3] = {0, 0, 1};
    CHECK(PointTriangleCollision(p0, zero, a0, up, b0, up, c0, up, 1e-9, &t, w), "rising triangle missed");
    CHECK(PetscAbsReal(t - 0.5) < 1e-12, "rising triangle: t = %g", (double) t);
  }
  { /* a rotating triangle (one vertex moving) sweeps through the point */
    const PetscReal p0[3] = {0.1, 0.1, 0.2}, dc[3] = {0, 0, 2};
    CHECK(PointTriangleCollision(p0, zero, a0, zero, b0, zero, c0, dc, 1e-9, &t, w), "rotating triangle missed");
    /* plane through a, b and c(t) = (0, 1, 2t): z = 2t y; the point is on it when 0.2 = 0.2 t */
    CHECK(PetscAbsReal(t - 1) < 1e-9, "rotating triangle: t = %g", (double) t);
  }
  { /* edge along x at z = 1 falls onto an edge along y at z = 0 over the step: t = 0.5 */
    const PetscReal e0[3] = {-1, 0, 1}, e1[3] = {1, 0, 1}, f0[3] = {0, -1, 0}, f1[3] = {0, 1, 0}, de[3] = {0, 0, -2};
    CHECK(EdgeEdgeCollision(e0, de, e1, de, f0, zero, f1, zero, 1e-9, &t, &s, &u), "crossing edges missed");
    CHECK(PetscAbsReal(t - 0.5) < 1e-12 && PetscAbsReal(s - 0.5) < 1e-12 && PetscAbsReal(u - 0.5) < 1e-12, "crossing edges: t = %g, s = %g, u = %g", (double) t, (double) s, (double) u);
  }
  { /* the same edge shifted beyond the other's end: no collision */
    const PetscReal e0[3] = {-1, 1.5, 1}, e1[3] = {1, 1.5, 1}, f0[3] = {0, -1, 0}, f1[3] = {0, 1, 0}, de[3] = {0, 0, -2};
    CHECK(!EdgeEdgeCollision(e0, de, e1, de, f0, zero, f1, zero, 1e-9, &t, &s, &u), "edges that pass apart collided");
  }
  { /* coplanar motion (a flat sheet sliding in its plane): point entering the triangle in-plane */
    const PetscReal p0[3] = {-0.5, 0.2, 0}, dp[3] = {1, 0, 0};
    CHECK(PointTriangleCollision(p0, dp, a0, zero, b0, zero, c0, zero, 1e-9, &t, w), "in-plane entry missed");
    CHECK(t > 0.4 && t <= 0.625, "in-plane entry at t = %g, expected a sampled time in (0.4, 0.625]", (double) t);
  }
  npassed++;
  PetscFunctionReturn(0);
}

/* Random linear motions: whenever a dense sampling of the step finds the point on
 * the other side of the triangle's plane inside the triangle (a crossing), the
 * continuous test reports a collision no later than the first sampled crossing. */
static PetscErrorCode GroupRandomSweeps(PetscRandom rnd)
{
  PetscInt crossings = 0;

  PetscFunctionBeginUser;
  for (PetscInt cfg = 0; cfg < 2000; cfg++) {
    PetscReal x0[12], dx[12], t, w[3], tfirst = -1, prev = 0;
    for (PetscInt k = 0; k < 12; k++) {
      PetscCall(PetscRandomGetValueReal(rnd, &x0[k]));
      PetscCall(PetscRandomGetValueReal(rnd, &dx[k]));
      dx[k] = 2 * (dx[k] - 0.5);
    }
    for (PetscInt i = 0; i <= 2000 && tfirst < 0; i++) {
      PetscReal tt = i / 2000.0, x[12], n[3], e1[3], e2[3], q[3], side, ww[3];
      for (PetscInt k = 0; k < 12; k++) x[k] = x0[k] + tt * dx[k];
      V3Sub(x + 6, x + 3, e1);
      V3Sub(x + 9, x + 3, e2);
      V3Cross(e1, e2, n);
      V3Sub(x, x + 3, q);
      side = V3Dot(n, q);
      if (i > 0 && (side < 0) != (prev < 0)) {
        /* the sign changed in this interval: a crossing if the point is inside */
        PetscReal dist = PointTriangleClosest(x, x + 3, x + 6, x + 9, ww);
        if (dist < 1e-3 * V3Norm(e1)) tfirst = tt;
      }
      prev = side;
    }
    if (tfirst < 0) continue;
    crossings++;
    CHECK(PointTriangleCollision(x0, dx, x0 + 3, dx + 3, x0 + 6, dx + 6, x0 + 9, dx + 9, 1e-6, &t, w), "random sweep %" PetscInt_FMT ": a crossing at t ~ %g was missed", cfg, (double) tfirst);
    CHECK(t <= tfirst + 1e-3, "random sweep %" PetscInt_FMT ": collision reported at t = %g after the crossing at %g", cfg, (double) t, (double) tfirst);
  }
  CHECK(crossings > 20, "only %" PetscInt_FMT " random sweeps crossed: the test would not see a miss", crossings);
  npassed++;
  PetscFunctionReturn(0);
}

/* The near list's distances in lanes (SelfNearDistances: the instruction set this
 * machine's start-up chose) against PairClosest's, to the bit: points about
 * triangles at every scale (every Voronoi region), degenerate triangles and
 * segments (collinear, a point, two points), parallel and crossing segments;
 * batches of every length 1..8 and their remainders. */
static PetscErrorCode GroupLanes(PetscRandom rnd)
{
  const PetscInt np = 53; /* pairs: six batches and a remainder of 5 */
  PetscReal      X[3 * 4 * 53];
  PetscInt       vert[53], tri[3 * 53], edge[4 * 53], pt[2 * 53], ee[2 * 53];
  PetscReal      dist[53];
  SelfSet        s;

  PetscFunctionBeginUser;
  PetscCall(PetscMemzero(&s, sizeof(s)));
  for (PetscInt k = 0; k < np; k++) {
    vert[k] = 4 * k, tri[3 * k] = 4 * k + 1, tri[3 * k + 1] = 4 * k + 2, tri[3 * k + 2] = 4 * k + 3;
    edge[4 * k] = 4 * k, edge[4 * k + 1] = 4 * k + 1, edge[4 * k + 2] = 4 * k + 2, edge[4 * k + 3] = 4 * k + 3;
    pt[2 * k] = k, pt[2 * k + 1] = k, ee[2 * k] = 2 * k, ee[2 * k + 1] = 2 * k + 1;
  }
  s.mesh.vert = vert, s.mesh.tri = tri, s.mesh.edge = edge, s.mesh.nv = np, s.mesh.nt = np, s.mesh.ne = 2 * np;
  for (PetscInt cfg = 0; cfg < 400; cfg++) {
    for (PetscInt k = 0; k < np; k++) {
      PetscReal *x = X + 12 * k, u, scale;
      PetscCall(PetscRandomGetValueReal(rnd, &u));
      scale = PetscPowReal(10.0, 4 * u - 2); /* the point from 0.01 to 100 triangle sizes away */
      for (PetscInt c = 0; c < 12; c++) {
        PetscCall(PetscRandomGetValueReal(rnd, &u));
        x[c] = (c < 3 ? scale : 1) * (u - 0.5);
      }
      switch ((cfg + k) % 7) { /* degenerate cases */
      case 1:
        for (PetscInt c = 0; c < 3; c++) x[9 + c] = 0.5 * (x[3 + c] + x[6 + c]); /* collinear triangle; segment cd's d on ab's line */
        break;
      case 2:
        for (PetscInt c = 0; c < 3; c++) x[3 + c] = x[c]; /* a point on a vertex; ab of length 0 */
        break;
      case 3:
        for (PetscInt c = 0; c < 3; c++) x[9 + c] = x[6 + c]; /* cd of length 0 */
        break;
      case 4:
        for (PetscInt c = 0; c < 3; c++) x[3 + c] = x[c], x[9 + c] = x[6 + c]; /* two points */
        break;
      case 5:
        for (PetscInt c = 0; c < 3; c++) x[9 + c] = x[6 + c] + 2 * (x[3 + c] - x[c]); /* parallel segments */
        break;
      case 6:
        for (PetscInt c = 0; c < 3; c++) x[c] = (x[3 + c] + x[6 + c] + x[9 + c]) / 3 + 1e-9 * x[c]; /* a point in the triangle */
        break;
      }
    }
    for (PetscInt kind = 0; kind < 2; kind++) {
      const PetscInt n = 1 + (cfg * 7 + kind) % np; /* batches of every length */
      s.pt = pt, s.ee = ee;
      SelfNearDistances(&s, kind, n, X, dist);
      for (PetscInt k = 0; k < n; k++) {
        Pair      pr;
        PetscReal nrm[3], d;
        PairParticles(&s, kind, k, pr.p);
        d = PairClosest(kind, X, &pr, nrm);
        CHECK(d == dist[k], "%s %" PetscInt_FMT " of %" PetscInt_FMT ": lanes %.17g, scalar %.17g", kind ? "edge-edge" : "point-triangle", k, n, (double) dist[k], (double) d);
      }
    }
  }
  npassed++;
  PetscFunctionReturn(0);
}

static PetscErrorCode Run(void)
{
  PetscRandom rnd;

  PetscFunctionBeginUser;
  PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
  PetscCall(PetscRandomSetSeed(rnd, 7));
  PetscCall(PetscRandomSeed(rnd));
  PetscCall(GroupClosest(rnd));
  PetscCall(GroupCubic());
  PetscCall(GroupKnownCollisions());
  PetscCall(GroupRandomSweeps(rnd));
  PetscCall(GroupLanes(rnd));
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
