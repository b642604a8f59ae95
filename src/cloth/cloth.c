/* The cloth lattice: options, DMDA layout, masses, pins and element lists. */
#include "clothimpl.h"
#include <petscdmda.h>
#include <petscsf.h>
#include <stdint.h>
#if defined(__GLIBC__)
#include <malloc.h> /* malloc_trim */
#endif
#include <partition.h>
#include <drape.h>

static const char *const orientation_names[] = {"horizontal", "vertical", "ClothOrientation", "CLOTH_", NULL};
static const char *const shape_names[]       = {"square", "circle", "polygon", "ClothShape", "CLOTH_", NULL};
static const char *const model_names[]       = {"drape", "paper", "ClothModel", "CLOTH_MODEL_", NULL};
static const char *const pin_names[]         = {"none", "corners", "edge_corners", "edge", "list", "ClothPinType", "CLOTH_PIN_", NULL};

PetscErrorCode ClothCreate(MPI_Comm comm, Cloth *cloth)
{
  Cloth c;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&c));
  c->comm        = comm;
  c->size[0]     = 1.0;
  c->size[1]     = 1.0;
  c->density     = 0.15;  /* kg/m^2: a light cotton (poplin, lawn) is 0.1-0.2     */
  c->damping     = 0.2;   /* 1/s: light air drag on a 1 m cloth                     */
  c->stretch[0]  = 500.0; /* N/m: tensile rigidity per unit width at small strain   */
  c->stretch[1]  = 500.0;
  c->shear       = 30.0; /* N/m per rad: KES G ~ 0.5 gf/(cm deg)                  */
  c->bend[0]     = 5e-6; /* N m: KES B ~ 0.05 gf cm^2/cm                           */
  c->bend[1]     = 5e-6;
  c->bend[2]     = -1; /* the bias: (Bw + Bf)/2 unless given or measured */
  c->gravity[2]  = -9.81;
  c->origin[2]   = 1.0;
  c->orientation = CLOTH_HORIZONTAL;
  c->pin         = CLOTH_PIN_NONE;
  c->Mx          = 32;
  c->My          = 32;
  PetscCall(PetscStrncpy(c->partition, "dmda", sizeof c->partition));

  c->hyst_stiffness = CLOTH_HYSTERESIS_STIFFNESS;

  c->imperfection_seed = 1;
  *cloth               = c;
  PetscFunctionReturn(0);
}

/* Read a 1- or 2-entry option: one value means warp = weft. */
static PetscErrorCode OptionsWarpWeft(PetscOptionItems *PetscOptionsObject, const char *name, const char *text, PetscReal value[2])
{
  PetscInt  n      = 3; /* one more than allowed: detects extra values */
  PetscReal tmp[3] = {value[0], value[1], 0};
  PetscBool set;
  char      deflt[64];

  PetscFunctionBeginUser;
  PetscCall(PetscSNPrintf(deflt, sizeof deflt, "%g,%g", (double) value[0], (double) value[1]));
  PetscCall(PetscOptionsRealArray(name, text, deflt, tmp, &n, &set));
  PetscCheck(!set || (n > 0 && n <= 2), PETSC_COMM_WORLD, PETSC_ERR_USER_INPUT, "Option %s needs one value (warp = weft) or two (warp,weft)", name);
  if (set) {
    value[0] = tmp[0];
    value[1] = n == 1 ? tmp[0] : tmp[1];
  }
  PetscFunctionReturn(0);
}

/* -cloth_bend Bw[,Bf[,Bb]]: one value means warp = weft; the bias Bb (what a strip
 * cut at 45 degrees measures) is (Bw + Bf)/2 unless given third. */
static PetscErrorCode OptionsBend(PetscOptionItems *PetscOptionsObject, PetscReal bend[3], PetscBool *bias_given)
{
  PetscInt  n      = 4; /* one more than allowed: detects extra values */
  PetscReal tmp[4] = {bend[0], bend[1], bend[2], 0};
  PetscBool set;
  char      deflt[96];

  PetscFunctionBeginUser;
  PetscCall(PetscSNPrintf(deflt, sizeof deflt, "%g,%g,%g", (double) bend[0], (double) bend[1], (double) (bend[2] < 0 ? 0.5 * (bend[0] + bend[1]) : bend[2])));
  PetscCall(PetscOptionsRealArray("-cloth_bend", "Bending rigidity warp[,weft[,bias]] (N m): the bias is what a strip cut at 45 degrees to the threads measures, (warp + weft)/2 unless given; 0 removes the bending energy", deflt, tmp, &n, &set));
  PetscCheck(!set || (n > 0 && n <= 3), PETSC_COMM_WORLD, PETSC_ERR_USER_INPUT, "Option -cloth_bend needs one value (warp = weft), two (warp,weft) or three (warp,weft,bias)");
  *bias_given = (PetscBool) (set && n == 3);
  if (set) {
    bend[0] = tmp[0];
    bend[1] = n == 1 ? tmp[0] : tmp[1];
    bend[2] = n == 3 ? tmp[2] : -1;
  }
  PetscFunctionReturn(0);
}

/* The per-area rigidities of the bending elements from the strip rigidities Bw, Bf,
 * Bb (what strips cut along the warp, the weft and at 45 degrees measure) on a
 * lattice of spacing dx x dy: warp triples aw, weft triples af, and the two families
 * of diagonal triples (i-1,j-1),(i,j),(i+1,j+1) and (i-1,j+1),(i,j),(i+1,j-1).
 *
 * A triple of arm length l whose line bends with curvature k stores kappa_e k^2 l^2/2;
 * with one triple per particle (area dx dy) a family along the unit direction n
 * stores beta k_n^2/2 per area for kappa_e = beta dx dy / l^2. Warp and weft triples
 * give D11 = aw and D22 = af of the plate's bending stiffness
 * W = (D11 k_xx^2 + D22 k_yy^2 + 2 D12 k_xx k_yy + D66 (2 k_xy)^2)/2; the two diagonal
 * families (l^2 = dx^2 + dy^2, k_n = (dx^2 k_xx + dy^2 k_yy +- 2 dx dy k_xy)/l^2) add
 * D11 = d dx^2/dy^2, D22 = d dy^2/dx^2, D12 = D66 = d, with d = 2 beta dx^2 dy^2/l^4,
 * i.e. kappa_e = d l^2/(2 dx dy). Cloth is all but inextensible against bending
 * (sqrt(B/Y) is a fraction of a millimetre), so a strip bends developably: along n
 * with curvature k it has k_ij = k n_i n_j and rigidity n n : D : n n. Along the warp
 * Bw = aw + d dx^2/dy^2, along the weft Bf = af + d dy^2/dx^2, at 45 degrees
 * Bb = (D11 + D22 + 2 D12 + 4 D66)/4 = (Bw + Bf + 6 d)/4. Hence
 * d = (4 Bb - Bw - Bf)/6, and aw, af >= 0 and d >= 0 bound Bb. Without the diagonals
 * (the paper's model) Bb = (Bw + Bf)/4: half the threads' mean, and a strip with no
 * twist rigidity measures less still. */
static PetscErrorCode ClothBendCoefficients(Cloth c)
{
  const PetscReal dx = c->size[0] / (c->Mx - 1), dy = c->size[1] / (c->My - 1), r2 = dx * dx / (dy * dy);
  const PetscReal bw = c->bend[0], bf = c->bend[1];
  const PetscReal lo = 0.25 * (bw + bf), hi = lo + 1.5 * PetscMin(bw / r2, bf * r2);
  PetscReal       bb, d;

  PetscFunctionBeginUser;
  /* the default bias, (Bw + Bf)/2, is the nearest the lattice can hold where it cannot
   * hold that (cells far from square: dx/dy beyond about 1.4 for Bw = Bf) */
  if (c->bias_default && c->model == CLOTH_MODEL_DRAPE) c->bend[2] = PetscMin(PetscMax(c->bend[2], lo), hi);
  bb = c->bend[2];
  d  = (4 * bb - bw - bf) / 6;
  if (c->model == CLOTH_MODEL_PAPER) {
    c->bend_coef[0] = bw;
    c->bend_coef[1] = bf;
    c->bend_coef[2] = 0;
    c->bend[2]      = lo; /* the bias this model has */
    PetscFunctionReturn(0);
  }
  if (!(bb >= lo * (1 - 1e-12) && bb <= hi * (1 + 1e-12))) {
    char sb[32], sw[32], sf[32], slo[32], shi[32], sx[32], sy[32]; /* given: the fewest digits that read back (DrapeFormatReal); derived: C's %.4g (PETSc's turns 1 into "1.") */
    (void) snprintf(slo, sizeof slo, "%.4g", (double) lo);
    (void) snprintf(shi, sizeof shi, "%.4g", (double) hi);
    (void) snprintf(sx, sizeof sx, "%.4g", (double) dx);
    (void) snprintf(sy, sizeof sy, "%.4g", (double) dy);
    SETERRQ(c->comm, PETSC_ERR_USER_INPUT,
            "-cloth_bend: the bias rigidity %s N m (what a strip cut at 45 degrees measures) must lie from (warp + weft)/4 = %s to %s N m for warp %s and weft %s N m on this lattice (spacing %s x %s m: cells nearer square allow more); give a bias "
            "in that range, leave it out (drape then takes the nearest to (warp + weft)/2), or use -cloth_model paper, which drops the bias term",
            DrapeFormatReal(bb, sb, sizeof sb), slo, shi, DrapeFormatReal(bw, sw, sizeof sw), DrapeFormatReal(bf, sf, sizeof sf), sx, sy);
  }
  c->bend_coef[2] = PetscMax(d, 0);
  c->bend_coef[0] = PetscMax(bw - c->bend_coef[2] * r2, 0);
  c->bend_coef[1] = PetscMax(bf - c->bend_coef[2] / r2, 0);
  PetscFunctionReturn(0);
}

/* Bounds of the outline file: its size, and its vertices (every lattice particle is
 * tested against every edge). */
#define OUTLINE_MAX_BYTES    (16 << 20)
#define OUTLINE_MAX_VERTICES 10000

/* The rings of an outline file's text: lines of any length, 'x y' in metres (a
 * trailing # comment allowed), a blank line between rings. */
static PetscErrorCode ClothParseOutline(Cloth c, char *text)
{
  PetscInt  n = 0, cap = 256, lineno = 0, inring = 0;
  PetscBool open_ring = PETSC_FALSE;
  char     *line, *next;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc1(2 * cap, &c->ring_xy));
  PetscCall(PetscMalloc1(cap + 1, &c->ring_start));
  c->nring = 0;
  for (line = text; line; line = next) {
    char  *p = line, *end;
    double x = 0, y = 0;
    lineno++;
    next = strchr(line, '\n');
    if (next) *next++ = 0;
    p[strcspn(p, "\r")] = 0;
    while (*p == ' ' || *p == '\t') p++;
    if (*p == '#') continue;
    if (!*p) { /* a blank line ends a ring */
      if (open_ring) {
        PetscCheck(inring >= 3, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "Ring %" PetscInt_FMT " of the outline %s has %" PetscInt_FMT " vertices; a ring needs at least 3", c->nring, c->outline, inring);
        open_ring = PETSC_FALSE;
      }
      continue;
    }
    {
      const char *text = p;
      PetscBool   ok   = PETSC_FALSE;
      x                = strtod(p, &end);
      if (end != p && (*end == ' ' || *end == '\t')) {
        p = end;
        y = strtod(p, &end);
        if (end != p) {
          for (p = end; *p == ' ' || *p == '\t';) p++;
          ok = (PetscBool) (!*p || *p == '#');
        }
      }
      PetscCheck(ok, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "Line %" PetscInt_FMT " of the outline %s is not 'x y' in metres: '%.80s'", lineno, c->outline, text);
    }
    PetscCheck(PetscAbsReal(x) <= 1e4 && PetscAbsReal(y) <= 1e4, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "Line %" PetscInt_FMT " of the outline %s has a coordinate that is not finite or beyond 1e4 m", lineno, c->outline);
    PetscCheck(n < OUTLINE_MAX_VERTICES, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "The outline %s has more than %d vertices; simplify it", c->outline, OUTLINE_MAX_VERTICES);
    if (!open_ring) {
      c->ring_start[c->nring++] = n;
      open_ring                 = PETSC_TRUE;
      inring                    = 0;
    }
    if (n >= cap || c->nring >= cap) {
      PetscReal *xy;
      PetscInt  *rs;
      cap *= 2;
      PetscCall(PetscMalloc1(2 * cap, &xy));
      PetscCall(PetscMalloc1(cap + 1, &rs));
      PetscCall(PetscArraycpy(xy, c->ring_xy, 2 * n));
      PetscCall(PetscArraycpy(rs, c->ring_start, c->nring));
      PetscCall(PetscFree(c->ring_xy));
      PetscCall(PetscFree(c->ring_start));
      c->ring_xy    = xy;
      c->ring_start = rs;
    }
    c->ring_xy[2 * n]     = x;
    c->ring_xy[2 * n + 1] = y;
    n++;
    inring++;
  }
  PetscCheck(!open_ring || inring >= 3, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "The last ring of the outline %s has %" PetscInt_FMT " vertices; a ring needs at least 3", c->outline, inring);
  PetscCheck(c->nring > 0, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "The outline %s has no polygon: write lines 'x y' (m), a blank line between rings", c->outline);
  c->ring_start[c->nring] = n;
  PetscFunctionReturn(0);
}

/* Read the polygon rings of -cloth_outline (every rank reads the small file). */
static PetscErrorCode ClothReadOutline(void *ctx)
{
  Cloth          c = (Cloth) ctx;
  FILE          *fp;
  char          *text;
  size_t         len = 0, got;
  PetscBool      isdir;
  PetscErrorCode ierr;

  PetscFunctionBeginUser;
  PetscCall(PetscTestDirectory(c->outline, 'r', &isdir));
  PetscCheck(!isdir, PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot read the cloth outline file %s: it is a directory", c->outline);
  fp = fopen(c->outline, "rb");
  PetscCheck(fp, PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "Cannot open the cloth outline file %s", c->outline);
  PetscCall(PetscMalloc1(OUTLINE_MAX_BYTES + 1, &text));
  while (len <= OUTLINE_MAX_BYTES && (got = fread(text + len, 1, OUTLINE_MAX_BYTES + 1 - len, fp)) > 0) len += got;
  (void) fclose(fp);
  if (len > OUTLINE_MAX_BYTES || memchr(text, 0, len)) PetscCall(PetscFree(text));
  PetscCheck(text, PETSC_COMM_SELF, PETSC_ERR_FILE_UNEXPECTED, "The cloth outline file %s is %s", c->outline, len > OUTLINE_MAX_BYTES ? "larger than 16 MB" : "not a text file");
  text[len] = 0;
  PetscCall(DrapeRegisterInput(c->outline, "cloth outline"));
  ierr = ClothParseOutline(c, text);
  PetscCall(PetscFree(text));
  PetscCall(ierr);
  PetscFunctionReturn(0);
}

/* Even-odd rule over all rings: holes are rings inside the outline. */
static PetscBool InsideOutline(Cloth c, PetscReal x, PetscReal y)
{
  PetscBool in = PETSC_FALSE;
  for (PetscInt r = 0; r < c->nring; r++) {
    PetscInt s = c->ring_start[r], e = c->ring_start[r + 1];
    for (PetscInt k = s, l = e - 1; k < e; l = k++) {
      PetscReal xk = c->ring_xy[2 * k], yk = c->ring_xy[2 * k + 1], xl = c->ring_xy[2 * l], yl = c->ring_xy[2 * l + 1];
      if ((yk > y) != (yl > y) && x < (xl - xk) * (y - yk) / (yl - yk) + xk) in = (PetscBool) !in;
    }
  }
  return in;
}

/* A lattice must fit in PetscInt (drape forms indices up to about 128 per particle:
 * matrix entries, element lists, the METIS graph) and, at least roughly, in memory:
 * refused before anything is allocated, with the limit named. Memory: a lower bound
 * (about 400 bytes per particle of the rank's share for the explicit schemes, and
 * with -cloth_partition metis the whole graph on rank 0) against what a node has. */
/* How large a lattice PetscInt can index: the one place that says it (docs/cluster.md
 * and docs/options.md quote it). Past these a 32-bit PetscInt would wrap:
 * - the unknowns: 3 per particle, so vectors of 3 N entries and global indices up to
 *   3 N (the DMDA's vectors, the state, the matrix's rows, self-contact's keys of
 *   primitives): N <= (2^31 - 1) / 3 = 715 827 882 particles, 26 754 x 26 754;
 * - a rank's element lists: up to 12 entries per local particle (4 shear corners of
 *   3 and 4 bending triples of 3 each), so a rank holds at most (2^31 - 1) / 12 =
 *   178 956 970 particles, owned and ghost (this binds only on fewer than 5 ranks);
 * - the implicit matrix of drapebe, per rank: 9 entries per block and 25 blocks per
 *   particle's row (the 5 x 5 particles its elements reach; SBAIJ keeps the upper
 *   13), so a rank owns at most (2^31 - 1) / 225 = 9 544 371 particles
 *   (ClothSetUpImplicit);
 * - serial METIS: 12 links per particle in its idx_t (partition.c).
 * A 64-bit PetscInt lifts all but METIS's; memory then bounds the lattice. */
#define CLOTH_LIST_ENTRIES   12  /* per local particle, in a rank's longest element list */
#define CLOTH_MATRIX_ENTRIES 225 /* per owned particle, in a rank's implicit matrix: 25 blocks of 9 */
/* drapebe's memory per particle, measured (BENCHMARKS.md, "drapebe's memory a
 * particle, by preconditioner": 2.32 kB with block IC(0), the default's first
 * choice; 2.73 kB with IC(1), 12.8 kB with ML): what a rank needs at least */
#define CLOTH_IMPLICIT_BYTES 2300.0

/* Does PetscInt index a lattice of Mx x My, and does the memory each rank has hold
 * it? Refused with a sentence before anything of its size is allocated. */
static PetscErrorCode ClothCheckLatticeSize(Cloth c, PetscInt Mx, PetscInt My)
{
  const PetscInt64 N = (PetscInt64) Mx * (PetscInt64) My, most = PETSC_MAX_INT / 3;
  PetscMPIInt      size, rank, local;
  MPI_Comm         node;
  PetscLogDouble   need, node_bytes, process_bytes;

  PetscFunctionBeginUser;
  PetscCheck(N <= most, c->comm, PETSC_ERR_USER_INPUT,
             "A %" PetscInt_FMT " x %" PetscInt_FMT " lattice (%.4g particles) has more unknowns (3 per particle) than this PETSc build's %d-bit PetscInt indexes: at most %" PetscInt64_FMT " particles (e.g. %d x %d)%s", Mx, My, (double) N,
             (int) (8 * sizeof(PetscInt)), most, (int) PetscFloorReal(PetscSqrtReal((PetscReal) most)), (int) PetscFloorReal(PetscSqrtReal((PetscReal) most)),
             sizeof(PetscInt) < 8 ? "; build PETSc with --with-64-bit-indices for larger lattices" : "");
  PetscCallMPI(MPI_Comm_size(c->comm, &size));
  PetscCallMPI(MPI_Comm_rank(c->comm, &rank));
  PetscCallMPI(MPI_Comm_split_type(c->comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node));
  PetscCallMPI(MPI_Comm_size(node, &local));
  PetscCallMPI(MPI_Comm_free(&node));
  PetscCall(DrapeMemoryAvailable(&node_bytes, &process_bytes));
  need = 400.0 * (PetscLogDouble) N / size;
  {
    /* serial METIS (on more than one rank) builds the whole particle graph on rank 0
     * and partitions it there: rank 0's peak rises by about CLOTH_METIS_BYTES a
     * lattice particle (2048^2 on 2 ranks, -memory_view: 1097 MB against 534 MB with
     * dmda, 134 bytes a particle; 107 for the disc inscribed in it, whose graph
     * leaves out the corners) */
    const PetscLogDouble CLOTH_METIS_BYTES = 140;
    PetscBool            metis, ok[2];
    PetscLogDouble       graph = 0;
    PetscCall(PetscStrcmp(c->partition, "metis", &metis));
    if (!rank && metis && size > 1) graph = CLOTH_METIS_BYTES * (PetscLogDouble) N;
    ok[0] = (PetscBool) (need * local <= node_bytes && need <= process_bytes);
    ok[1] = (PetscBool) (need * local + graph <= node_bytes && need + graph <= process_bytes);
    PetscCall(MPIU_Allreduce(MPI_IN_PLACE, ok, 2, MPIU_BOOL, MPI_LAND, c->comm));
    PetscCheck(ok[0], c->comm, PETSC_ERR_USER_INPUT,
               "A %" PetscInt_FMT " x %" PetscInt_FMT " lattice needs at least %.1f GB per rank (%.1f GB on a node running %d ranks), more than this machine gives a run (%.1f GB per node%s): use a smaller lattice, or more nodes", Mx, My, need / 1e9,
               need * local / 1e9, (int) local, node_bytes / 1e9, process_bytes < node_bytes ? ", less per process" : "");
    if (!ok[1]) {
      PetscBool   parallel;
      const char *instead         = "dmda (blocks of the lattice)";
      char        per_process[64] = "";
      PetscCall(PartitionUsable("parmetis", &parallel));
      if (parallel) instead = "parmetis, which partitions the graph in parallel, or dmda";
      PetscCall(PartitionUsable("ptscotch", &parallel));
      if (parallel) instead = "ptscotch, which partitions the graph in parallel (each rank builds its part), or dmda";
      PetscCallMPI(MPI_Bcast(&graph, 1, MPI_DOUBLE, 0, c->comm));
      if (process_bytes < node_bytes) PetscCall(PetscSNPrintf(per_process, sizeof per_process, ", %.1f GB per process", process_bytes / 1e9));
      SETERRQ(c->comm, PETSC_ERR_USER_INPUT,
              "-cloth_partition metis builds the whole particle graph of the %" PetscInt_FMT " x %" PetscInt_FMT
              " lattice on rank 0: about %.1f GB (%.0f bytes a particle) on top of the rank's own %.1f GB, more than this machine gives a run (%.1f GB per node%s, %d ranks on it); use -cloth_partition %s",
              Mx, My, graph / 1e9, CLOTH_METIS_BYTES, need / 1e9, node_bytes / 1e9, per_process, (int) local, instead);
    }
  }
  PetscFunctionReturn(0);
}

/* The largest n over the ranks: does n times per fit PetscInt on every rank?
 * Collective. */
static PetscErrorCode ClothCheckRankIndex(Cloth c, PetscInt n, PetscInt per, PetscInt *nmax, PetscBool *fits)
{
  PetscFunctionBeginUser;
  PetscCall(MPIU_Allreduce(&n, nmax, 1, MPIU_INT, MPI_MAX, c->comm));
  *fits = (PetscBool) ((PetscInt64) *nmax * per <= PETSC_MAX_INT);
  PetscFunctionReturn(0);
}

/* A portable generator (splitmix64): the same numbers from a seed on every machine. */
static PetscReal SplitMix(uint64_t *state)
{
  uint64_t z = (*state += 0x9E3779B97F4A7C15ULL);
  z          = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z          = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  z          = z ^ (z >> 31);
  return (PetscReal) (z >> 11) * 0x1.0p-53; /* [0, 1) */
}

/* The imperfection's plane waves (CLOTH_IMPERFECTION_MODES in clothimpl.h), from the
 * seed: every rank draws the same ones. */
static PetscErrorCode ClothImperfectionSetUp(Cloth c)
{
  uint64_t  state = (uint64_t) c->imperfection_seed;
  PetscReal lo    = PetscMin(c->size[0], c->size[1]);

  PetscFunctionBeginUser;
  PetscCall(DrapeCheckReal(c->comm, "-cloth_imperfection (its amplitude)", 1, &c->imperfection[0], 0, 1, "m"));
  const PetscBool derived = (PetscBool) (c->imperfection[1] == 0); /* the wavelength */
  if (derived) c->imperfection[1] = 0.25 * lo;
  PetscCall(DrapeCheckReal(c->comm, "-cloth_imperfection (its wavelength)", 1, &c->imperfection[1], 1e-4, 1e3, "m"));
  if (c->imperfection[0] > 0.05 * c->imperfection[1]) {
    char sa[32], sl[32]; /* given: the fewest digits that read back (DrapeFormatReal); derived: C's %.4g */
    if (derived) (void) snprintf(sl, sizeof sl, "%.4g", (double) c->imperfection[1]);
    SETERRQ(c->comm, PETSC_ERR_USER_INPUT,
            "-cloth_imperfection's amplitude %s m is more than 5%% of its wavelength %s m: the initial sheet would no longer be nearly flat (its slopes reach about 2 pi sqrt(2) amplitude/wavelength); give a smaller amplitude or a longer wavelength",
            DrapeFormatReal(c->imperfection[0], sa, sizeof sa), derived ? sl : DrapeFormatReal(c->imperfection[1], sl, sizeof sl));
  }
  PetscCall(DrapeCheckIntOption(c->comm, "-cloth_imperfection_seed"));
  PetscCall(DrapeCheckInt(c->comm, "-cloth_imperfection_seed", c->imperfection_seed, 0, PETSC_MAX_INT));
  for (PetscInt m = 0; m < CLOTH_IMPERFECTION_MODES; m++) {
    const PetscReal alpha = PETSC_PI * (m + SplitMix(&state)) / CLOTH_IMPERFECTION_MODES; /* stratified: distinct directions */
    c->imperf_dir[m][0]   = PetscCosReal(alpha);
    c->imperf_dir[m][1]   = PetscSinReal(alpha);
    c->imperf_phase[m]    = 2 * PETSC_PI * SplitMix(&state);
  }
  PetscFunctionReturn(0);
}

/* The imperfection at sheet coordinates (a, b) from the centre, m. */
static PetscReal ClothImperfection(Cloth c, PetscReal a, PetscReal b)
{
  const PetscReal k = 2 * PETSC_PI / c->imperfection[1];
  PetscReal       w = 0;

  for (PetscInt m = 0; m < CLOTH_IMPERFECTION_MODES; m++) w += PetscCosReal(k * (a * c->imperf_dir[m][0] + b * c->imperf_dir[m][1]) + c->imperf_phase[m]);
  return c->imperfection[0] * PetscSqrtReal(2.0 / CLOTH_IMPERFECTION_MODES) * w;
}

PetscErrorCode ClothSetFromOptions(Cloth c)
{
  PetscInt          n, npin = 0, ipin = (PetscInt) c->pin, iorient = (PetscInt) c->orientation, hess = 0;
  PetscBool         set, bias_given = PETSC_FALSE;
  const char *const hessian_names[] = {"projected", "exact", "ClothHessian", "", NULL};

  PetscFunctionBeginUser;
  PetscOptionsBegin(c->comm, NULL, "Cloth: lattice, material, pins and initial state", "Cloth");
  PetscCall(PetscOptionsInt("-da_grid_x", "Particles along the warp (lattice columns)", "ClothSetFromOptions", c->Mx, &c->Mx, NULL));
  PetscCall(PetscOptionsInt("-da_grid_y", "Particles along the weft (lattice rows)", "ClothSetFromOptions", c->My, &c->My, NULL));
  {
    PetscReal tmp[3] = {c->size[0], c->size[1], 0};
    n                = 3; /* one more than allowed: detects extra values */
    PetscCall(PetscOptionsRealArray("-cloth_size", "Cloth size along warp,weft (m)", "ClothSetFromOptions", tmp, &n, &set));
    PetscCheck(!set || (n >= 1 && n <= 2), c->comm, PETSC_ERR_USER_INPUT, "-cloth_size takes one value (a square) or two (warp,weft), in metres");
    if (set) {
      c->size[0] = tmp[0];
      c->size[1] = n == 1 ? tmp[0] : tmp[1];
    }
  }
  {
    char fabric[64], list[1024], text[1200];
    PetscCall(ClothFabricList(list, sizeof list));
    PetscCall(PetscSNPrintf(text, sizeof text, "Measured fabric for density and rigidities (Wang, Ramamoorthi & O'Brien 2011; the -cloth_* options below override single values): %s", list));
    PetscCall(PetscOptionsString("-cloth_fabric", text, "ClothSetFabric", "", fabric, sizeof fabric, &set));
    if (set) PetscCall(ClothSetFabric(c, fabric));
  }
  PetscCall(PetscOptionsReal("-cloth_density", "Areal density (kg/m^2)", "ClothSetFromOptions", c->density, &c->density, NULL));
  PetscCall(PetscOptionsReal("-cloth_damping", "Mass-proportional damping c, force -c m v (1/s)", "ClothSetFromOptions", c->damping, &c->damping, NULL));
  PetscCall(OptionsWarpWeft(PetscOptionsObject, "-cloth_stretch", "Tensile rigidity warp[,weft] (N/m); 0 removes the stretch energy", c->stretch));
  PetscCall(PetscOptionsReal("-cloth_shear", "In-plane shear rigidity (N/m: energy per area S gamma^2/2 for a shear angle gamma); 0 removes the shear energy", "ClothSetFromOptions", c->shear, &c->shear, NULL));
  PetscCall(OptionsBend(PetscOptionsObject, c->bend, &bias_given));
  PetscCall(PetscOptionsBool("-cloth_bend_table", "Bending rigidity that varies with curvature as the fabric's measured table (-cloth_fabric; samples at 0, 10, 20, 30, 40 1/m, linear between, held beyond), relative to -cloth_bend",
                             "ClothSetFromOptions", c->bend_table, &c->bend_table, NULL));
  {
    PetscInt samples = c->bend_nb;
    PetscCall(PetscOptionsInt("-cloth_bend_table_samples", "How many of the table's samples -cloth_bend_table uses (2 to all; the rigidity is held at the last one used beyond it): a sensitivity study of the table's last samples",
                              "ClothSetFromOptions", samples, &samples, &set));
    PetscCheck(!set || (c->bend_table && c->bend_nb > 0 && samples >= 2 && samples <= c->bend_nb), c->comm, PETSC_ERR_USER_INPUT,
               "-cloth_bend_table_samples goes with -cloth_bend_table and -cloth_fabric, and must lie from 2 to the %" PetscInt_FMT " samples of the fabric's bending table; got %" PetscInt_FMT, c->bend_nb, samples);
    if (set) c->bend_nb = samples;
  }
  PetscCall(OptionsWarpWeft(
    PetscOptionsObject, "-cloth_bend_hysteresis",
    "Bending hysteresis 2HB warp[,weft] (N m/m = N; KES-F's 2HB, 1 gf cm/cm = 9.80665e-3 N): the friction between the yarns of a bent fabric, a moment HB per unit width against the change of curvature (Grosberg's law); 0: none", c->hysteresis));
  PetscCall(PetscOptionsReal("-cloth_bend_hysteresis_stiffness", "Stick stiffness of the bending friction, a multiple of the direction's bending rigidity: the regularisation of Grosberg's rigid-plastic friction (larger: closer to it, stiffer steps)",
                             "ClothSetFromOptions", c->hyst_stiffness, &c->hyst_stiffness, NULL));
  {
    PetscInt imodel = (PetscInt) c->model;
    PetscCall(PetscOptionsEList("-cloth_model", "Bending model: drape (thread triples and diagonal triples: warp, weft and bias rigidity) or paper (the paper's thread triples only: no bias rigidity)", "ClothSetFromOptions", model_names, 2,
                                model_names[imodel], &imodel, NULL));
    c->model = (ClothModel) imodel;
  }
  n = 3;
  PetscCall(PetscOptionsRealArray("-gravity", "Gravity vector gx,gy,gz (m/s^2)", "ClothSetFromOptions", c->gravity, &n, &set));
  PetscCheck(!set || n == 3, c->comm, PETSC_ERR_USER_INPUT, "Option -gravity needs three components gx,gy,gz; got %" PetscInt_FMT, n);
  n = 3;
  PetscCall(PetscOptionsRealArray("-cloth_center", "Centre of the initial flat sheet x,y,z (m)", "ClothSetFromOptions", c->origin, &n, &set));
  PetscCheck(!set || n == 3, c->comm, PETSC_ERR_USER_INPUT, "Option -cloth_center needs three components x,y,z; got %" PetscInt_FMT, n);
  PetscCall(PetscOptionsEList("-cloth_orientation", "Initial sheet: horizontal (warp x, weft y) or vertical (warp x, weft z)", "ClothSetFromOptions", orientation_names, 2, orientation_names[iorient], &iorient, NULL));
  PetscCall(PetscOptionsReal("-cloth_tilt", "Initial sheet turned about its warp direction by this angle from -cloth_orientation (degrees; the weft rises towards +z)", "ClothSetFromOptions", c->tilt, &c->tilt, NULL));
  PetscCall(DrapeCheckReal(c->comm, "-cloth_tilt", 1, &c->tilt, -180, 180, "degrees"));
  n = 3; /* one more than allowed: detects extra values */
  {
    PetscReal tmp[3] = {0, 0, 0};
    PetscCall(PetscOptionsRealArray("-cloth_imperfection",
                                    "A specimen that is not quite flat: rms amplitude[,wavelength] (m) of a smooth random out-of-plane displacement of the initial sheet (a sum of plane waves in material coordinates: the same specimen on every "
                                    "lattice); wavelength 0 or not given: a quarter of the smaller -cloth_size; amplitude 0: flat",
                                    "ClothSetFromOptions", tmp, &n, &set));
    PetscCheck(!set || (n > 0 && n <= 2), c->comm, PETSC_ERR_USER_INPUT, "Option -cloth_imperfection needs one value (amplitude) or two (amplitude,wavelength), in m");
    if (set) {
      c->imperfection[0] = tmp[0];
      c->imperfection[1] = n == 2 ? tmp[1] : 0;
    }
  }
  PetscCall(PetscOptionsInt("-cloth_imperfection_seed", "Which specimen: the seed of -cloth_imperfection's random field (an integer >= 0; the same seed gives the same specimen on any lattice, rank count and machine)", "ClothSetFromOptions",
                            c->imperfection_seed, &c->imperfection_seed, NULL));
  {
    PetscInt  ishape = (PetscInt) c->shape;
    PetscBool set_outline;
    PetscCall(PetscOptionsEList("-cloth_shape", "Cloth outline: square (the whole lattice), circle (the disc inscribed in -cloth_size, e.g. a Cusick specimen), polygon (-cloth_outline)", "ClothSetFromOptions", shape_names, 3, shape_names[ishape],
                                &ishape, NULL));
    c->shape = (ClothShape) ishape;
    PetscCall(PetscOptionsString("-cloth_outline", "Polygon file for -cloth_shape polygon: lines 'x y' (m, sheet coordinates centred on the cloth), a blank line between rings; the first ring is the outline, the others holes", "ClothSetFromOptions",
                                 c->outline, c->outline, sizeof c->outline, &set_outline));
    if (set_outline && c->shape == CLOTH_SQUARE) c->shape = CLOTH_POLYGON;
  }
  PetscCall(PetscOptionsEList("-cloth_pin", "Pinned particles: none, corners (all 4), edge_corners (two corners of the last weft row), edge (the last weft row), list", "ClothSetFromOptions", pin_names, 5, pin_names[ipin], &ipin, NULL));
  npin = 2 * 1024; /* one more than allowed: detects truncation */
  PetscCall(PetscMalloc1(npin, &c->pin_list));
  PetscCall(PetscOptionsIntArray("-cloth_pin_list", "Pinned lattice indices i0,j0,i1,j1,... (with -cloth_pin list)", "ClothSetFromOptions", c->pin_list, &npin, &set));
  PetscCheck(!set || npin < 2 * 1024, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin_list takes at most 1023 pairs; for more, pin an edge or the corners");
  c->npin_list = set ? npin / 2 : 0;
  {
    char list[256], text[1024];
    PetscCall(PartitionList(list, sizeof list));
    PetscCall(PetscSNPrintf(text, sizeof text,
                            "Particles to ranks: dmda (blocks of the lattice), metis (serial METIS k-way partition of the interaction graph, on rank 0), or a parallel partition of the graph through PETSc's MatPartitioning (ptscotch, "
                            "parmetis); the graph partitions balance irregular shapes. This build: %s",
                            list));
    PetscCall(PetscOptionsString("-cloth_partition", text, "ClothSetFromOptions", c->partition, c->partition, sizeof c->partition, NULL));
  }
  PetscCall(PetscOptionsEList("-cloth_hessian", "Hessian in the implicit matrix: projected (SPD, default) or exact (may be indefinite)", "ClothSetFromOptions", hessian_names, 2, hessian_names[0], &hess, NULL));
  PetscOptionsEnd();
  c->pin           = (ClothPinType) ipin;
  c->orientation   = (ClothOrientation) iorient;
  c->exact_hessian = hess == 1 ? PETSC_TRUE : PETSC_FALSE;
  {
    PetscBool known;
    char      list[256];
    PetscCall(PartitionKnown(c->partition, &known));
    PetscCall(PartitionList(list, sizeof list));
    PetscCheck(known, c->comm, PETSC_ERR_USER_INPUT, "-cloth_partition %s is not a partitioner this build has (ptscotch and parmetis need a PETSc configured with PT-Scotch or ParMETIS); it has %s", c->partition, list);
  }

  for (const char *const *name = (const char *const[]){"-da_grid_x", "-da_grid_y", "-da_processors_x", "-da_processors_y", "-da_refine", "-da_refine_x", "-da_refine_y", NULL}; *name; name++)
    PetscCall(DrapeCheckIntOption(c->comm, *name)); /* the DMDA reads these too */
  PetscCheck(c->Mx >= 2 && c->My >= 2, c->comm, PETSC_ERR_USER_INPUT, "The lattice must have at least 2 x 2 particles; got -da_grid_x %" PetscInt_FMT " -da_grid_y %" PetscInt_FMT, c->Mx, c->My);
  PetscCall(ClothCheckLatticeSize(c, c->Mx, c->My));
  /* ranges no real cloth or scene approaches: a typo or a hostile value, not a fabric */
  PetscCall(DrapeCheckReal(c->comm, "-cloth_size", 2, c->size, 1e-3, 1e3, "m"));
  PetscCall(DrapeCheckReal(c->comm, "-cloth_density", 1, &c->density, 1e-4, 1e2, "kg/m^2"));
  PetscCall(DrapeCheckReal(c->comm, "-cloth_damping", 1, &c->damping, 0, 1e4, "1/s"));
  PetscCall(DrapeCheckReal(c->comm, "-cloth_stretch", 2, c->stretch, 0, 1e7, "N/m"));
  PetscCall(DrapeCheckReal(c->comm, "-cloth_shear", 1, &c->shear, 0, 1e6, "N/m"));
  c->bias_default = (PetscBool) (c->bend[2] < 0);
  if (c->bend[2] < 0) c->bend[2] = 0.5 * (c->bend[0] + c->bend[1]);
  PetscCheck(c->model == CLOTH_MODEL_DRAPE || !bias_given, c->comm, PETSC_ERR_USER_INPUT, "-cloth_model paper has no bias rigidity: give -cloth_bend warp[,weft], or use -cloth_model drape for a third value");
  PetscCall(DrapeCheckReal(c->comm, "-cloth_bend", 3, c->bend, 0, 1, "N m"));
  PetscCall(ClothBendCoefficients(c));
  PetscCall(DrapeCheckReal(c->comm, "-cloth_bend_hysteresis", 2, c->hysteresis, 0, 1, "N m/m"));
  PetscCall(DrapeCheckReal(c->comm, "-cloth_bend_hysteresis_stiffness", 1, &c->hyst_stiffness, 1e-2, 1e6, "(times the bending rigidity)"));
  for (PetscInt d = 0; d < 2; d++) {
    PetscCheck(c->hysteresis[d] == 0 || c->bend[d] > 0, c->comm, PETSC_ERR_USER_INPUT, "-cloth_bend_hysteresis needs a %s bending rigidity (-cloth_bend) above 0: its friction's stick stiffness is a multiple of it", d ? "weft" : "warp");
    c->friction[d].area = 1;
    c->friction[d].hb   = 0.5 * c->hysteresis[d];
    c->friction[d].K    = c->hyst_stiffness * c->bend[d];
  }
  PetscCheck(!c->bend_table || c->bend_nb > 0, c->comm, PETSC_ERR_USER_INPUT, "-cloth_bend_table needs a measured bending table: give -cloth_fabric NAME (the ten fabrics of -help); without it the bending rigidity is -cloth_bend at every curvature");
  PetscCall(DrapeCheckReal(c->comm, "-gravity", 3, c->gravity, -1e3, 1e3, "m/s^2 (each component)"));
  PetscCall(DrapeCheckReal(c->comm, "-cloth_center", 3, c->origin, -1e4, 1e4, "m"));
  PetscCall(ClothImperfectionSetUp(c));
  PetscCall(DrapeCheckIntOption(c->comm, "-cloth_pin_list"));
  PetscCall(DrapeCheckPathLength(c->comm, "-cloth_outline", c->outline, sizeof c->outline));
  PetscCheck(c->shape != CLOTH_POLYGON || c->outline[0], c->comm, PETSC_ERR_USER_INPUT, "-cloth_shape polygon needs -cloth_outline FILE");
  if (c->shape == CLOTH_POLYGON) PetscCall(DrapeCollective(c->comm, ClothReadOutline, c));
  PetscCheck(c->pin != CLOTH_PIN_LIST || c->npin_list > 0, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin list needs -cloth_pin_list i0,j0,i1,j1,...");
  PetscCheck(c->npin_list == 0 || c->pin == CLOTH_PIN_LIST, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin_list is used only with -cloth_pin list");
  PetscCheck(npin % 2 == 0, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin_list needs pairs i,j; got %" PetscInt_FMT " numbers", npin);
  for (PetscInt p = 0; p < c->npin_list; p++) {
    PetscInt i = c->pin_list[2 * p], j = c->pin_list[2 * p + 1];
    PetscCheck(i >= 0 && i < c->Mx && j >= 0 && j < c->My, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin_list entry (%" PetscInt_FMT ",%" PetscInt_FMT ") is outside the %" PetscInt_FMT " x %" PetscInt_FMT " lattice (indices start at 0)", i, j, c->Mx,
               c->My);
  }
  PetscFunctionReturn(0);
}

/* Is lattice point (i, j) inside the outline (circle or polygon)? Outside the lattice:
 * no. */
static PetscBool InsideShape(Cloth c, PetscInt i, PetscInt j)
{
  PetscReal a, b;

  if (i < 0 || j < 0 || i >= c->Mx || j >= c->My) return PETSC_FALSE;
  if (c->shape == CLOTH_SQUARE) return PETSC_TRUE;
  if (c->shape == CLOTH_POLYGON) return InsideOutline(c, i * c->spacing[0] - 0.5 * c->size[0], j * c->spacing[1] - 0.5 * c->size[1]);
  a = (i - 0.5 * (c->Mx - 1)) / (0.5 * (c->Mx - 1));
  b = (j - 0.5 * (c->My - 1)) / (0.5 * (c->My - 1));
  return (PetscBool) (a * a + b * b <= 1 + 1e-12);
}

/* The cloth is its lattice cells inside the outline (all four corners inside): a
 * particle inside that is a corner of no such cell (a spike of the cut) carries no
 * area and would hang on edges of no width, so it is not part of the cloth. in: the
 * 3 x 3 points around the particle, row by row. */
static inline PetscBool ActiveFromNeighbourhood(const PetscBool in[9])
{
  if (!in[4]) return PETSC_FALSE;
  for (PetscInt dj = 0; dj < 2; dj++)
    for (PetscInt di = 0; di < 2; di++)
      if (in[3 * dj + di] && in[3 * dj + di + 1] && in[3 * dj + di + 3] && in[3 * dj + di + 4]) return PETSC_TRUE;
  return PETSC_FALSE;
}

/* Activity outside the kept box: from the outline. */
static __attribute__((noinline)) PetscBool ActiveFromOutline(Cloth c, PetscInt i, PetscInt j)
{
  PetscBool in[9];

  if (!InsideShape(c, i, j)) return PETSC_FALSE;
  for (PetscInt k = 0; k < 9; k++) in[k] = InsideShape(c, i + k % 3 - 1, j + k / 3 - 1);
  return ActiveFromNeighbourhood(in);
}

/* ClothIsActive, inlined into the set-up's loops (hundreds of calls per particle). */
static inline PetscBool Active(Cloth c, PetscInt i, PetscInt j)
{
  if (c->shape == CLOTH_SQUARE) return PETSC_TRUE;
  if (c->act && i >= c->act_i0 && i < c->act_i0 + c->act_w && j >= c->act_j0 && j < c->act_j0 + c->act_h) return (PetscBool) c->act[(j - c->act_j0) * c->act_w + i - c->act_i0];
  return ActiveFromOutline(c, i, j);
}

PetscBool ClothIsActive(Cloth c, PetscInt i, PetscInt j) { return Active(c, i, j); }

/* The activity of columns i0 .. i1 - 1 and rows j0 .. j1 - 1 (clipped to the
 * lattice), kept for ClothIsActive: the rank's particles and their neighbours. */
static PetscErrorCode ClothActivityPatch(Cloth c, PetscInt i0, PetscInt i1, PetscInt j0, PetscInt j1)
{
  PetscBool *in;
  PetscInt   w, h;

  PetscFunctionBeginUser;
  PetscCall(PetscFree(c->act));
  if (c->shape == CLOTH_SQUARE) PetscFunctionReturn(0);
  i0 = PetscMax(i0, 0), i1 = PetscMin(i1, c->Mx), j0 = PetscMax(j0, 0), j1 = PetscMin(j1, c->My);
  w = PetscMax(i1 - i0, 0), h = PetscMax(j1 - j0, 0);
  /* the outline test once per point, on a frame one wider */
  PetscCall(PetscMalloc1((w + 2) * (h + 2), &in));
  for (PetscInt j = 0; j < h + 2; j++)
    for (PetscInt i = 0; i < w + 2; i++) in[j * (w + 2) + i] = InsideShape(c, i0 + i - 1, j0 + j - 1);
  PetscCall(PetscMalloc1(w * h + 1, &c->act));
  for (PetscInt j = 0; j < h; j++)
    for (PetscInt i = 0; i < w; i++) {
      PetscBool nb[9];
      for (PetscInt k = 0; k < 9; k++) nb[k] = in[(j + k / 3) * (w + 2) + i + k % 3];
      c->act[j * w + i] = (unsigned char) ActiveFromNeighbourhood(nb);
    }
  PetscCall(PetscFree(in));
  c->act_i0 = i0, c->act_j0 = j0, c->act_w = w, c->act_h = h;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothGetActive(Cloth c, const PetscBool **active)
{
  PetscFunctionBeginUser;
  *active = c->active;
  PetscFunctionReturn(0);
}

static PetscBool IsPinned(Cloth c, PetscInt i, PetscInt j)
{
  PetscBool last_row = (PetscBool) (j == c->My - 1), end_col = (PetscBool) (i == 0 || i == c->Mx - 1);

  switch (c->pin) {
  case CLOTH_PIN_NONE:
    return PETSC_FALSE;
  case CLOTH_PIN_CORNERS:
    return (PetscBool) (end_col && (j == 0 || last_row));
  case CLOTH_PIN_EDGE_CORNERS:
    return (PetscBool) (end_col && last_row);
  case CLOTH_PIN_EDGE:
    return last_row;
  case CLOTH_PIN_LIST:
    for (PetscInt p = 0; p < c->npin_list; p++)
      if (c->pin_list[2 * p] == i && c->pin_list[2 * p + 1] == j) return PETSC_TRUE;
  }
  return PETSC_FALSE;
}

/* A pin asked for on a lattice particle that a circle or an outline cuts away would
 * silently pin nothing (a Cusick specimen pinned at its corners fell free). Every
 * rank decides alike from the outline: no communication. */
static PetscErrorCode ClothCheckPins(Cloth c)
{
  const char *shape = c->shape == CLOTH_CIRCLE ? "-cloth_shape circle: the disc inscribed in the lattice" : "the outline of -cloth_outline";

  PetscFunctionBeginUser;
  if (c->pin == CLOTH_PIN_LIST)
    for (PetscInt p = 0; p < c->npin_list; p++) {
      const PetscInt i = c->pin_list[2 * p], j = c->pin_list[2 * p + 1];
      PetscCheck(Active(c, i, j), c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin_list entry (%" PetscInt_FMT ",%" PetscInt_FMT ") is outside the cloth (%s); pin particles of the cloth, lattice indices inside it", i, j, shape);
    }
  if (c->pin == CLOTH_PIN_CORNERS || c->pin == CLOTH_PIN_EDGE_CORNERS)
    for (PetscInt k = 0; k < 4; k++) {
      const PetscInt i = k % 2 ? c->Mx - 1 : 0, j = k / 2 ? c->My - 1 : 0;
      if (!IsPinned(c, i, j)) continue;
      PetscCheck(Active(c, i, j), c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin %s pins the lattice corner (%" PetscInt_FMT ",%" PetscInt_FMT "), which is outside the cloth (%s); pin particles of the cloth with -cloth_pin list", pin_names[c->pin], i, j,
                 shape);
    }
  if (c->pin == CLOTH_PIN_EDGE) {
    PetscBool any = PETSC_FALSE;
    for (PetscInt i = 0; i < c->Mx && !any; i++) any = Active(c, i, c->My - 1);
    PetscCheck(any, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin edge pins the last weft row (j = %" PetscInt_FMT "), which is outside the cloth (%s); pin particles of the cloth with -cloth_pin list", c->My - 1, shape);
  }
  PetscFunctionReturn(0);
}

/* Share of the lattice spacing that a boundary row/column carries (1/2). */
/* Area weights from the lattice cells inside the cloth: cell (i, j) has corners (i, j),
 * (i+1, j), (i, j+1), (i+1, j+1) and belongs to the cloth when all four are active
 * (mask value 1; 2 marks a particle being pruned, still a corner). A particle owns a
 * quarter of each of its (up to four) cells, a lattice edge half of each of its (up
 * to two) cells: on the full rectangle the boundary rows get half and the corners a
 * quarter, and a cut outline (circle, polygon) weighs its edge particles and edges by
 * the area they stand for. */
static inline PetscBool CellIn(Cloth c, PetscInt i, PetscInt j)
{
  if (i < 0 || j < 0 || i + 1 >= c->Mx || j + 1 >= c->My) return PETSC_FALSE;
  return (PetscBool) (Active(c, i, j) && Active(c, i + 1, j) && Active(c, i, j + 1) && Active(c, i + 1, j + 1));
}

/* Fraction of a full particle's area dx dy that particle (i, j) stands for. */
static PetscReal ClothCellWeight(Cloth c, PetscInt i, PetscInt j) { return 0.25 * (CellIn(c, i - 1, j - 1) + CellIn(c, i, j - 1) + CellIn(c, i - 1, j) + CellIn(c, i, j)); }

/* Fraction of a full strip width that the warp edge (i, j)-(i+1, j) (warp = PETSC_TRUE)
 * or the weft edge (i, j)-(i, j+1) stands for. */
static PetscReal EdgeCellWeight(Cloth c, PetscBool warp, PetscInt i, PetscInt j) { return warp ? 0.5 * (CellIn(c, i, j - 1) + CellIn(c, i, j)) : 0.5 * (CellIn(c, i - 1, j) + CellIn(c, i, j)); }

/* Share of the area dx dy that particle (i, j) gives the bending triples along
 * (di, dj): half of each of its two lattice edges along a thread (warp or weft), its
 * cells' weight along a diagonal. */
static PetscReal TripleShare(Cloth c, PetscInt i, PetscInt j, PetscInt di, PetscInt dj)
{
  if (dj == 0) return 0.5 * (EdgeCellWeight(c, PETSC_TRUE, i - 1, j) + EdgeCellWeight(c, PETSC_TRUE, i, j));
  if (di == 0) return 0.5 * (EdgeCellWeight(c, PETSC_FALSE, i, j - 1) + EdgeCellWeight(c, PETSC_FALSE, i, j));
  return ClothCellWeight(c, i, j);
}

/* Is there a bending triple along (di, dj) centred on (i, j)? */
static PetscBool TripleIn(Cloth c, PetscInt i, PetscInt j, PetscInt di, PetscInt dj)
{
  if (i - di < 0 || i + di < 0 || i - di >= c->Mx || i + di >= c->Mx || j - dj < 0 || j + dj < 0 || j - dj >= c->My || j + dj >= c->My) return PETSC_FALSE;
  return (PetscBool) (Active(c, i - di, j - dj) && Active(c, i, j) && Active(c, i + di, j + dj));
}

/* Weight of the bending triple along (di, dj) centred on (i, j): its particle's share
 * and, in drape's model, the share of a neighbour on its line that ends the line (no
 * triple is centred there), so that the triples of every line stand for the whole
 * area of its particles. Without the ends a line of n particles bends with n - 2
 * triples for n - 1 segments: where threads meet a cut edge at an angle (a strip at
 * 45 degrees, the Cusick specimen) the sheet is softer by about a spacing over the
 * width (9 % on a 25 mm bias strip at 1.75 mm). A pinned end is held, not bent: the
 * clamp of a cantilever acts at the middle of its last pinned segment, and the
 * triple there keeps its own share. The paper's model keeps the particle's share
 * alone. */
static PetscReal TripleWeight(Cloth c, PetscInt i, PetscInt j, PetscInt di, PetscInt dj)
{
  PetscReal w = TripleShare(c, i, j, di, dj);

  if (c->model == CLOTH_MODEL_DRAPE) {
    if (!TripleIn(c, i - di, j - dj, di, dj) && !IsPinned(c, i - di, j - dj)) w += TripleShare(c, i - di, j - dj, di, dj);
    if (!TripleIn(c, i + di, j + dj, di, dj) && !IsPinned(c, i + di, j + dj)) w += TripleShare(c, i + di, j + dj, di, dj);
  }
  return w;
}

static PetscErrorCode ElementsAllocate(ClothElements *el, PetscInt n, PetscInt nper)
{
  PetscFunctionBeginUser;
  el->n       = 0;
  el->nclass  = 0;
  el->has_law = PETSC_FALSE;
  PetscCall(PetscMalloc3(nper * n + 1, &el->p, n + 1, &el->cls, n + 1, &el->own));
  PetscFunctionReturn(0);
}

static PetscBool LawEqual(const KernelBendLaw *a, const KernelBendLaw *b)
{
  if (a->n != b->n) return PETSC_FALSE;
  if (!a->n) return PETSC_TRUE;
  if (a->L != b->L || a->dk != b->dk) return PETSC_FALSE;
  for (PetscInt i = 0; i < a->n; i++)
    if (a->b[i] != b->b[i]) return PETSC_FALSE;
  return PETSC_TRUE;
}

/* Element e gets the class of (coef, rest, law), a new one if no class has these
 * values; law NULL: none (linear). */
static PetscErrorCode ElementsSetCoefficient(ClothElements *el, PetscInt e, PetscReal coef, PetscReal rest, const KernelBendLaw *law)
{
  const KernelBendLaw none = {0};
  PetscInt            k    = 0;

  PetscFunctionBeginUser;
  if (!law) law = &none;
  while (k < el->nclass && !(el->coef_tab[k] == coef && el->rest_tab[k] == rest && LawEqual(&el->law_tab[k], law))) k++;
  if (k == el->nclass) {
    PetscCheck(k < CLOTH_ELEMENT_CLASSES, PETSC_COMM_SELF, PETSC_ERR_SUP, "More than %d distinct element coefficients in one list", CLOTH_ELEMENT_CLASSES);
    el->coef_tab[k] = coef;
    el->rest_tab[k] = rest;
    el->law_tab[k]  = *law;
    el->nclass++;
  }
  if (law->n) el->has_law = PETSC_TRUE;
  el->cls[e] = (unsigned char) k;
  PetscFunctionReturn(0);
}

/* The law of the bending triples of table row r (0 warp, 1 weft, 2 bias), segments
 * of rest length L; n = 0 (linear) without -cloth_bend_table. */
static void ClothTripleLaw(Cloth c, PetscInt r, PetscReal L, KernelBendLaw *law)
{
  law->n  = c->bend_table ? c->bend_nb : 0;
  law->L  = L;
  law->dk = c->bend_dk;
  for (PetscInt i = 0; i < KERNEL_BEND_LAW_MAX; i++) law->b[i] = i < law->n ? c->bend_b[r][i] : 0;
}

static PetscErrorCode ElementsDestroy(ClothElements *el)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree3(el->p, el->cls, el->own));
  PetscFunctionReturn(0);
}

/* The local index of each lattice particle of a box around the rank's particles
 * (owned and ghosts), -1 for the others: columns i0 .. i0 + w - 1, rows j0 ... */
typedef struct {
  PetscInt  i0, j0, w, h;
  PetscInt *l;
} ClothLocalMap;

static inline PetscInt MapLocal(const ClothLocalMap *m, PetscInt i, PetscInt j)
{
  i -= m->i0, j -= m->j0;
  return i >= 0 && i < m->w && j >= 0 && j < m->h ? m->l[j * m->w + i] : -1;
}

static inline PetscBool MapOwned(const ClothLocalMap *m, PetscInt nowned, PetscInt i, PetscInt j)
{
  const PetscInt l = MapLocal(m, i, j);
  return (PetscBool) (l >= 0 && l < nowned);
}

/* Build the element lists: every element with at least one owned particle (so
 * owned particles receive all their forces without a reverse scatter), in natural
 * lattice order, its energy counted by the owner of its first or vertex particle.
 * Each element is found at its anchor (i, j), a neighbour of each of its particles:
 * the loop runs over the local particles only. */
static PetscErrorCode ClothBuildElements(Cloth c, const ClothLocalMap *map)
{
  const PetscReal    dx = c->spacing[0], dy = c->spacing[1];
  const PetscInt     Mx = c->Mx, My = c->My, nl = c->nlocal, nowned = c->nowned;
  ClothElements     *st = &c->stretch_el, *sh = &c->shear_el, *be = &c->bend_el;
  ClothFrictionList *fr = &c->friction_el;
  KernelBendLaw      law[3]; /* warp, weft and diagonal triples */

#define LOCAL(i, j) MapLocal(map, i, j)
#define OWNED(i, j) MapOwned(map, nowned, i, j)
#define ACT(i, j)   Active(c, i, j)
  PetscFunctionBeginUser;
  PetscCall(ElementsAllocate(st, 2 * nl, 2));
  PetscCall(ElementsAllocate(sh, 4 * nl, 3));
  PetscCall(ElementsAllocate(be, (c->bend_coef[2] > 0 ? 4 : 2) * nl, 3));
  fr->n = 0;
  if (c->hysteresis[0] > 0 || c->hysteresis[1] > 0) PetscCall(PetscMalloc5(5 * 2 * nl, &fr->p, 2 * nl, &fr->own, 2 * nl, &fr->dir, 2 * nl, &fr->area, 2 * nl, &fr->kp));
  ClothTripleLaw(c, 0, dx, &law[0]);
  ClothTripleLaw(c, 1, dy, &law[1]);
  ClothTripleLaw(c, 2, PetscSqrtReal(dx * dx + dy * dy), &law[2]);
  for (PetscInt j = map->j0; j < map->j0 + map->h; j++) {
    for (PetscInt i = map->i0; i < map->i0 + map->w; i++) {
      if (LOCAL(i, j) < 0) continue;
      /* stretch along the warp (i) and the weft (j) */
      if (c->stretch[0] > 0 && i + 1 < Mx && (OWNED(i, j) || OWNED(i + 1, j)) && ACT(i, j) && ACT(i + 1, j)) {
        PetscInt e       = st->n++;
        st->p[2 * e]     = LOCAL(i, j);
        st->p[2 * e + 1] = LOCAL(i + 1, j);
        PetscCall(ElementsSetCoefficient(st, e, c->stretch[0] * dy * EdgeCellWeight(c, PETSC_TRUE, i, j) / dx, dx, NULL));
        st->own[e] = (unsigned char) OWNED(i, j);
      }
      if (c->stretch[1] > 0 && j + 1 < My && (OWNED(i, j) || OWNED(i, j + 1)) && ACT(i, j) && ACT(i, j + 1)) {
        PetscInt e       = st->n++;
        st->p[2 * e]     = LOCAL(i, j);
        st->p[2 * e + 1] = LOCAL(i, j + 1);
        PetscCall(ElementsSetCoefficient(st, e, c->stretch[1] * dx * EdgeCellWeight(c, PETSC_FALSE, i, j) / dy, dy, NULL));
        st->own[e] = (unsigned char) OWNED(i, j);
      }
      /* shear: the four corners of cell (i, j) in a row as (a, b, vertex c), vertices
       * (i,j), (i+1,j), (i,j+1), (i+1,j+1): the force loop reads them as one cell */
      if (c->shear > 0 && i + 1 < Mx && j + 1 < My && (OWNED(i, j) || OWNED(i + 1, j) || OWNED(i, j + 1) || OWNED(i + 1, j + 1)) && ACT(i, j) && ACT(i + 1, j) && ACT(i, j + 1) && ACT(i + 1, j + 1)) {
        const PetscInt corner[4][3] = {
          {LOCAL(i + 1, j), LOCAL(i, j + 1), LOCAL(i, j)}, {LOCAL(i, j), LOCAL(i + 1, j + 1), LOCAL(i + 1, j)}, {LOCAL(i + 1, j + 1), LOCAL(i, j), LOCAL(i, j + 1)}, {LOCAL(i, j + 1), LOCAL(i + 1, j), LOCAL(i + 1, j + 1)}};
        for (PetscInt k = 0; k < 4; k++) {
          PetscInt e = sh->n++;
          for (PetscInt q = 0; q < 3; q++) sh->p[3 * e + q] = corner[k][q];
          PetscCall(ElementsSetCoefficient(sh, e, c->shear / 8, 0, NULL));
          sh->own[e] = (unsigned char) OWNED(i, j);
        }
      }
      /* bending: triples along the warp and the weft centred on (i, j) */
      if (c->bend_coef[0] > 0 && i >= 1 && i + 1 < Mx && (OWNED(i - 1, j) || OWNED(i, j) || OWNED(i + 1, j)) && ACT(i - 1, j) && ACT(i, j) && ACT(i + 1, j)) {
        PetscInt e       = be->n++;
        be->p[3 * e]     = LOCAL(i - 1, j);
        be->p[3 * e + 1] = LOCAL(i + 1, j);
        be->p[3 * e + 2] = LOCAL(i, j);
        PetscCall(ElementsSetCoefficient(be, e, c->bend_coef[0] * dy * TripleWeight(c, i, j, 1, 0) / dx, 0, &law[0]));
        be->own[e] = (unsigned char) OWNED(i, j);
      }
      if (c->bend_coef[1] > 0 && j >= 1 && j + 1 < My && (OWNED(i, j - 1) || OWNED(i, j) || OWNED(i, j + 1)) && ACT(i, j - 1) && ACT(i, j) && ACT(i, j + 1)) {
        PetscInt e       = be->n++;
        be->p[3 * e]     = LOCAL(i, j - 1);
        be->p[3 * e + 1] = LOCAL(i, j + 1);
        be->p[3 * e + 2] = LOCAL(i, j);
        PetscCall(ElementsSetCoefficient(be, e, c->bend_coef[1] * dx * TripleWeight(c, i, j, 0, 1) / dy, 0, &law[1]));
        be->own[e] = (unsigned char) OWNED(i, j);
      }
      /* bending friction: the warp and weft triples centred on (i, j) with the
       * neighbours of (i, j) across them (KernelFriction) */
      for (PetscInt d = 0; d < 2; d++) {
        const PetscInt di = d ? 0 : 1, dj = d ? 1 : 0; /* along the triple; across it: (dj, di) */
        PetscInt       q[5][2] = {{i - di, j - dj}, {i + di, j + dj}, {i, j}, {i - dj, j - di}, {i + dj, j + di}};
        PetscBool      mine    = PETSC_FALSE;
        if (c->hysteresis[d] <= 0 || !TripleIn(c, i, j, di, dj)) continue;
        for (PetscInt a = 3; a < 5; a++)
          if (q[a][0] < 0 || q[a][1] < 0 || q[a][0] >= Mx || q[a][1] >= My || !ACT(q[a][0], q[a][1])) q[a][0] = i, q[a][1] = j; /* the edge: c itself */
        if (q[3][0] == q[4][0] && q[3][1] == q[4][1]) continue;                                                                 /* a lone line: no axis */
        for (PetscInt a = 0; a < 5; a++) mine = (PetscBool) (mine || OWNED(q[a][0], q[a][1]));
        if (!mine) continue;
        PetscInt e = fr->n++;
        for (PetscInt a = 0; a < 5; a++) {
          fr->p[5 * e + a] = LOCAL(q[a][0], q[a][1]);
          PetscCheck(fr->p[5 * e + a] >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "Particle (%" PetscInt_FMT ", %" PetscInt_FMT ") of a friction element is not local", q[a][0], q[a][1]);
        }
        fr->own[e]  = (unsigned char) OWNED(i, j);
        fr->dir[e]  = (unsigned char) d;
        fr->area[e] = dx * dy * TripleWeight(c, i, j, di, dj);
        fr->kp[e]   = 0; /* the flat sheet */
      }
      /* bias: the two diagonal triples centred on an interior (i, j) (ClothBendCoefficients) */
      for (PetscInt s = -1; c->bend_coef[2] > 0 && s <= 1 && i >= 1 && i + 1 < Mx && j >= 1 && j + 1 < My; s += 2) {
        if (!(OWNED(i - 1, j - s) || OWNED(i, j) || OWNED(i + 1, j + s)) || !ACT(i - 1, j - s) || !ACT(i, j) || !ACT(i + 1, j + s)) continue;
        PetscInt e       = be->n++;
        be->p[3 * e]     = LOCAL(i - 1, j - s);
        be->p[3 * e + 1] = LOCAL(i + 1, j + s);
        be->p[3 * e + 2] = LOCAL(i, j);
        PetscCall(ElementsSetCoefficient(be, e, c->bend_coef[2] * (dx * dx + dy * dy) / (2 * dx * dy) * TripleWeight(c, i, j, 1, s), 0, &law[2]));
        be->own[e] = (unsigned char) OWNED(i, j);
      }
    }
  }
#undef LOCAL
#undef OWNED
#undef ACT
  PetscCheck(sh->n % 4 == 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "The shear list must hold whole cells (four corners each); it has %" PetscInt_FMT " corners", sh->n);
  PetscFunctionReturn(0);
}

static PetscInt CountOwned(const ClothElements *el, PetscInt per)
{
  PetscInt n = 0;
  for (PetscInt e = 0; e < el->n; e++) n += el->own[e];
  return n / per;
}

/* Position of lattice particle (i, j) in the initial sheet: flat, or with `imperfect`
 * moved by the imperfection (-cloth_imperfection) along the sheet's normal (the warp
 * crossed with the weft). */
static void InitialPosition(Cloth c, PetscInt i, PetscInt j, PetscBool imperfect, PetscReal x[3])
{
  PetscReal a = i * c->spacing[0] - 0.5 * c->size[0], b = j * c->spacing[1] - 0.5 * c->size[1];
  PetscReal w = imperfect && c->imperfection[0] > 0 ? ClothImperfection(c, a, b) : 0;
  x[0]        = c->origin[0] + a;
  if (c->tilt == 0) {
    x[1] = c->origin[1] + (c->orientation == CLOTH_HORIZONTAL ? b : -w);
    x[2] = c->origin[2] + (c->orientation == CLOTH_HORIZONTAL ? w : b);
  } else { /* turned about the warp direction */
    const PetscReal theta = (c->orientation == CLOTH_HORIZONTAL ? 0 : PETSC_PI / 2) + c->tilt * PETSC_PI / 180;
    x[1]                  = c->origin[1] + b * PetscCosReal(theta) - w * PetscSinReal(theta);
    x[2]                  = c->origin[2] + b * PetscSinReal(theta) + w * PetscCosReal(theta);
  }
}

static PetscBool ActiveCallback(void *ctx, PetscInt i, PetscInt j) { return Active((Cloth) ctx, i, j); }

/* The 12 interaction neighbours (paper Fig. 2), and the 4 of the diagonal bending
 * triples: whatever a kernel of an owned particle touches is owned or one of these
 * ghosts. */
static const PetscInt neighbours[16][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {-1, 1}, {1, -1}, {-1, -1}, {2, 0}, {-2, 0}, {0, 2}, {0, -2}, {2, 2}, {-2, 2}, {2, -2}, {-2, -2}};

PetscErrorCode ClothGetLocalWork(Cloth c, Vec *Yl)
{
  PetscFunctionBeginUser;
  if (!c->Yl) {
    PetscCall(VecCreateSeq(PETSC_COMM_SELF, 3 * c->nlocal, &c->Yl));
    PetscCall(VecSetBlockSize(c->Yl, 3));
  }
  *Yl = c->Yl;
  PetscFunctionReturn(0);
}

/* Global -> local scatter (owned + ghost). Its index lists cost about 48 bytes per
 * local particle while it is made and 24 after, even as a copy (no ghosts): made
 * only where a rank has ghosts or the Hessian's work needs it. Collective. */
static PetscErrorCode ClothBuildGhostScatter(Cloth c)
{
  IS from, to;

  Vec Yl;

  PetscFunctionBeginUser;
  PetscCall(ClothGetLocalWork(c, &Yl));
  PetscCall(ISCreateBlock(c->comm, 3, c->nlocal, c->global, PETSC_USE_POINTER, &from));
  PetscCall(ISCreateStride(PETSC_COMM_SELF, 3 * c->nlocal, 0, 1, &to));
  PetscCall(VecScatterCreate(c->Xg, from, Yl, to, &c->ghost));
  PetscCall(ISDestroy(&from));
  PetscCall(ISDestroy(&to));
  PetscFunctionReturn(0);
}

/* Local layout from the partition's destinations (dest: the new owner of each
 * particle of this rank's home block, PartitionDestinations): owned particles first
 * (natural order), then the ghosts, the neighbours the kernels of owned particles
 * touch (natural order); global block numbers rank by rank; ghost scatter where some
 * rank has ghosts. Nothing of the whole lattice is held: with the DMDA's blocks a
 * particle's owner and global number are functions of (i, j); with a graph
 * partition each rank receives its particles from their home ranks, tells the home
 * ranks their global numbers, and asks them for those of its ghosts (a PetscSF whose
 * roots are the home blocks: communication of the ghost layer). map: the local
 * index of each particle of a box around the local ones. */
static PetscErrorCode ClothBuildLayout(Cloth c, const PartitionBlocks *b, const PetscInt *dest, ClothLocalMap *map)
{
  const PetscInt  Mx = c->Mx, My = c->My, nneighbour = c->bend_coef[2] > 0 ? 16 : 12;
  const PetscBool graph = PartitionIsGraph(c->partition);
  PetscMPIInt     rank, size;
  PetscInt        i0, i1, j0, j1, nb, *owned, nghost = 0, *home_global = NULL;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(c->comm, &rank));
  PetscCallMPI(MPI_Comm_size(c->comm, &size));
  i0 = b->x0[rank % b->m], i1 = b->x0[rank % b->m + 1], j0 = b->y0[rank / b->m], j1 = b->y0[rank / b->m + 1], nb = (i1 - i0) * (j1 - j0);
  if (!graph) { /* the home block */
    c->nowned = nb;
    PetscCall(PetscMalloc1(nb + 1, &owned));
    for (PetscInt j = j0, k = 0; j < j1; j++)
      for (PetscInt i = i0; i < i1; i++) owned[k++] = j * Mx + i;
    c->rstart = nb ? PartitionBlockNumber(b, i0, j0) : 0;
  } else { /* each home particle to its destination: counts, then the natural numbers */
    PetscMPIInt *scount, *sdispl, *rcount, *rdispl;
    PetscInt    *send, *place, *perm, *back, *got, nrecv, end;
    PetscCall(PetscCalloc4(size, &scount, size + 1, &sdispl, size, &rcount, size + 1, &rdispl));
    for (PetscInt k = 0; k < nb; k++) scount[dest[k]]++;
    for (PetscMPIInt r = 0; r < size; r++) sdispl[r + 1] = sdispl[r] + scount[r];
    PetscCallMPI(MPI_Alltoall(scount, 1, MPI_INT, rcount, 1, MPI_INT, c->comm));
    for (PetscMPIInt r = 0; r < size; r++) rdispl[r + 1] = rdispl[r] + rcount[r];
    nrecv = rdispl[size];
    PetscCall(PetscMalloc3(nb + 1, &send, nb + 1, &place, nb + 1, &got));
    for (PetscMPIInt r = 0; r < size; r++) scount[r] = 0;
    for (PetscInt k = 0; k < nb; k++) {
      place[k]       = sdispl[dest[k]] + scount[dest[k]]++;
      send[place[k]] = (j0 + k / (i1 - i0)) * Mx + i0 + k % (i1 - i0);
    }
    PetscCall(PetscMalloc1(nrecv + 1, &owned));
    PetscCall(PetscMalloc2(nrecv + 1, &perm, nrecv + 1, &back));
    PetscCallMPI(MPI_Alltoallv(send, scount, sdispl, MPIU_INT, owned, rcount, rdispl, MPIU_INT, c->comm));
    for (PetscInt q = 0; q < nrecv; q++) perm[q] = q;
    PetscCall(PetscSortIntWithArray(nrecv, owned, perm));
    c->nowned = nrecv;
    PetscCallMPI(MPI_Scan(&c->nowned, &end, 1, MPIU_INT, MPI_SUM, c->comm));
    c->rstart = end - c->nowned;
    /* the home ranks learn the global numbers of their particles */
    for (PetscInt k = 0; k < nrecv; k++) back[perm[k]] = c->rstart + k;
    PetscCallMPI(MPI_Alltoallv(back, rcount, rdispl, MPIU_INT, got, scount, sdispl, MPIU_INT, c->comm));
    PetscCall(PetscMalloc1(nb + 1, &home_global));
    for (PetscInt k = 0; k < nb; k++) home_global[k] = got[place[k]];
    PetscCall(PetscFree3(send, place, got));
    PetscCall(PetscFree4(scount, sdispl, rcount, rdispl));
    PetscCall(PetscFree2(perm, back));
  }
  /* the box of the owned particles and their neighbours; with a graph partition, of
   * the active ones (the inactive, in no element, are shared out over the ranks
   * wherever they lie: PartitionDestinations), and every rank has some */
  {
    PetscInt imin = Mx, imax = -1, jmin = My, jmax = -1;
    for (PetscInt k = 0; k < c->nowned; k++) {
      const PetscInt i = owned[k] % Mx, j = owned[k] / Mx;
      if (graph && !Active(c, i, j)) continue;
      imin = PetscMin(imin, i), imax = PetscMax(imax, i), jmin = PetscMin(jmin, j), jmax = PetscMax(jmax, j);
    }
    map->i0 = PetscMax(imin - 2, 0), map->j0 = PetscMax(jmin - 2, 0);
    map->w = imax >= 0 ? PetscMin(imax + 3, Mx) - map->i0 : 0;
    map->h = imax >= 0 ? PetscMin(jmax + 3, My) - map->j0 : 0;
  }
  PetscCall(PetscMalloc1(map->w * map->h + 1, &map->l));
  for (PetscInt q = 0; q < map->w * map->h; q++) map->l[q] = -1;
  for (PetscInt k = 0; k < c->nowned; k++) {
    const PetscInt i = owned[k] % Mx - map->i0, j = owned[k] / Mx - map->j0;
    if (i >= 0 && i < map->w && j >= 0 && j < map->h) map->l[j * map->w + i] = k;
  }
  /* the ghosts: the other particles of the box with an owned neighbour (a ghost's
   * number marks it; the owned are those below nowned) */
  for (PetscInt q = 0; q < map->w * map->h; q++) {
    const PetscInt i = map->i0 + q % map->w, j = map->j0 + q / map->w;
    if (map->l[q] >= 0) continue;
    for (PetscInt s = 0; s < nneighbour; s++) {
      const PetscInt l = MapLocal(map, i + neighbours[s][0], j + neighbours[s][1]);
      if (l >= 0 && l < c->nowned) {
        map->l[q] = c->nowned + nghost++;
        break;
      }
    }
  }
  c->nlocal = c->nowned + nghost;
  PetscCall(PetscMalloc1(c->nlocal + 1, &c->natural));
  PetscCall(PetscArraycpy(c->natural, owned, c->nowned));
  PetscCall(PetscFree(owned));
  for (PetscInt q = 0; q < map->w * map->h; q++)
    if (map->l[q] >= c->nowned) c->natural[map->l[q]] = (map->j0 + q / map->w) * Mx + map->i0 + q % map->w;
  /* global block numbers; one array where they are the natural ones (one rank) */
  PetscCall(PetscMalloc1(c->nlocal + 1, &c->global));
  for (PetscInt k = 0; k < c->nowned; k++) c->global[k] = c->rstart + k;
  if (!graph)
    for (PetscInt g = c->nowned; g < c->nlocal; g++) c->global[g] = PartitionBlockNumber(b, c->natural[g] % Mx, c->natural[g] / Mx);
  else { /* the ghosts' from their home ranks */
    PetscSF      sf;
    PetscSFNode *remote;
    PetscCall(PetscMalloc1(nghost + 1, &remote));
    for (PetscInt g = 0; g < nghost; g++) {
      const PetscInt    i = c->natural[c->nowned + g] % Mx, j = c->natural[c->nowned + g] / Mx;
      const PetscMPIInt r  = PartitionBlockRank(b, i, j);
      const PetscInt    a0 = b->x0[r % b->m], a1 = b->x0[r % b->m + 1], b0 = b->y0[r / b->m];
      remote[g].rank  = r;
      remote[g].index = (j - b0) * (a1 - a0) + i - a0;
    }
    PetscCall(PetscSFCreate(c->comm, &sf));
    PetscCall(PetscSFSetGraph(sf, nb, nghost, NULL, PETSC_COPY_VALUES, remote, PETSC_OWN_POINTER));
    PetscCall(PetscSFBcastBegin(sf, MPIU_INT, home_global, c->global + c->nowned, MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(sf, MPIU_INT, home_global, c->global + c->nowned, MPI_REPLACE));
    PetscCall(PetscSFDestroy(&sf));
    PetscCall(PetscFree(home_global));
  }
  {
    PetscBool same = PETSC_TRUE;
    for (PetscInt l = 0; l < c->nlocal && same; l++) same = (PetscBool) (c->global[l] == c->natural[l]);
    if (same) {
      PetscCall(PetscFree(c->global));
      c->global = c->natural;
    }
  }
  /* the global vector only ever wraps caller arrays; the ghost scatter and the local
   * copy of the positions are made where the element lists' loops first need them
   * (ClothSetUpGhosts): the explicit schemes' lattice kernel has its own */
  PetscCall(VecCreateMPIWithArray(c->comm, 3, 3 * c->nowned, PETSC_DETERMINE, NULL, &c->Xg));
  PetscCall(MPIU_Allreduce(MPI_IN_PLACE, &nghost, 1, MPIU_INT, MPI_MAX, c->comm));
  c->any_ghost = (PetscBool) (nghost > 0);
  PetscFunctionReturn(0);
}

PetscErrorCode ClothSetUpGhosts(Cloth c)
{
  PetscFunctionBeginUser;
  if (c->any_ghost && !c->ghost) PetscCall(ClothBuildGhostScatter(c));
  if (c->nlocal > c->nowned && !c->Xl) {
    PetscCall(VecCreateSeq(PETSC_COMM_SELF, 3 * c->nlocal, &c->Xl));
    PetscCall(VecSetBlockSize(c->Xl, 3));
  }
  PetscFunctionReturn(0);
}

/* Scatter between the Cloth's particle order and the DMDA's (I/O in natural
 * order); NULL when they are the same (the DMDA partition, or one rank). The DMDA's
 * numbering is computed from its ownership ranges (PartitionBlockNumber), not asked
 * of its AO, which would keep two more integers for every unknown for the rest of
 * the run. */
static PetscErrorCode ClothBuildDMDAScatter(Cloth c, const PartitionBlocks *b)
{
  PetscInt   *idx;
  PetscMPIInt rank;
  IS          from, to;
  Vec         Xda;
  PetscBool   same = PETSC_TRUE;

  PetscFunctionBeginUser;
  if (!PartitionIsGraph(c->partition)) PetscFunctionReturn(0);
  PetscCallMPI(MPI_Comm_rank(c->comm, &rank));
  PetscCall(PetscMalloc1(c->nowned + 1, &idx));
  for (PetscInt k = 0; k < c->nowned; k++) {
    idx[k] = PartitionBlockNumber(b, c->natural[k] % c->Mx, c->natural[k] / c->Mx);
    same   = (PetscBool) (same && idx[k] == c->rstart + k);
  }
  PetscCall(MPIU_Allreduce(MPI_IN_PLACE, &same, 1, MPIU_BOOL, MPI_LAND, c->comm));
  if (!same) {
    const PetscInt lx = b->x0[rank % b->m + 1] - b->x0[rank % b->m], ly = b->y0[rank / b->m + 1] - b->y0[rank / b->m];
    PetscCall(ISCreateBlock(c->comm, 3, c->nowned, idx, PETSC_USE_POINTER, &to));
    PetscCall(ISCreateStride(c->comm, 3 * c->nowned, 3 * c->rstart, 1, &from));
    PetscCall(VecCreateMPIWithArray(c->comm, 3, 3 * lx * ly, PETSC_DETERMINE, NULL, &Xda));
    PetscCall(VecScatterCreate(c->Xg, from, Xda, to, &c->to_dmda));
    PetscCall(VecDestroy(&Xda));
    PetscCall(ISDestroy(&from));
    PetscCall(ISDestroy(&to));
  }
  PetscCall(PetscFree(idx));
  PetscFunctionReturn(0);
}

static PetscInt WeightCallback(void *ctx, PetscInt i, PetscInt j)
{
  Cloth     c = (Cloth) ctx;
  PetscReal x[3];

  InitialPosition(c, i, j, PETSC_FALSE, x);
  return c->work(c->work_ctx, x);
}

PetscErrorCode ClothSetUp(Cloth c)
{
  PetscInt       *dest, counts[5], sums[5], i0, i1, j0, j1;
  PetscReal       mass;
  PetscMPIInt     rank;
  PartitionBlocks blocks;
  ClothLocalMap   map;

  PetscFunctionBeginUser;
  if (c->setup) PetscFunctionReturn(0);
  PetscCall(PetscLogEventBegin(drape_log.cloth_setup, 0, 0, 0, 0));
  PetscCallMPI(MPI_Comm_rank(c->comm, &rank));
  PetscCall(DMDACreate2d(c->comm, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DMDA_STENCIL_BOX, c->Mx, c->My, PETSC_DECIDE, PETSC_DECIDE, 3, 0, NULL, NULL, &c->da)); /* for I/O only: no ghosts */
  PetscCall(DMSetFromOptions(c->da));
  {
    PetscInt Mx, My; /* -da_refine and -da_grid_* reach the DMDA here */
    PetscCall(DMDAGetInfo(c->da, NULL, &Mx, &My, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
    if (Mx != c->Mx || My != c->My) PetscCall(ClothCheckLatticeSize(c, Mx, My));
  }
  PetscCall(DMSetUp(c->da));
  PetscCall(DMDASetFieldName(c->da, 0, "x"));
  PetscCall(DMDASetFieldName(c->da, 1, "y"));
  PetscCall(DMDASetFieldName(c->da, 2, "z"));
  PetscCall(DMDAGetInfo(c->da, NULL, &c->Mx, &c->My, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
  c->spacing[0]    = c->size[0] / (c->Mx - 1);
  c->spacing[1]    = c->size[1] / (c->My - 1);
  c->friction[0].L = c->spacing[0];
  c->friction[1].L = c->spacing[1];

  /* the home block (this rank's DMDA block) and, for a cut outline, its activity
   * with a frame wide enough for the graph's and the elements' neighbours */
  PetscCall(PartitionBlocksCreate(c->da, &blocks));
  i0 = blocks.x0[rank % blocks.m], i1 = blocks.x0[rank % blocks.m + 1], j0 = blocks.y0[rank / blocks.m], j1 = blocks.y0[rank / blocks.m + 1];
  if (c->shape != CLOTH_SQUARE) {
    PetscInt nact = 0;
    PetscCall(ClothActivityPatch(c, i0 - 4, i1 + 4, j0 - 4, j1 + 4));
    for (PetscInt j = j0; j < j1; j++)
      for (PetscInt i = i0; i < i1; i++) nact += Active(c, i, j);
    PetscCall(MPIU_Allreduce(MPI_IN_PLACE, &nact, 1, MPIU_INT, MPI_SUM, c->comm));
    PetscCheck(nact > 0, c->comm, PETSC_ERR_USER_INPUT, "No lattice particle lies inside the cloth's outline; check -cloth_outline against -cloth_size");
    PetscCall(ClothCheckPins(c));
  }
  PetscCall(PetscMalloc1((i1 - i0) * (j1 - j0) + 1, &dest));
  PetscCall(PetscLogEventBegin(drape_log.partition, 0, 0, 0, 0));
  PetscCall(PartitionDestinations(c->comm, c->partition, &blocks, ActiveCallback, c->work ? WeightCallback : NULL, c, dest));
  PetscCall(PetscLogEventEnd(drape_log.partition, 0, 0, 0, 0));
  PetscCall(ClothBuildLayout(c, &blocks, dest, &map));
  PetscCall(PetscFree(dest));
  if (c->shape != CLOTH_SQUARE && PartitionIsGraph(c->partition)) PetscCall(ClothActivityPatch(c, map.i0 - 2, map.i0 + map.w + 2, map.j0 - 2, map.j0 + map.h + 2));
  PetscCall(ClothBuildDMDAScatter(c, &blocks));
  PetscCall(PartitionBlocksDestroy(&blocks));
#if defined(__GLIBC__)
  /* What the set-up has freed by now (a graph partition's transient memory: the
   * MATMPIADJ graph, PT-Scotch's own, the exchange of particles, 43-51 MiB a rank at
   * 2048^2 on 16 ranks, where a rank's share of the lattice is about 70 MiB; 36 MB
   * on one rank with the DMDA's blocks) the C library's heap keeps, in small pieces:
   * hand it back before the element lists, the largest arrays, are made (2048^2,
   * -memory_view: ptscotch on 16 ranks 7 % less, all ranks and the largest; dmda on
   * one rank 900 -> 864 MB; BENCHMARKS.md) */
  (void) malloc_trim(0);
#endif

  PetscCall(PetscMalloc3(c->nowned, &c->mass, c->nowned, &c->pinned, c->nowned, &c->active));
  /* the owned particles come first in the local order: owned_local is 0, 1, ...,
   * which the natural (or global) numbers already are on one rank (on rank 0) */
  c->owned_local = c->natural;
  for (PetscInt k = 0; k < c->nowned && c->owned_local; k++)
    if (c->natural[k] != k) c->owned_local = NULL;
  if (!c->owned_local && c->rstart == 0) c->owned_local = c->global;
  if (!c->owned_local) {
    PetscCall(PetscMalloc1(c->nowned, &c->owned_local));
    for (PetscInt k = 0; k < c->nowned; k++) c->owned_local[k] = k;
  }
  mass = 0;
  for (PetscInt k = 0; k < c->nowned; k++) {
    PetscInt i = c->natural[k] % c->Mx, j = c->natural[k] / c->Mx;
    c->active[k] = Active(c, i, j);
    c->mass[k]   = c->density * c->spacing[0] * c->spacing[1] * (c->active[k] ? ClothCellWeight(c, i, j) : 1); /* inactive: held like a pin, a nominal mass for the matrix */
    c->pinned[k] = (PetscBool) (IsPinned(c, i, j) || !c->active[k]);
    if (c->active[k]) mass += c->mass[k];
  }
  {
    PetscInt  nmax;
    PetscBool fits;
    PetscCall(ClothCheckRankIndex(c, c->nlocal, CLOTH_LIST_ENTRIES, &nmax, &fits));
    PetscCheck(fits, c->comm, PETSC_ERR_USER_INPUT,
               "A rank holds %" PetscInt_FMT " particles of the %" PetscInt_FMT " x %" PetscInt_FMT " lattice, more than this PETSc build's %d-bit PetscInt indexes in its element lists (%d entries per particle: at most %" PetscInt_FMT
               "): run on more ranks%s",
               nmax, c->Mx, c->My, (int) (8 * sizeof(PetscInt)), CLOTH_LIST_ENTRIES, PETSC_MAX_INT / CLOTH_LIST_ENTRIES, sizeof(PetscInt) < 8 ? ", or build PETSc with --with-64-bit-indices" : "");
  }
  PetscCall(ClothBuildElements(c, &map));
  PetscCall(PetscFree(map.l));
  PetscCall(ClothLatticeSetUp(c));
  /* partition quality: owned active particles and cut stretch edges */
  counts[0] = CountOwned(&c->stretch_el, 1);
  counts[1] = CountOwned(&c->shear_el, 4);
  counts[2] = CountOwned(&c->bend_el, 1);
  counts[3] = 0;
  counts[4] = 0;
  for (PetscInt k = 0; k < c->nowned; k++) counts[3] += c->pinned[k] && c->active[k];
  for (PetscInt e = 0; e < c->stretch_el.n; e++)
    if (c->stretch_el.own[e] && (c->stretch_el.p[2 * e] >= c->nowned || c->stretch_el.p[2 * e + 1] >= c->nowned)) counts[4]++;
  PetscCall(MPIU_Allreduce(counts, sums, 5, MPIU_INT, MPI_SUM, c->comm));
  PetscCall(MPIU_Allreduce(&mass, &c->total_mass, 1, MPIU_REAL, MPI_SUM, c->comm));
  c->nstretch = sums[0];
  c->nshear   = sums[1];
  c->nbend    = sums[2];
  c->npinned  = sums[3];
  c->ncut     = sums[4];
  {
    PetscInt act = 0, range[4]; /* -min, max of the active particles a rank owns, and of all it owns */
    for (PetscInt k = 0; k < c->nowned; k++) act += c->active[k];
    range[0] = -act, range[1] = act, range[2] = -c->nowned, range[3] = c->nowned;
    PetscCall(MPIU_Allreduce(MPI_IN_PLACE, range, 4, MPIU_INT, MPI_MAX, c->comm));
    PetscCall(MPIU_Allreduce(&act, &sums[0], 1, MPIU_INT, MPI_SUM, c->comm));
    c->active_total = sums[0];
    c->owned_min    = -range[0];
    c->owned_max    = range[1];
    c->held_min     = -range[2];
    c->held_max     = range[3];
  }
  c->setup = PETSC_TRUE;
  PetscCall(PetscLogEventEnd(drape_log.cloth_setup, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothSetUpImplicit(Cloth c)
{
  PetscFunctionBeginUser;
  PetscCheck(c->setup, c->comm, PETSC_ERR_ORDER, "ClothSetUpImplicit needs ClothSetUp first");
  if (c->Zl) PetscFunctionReturn(0);
  { /* before the matrix: its indices per rank, and the memory the implicit step needs */
    PetscInt       nmax;
    PetscBool      fits;
    PetscMPIInt    local;
    MPI_Comm       node;
    PetscLogDouble need, node_bytes, process_bytes;
    PetscCall(ClothCheckRankIndex(c, c->nowned, CLOTH_MATRIX_ENTRIES, &nmax, &fits));
    PetscCheck(fits, c->comm, PETSC_ERR_USER_INPUT,
               "A rank owns %" PetscInt_FMT " particles of the %" PetscInt_FMT " x %" PetscInt_FMT " lattice, more than this PETSc build's %d-bit PetscInt indexes in the implicit matrix's entries (up to %d per particle: at most %" PetscInt_FMT
               "): run on more ranks%s",
               nmax, c->Mx, c->My, (int) (8 * sizeof(PetscInt)), CLOTH_MATRIX_ENTRIES, PETSC_MAX_INT / CLOTH_MATRIX_ENTRIES, sizeof(PetscInt) < 8 ? ", or build PETSc with --with-64-bit-indices" : "");
    PetscCallMPI(MPI_Comm_split_type(c->comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node));
    PetscCallMPI(MPI_Comm_size(node, &local));
    PetscCallMPI(MPI_Comm_free(&node));
    PetscCall(DrapeMemoryAvailable(&node_bytes, &process_bytes));
    need = CLOTH_IMPLICIT_BYTES * (PetscLogDouble) nmax;
    fits = (PetscBool) (need * local <= node_bytes && need <= process_bytes);
    PetscCall(MPIU_Allreduce(MPI_IN_PLACE, &fits, 1, MPIU_BOOL, MPI_LAND, c->comm));
    PetscCheck(fits, c->comm, PETSC_ERR_USER_INPUT,
               "The implicit step (drapebe) on a %" PetscInt_FMT " x %" PetscInt_FMT " lattice needs at least %.1f GB per rank (%.0f bytes per particle, %" PetscInt_FMT
               " particles on the largest rank; %.1f GB on a node running %d ranks), more than this machine gives a run (%.1f GB per node%s): use an explicit scheme (-ts_type basicsymplectic), a smaller lattice, or more nodes",
               c->Mx, c->My, need / 1e9, CLOTH_IMPLICIT_BYTES, nmax, need * local / 1e9, (int) local, node_bytes / 1e9, process_bytes < node_bytes ? ", less per process" : "");
  }
  if (!c->ghost) PetscCall(ClothBuildGhostScatter(c));
  PetscCall(ClothSetUpGhosts(c));
  PetscCall(VecCreateSeq(PETSC_COMM_SELF, 3 * c->nlocal, &c->Zl));
  PetscCall(VecSetBlockSize(c->Zl, 3));
  PetscCall(PetscMalloc1(c->nlocal, &c->col_map));
  PetscCall(PetscMalloc1(c->nlocal, &c->pinned_local));
  for (PetscInt l = 0; l < c->nlocal; l++) {
    PetscInt i = c->natural[l] % c->Mx, j = c->natural[l] / c->Mx;
    c->pinned_local[l] = (PetscBool) (IsPinned(c, i, j) || !Active(c, i, j));
    c->col_map[l]      = c->pinned_local[l] ? -1 : c->global[l];
  }
  if (c->nlocal == c->nowned) /* no ghosts: every row is a column */
    c->row_map = c->col_map;
  else {
    PetscCall(PetscMalloc1(c->nlocal, &c->row_map));
    for (PetscInt l = 0; l < c->nlocal; l++) c->row_map[l] = l < c->nowned ? c->col_map[l] : -1;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ClothDestroy(Cloth *cloth)
{
  Cloth c = *cloth;

  PetscFunctionBeginUser;
  if (!c) PetscFunctionReturn(0);
  PetscCall(PetscFree(c->pin_list));
  PetscCall(PetscFree(c->act));
  PetscCall(PetscFree(c->ring_xy));
  PetscCall(PetscFree(c->ring_start));
  if (c->setup) {
    PetscCall(ClothLatticeDestroy(c));
    PetscCall(ElementsDestroy(&c->stretch_el));
    PetscCall(ElementsDestroy(&c->shear_el));
    PetscCall(ElementsDestroy(&c->bend_el));
    PetscCall(PetscFree3(c->mass, c->pinned, c->active));
    if (c->owned_local != c->natural && c->owned_local != c->global) PetscCall(PetscFree(c->owned_local));
    if (c->row_map != c->col_map) PetscCall(PetscFree(c->row_map));
    PetscCall(PetscFree(c->col_map));
    PetscCall(PetscFree(c->pinned_local));
    if (c->global != c->natural) PetscCall(PetscFree(c->global));
    PetscCall(PetscFree(c->natural));
    PetscCall(PetscFree3(c->ctype, c->cnormal, c->cblock));
    PetscCall(PetscFree(c->hdiag));
    PetscCall(PetscFree5(c->rb_start, c->rb_ncols, c->rb_colstart, c->rb_map, c->rb_diag));
    PetscCall(PetscFree(c->rb_cols));
    PetscCall(PetscFree(c->rb_val));
    PetscCall(PetscFree(c->rb_chunk));
    PetscCall(PetscFree5(c->rb_lo, c->rb_cut, c->rb_done, c->rb_vstart, c->rb_gstart));
    PetscCall(PetscFree(c->rb_gval));
    PetscCall(PetscFree4(c->ex_row, c->ex_col, c->ex_map, c->ex_val));
    PetscCall(PetscFree2(c->px_row, c->px_col));
    if (c->friction_el.p) PetscCall(PetscFree5(c->friction_el.p, c->friction_el.own, c->friction_el.dir, c->friction_el.area, c->friction_el.kp));
  }
  PetscCall(VecDestroy(&c->Xg));
  PetscCall(VecDestroy(&c->Xl));
  PetscCall(VecDestroy(&c->Yl));
  PetscCall(VecDestroy(&c->Zl));
  PetscCall(VecScatterDestroy(&c->ghost));
  PetscCall(VecScatterDestroy(&c->to_dmda));
  PetscCall(DMDestroy(&c->da));
  PetscCall(PetscFree(*cloth));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothGetInfo(Cloth c, ClothInfo *info)
{
  PetscFunctionBeginUser;
  info->Mx             = c->Mx;
  info->My             = c->My;
  info->nparticles     = c->Mx * c->My;
  info->npinned        = c->npinned;
  info->nactive        = (PetscInt) c->active_total;
  info->owned_min      = c->owned_min;
  info->owned_max      = c->owned_max;
  info->held_min       = c->held_min;
  info->held_max       = c->held_max;
  info->ncut           = c->ncut;
  info->partition      = c->partition;
  info->model          = model_names[c->model];
  info->bend_table     = c->bend_table;
  info->hysteresis[0]  = c->hysteresis[0];
  info->hysteresis[1]  = c->hysteresis[1];
  info->hyst_stiffness = c->hyst_stiffness;
  info->nstretch       = c->nstretch;
  info->nshear         = c->nshear;
  info->nbend          = c->nbend;
  info->nowned         = c->nowned;
  info->mass           = c->total_mass;
  info->density        = c->density;
  info->damping        = c->damping;
  info->shear          = c->shear;
  for (PetscInt d = 0; d < 3; d++) info->gravity[d] = c->gravity[d];
  info->bend[2] = c->bend[2];
  for (PetscInt d = 0; d < 2; d++) {
    info->size[d]    = c->size[d];
    info->spacing[d] = c->spacing[d];
    info->stretch[d] = c->stretch[d];
    info->bend[d]    = c->bend[d];
  }

  info->imperfection[0]   = c->imperfection[0];
  info->imperfection[1]   = c->imperfection[1];
  info->imperfection_seed = c->imperfection_seed;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothGetDM(Cloth c, DM *da)
{
  PetscFunctionBeginUser;
  *da = c->da;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothGetMasses(Cloth c, const PetscReal **mass, const PetscBool **pinned)
{
  PetscFunctionBeginUser;
  if (mass) *mass = c->mass;
  if (pinned) *pinned = c->pinned;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothSetInitialState(Cloth c, PetscScalar *x, PetscScalar *v)
{
  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < c->nowned; k++) {
    InitialPosition(c, c->natural[k] % c->Mx, c->natural[k] / c->Mx, PETSC_TRUE, x + 3 * k);
    for (PetscInt d = 0; d < 3; d++) v[3 * k + d] = 0;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ClothSetPartitionWeight(Cloth c, PetscInt (*work)(void *, const PetscReal x[3]), void *ctx)
{
  PetscFunctionBeginUser;
  c->work     = work;
  c->work_ctx = ctx;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothGetNatural(Cloth c, const PetscInt **natural)
{
  PetscFunctionBeginUser;
  *natural = c->natural;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothCreateVector(Cloth c, Vec *X)
{
  PetscFunctionBeginUser;
  PetscCall(VecCreateMPI(c->comm, 3 * c->nowned, PETSC_DETERMINE, X));
  PetscCall(VecSetBlockSize(*X, 3));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothToDMDA(Cloth c, const PetscScalar *x, Vec Xda)
{
  PetscFunctionBeginUser;
  if (!c->to_dmda) {
    PetscScalar *a;
    PetscCall(VecGetArray(Xda, &a));
    PetscCall(PetscArraycpy(a, x, 3 * c->nowned));
    PetscCall(VecRestoreArray(Xda, &a));
  } else {
    PetscCall(VecPlaceArray(c->Xg, x));
    PetscCall(VecScatterBegin(c->to_dmda, c->Xg, Xda, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterEnd(c->to_dmda, c->Xg, Xda, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecResetArray(c->Xg));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ClothFromDMDA(Cloth c, Vec Xda, PetscScalar *x)
{
  PetscFunctionBeginUser;
  if (!c->to_dmda) {
    const PetscScalar *a;
    PetscCall(VecGetArrayRead(Xda, &a));
    PetscCall(PetscArraycpy(x, a, 3 * c->nowned));
    PetscCall(VecRestoreArrayRead(Xda, &a));
  } else {
    PetscCall(VecPlaceArray(c->Xg, x));
    PetscCall(VecScatterBegin(c->to_dmda, Xda, c->Xg, INSERT_VALUES, SCATTER_REVERSE));
    PetscCall(VecScatterEnd(c->to_dmda, Xda, c->Xg, INSERT_VALUES, SCATTER_REVERSE));
    PetscCall(VecResetArray(c->Xg));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ClothView(Cloth c, PetscViewer viewer)
{
  PetscFunctionBeginUser;
  PetscCall(PetscViewerASCIIPrintf(viewer, "Cloth: %" PetscInt_FMT " x %" PetscInt_FMT " particles (%g x %g m, spacing %g x %g m), %" PetscInt_FMT " pinned, mass %g kg\n", c->Mx, c->My, (double) c->size[0], (double) c->size[1],
                                   (double) c->spacing[0], (double) c->spacing[1], c->npinned, (double) c->total_mass));
  PetscCall(PetscViewerASCIIPrintf(viewer, "  interactions: %" PetscInt_FMT " stretch edges, %" PetscInt_FMT " shear cells, %" PetscInt_FMT " bending triples\n", c->nstretch, c->nshear, c->nbend));
  {
    PetscMPIInt size;
    PetscCallMPI(MPI_Comm_size(c->comm, &size));
    if (size > 1)
      PetscCall(PetscViewerASCIIPrintf(viewer,
                                       "  partition: %s on %d ranks, %" PetscInt_FMT " to %" PetscInt_FMT " active particles per rank (imbalance %.3f; %" PetscInt_FMT " to %" PetscInt_FMT " with those outside the outline), %" PetscInt_FMT
                                       " of %" PetscInt_FMT " stretch edges cut\n",
                                       c->partition, size, c->owned_min, c->owned_max, (double) (c->owned_max * size / PetscMax(c->active_total, 1)), c->held_min, c->held_max, c->ncut, c->nstretch));
  }
  if (c->fabric[0]) PetscCall(PetscViewerASCIIPrintf(viewer, "  fabric: %s\n", c->fabric));
  PetscCall(PetscViewerASCIIPrintf(viewer, "  material: stretch %g,%g N/m, shear %g N/m, bend %g,%g,%g N m (warp, weft, bias), density %g kg/m^2, damping %g 1/s\n", (double) c->stretch[0], (double) c->stretch[1], (double) c->shear,
                                   (double) c->bend[0], (double) c->bend[1], (double) c->bend[2], (double) c->density, (double) c->damping));
  PetscCall(PetscViewerASCIIPrintf(viewer, "  model: %s (%s)\n", model_names[c->model],
                                   c->model == CLOTH_MODEL_PAPER ? "the paper's thread triples: no twist rigidity, a 45 degree strip bends at (warp + weft)/4 or less" : "thread triples and diagonal triples: warp, weft and bias bending rigidity"));
  if (c->imperfection[0] > 0)
    PetscCall(PetscViewerASCIIPrintf(viewer, "  initial imperfection (-cloth_imperfection): %g m rms out of plane, wavelength %g m, seed %" PetscInt_FMT "\n", (double) c->imperfection[0], (double) c->imperfection[1], c->imperfection_seed));
  if (c->hysteresis[0] > 0 || c->hysteresis[1] > 0)
    PetscCall(PetscViewerASCIIPrintf(viewer, "  bending hysteresis (-cloth_bend_hysteresis): 2HB %g,%g N m/m (warp, weft; friction moment HB = 2HB/2 per unit width), stick stiffness %g x B: stick range %.3g,%.3g 1/m\n", (double) c->hysteresis[0],
                                     (double) c->hysteresis[1], (double) c->hyst_stiffness, (double) (c->friction[0].K > 0 ? c->friction[0].hb / c->friction[0].K : 0), (double) (c->friction[1].K > 0 ? c->friction[1].hb / c->friction[1].K : 0)));
  if (c->bend_table) {
    static const char *rows[3] = {"warp", "weft", "bias"};
    PetscCall(PetscViewerASCIIPrintf(viewer, "  bending varies with curvature (-cloth_bend_table), relative rigidity at 0, %.4g, ..., %.4g 1/m, held beyond:", (double) c->bend_dk, (double) ((c->bend_nb - 1) * c->bend_dk)));
    for (PetscInt r = 0; r < (c->model == CLOTH_MODEL_PAPER ? 2 : 3); r++) {
      PetscCall(PetscViewerASCIIPrintf(viewer, " %s", rows[r]));
      for (PetscInt i = 0; i < c->bend_nb; i++) PetscCall(PetscViewerASCIIPrintf(viewer, "%s%.3g", i ? "," : " ", (double) c->bend_b[r][i]));
    }
    PetscCall(PetscViewerASCIIPrintf(viewer, "\n"));
  }
  PetscCall(PetscViewerASCIIPrintf(viewer, "  gravity (%g, %g, %g) m/s^2, Hessian %s\n", (double) c->gravity[0], (double) c->gravity[1], (double) c->gravity[2], c->exact_hessian ? "exact" : "SPD-projected"));
  PetscFunctionReturn(0);
}
