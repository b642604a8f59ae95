/* Broad phase of self-contact by a uniform spatial hash (Teschner et al. 2003): the
 * same candidate pairs as CGAL's box intersection (broadphase.cxx), in time linear
 * in the boxes and the pairs found.
 *
 * The boxes of the triangles (or edges) are entered in every cell of a uniform grid
 * they overlap, the cells hashed into a table of buckets stored as one sorted array
 * (a counting sort: no allocation per cell). A vertex (or an edge) looks in the cells
 * its box overlaps; a pair whose boxes overlap is reported from one cell only, the
 * one that holds the lower corner of the boxes' intersection, so no pair is found
 * twice. The cell size is the mean extent of the entered boxes, doubled while the
 * boxes would take more than 8 cells each on average (a few long sweeps). */
#include "selfcontactimpl.h"
#include <stdint.h> /* INT64_MAX */

typedef struct {
  PetscReal lo[3], hi[3];
} SelfBox;

typedef struct {
  PetscReal           inv;     /* 1 / cell size                                        */
  PetscInt64          mask;    /* buckets - 1 (a power of two)                         */
  PetscInt64          base[3]; /* the lowest cell of the entered boxes                 */
  PetscInt           *start;   /* entries of bucket b: start[b] .. start[b + 1] - 1     */
  PetscInt           *item;    /* the box of each entry                                 */
  unsigned long long *key;     /* its cell (CellKey)                                    */
} SelfGrid;

/* A cell's key: its coordinates from the grid's base, KEY_BITS bits each (GridCreate
 * makes the cells large enough), and KEY_NONE for a cell outside that range, where
 * no box was entered. */
#define KEY_BITS 21
#define KEY_NONE (~0ULL)

static void MakeBoxes(PetscInt n, PetscInt nv, const PetscInt *prim, const PetscReal *x0, const PetscReal *x1, PetscReal r, SelfBox *b)
{
  for (PetscInt k = 0; k < n; k++) {
    for (PetscInt d = 0; d < 3; d++) b[k].lo[d] = PETSC_MAX_REAL, b[k].hi[d] = -PETSC_MAX_REAL;
    for (PetscInt v = 0; v < nv; v++) {
      const PetscInt p = prim[nv * k + v];
      for (PetscInt d = 0; d < 3; d++) {
        b[k].lo[d] = PetscMin(b[k].lo[d], PetscMin(x0[3 * p + d], x1[3 * p + d]));
        b[k].hi[d] = PetscMax(b[k].hi[d], PetscMax(x0[3 * p + d], x1[3 * p + d]));
      }
    }
    for (PetscInt d = 0; d < 3; d++) b[k].lo[d] -= r, b[k].hi[d] += r;
  }
}

/* floor(x / cell size) without a call to floor (x86-64's baseline has no rounding
 * instruction): exact for |x / cell| < 2^52, which GridCreate checks first */
static inline PetscInt64 CellOf(const SelfGrid *g, PetscReal x)
{
  const PetscReal  v = x * g->inv;
  const PetscInt64 i = (PetscInt64) v;
  return i - (PetscInt64) (v < (PetscReal) i);
}

/* The low LOCAL_BITS bits of x spread to every third bit (Morton order). */
#define LOCAL_BITS 7
static inline unsigned long long Spread3(unsigned long long x)
{
  x &= (1ULL << LOCAL_BITS) - 1; /* at most 10 bits: */
  x = (x | x << 16) & 0x030000FFULL;
  x = (x | x << 8) & 0x0300F00FULL;
  x = (x | x << 4) & 0x030C30C3ULL;
  return (x | x << 2) & 0x09249249ULL;
}

/* A cell's bucket: the cells of each block of 2^LOCAL_BITS cells a side in Morton
 * order, the block's offset hashed (Teschner et al.'s primes) and xor-ed onto it, so
 * that neighbouring cells share aligned runs of buckets (the queries, in lattice
 * order, then walk the table nearly in order) while cells of different blocks
 * spread over the whole table. Any map of cells to buckets gives the same pairs
 * (a bucket's entries are checked against the cell). */
static inline PetscInt64 Bucket(const SelfGrid *g, PetscInt64 i, PetscInt64 j, PetscInt64 k)
{
  const unsigned long long u = (unsigned long long) i, v = (unsigned long long) j, w = (unsigned long long) k;
  const unsigned long long morton = Spread3(u) | Spread3(v) << 1 | Spread3(w) << 2;
  const unsigned long long block  = ((u >> LOCAL_BITS) * 73856093ULL) ^ ((v >> LOCAL_BITS) * 19349663ULL) ^ ((w >> LOCAL_BITS) * 83492791ULL);
  return (PetscInt64) ((morton ^ ((block * 0x9E3779B97F4A7C15ULL) >> 24)) & (unsigned long long) g->mask);
}

static inline unsigned long long CellKey(const SelfGrid *g, const PetscInt64 c[3])
{
  unsigned long long key = 0;
  for (PetscInt d = 0; d < 3; d++) {
    const PetscInt64 o = c[d] - g->base[d];
    if (o < 0 || o >= (1LL << KEY_BITS)) return KEY_NONE;
    key = key << KEY_BITS | (unsigned long long) o;
  }
  return key;
}

/* (without a branch: whether two boxes overlap is a coin's toss in the tiles' loops) */
static inline PetscBool Overlap(const SelfBox *a, const SelfBox *b)
{
  int apart = 0;
  for (PetscInt d = 0; d < 3; d++) apart |= (a->lo[d] > b->hi[d]) | (b->lo[d] > a->hi[d]);
  return (PetscBool) !apart;
}

/* Is (i, j, k) the cell of the lower corner of the intersection of a and b? */
static inline PetscBool FirstCell(const SelfGrid *g, const SelfBox *a, const SelfBox *b, const PetscInt64 c[3])
{
  for (PetscInt d = 0; d < 3; d++)
    if (CellOf(g, PetscMax(a->lo[d], b->lo[d])) != c[d]) return PETSC_FALSE;
  return PETSC_TRUE;
}

/* the number of cells box b overlaps (real: no overflow for a box much larger than a cell) */
static PetscReal CellsOf(const SelfGrid *g, const SelfBox *b)
{
  PetscReal n = 1;
  for (PetscInt d = 0; d < 3; d++) n *= PetscFloorReal(b->hi[d] * g->inv) - PetscFloorReal(b->lo[d] * g->inv) + 1;
  return n;
}

#define FOR_CELLS(g, b, c)                                                                                                                                                                                                                               \
  for (c[0] = CellOf(g, (b)->lo[0]); c[0] <= CellOf(g, (b)->hi[0]); c[0]++)                                                                                                                                                                              \
    for (c[1] = CellOf(g, (b)->lo[1]); c[1] <= CellOf(g, (b)->hi[1]); c[1]++)                                                                                                                                                                            \
      for (c[2] = CellOf(g, (b)->lo[2]); c[2] <= CellOf(g, (b)->hi[2]); c[2]++)

static PetscErrorCode GridCreate(PetscInt n, const SelfBox *b, SelfGrid *g)
{
  PetscReal  ext = 0, far = 0, cells;
  PetscInt64 nent, nb     = 1;
  PetscInt  *fill;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < n; k++)
    for (PetscInt d = 0; d < 3; d++) {
      ext += (b[k].hi[d] - b[k].lo[d]) / (3 * (PetscReal) PetscMax(n, 1));
      far = PetscMax(far, PetscMax(PetscAbsReal(b[k].lo[d]), PetscAbsReal(b[k].hi[d])));
    }
  g->inv = ext > 0 ? 1 / ext : 1;
  /* cell coordinates are 64-bit integers (exact in a double below 2^52) */
  PetscCheck(far * g->inv < 4503599627370496.0, PETSC_COMM_SELF, PETSC_ERR_FP, "Self-contact: a particle is %g m from the origin, %g times the size of the particles' boxes (the step diverged); reduce -ts_dt or use -ts_type drapebe", (double) far,
             (double) (far * g->inv));
  for (;;) { /* doubled while the boxes take more than 8 cells each, or span more than 2^KEY_BITS cells a side */
    PetscInt64 top[3];
    PetscBool  fits = PETSC_TRUE;
    cells           = 0;
    for (PetscInt d = 0; d < 3; d++) g->base[d] = INT64_MAX, top[d] = INT64_MIN;
    for (PetscInt k = 0; k < n; k++) {
      cells += CellsOf(g, &b[k]);
      for (PetscInt d = 0; d < 3; d++) g->base[d] = PetscMin(g->base[d], CellOf(g, b[k].lo[d])), top[d] = PetscMax(top[d], CellOf(g, b[k].hi[d]));
    }
    for (PetscInt d = 0; d < 3; d++) fits = (PetscBool) (fits && (!n || top[d] - g->base[d] < (1LL << KEY_BITS)));
    if (fits && cells <= 8 * (PetscReal) PetscMax(n, 1)) break;
    g->inv /= 2;
  }
  if (!n)
    for (PetscInt d = 0; d < 3; d++) g->base[d] = 0; /* (no entry: every key is KEY_NONE or matches none) */
  nent = (PetscInt64) cells;
  while (nb < 2 * nent) nb *= 2;
  g->mask = nb - 1;
  PetscCall(PetscCalloc1(nb + 1, &g->start));
  PetscCall(PetscMalloc2(nent + 1, &g->item, nent + 1, &g->key));
  PetscCall(PetscMalloc1(nb, &fill));
  for (PetscInt k = 0; k < n; k++) {
    PetscInt64 c[3];
    FOR_CELLS(g, &b[k], c) g->start[Bucket(g, c[0], c[1], c[2]) + 1]++;
  }
  for (PetscInt64 i = 0; i < nb; i++) g->start[i + 1] += g->start[i];
  for (PetscInt64 i = 0; i < nb; i++) fill[i] = g->start[i];
  for (PetscInt k = 0; k < n; k++) {
    PetscInt64 c[3];
    FOR_CELLS(g, &b[k], c)
    {
      const PetscInt e = fill[Bucket(g, c[0], c[1], c[2])]++;
      g->item[e]       = k;
      g->key[e]        = CellKey(g, c);
    }
  }
  PetscCall(PetscFree(fill));
  PetscFunctionReturn(0);
}

static PetscErrorCode GridDestroy(SelfGrid *g)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree(g->start));
  PetscCall(PetscFree2(g->item, g->key));
  PetscFunctionReturn(0);
}

/* *a, holding used entries, made to hold at least need (doubled, at least 64) */
static PetscErrorCode Reserve(PetscInt **a, PetscInt *cap, PetscInt used, PetscInt need)
{
  PetscInt *na;

  PetscFunctionBeginUser;
  if (need <= *cap) PetscFunctionReturn(0);
  *cap = PetscMax(PetscMax(2 * *cap, need), 64);
  PetscCall(PetscMalloc1(*cap, &na));
  PetscCall(PetscArraycpy(na, *a, used));
  PetscCall(PetscFree(*a));
  *a = na;
  PetscFunctionReturn(0);
}

/* The pairs a broad phase finds, in any order, 2 entries each (both hashes); FoundStore
 * puts them in the order SelfBroadPhase returns them. */
typedef struct {
  PetscInt *p, n, cap;
} Found;

static inline PetscErrorCode FoundPush(Found *F, PetscInt first, PetscInt second)
{
  PetscFunctionBeginUser;
  if (PetscUnlikely(2 * F->n + 2 > F->cap)) PetscCall(Reserve(&F->p, &F->cap, 2 * F->n, 2 * F->n + 2));
  F->p[2 * F->n] = first, F->p[2 * F->n + 1] = second;
  F->n++;
  PetscFunctionReturn(0);
}

/* The found pairs in order (by first, of nfirst, then by second) as SelfBroadPhase returns them. */
static PetscErrorCode FoundStore(Found *F, PetscInt nfirst, PetscInt *n, PetscInt **out)
{
  PetscInt *start, *pair;

  PetscFunctionBeginUser;
  PetscCall(PetscCalloc1(nfirst + 2, &start));
  PetscCall(PetscMalloc1(2 * F->n + 1, &pair));
  for (PetscInt k = 0; k < F->n; k++) start[F->p[2 * k] + 2]++;
  for (PetscInt f = 0; f < nfirst; f++) start[f + 2] += start[f + 1];
  for (PetscInt k = 0; k < F->n; k++) pair[2 * start[F->p[2 * k] + 1]++ + 1] = F->p[2 * k + 1];
  for (PetscInt f = 0; f < nfirst; f++) { /* start[f] .. start[f + 1]: f's seconds */
    const PetscInt b = f ? start[f] : 0, e = start[f + 1];
    PetscInt       i, j;
    for (i = b + 1; i < e; i++) { /* insertion: a few each */
      const PetscInt v = pair[2 * i + 1];
      for (j = i; j > b && pair[2 * j - 1] > v; j--) pair[2 * j + 1] = pair[2 * j - 1];
      pair[2 * j + 1] = v;
    }
    for (i = b; i < e; i++) pair[2 * i] = f;
  }
  PetscCall(PetscFree(start));
  PetscCall(PetscFree(F->p));
  F->cap = 0;
  *n     = F->n;
  *out   = pair;
  F->n   = 0;
  PetscFunctionReturn(0);
}

PetscErrorCode SelfBroadPhaseHash(const SelfMesh *m, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscInt *npt, PetscInt **pt, PetscInt *nee, PetscInt **ee)
{
  SelfBox *vb, *tb, *eb;
  SelfGrid g;
  Found    F = {NULL, 0, 0};

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc3(m->nv + 1, &vb, m->nt + 1, &tb, m->ne + 1, &eb));
  MakeBoxes(m->nv, 1, m->vert, x0, x1, r, vb);
  MakeBoxes(m->nt, 3, m->tri, x0, x1, r, tb);
  MakeBoxes(m->ne, 2, m->edge, x0, x1, r, eb);
  /* vertex - triangle */
  PetscCall(GridCreate(m->nt, tb, &g));
  for (PetscInt v = 0; v < m->nv; v++) {
    const PetscInt p = m->vert[v];
    PetscInt64     c[3];
    FOR_CELLS(&g, &vb[v], c)
    {
      const PetscInt64         bk  = Bucket(&g, c[0], c[1], c[2]);
      const unsigned long long key = CellKey(&g, c);
      for (PetscInt e = g.start[bk]; e < g.start[bk + 1]; e++) {
        const PetscInt  t = g.item[e];
        const PetscInt *T = m->tri + 3 * t;
        if (g.key[e] != key) continue;
        if (p == T[0] || p == T[1] || p == T[2] || !Overlap(&vb[v], &tb[t]) || !FirstCell(&g, &vb[v], &tb[t], c)) continue;
        PetscCall(FoundPush(&F, v, t));
      }
    }
  }
  PetscCall(GridDestroy(&g));
  PetscCall(FoundStore(&F, m->nv, npt, pt));
  /* edge - edge */
  PetscCall(GridCreate(m->ne, eb, &g));
  for (PetscInt a = 0; a < m->ne; a++) {
    const PetscInt *A = m->edge + 2 * a;
    PetscInt64      c[3];
    FOR_CELLS(&g, &eb[a], c)
    {
      const PetscInt64         bk  = Bucket(&g, c[0], c[1], c[2]);
      const unsigned long long key = CellKey(&g, c);
      for (PetscInt e = g.start[bk]; e < g.start[bk + 1]; e++) {
        const PetscInt  b = g.item[e];
        const PetscInt *B = m->edge + 2 * b;
        if (b <= a || g.key[e] != key) continue;
        if (A[0] == B[0] || A[0] == B[1] || A[1] == B[0] || A[1] == B[1] || !Overlap(&eb[a], &eb[b]) || !FirstCell(&g, &eb[a], &eb[b], c)) continue;
        PetscCall(FoundPush(&F, a, b));
      }
    }
  }
  PetscCall(GridDestroy(&g));
  PetscCall(FoundStore(&F, m->ne, nee, ee));
  PetscCall(PetscFree3(vb, tb, eb));
  PetscFunctionReturn(0);
}

/* ---- the broad phase on the lattice's tiles ----
 * The same pairs again, found in two levels: the primitives grouped by the tile of
 * the lattice their first particle is in (a vertex's own, a triangle's or an edge's
 * lowest corner: TILE x TILE cells), each tile's box the union of its primitives'
 * (vertices, triangles and edges apart); the pairs of tiles whose boxes overlap
 * found by the hash above, and within each such pair every pair of primitives
 * tested. A cloth is its lattice: a tile's primitives lie together, so its box is
 * barely larger than theirs and the hash holds a few times fewer entries. Two
 * primitives' boxes overlap only if their tiles' do, and the hash finds each pair
 * of tiles once: each pair of primitives is found once. The pairs are then put in
 * the others' order (by first, then second) by a counting sort on the first. */
#define TILE 2

typedef struct {
  PetscInt  n;     /* tiles with a primitive of the kind             */
  PetscInt *start; /* primitives of tile k: item[start[k] .. start[k + 1]), ascending */
  PetscInt *item;
  SelfBox  *box;  /* each tile's box                                 */
  SelfBox  *ibox; /* the primitives' boxes in the order of item      */
  PetscInt *ip;   /* and their particles, stride each                */
} TileSet;

/* The tiles of the n primitives (stride particles each, the first at prim[stride e])
 * with boxes b: those that hold one, numbered in the lattice's order. */
static PetscErrorCode TileSetCreate(PetscInt n, const PetscInt *prim, PetscInt stride, const SelfBox *b, const PetscInt *nat, PetscInt Mx, TileSet *T)
{
  PetscInt lo[2] = {PETSC_MAX_INT, PETSC_MAX_INT}, hi[2] = {0, 0}, nx, ncell, *of, *count, *fill;

  PetscFunctionBeginUser;
  for (PetscInt e = 0; e < n; e++) {
    const PetscInt a = nat[prim[stride * e]], c[2] = {(a % Mx) / TILE, (a / Mx) / TILE};
    for (PetscInt d = 0; d < 2; d++) lo[d] = PetscMin(lo[d], c[d]), hi[d] = PetscMax(hi[d], c[d]);
  }
  nx    = n ? hi[0] - lo[0] + 1 : 0;
  ncell = n ? nx * (hi[1] - lo[1] + 1) : 0;
  PetscCall(PetscMalloc1(n + 1, &of));
  PetscCall(PetscCalloc1(ncell + 1, &count));
  for (PetscInt e = 0; e < n; e++) {
    const PetscInt a = nat[prim[stride * e]];
    of[e]            = ((a / Mx) / TILE - lo[1]) * nx + (a % Mx) / TILE - lo[0];
    count[of[e]]++;
  }
  T->n = 0;
  for (PetscInt c = 0; c < ncell; c++) T->n += count[c] > 0;
  PetscCall(PetscMalloc3(T->n + 1, &T->start, n + 1, &T->item, T->n + 1, &T->box));
  PetscCall(PetscMalloc1(ncell + 1, &fill));
  T->start[0] = 0;
  for (PetscInt c = 0, k = 0; c < ncell; c++) { /* the tiles that hold one, in order; fill: each one's number */
    fill[c] = -1;
    if (!count[c]) continue;
    fill[c]         = k;
    T->start[k + 1] = T->start[k] + count[c];
    for (PetscInt d = 0; d < 3; d++) T->box[k].lo[d] = PETSC_MAX_REAL, T->box[k].hi[d] = -PETSC_MAX_REAL;
    k++;
  }
  for (PetscInt k = 0; k < T->n; k++) count[k] = T->start[k];
  for (PetscInt e = 0; e < n; e++) {
    const PetscInt k    = fill[of[e]];
    SelfBox       *B    = &T->box[k];
    T->item[count[k]++] = e;
    for (PetscInt d = 0; d < 3; d++) B->lo[d] = PetscMin(B->lo[d], b[e].lo[d]), B->hi[d] = PetscMax(B->hi[d], b[e].hi[d]);
  }
  PetscCall(PetscMalloc2(n + 1, &T->ibox, stride * n + 1, &T->ip)); /* (the pairs' tests then read each tile's primitives in order) */
  for (PetscInt j = 0; j < n; j++) {
    T->ibox[j] = b[T->item[j]];
    for (PetscInt d = 0; d < stride; d++) T->ip[stride * j + d] = prim[stride * T->item[j] + d];
  }
  PetscCall(PetscFree(fill));
  PetscCall(PetscFree(count));
  PetscCall(PetscFree(of));
  PetscFunctionReturn(0);
}

static PetscErrorCode TileSetDestroy(TileSet *T)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree2(T->ibox, T->ip));
  PetscCall(PetscFree3(T->start, T->item, T->box));
  PetscFunctionReturn(0);
}

/* The pairs of tiles of A (queries) and B (entered) whose boxes overlap, each once
 * (self: A is B, and only tiles b > a, and each tile with itself), handed to fine(a, b). */
#define FOR_TILE_PAIRS(A, B, self, ta_, tb_, ...)                                                                                                                                                                                                        \
  do {                                                                                                                                                                                                                                                   \
    SelfGrid g_;                                                                                                                                                                                                                                         \
    PetscCall(GridCreate((B)->n, (B)->box, &g_));                                                                                                                                                                                                        \
    for (PetscInt ta_ = 0; ta_ < (A)->n; ta_++) {                                                                                                                                                                                                        \
      PetscInt64 c_[3];                                                                                                                                                                                                                                  \
      if (self) {                                                                                                                                                                                                                                        \
        const PetscInt tb_ = ta_;                                                                                                                                                                                                                        \
        __VA_ARGS__                                                                                                                                                                                                                                      \
      }                                                                                                                                                                                                                                                  \
      FOR_CELLS(&g_, &(A)->box[ta_], c_)                                                                                                                                                                                                                 \
      {                                                                                                                                                                                                                                                  \
        const PetscInt64         bk_  = Bucket(&g_, c_[0], c_[1], c_[2]);                                                                                                                                                                                \
        const unsigned long long key_ = CellKey(&g_, c_);                                                                                                                                                                                                \
        for (PetscInt e_ = g_.start[bk_]; e_ < g_.start[bk_ + 1]; e_++) {                                                                                                                                                                                \
          const PetscInt tb_ = g_.item[e_];                                                                                                                                                                                                              \
          if (g_.key[e_] != key_ || ((self) && tb_ <= ta_) || !Overlap(&(A)->box[ta_], &(B)->box[tb_]) || !FirstCell(&g_, &(A)->box[ta_], &(B)->box[tb_], c_)) continue;                                                                                 \
          __VA_ARGS__                                                                                                                                                                                                                                    \
        }                                                                                                                                                                                                                                                \
      }                                                                                                                                                                                                                                                  \
    }                                                                                                                                                                                                                                                    \
    PetscCall(GridDestroy(&g_));                                                                                                                                                                                                                         \
  } while (0)

PetscErrorCode SelfBroadPhaseTiles(const SelfMesh *m, const PetscInt *nat, PetscInt Mx, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscInt *npt, PetscInt **pt, PetscInt *nee, PetscInt **ee)
{
  SelfBox *vb, *tb, *eb;
  TileSet  V, T, E;
  Found    F = {NULL, 0, 0};

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc3(m->nv + 1, &vb, m->nt + 1, &tb, m->ne + 1, &eb));
  MakeBoxes(m->nv, 1, m->vert, x0, x1, r, vb);
  MakeBoxes(m->nt, 3, m->tri, x0, x1, r, tb);
  MakeBoxes(m->ne, 2, m->edge, x0, x1, r, eb);
  PetscCall(TileSetCreate(m->nv, m->vert, 1, vb, nat, Mx, &V));
  PetscCall(TileSetCreate(m->nt, m->tri, 3, tb, nat, Mx, &T));
  PetscCall(TileSetCreate(m->ne, m->edge, 2, eb, nat, Mx, &E));
  /* vertex - triangle */
  FOR_TILE_PAIRS(
    &V, &T, PETSC_FALSE, a, b, for (PetscInt i = V.start[a]; i < V.start[a + 1]; i++) {
      const PetscInt v = V.item[i], p = V.ip[i];
      const SelfBox *B = &V.ibox[i];
      if (!Overlap(B, &T.box[b])) continue;
      for (PetscInt j = T.start[b]; j < T.start[b + 1]; j++) {
        const PetscInt *P = T.ip + 3 * j;
        if (p == P[0] || p == P[1] || p == P[2] || !Overlap(B, &T.ibox[j])) continue;
        PetscCall(FoundPush(&F, v, T.item[j]));
      }
    });
  PetscCall(FoundStore(&F, m->nv, npt, pt));
  /* edge - edge */
  FOR_TILE_PAIRS(
    &E, &E, PETSC_TRUE, a, b, for (PetscInt i = E.start[a]; i < E.start[a + 1]; i++) {
      const PetscInt e = E.item[i], *A = E.ip + 2 * i;
      const SelfBox *Ab = &E.ibox[i];
      if (!Overlap(Ab, &E.box[b])) continue;
      for (PetscInt j = (a == b ? i + 1 : E.start[b]); j < E.start[b + 1]; j++) {
        const PetscInt f = E.item[j], *B = E.ip + 2 * j;
        if (A[0] == B[0] || A[0] == B[1] || A[1] == B[0] || A[1] == B[1] || !Overlap(Ab, &E.ibox[j])) continue;
        PetscCall(FoundPush(&F, PetscMin(e, f), PetscMax(e, f)));
      }
    });
  PetscCall(FoundStore(&F, m->ne, nee, ee));
  PetscCall(TileSetDestroy(&V));
  PetscCall(TileSetDestroy(&T));
  PetscCall(TileSetDestroy(&E));
  PetscCall(PetscFree3(vb, tb, eb));
  PetscFunctionReturn(0);
}
