static const char help[] = "Unit tests of the self-contact broad phases (src/selfcontact/): CGAL's box intersection, the\n"
                           "uniform spatial hash and the hash of the lattice's tiles find exactly the pairs a brute-force test of\n"
                           "every pair of boxes finds, in the same order, on folded, crumpled and partly exploded lattices, and\n"
                           "with the particles numbered in any order (a rank's own particles, then its halo).\n";

#include <petscsys.h>
#include <selfcontact/selfcontactimpl.h>

static PetscInt npassed = 0;

#define CHECK(cond, ...)                                                                                                                                                                                                                                 \
  do {                                                                                                                                                                                                                                                   \
    PetscCheck(cond, PETSC_COMM_SELF, PETSC_ERR_PLIB, __VA_ARGS__);                                                                                                                                                                                      \
  } while (0)

/* The surface of a full n x n lattice as src/selfcontact/selfcontact.c builds it: two
 * triangles per cell split along (i,j)-(i+1,j+1); warp, weft and diagonal edges. */
static PetscErrorCode LatticeMesh(PetscInt n, SelfMesh *m)
{
  PetscInt t = 0, e = 0;

  PetscFunctionBeginUser;
  m->nv = n * n;
  m->nt = 2 * (n - 1) * (n - 1);
  m->ne = 2 * n * (n - 1) + (n - 1) * (n - 1);
  PetscCall(PetscMalloc3(m->nv, &m->vert, 3 * m->nt, &m->tri, 2 * m->ne, &m->edge));
  for (PetscInt p = 0; p < m->nv; p++) m->vert[p] = p;
  for (PetscInt j = 0; j < n; j++)
    for (PetscInt i = 0; i < n; i++) {
      const PetscInt a = j * n + i;
      if (i + 1 < n) m->edge[2 * e] = a, m->edge[2 * e + 1] = a + 1, e++;
      if (j + 1 < n) m->edge[2 * e] = a, m->edge[2 * e + 1] = a + n, e++;
      if (i + 1 < n && j + 1 < n) {
        const PetscInt T[6] = {a, a + 1, a + n + 1, a, a + n + 1, a + n};
        m->edge[2 * e] = a, m->edge[2 * e + 1] = a + n + 1, e++;
        for (PetscInt k = 0; k < 6; k++) m->tri[3 * t + k] = T[k];
        t += 2;
      }
    }
  PetscFunctionReturn(0);
}

static void Box(const PetscInt *p, PetscInt np, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscReal lo[3], PetscReal hi[3])
{
  for (PetscInt d = 0; d < 3; d++) lo[d] = PETSC_MAX_REAL, hi[d] = -PETSC_MAX_REAL;
  for (PetscInt v = 0; v < np; v++)
    for (PetscInt d = 0; d < 3; d++) {
      lo[d] = PetscMin(lo[d], PetscMin(x0[3 * p[v] + d], x1[3 * p[v] + d]));
      hi[d] = PetscMax(hi[d], PetscMax(x0[3 * p[v] + d], x1[3 * p[v] + d]));
    }
  for (PetscInt d = 0; d < 3; d++) lo[d] -= r, hi[d] += r;
}

static PetscBool Overlap(const PetscReal alo[3], const PetscReal ahi[3], const PetscReal blo[3], const PetscReal bhi[3])
{
  for (PetscInt d = 0; d < 3; d++)
    if (alo[d] > bhi[d] || blo[d] > ahi[d]) return PETSC_FALSE;
  return PETSC_TRUE;
}

static PetscBool Share(const PetscInt *a, PetscInt na, const PetscInt *b, PetscInt nb)
{
  for (PetscInt i = 0; i < na; i++)
    for (PetscInt j = 0; j < nb; j++)
      if (a[i] == b[j]) return PETSC_TRUE;
  return PETSC_FALSE;
}

/* every pair of boxes, in lexicographic order: what both broad phases must return */
static PetscErrorCode BruteForce(const SelfMesh *m, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscInt *npt, PetscInt **pt, PetscInt *nee, PetscInt **ee)
{
  PetscReal *lo, *hi;
  PetscInt   n = 0, cap = 1024;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc2(3 * (m->nt + m->ne), &lo, 3 * (m->nt + m->ne), &hi));
  for (PetscInt t = 0; t < m->nt; t++) Box(m->tri + 3 * t, 3, x0, x1, r, lo + 3 * t, hi + 3 * t);
  PetscCall(PetscMalloc1(2 * cap, pt));
  for (PetscInt v = 0; v < m->nv; v++) {
    PetscReal vlo[3], vhi[3];
    Box(&m->vert[v], 1, x0, x1, r, vlo, vhi);
    for (PetscInt t = 0; t < m->nt; t++) {
      if (Share(&m->vert[v], 1, m->tri + 3 * t, 3) || !Overlap(vlo, vhi, lo + 3 * t, hi + 3 * t)) continue;
      if (n == cap) PetscCall(PetscRealloc(2 * (cap *= 2) * sizeof(PetscInt), pt));
      (*pt)[2 * n] = v, (*pt)[2 * n + 1] = t, n++;
    }
  }
  *npt = n;
  n = 0, cap = 1024;
  for (PetscInt e = 0; e < m->ne; e++) Box(m->edge + 2 * e, 2, x0, x1, r, lo + 3 * e, hi + 3 * e);
  PetscCall(PetscMalloc1(2 * cap, ee));
  for (PetscInt a = 0; a < m->ne; a++)
    for (PetscInt b = a + 1; b < m->ne; b++) {
      if (Share(m->edge + 2 * a, 2, m->edge + 2 * b, 2) || !Overlap(lo + 3 * a, hi + 3 * a, lo + 3 * b, hi + 3 * b)) continue;
      if (n == cap) PetscCall(PetscRealloc(2 * (cap *= 2) * sizeof(PetscInt), ee));
      (*ee)[2 * n] = a, (*ee)[2 * n + 1] = b, n++;
    }
  *nee = n;
  PetscCall(PetscFree2(lo, hi));
  PetscFunctionReturn(0);
}

/* An n x n sheet of spacing s, folded over at its middle row into two layers `gap`
 * apart (a hairpin), crumpled by random offsets of `noise` spacings, and moved
 * over the step by random displacements of `move` spacings; `fly` particles get a
 * displacement of `far` spacings (long sweeps). */
static void Sheet(PetscRandom rnd, PetscInt n, PetscReal s, PetscReal gap, PetscReal noise, PetscReal move, PetscInt fly, PetscReal far, PetscReal *x0, PetscReal *x1)
{
  for (PetscInt j = 0; j < n; j++)
    for (PetscInt i = 0; i < n; i++) {
      const PetscInt p    = j * n + i;
      const PetscInt jj   = j < n / 2 ? j : n - 1 - j;
      PetscReal      u[6] = {0, 0, 0, 0, 0, 0};
      for (PetscInt k = 0; k < 6; k++) PetscRandomGetValueReal(rnd, &u[k]);
      x0[3 * p]     = i * s + noise * s * (u[0] - 0.5);
      x0[3 * p + 1] = jj * s + noise * s * (u[1] - 0.5);
      x0[3 * p + 2] = (j < n / 2 ? 0 : gap) + noise * s * (u[2] - 0.5);
      for (PetscInt d = 0; d < 3; d++) x1[3 * p + d] = x0[3 * p + d] + move * s * (u[3 + d] - 0.5);
      if (p % (n * n / PetscMax(fly, 1) + 1) == 0 && fly)
        for (PetscInt d = 0; d < 3; d++) x1[3 * p + d] += far * s * (u[3 + d] - 0.5);
    }
}

static PetscErrorCode Same(const char *what, PetscInt na, const PetscInt *a, PetscInt nb, const PetscInt *b)
{
  PetscFunctionBeginUser;
  CHECK(na == nb, "%s: %" PetscInt_FMT " pairs against %" PetscInt_FMT, what, na, nb);
  for (PetscInt k = 0; k < 2 * na; k++) CHECK(a[k] == b[k], "%s: pair %" PetscInt_FMT " differs", what, k / 2);
  PetscFunctionReturn(0);
}

/* both broad phases against brute force on small lattices, then against each other
 * on a large one */
static PetscErrorCode GroupAgainstBruteForce(PetscRandom rnd)
{
  const struct {
    PetscInt  n;
    PetscReal gap, noise, move, far;
    PetscInt  fly;
  } cases[] = {
    {16, 0.3, 0, 0.1, 0, 0},     /* two flat layers, a thickness apart                */
    {16, 0.25, 0.8, 0.4, 0, 0},  /* crumpled layers, large steps                      */
    {21, 0.2, 2.0, 1.0, 0, 0},   /* a tangle: every neighbourhood overlaps            */
    {16, 0.3, 0.3, 0.2, 12, 20}, /* a few particles swept across the sheet (the cell size doubles) */
  };
  const PetscReal s = 0.01, r = 1.5 * 0.25 * s;

  PetscFunctionBeginUser;
  for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); c++) {
    SelfMesh   m;
    PetscReal *x0, *x1;
    PetscReal *y0, *y1;
    PetscInt   n[5][2], *pairs[5][2], *nat, *perm, *inv, N;
    PetscCall(LatticeMesh(cases[c].n, &m));
    N = m.nv;
    PetscCall(PetscMalloc2(3 * N, &x0, 3 * N, &x1));
    Sheet(rnd, cases[c].n, s, cases[c].gap * s, cases[c].noise, cases[c].move, cases[c].fly, cases[c].far, x0, x1);
    PetscCall(BruteForce(&m, x0, x1, r, &n[0][0], &pairs[0][0], &n[0][1], &pairs[0][1]));
    PetscCall(SelfBroadPhase(&m, x0, x1, r, &n[1][0], &pairs[1][0], &n[1][1], &pairs[1][1]));
    PetscCall(SelfBroadPhaseHash(&m, x0, x1, r, &n[2][0], &pairs[2][0], &n[2][1], &pairs[2][1]));
    PetscCall(PetscMalloc5(N, &nat, N, &perm, N, &inv, 3 * N, &y0, 3 * N, &y1));
    for (PetscInt p = 0; p < N; p++) nat[p] = p;
    PetscCall(SelfBroadPhaseTiles(&m, nat, cases[c].n, x0, x1, r, &n[3][0], &pairs[3][0], &n[3][1], &pairs[3][1]));
    /* the same sheet with its particles numbered at random: a primitive's tile comes
     * from its first particle's natural index, not from its number */
    for (PetscInt p = 0; p < N; p++) perm[p] = p;
    for (PetscInt p = N - 1; p > 0; p--) {
      PetscReal u;
      PetscInt  q, t;
      PetscCall(PetscRandomGetValueReal(rnd, &u));
      q = (PetscInt) (u * (p + 1)) % (p + 1), t = perm[p], perm[p] = perm[q], perm[q] = t;
    }
    for (PetscInt p = 0; p < N; p++) {
      inv[perm[p]] = p, nat[perm[p]] = p;
      for (PetscInt d = 0; d < 3; d++) y0[3 * perm[p] + d] = x0[3 * p + d], y1[3 * perm[p] + d] = x1[3 * p + d];
    }
    for (PetscInt k = 0; k < m.nv; k++) m.vert[k] = perm[m.vert[k]];
    for (PetscInt k = 0; k < 3 * m.nt; k++) m.tri[k] = perm[m.tri[k]];
    for (PetscInt k = 0; k < 2 * m.ne; k++) m.edge[k] = perm[m.edge[k]];
    PetscCall(SelfBroadPhaseTiles(&m, nat, cases[c].n, y0, y1, r, &n[4][0], &pairs[4][0], &n[4][1], &pairs[4][1]));
    CHECK(n[0][0] > m.nv && n[0][1] > m.ne, "case %zu: too few pairs to test (%" PetscInt_FMT ", %" PetscInt_FMT ")", c, n[0][0], n[0][1]);
    PetscCall(Same("CGAL point-triangle", n[1][0], pairs[1][0], n[0][0], pairs[0][0]));
    PetscCall(Same("CGAL edge-edge", n[1][1], pairs[1][1], n[0][1], pairs[0][1]));
    PetscCall(Same("hash point-triangle", n[2][0], pairs[2][0], n[0][0], pairs[0][0]));
    PetscCall(Same("hash edge-edge", n[2][1], pairs[2][1], n[0][1], pairs[0][1]));
    PetscCall(Same("tiles point-triangle", n[3][0], pairs[3][0], n[0][0], pairs[0][0]));
    PetscCall(Same("tiles edge-edge", n[3][1], pairs[3][1], n[0][1], pairs[0][1]));
    PetscCall(Same("tiles point-triangle, numbered at random", n[4][0], pairs[4][0], n[0][0], pairs[0][0]));
    PetscCall(Same("tiles edge-edge, numbered at random", n[4][1], pairs[4][1], n[0][1], pairs[0][1]));
    for (PetscInt i = 0; i < 5; i++) {
      PetscCall(PetscFree(pairs[i][0]));
      PetscCall(PetscFree(pairs[i][1]));
    }
    PetscCall(PetscFree5(nat, perm, inv, y0, y1));
    PetscCall(PetscFree2(x0, x1));
    PetscCall(PetscFree3(m.vert, m.tri, m.edge));
  }
  npassed++;
  { /* 121 x 121, folded and moving: the two agree */
    SelfMesh   m;
    PetscReal *x0, *x1;
    PetscInt   n[3][2], *pairs[3][2], *nat;
    PetscCall(LatticeMesh(121, &m));
    PetscCall(PetscMalloc3(3 * m.nv, &x0, 3 * m.nv, &x1, m.nv, &nat));
    for (PetscInt p = 0; p < m.nv; p++) nat[p] = p;
    Sheet(rnd, 121, s, 0.3 * s, 0.2, 0.2, 40, 10, x0, x1);
    PetscCall(SelfBroadPhase(&m, x0, x1, r, &n[0][0], &pairs[0][0], &n[0][1], &pairs[0][1]));
    PetscCall(SelfBroadPhaseHash(&m, x0, x1, r, &n[1][0], &pairs[1][0], &n[1][1], &pairs[1][1]));
    PetscCall(SelfBroadPhaseTiles(&m, nat, 121, x0, x1, r, &n[2][0], &pairs[2][0], &n[2][1], &pairs[2][1]));
    CHECK(n[0][0] > m.nv / 2 && n[0][1] > m.ne / 2, "121^2: too few pairs to test (%" PetscInt_FMT ", %" PetscInt_FMT ")", n[0][0], n[0][1]);
    PetscCall(Same("121^2 point-triangle", n[1][0], pairs[1][0], n[0][0], pairs[0][0]));
    PetscCall(Same("121^2 edge-edge", n[1][1], pairs[1][1], n[0][1], pairs[0][1]));
    PetscCall(Same("121^2 point-triangle, tiles", n[2][0], pairs[2][0], n[0][0], pairs[0][0]));
    PetscCall(Same("121^2 edge-edge, tiles", n[2][1], pairs[2][1], n[0][1], pairs[0][1]));
    for (PetscInt i = 0; i < 3; i++) {
      PetscCall(PetscFree(pairs[i][0]));
      PetscCall(PetscFree(pairs[i][1]));
    }
    PetscCall(PetscFree3(x0, x1, nat));
    PetscCall(PetscFree3(m.vert, m.tri, m.edge));
  }
  npassed++;
  PetscFunctionReturn(0);
}

static PetscErrorCode Run(void)
{
  PetscRandom rnd;

  PetscFunctionBeginUser;
  PetscCall(PetscRandomCreate(PETSC_COMM_SELF, &rnd));
  PetscCall(PetscRandomSetSeed(rnd, 11));
  PetscCall(PetscRandomSeed(rnd));
  PetscCall(GroupAgainstBruteForce(rnd));
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
