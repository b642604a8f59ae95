/* Particle ownership: DMDA blocks, serial METIS k-way, or a parallel partitioner
 * through PETSc's MatPartitioning (PT-Scotch, ParMETIS). */
#define _POSIX_C_SOURCE 200809L /* setenv */
#include <dlfcn.h>              /* dlsym: PT-Scotch's index width */
#include <stdlib.h>
#include <partition.h>
#include <petscdmda.h>
#include <petscmat.h>
#include <petscsf.h>
#include <metis.h>

/* The 12 interaction neighbours of the paper (Fig. 2): stretch, shear, bending. */
static const PetscInt stencil[12][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {-1, 1}, {1, -1}, {-1, -1}, {2, 0}, {-2, 0}, {0, 2}, {0, -2}};

typedef PetscErrorCode (*PartitionFn)(MPI_Comm, const char *, const PartitionBlocks *, PetscBool (*)(void *, PetscInt, PetscInt), PetscInt (*)(void *, PetscInt, PetscInt), void *, PetscInt *);

PetscErrorCode PartitionBlocksCreate(DM da, PartitionBlocks *b)
{
  const PetscInt *lx, *ly;

  PetscFunctionBeginUser;
  PetscCall(DMDAGetInfo(da, NULL, &b->Mx, &b->My, NULL, &b->m, &b->n, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
  PetscCall(DMDAGetOwnershipRanges(da, &lx, &ly, NULL));
  PetscCall(PetscMalloc4(b->m + 1, &b->x0, b->n + 1, &b->y0, b->Mx, &b->col, b->My, &b->row));
  b->x0[0] = b->y0[0] = 0;
  for (PetscInt p = 0; p < b->m; p++) {
    b->x0[p + 1] = b->x0[p] + lx[p];
    for (PetscInt i = b->x0[p]; i < b->x0[p + 1]; i++) b->col[i] = p;
  }
  for (PetscInt p = 0; p < b->n; p++) {
    b->y0[p + 1] = b->y0[p] + ly[p];
    for (PetscInt j = b->y0[p]; j < b->y0[p + 1]; j++) b->row[j] = p;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode PartitionBlocksDestroy(PartitionBlocks *b)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree4(b->x0, b->y0, b->col, b->row));
  PetscFunctionReturn(0);
}

/* Columns [*i0, *i1) and rows [*j0, *j1) of rank r's home block. */
static void HomeBlock(const PartitionBlocks *b, PetscMPIInt r, PetscInt *i0, PetscInt *i1, PetscInt *j0, PetscInt *j1)
{
  *i0 = b->x0[r % b->m];
  *i1 = b->x0[r % b->m + 1];
  *j0 = b->y0[r / b->m];
  *j1 = b->y0[r / b->m + 1];
}

/* METIS can leave a part empty on a tiny graph (a 2 x 2 lattice on 2 ranks): a rank
 * without particles breaks the solvers (an empty block for ICC). Each empty part
 * takes a vertex of the largest part (there are at least as many vertices as parts). */
static PetscErrorCode PartitionFillEmpty(idx_t nv, PetscMPIInt nparts, idx_t *part)
{
  PetscInt *count;

  PetscFunctionBeginUser;
  PetscCall(PetscCalloc1(nparts, &count));
  for (idx_t v = 0; v < nv; v++) count[part[v]]++;
  for (PetscMPIInt p = 0; p < nparts; p++) {
    PetscMPIInt largest = 0;
    if (count[p]) continue;
    for (PetscMPIInt q = 1; q < nparts; q++)
      if (count[q] > count[largest]) largest = q;
    for (idx_t v = nv - 1; v >= 0; v--)
      if (part[v] == largest) {
        part[v] = p;
        count[largest]--;
        count[p]++;
        break;
      }
  }
  PetscCall(PetscFree(count));
  PetscFunctionReturn(0);
}

/* The same for a distributed partition: vertices vstart, vstart + 1, ... of part[]
 * on this rank; the vertex an empty part takes is the last of the largest part. */
static PetscErrorCode PartitionFillEmptyParallel(MPI_Comm comm, PetscInt nv, PetscInt vstart, PetscInt *part)
{
  PetscMPIInt size;
  PetscInt   *count;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(PetscCalloc1(size, &count));
  for (PetscInt v = 0; v < nv; v++) count[part[v]]++;
  PetscCall(MPIU_Allreduce(MPI_IN_PLACE, count, size, MPIU_INT, MPI_SUM, comm));
  for (PetscMPIInt p = 0; p < size; p++) {
    PetscMPIInt largest = 0;
    PetscInt    last    = -1;
    if (count[p]) continue;
    for (PetscMPIInt q = 1; q < size; q++)
      if (count[q] > count[largest]) largest = q;
    for (PetscInt v = nv - 1; v >= 0 && last < 0; v--)
      if (part[v] == largest) last = vstart + v;
    PetscCall(MPIU_Allreduce(MPI_IN_PLACE, &last, 1, MPIU_INT, MPI_MAX, comm));
    if (last >= vstart && last < vstart + nv) part[last - vstart] = p;
    count[largest]--;
    count[p]++;
  }
  PetscCall(PetscFree(count));
  PetscFunctionReturn(0);
}

static PetscErrorCode PartitionDMDA(MPI_Comm comm, const char *type, const PartitionBlocks *b, PetscBool (*active)(void *, PetscInt, PetscInt), PetscInt (*weight)(void *, PetscInt, PetscInt), void *ctx, PetscInt *dest)
{
  PetscMPIInt rank;
  PetscInt    i0, i1, j0, j1;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  HomeBlock(b, rank, &i0, &i1, &j0, &j1);
  for (PetscInt k = 0; k < (i1 - i0) * (j1 - j0); k++) dest[k] = rank;
  PetscFunctionReturn(0);
}

/* Serial METIS: rank 0 builds the whole graph, partitions it and sends each rank
 * the destinations of its home block (set-up only; nothing of it is kept). */
static PetscErrorCode PartitionMetis(MPI_Comm comm, const char *type, const PartitionBlocks *b, PetscBool (*active)(void *, PetscInt, PetscInt), PetscInt (*weight)(void *, PetscInt, PetscInt), void *ctx, PetscInt *dest)
{
  const PetscInt Mx = b->Mx, My = b->My, N = Mx * My;
  PetscMPIInt    size, rank, *counts = NULL, *displs = NULL, nb;
  PetscInt      *send = NULL, i0, i1, j0, j1;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  /* METIS numbers vertices and links with its own idx_t (32 bits in Debian's METIS,
   * whatever PetscInt is): every rank refuses a graph it cannot number */
  PetscCheck(12 * (PetscInt64) N <= (PetscInt64) IDX_MAX, comm, PETSC_ERR_SUP,
             "-cloth_partition metis cannot partition a %" PetscInt_FMT " x %" PetscInt_FMT " lattice: its particle graph (up to 12 links per particle) exceeds METIS's %d-bit indices; use -cloth_partition dmda or a parallel partitioner", Mx, My,
             IDXTYPEWIDTH);
  HomeBlock(b, rank, &i0, &i1, &j0, &j1);
  PetscCall(PetscMPIIntCast((i1 - i0) * (j1 - j0), &nb));
  if (!rank) {
    idx_t *vertex, *xadj, *adjncy, *part, *vwgt, nv = 0, ne = 0, ncon = 1, nparts = size, objval, options[METIS_NOPTIONS];
    PetscCall(PetscMalloc5(N, &vertex, N + 1, &xadj, 12 * N + 1, &adjncy, N + 1, &part, N + 1, &vwgt));
    for (PetscInt n = 0; n < N; n++) {
      vertex[n] = active(ctx, n % Mx, n / Mx) ? nv++ : -1;
      if (vertex[n] >= 0) vwgt[vertex[n]] = weight ? (idx_t) weight(ctx, n % Mx, n / Mx) : 1;
    }
    xadj[0] = 0;
    for (PetscInt n = 0; n < N; n++) {
      if (vertex[n] < 0) continue;
      for (PetscInt s = 0; s < 12; s++) {
        PetscInt i = n % Mx + stencil[s][0], j = n / Mx + stencil[s][1];
        if (i >= 0 && i < Mx && j >= 0 && j < My && vertex[j * Mx + i] >= 0) adjncy[ne++] = vertex[j * Mx + i];
      }
      xadj[vertex[n] + 1] = ne;
    }
    if (size > 1 && nv > 0) {
      int status;
      METIS_SetDefaultOptions(options);
      options[METIS_OPTION_SEED]      = 2026;
      options[METIS_OPTION_NUMBERING] = 0;
      status                          = METIS_PartGraphKway(&nv, &ncon, xadj, adjncy, vwgt, NULL, NULL, &nparts, NULL, NULL, options, &objval, part);
      PetscCheck(status == METIS_OK, PETSC_COMM_SELF, PETSC_ERR_LIB, "METIS_PartGraphKway failed with status %d", status);
    } else
      for (idx_t v = 0; v < nv; v++) part[v] = 0;
    if (nv >= size) PetscCall(PartitionFillEmpty(nv, size, part));
    /* each rank's home block, row by row; inactive particles (outside the cloth's
     * outline) do no work: home here, PartitionSpreadInactive shares them out */
    PetscCall(PetscMalloc3(N, &send, size, &counts, size, &displs));
    for (PetscMPIInt r = 0, pos = 0; r < size; r++) {
      PetscInt a0, a1, b0, b1;
      HomeBlock(b, r, &a0, &a1, &b0, &b1);
      displs[r] = pos;
      for (PetscInt j = b0; j < b1; j++)
        for (PetscInt i = a0; i < a1; i++) send[pos++] = vertex[j * Mx + i] >= 0 ? (PetscInt) part[vertex[j * Mx + i]] : r;
      counts[r] = pos - displs[r];
    }
    PetscCall(PetscFree5(vertex, xadj, adjncy, part, vwgt));
  }
  PetscCallMPI(MPI_Scatterv(send, counts, displs, MPIU_INT, dest, nb, MPIU_INT, 0, comm));
  if (!rank) PetscCall(PetscFree3(send, counts, displs));
  PetscFunctionReturn(0);
}

/* The partitioner numbers its parts as it likes; part p goes to rank p. Named at
 * random, a rank's part lies anywhere, away from its home block, whose particles it
 * sends to their owners at the set-up and whose output passes through it (the
 * DMDA's scatter); and when the inactive particles stayed at home (before
 * PartitionSpreadInactive), the arrays that span a box around a rank's particles
 * spanned its part and its corner: at 2048^2 on 16 ranks a corner block's rank held
 * a box about six times its part. So each part is renamed after the home block it
 * takes most of
 * (counted in active particles), the blocks that give most first, and the parts left
 * take the names left in order; the parts themselves, their balance and cut do not
 * change. dest: the home block's destinations, renamed where the particle is active.
 * O(P) on every rank (one allgather of a pair per rank). Collective. */
static PetscErrorCode PartitionRename(MPI_Comm comm, const PartitionBlocks *b, PetscBool (*active)(void *, PetscInt, PetscInt), void *ctx, PetscInt *dest)
{
  PetscMPIInt size, rank;
  PetscInt   *count, best[2] = {0, -1}, *all, *name, next = 0, i0, i1, j0, j1;
  PetscInt64 *key, most = 0;
  PetscBool  *named;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  HomeBlock(b, rank, &i0, &i1, &j0, &j1);
  PetscCall(PetscCalloc1(size, &count));
  for (PetscInt j = j0, k = 0; j < j1; j++)
    for (PetscInt i = i0; i < i1; i++, k++)
      if (active(ctx, i, j)) count[dest[k]]++;
  for (PetscMPIInt p = 0; p < size; p++)
    if (count[p] > best[0]) best[0] = count[p], best[1] = p;
  PetscCall(PetscMalloc4(2 * size, &all, size, &key, size, &name, size, &named));
  PetscCallMPI(MPI_Allgather(best, 2, MPIU_INT, all, 2, MPIU_INT, comm));
  /* the same order on every rank: most particles first, then by home rank (a key
   * below (largest count + 1) P: a home block's count times the ranks is at most the
   * lattice's particles) */
  for (PetscMPIInt r = 0; r < size; r++) most = PetscMax(most, all[2 * r]);
  for (PetscMPIInt r = 0; r < size; r++) {
    key[r]   = (most - (PetscInt64) all[2 * r]) * size + r;
    name[r]  = -1;
    named[r] = PETSC_FALSE;
  }
  PetscCall(PetscSortInt64(size, key));
  for (PetscMPIInt q = 0; q < size; q++) {
    const PetscInt r = (PetscInt) (key[q] % size), p = all[2 * r + 1];
    if (p >= 0 && name[p] < 0) name[p] = r, named[r] = PETSC_TRUE;
  }
  for (PetscMPIInt p = 0; p < size; p++) {
    if (name[p] >= 0) continue;
    while (named[next]) next++;
    name[p] = next, named[next] = PETSC_TRUE;
  }
  for (PetscInt j = j0, k = 0; j < j1; j++)
    for (PetscInt i = i0; i < i1; i++, k++)
      if (active(ctx, i, j)) dest[k] = name[dest[k]];
  PetscCall(PetscFree4(all, key, name, named));
  PetscCall(PetscFree(count));
  PetscFunctionReturn(0);
}

/* Inactive particles (outside the outline: pinned, in no element) cost a rank their
 * state and their numbers (about 80 bytes each) and no work. Kept at home, the
 * ranks of a disc's corner blocks held most of them (at 4096^2 on 16 ranks about
 * 720 000 each, against 60 000-200 000 elsewhere): each rank now takes an equal
 * share, the home blocks' inactive particles in the order of their ranks cut into P
 * runs of equal length (the first I mod P one longer), so every rank owns about the
 * same number of particles. They may lie far from the rank's part: the arrays that
 * span a box around a rank's particles span its active ones (ClothBuildLayout, the
 * lattice kernel's patch). One scan and one broadcast. Collective. */
static PetscErrorCode PartitionSpreadInactive(MPI_Comm comm, const PartitionBlocks *b, PetscBool (*active)(void *, PetscInt, PetscInt), void *ctx, PetscInt *dest)
{
  PetscMPIInt size, rank;
  PetscInt64  mine = 0, first, total, base, rem;
  PetscInt    i0, i1, j0, j1;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  HomeBlock(b, rank, &i0, &i1, &j0, &j1);
  for (PetscInt j = j0; j < j1; j++)
    for (PetscInt i = i0; i < i1; i++) mine += !active(ctx, i, j);
  PetscCallMPI(MPI_Scan(&mine, &first, 1, MPIU_INT64, MPI_SUM, comm));
  total = first;
  PetscCallMPI(MPI_Bcast(&total, 1, MPIU_INT64, size - 1, comm));
  first -= mine;
  base = total / size, rem = total % size;
  for (PetscInt j = j0, k = 0; j < j1; j++)
    for (PetscInt i = i0; i < i1; i++, k++) {
      if (active(ctx, i, j)) continue;
      /* runs 0 .. rem - 1 hold base + 1, the others base */
      dest[k] = (PetscInt) (first < rem * (base + 1) ? first / (base + 1) : rem + (first - rem * (base + 1)) / base);
      first++;
    }
  PetscFunctionReturn(0);
}

/* A parallel partitioner of PETSc's (MatPartitioning type `type`) on the graph of the
 * lattice's tiles: each rank cuts its home block into tiles of PARTITION_TILE x
 * PARTITION_TILE particles (smaller at the block's edges), a tile with active
 * particles is a vertex weighing the sum of theirs, linked to the tiles of their 12
 * neighbours. Each rank builds its tiles' rows of the graph, a MATMPIADJ; the vertex
 * numbers of the neighbours in other blocks (up to two particles beyond the block's
 * edge) come through a PetscSF from their home ranks. Tiles of 2 x 2 particles give a
 * graph of a quarter of the vertices and a sixth of the links of the particles' (the
 * partitioner's time and memory shrink alike), at the cost of parts whose edges are
 * steps of two particles; a lattice with fewer than 64 tiles per rank is partitioned
 * particle by particle. */
#define PARTITION_TILE 2
/* PETSc hands PT-Scotch its PetscInt arrays as SCOTCH_Num. A PETSc with 64-bit
 * indices linked with a PT-Scotch of 32-bit SCOTCH_Num (Debian's libpetsc64 package
 * and the libptscotch it shares with the 32-bit one) fails inside it with
 * "dgraphGatherAll2: communication error" and a traceback. The library says its
 * width (SCOTCH_numSizeof, Scotch 6 and later; looked up among the loaded symbols,
 * since drape does not link Scotch itself). */
static PetscBool ScotchIndicesMatch(void)
{
  int (*numsizeof)(void);

  *(void **) &numsizeof = dlsym(RTLD_DEFAULT, "SCOTCH_numSizeof");
  return (PetscBool) (!numsizeof || numsizeof() == (int) sizeof(PetscInt));
}

static PetscErrorCode CheckScotchIndices(MPI_Comm comm)
{
  int (*numsizeof)(void);

  PetscFunctionBeginUser;
  *(void **) &numsizeof = dlsym(RTLD_DEFAULT, "SCOTCH_numSizeof");
  if (numsizeof)
    PetscCheck(
      numsizeof() == (int) sizeof(PetscInt), comm, PETSC_ERR_SUP,
      "-cloth_partition ptscotch cannot run with this PETSc: its indices are %d-bit and the PT-Scotch it is linked with takes %d-bit ones (as in Debian's 64-bit PETSc package), so PT-Scotch would fail; use -cloth_partition dmda or metis, or a PETSc "
      "whose PT-Scotch matches its indices (configured with --download-ptscotch)",
      8 * (int) sizeof(PetscInt), 8 * numsizeof());
  PetscFunctionReturn(0);
}

static PetscErrorCode PartitionMat(MPI_Comm comm, const char *type, const PartitionBlocks *b, PetscBool (*active)(void *, PetscInt, PetscInt), PetscInt (*weight)(void *, PetscInt, PetscInt), void *ctx, PetscInt *dest)
{
  const PetscInt  Mx = b->Mx, My = b->My;
  PetscMPIInt     size, rank;
  PetscInt        i0, i1, j0, j1, lx, ly, tile = PARTITION_TILE, ntx, nty, ntiles, ei0, ei1, ej0, ej1, ew, nv, vstart, nvglobal, *tvid, *tw, *vid, *ext, *ia, *ja, *vw = NULL, *part, nleaf = 0, ne = 0;
  PetscSF         sf;
  PetscSFNode    *remote;
  PetscInt       *leaf;
  Mat             adj;
  MatPartitioning mp;
  IS              is;
  const PetscInt *p;

  PetscFunctionBeginUser;
  if (!strcmp(type, MATPARTITIONINGPTSCOTCH)) PetscCall(CheckScotchIndices(comm));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  HomeBlock(b, rank, &i0, &i1, &j0, &j1);
  lx = i1 - i0, ly = j1 - j0;
  PetscCall(PetscMalloc1(lx * ly + 1, &vid));
  for (PetscInt j = j0; j < j1; j++)
    for (PetscInt i = i0; i < i1; i++) vid[(j - j0) * lx + i - i0] = active(ctx, i, j) ? (weight ? weight(ctx, i, j) : 1) : -1;
  /* the tiles, their weights and vertex numbers (rank by rank); particle by particle
   * where tiles would be too few */
  for (PetscInt pass = 0; pass < 2; pass++) {
    ntx = (lx + tile - 1) / tile, nty = (ly + tile - 1) / tile, ntiles = ntx * nty;
    PetscCall(PetscCalloc2(ntiles + 1, &tvid, ntiles + 1, &tw));
    for (PetscInt k = 0; k < lx * ly; k++)
      if (vid[k] >= 0) tw[((k / lx) / tile) * ntx + (k % lx) / tile] += vid[k];
    nv = 0;
    for (PetscInt t = 0; t < ntiles; t++) tvid[t] = tw[t] > 0 ? nv++ : -1;
    PetscCallMPI(MPI_Scan(&nv, &vstart, 1, MPIU_INT, MPI_SUM, comm));
    nvglobal = vstart;
    PetscCallMPI(MPI_Bcast(&nvglobal, 1, MPIU_INT, size - 1, comm));
    vstart -= nv;
    if (tile == 1 || nvglobal >= 64 * (PetscInt) size) break;
    PetscCall(PetscFree2(tvid, tw));
    tile = 1;
  }
  /* each particle's vertex: its tile's, -1 if inactive */
  for (PetscInt k = 0; k < lx * ly; k++)
    if (vid[k] >= 0) vid[k] = vstart + tvid[((k / lx) / tile) * ntx + (k % lx) / tile];
  /* the frame around the block: leaves of an SF whose roots are the home ranks' vid */
  ei0 = PetscMax(i0 - 2, 0), ei1 = PetscMin(i1 + 2, Mx), ej0 = PetscMax(j0 - 2, 0), ej1 = PetscMin(j1 + 2, My), ew = ei1 - ei0;
  PetscCall(PetscMalloc1(ew * (ej1 - ej0) + 1, &ext));
  PetscCall(PetscMalloc1(ew * (ej1 - ej0) + 1, &leaf)); /* the SF's own: freed one by one */
  PetscCall(PetscMalloc1(ew * (ej1 - ej0) + 1, &remote));
  for (PetscInt j = ej0; j < ej1; j++)
    for (PetscInt i = ei0; i < ei1; i++) {
      const PetscInt e = (j - ej0) * ew + i - ei0;
      if (i >= i0 && i < i1 && j >= j0 && j < j1) {
        ext[e] = vid[(j - j0) * lx + i - i0];
        continue;
      }
      {
        const PetscMPIInt r = PartitionBlockRank(b, i, j);
        PetscInt          a0, a1, b0, b1;
        HomeBlock(b, r, &a0, &a1, &b0, &b1);
        leaf[nleaf]         = e;
        remote[nleaf].rank  = r;
        remote[nleaf].index = (j - b0) * (a1 - a0) + i - a0;
        nleaf++;
      }
    }
  PetscCall(PetscSFCreate(comm, &sf));
  PetscCall(PetscSFSetGraph(sf, lx * ly, nleaf, leaf, PETSC_OWN_POINTER, remote, PETSC_OWN_POINTER));
  PetscCall(PetscSFBcastBegin(sf, MPIU_INT, vid, ext, MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sf, MPIU_INT, vid, ext, MPI_REPLACE));
  PetscCall(PetscSFDestroy(&sf));
  /* the rows, a tile's links sorted and each once: MatCreateMPIAdj takes ia, ja and
   * the weights (PetscFree'd with it) */
  PetscCall(PetscMalloc1(nv + 1, &ia));
  PetscCall(PetscMalloc1(12 * tile * tile * nv + 1, &ja));
  if (weight || tile > 1) PetscCall(PetscMalloc1(nv + 1, &vw));
  ia[0] = 0;
  for (PetscInt t = 0, v = 0; t < ntiles; t++) {
    const PetscInt ti0 = i0 + (t % ntx) * tile, tj0 = j0 + (t / ntx) * tile, self = vstart + tvid[t];
    PetscInt       n = 0;
    if (tvid[t] < 0) continue;
    for (PetscInt j = tj0; j < PetscMin(tj0 + tile, j1); j++)
      for (PetscInt i = ti0; i < PetscMin(ti0 + tile, i1); i++) {
        if (vid[(j - j0) * lx + i - i0] < 0) continue;
        for (PetscInt s = 0; s < 12; s++) {
          const PetscInt a = i + stencil[s][0], c = j + stencil[s][1];
          if (a >= 0 && a < Mx && c >= 0 && c < My && ext[(c - ej0) * ew + a - ei0] >= 0 && ext[(c - ej0) * ew + a - ei0] != self) ja[ne + n++] = ext[(c - ej0) * ew + a - ei0];
        }
      }
    PetscCall(PetscSortRemoveDupsInt(&n, ja + ne));
    ne += n;
    if (vw) vw[v] = tw[t];
    ia[++v] = ne;
  }
  PetscCall(PetscFree2(tvid, tw));
  PetscCall(PetscFree(ext));
  {
    /* Scotch 7 runs threads of its own that call MPI, which drape initialises for one
     * thread: oversubscribed ranks then hang or crash now and then (3 in 12 runs of
     * the Cusick disc on 4 ranks); one thread each, unless MPI allows more */
    int provided;
    PetscCallMPI(MPI_Query_thread(&provided));
    if (provided < MPI_THREAD_MULTIPLE) PetscCheck(!setenv("SCOTCH_PTHREAD_NUMBER", "1", 1), PETSC_COMM_SELF, PETSC_ERR_SYS, "Cannot set SCOTCH_PTHREAD_NUMBER in the environment");
  }
  PetscCall(MatCreateMPIAdj(comm, nv, nvglobal, ia, ja, NULL, &adj));
  PetscCall(MatPartitioningCreate(comm, &mp));
  PetscCall(MatPartitioningSetAdjacency(mp, adj));
  PetscCall(MatPartitioningSetType(mp, type));
  PetscCall(MatPartitioningSetNParts(mp, size));
  if (vw) PetscCall(MatPartitioningSetVertexWeights(mp, vw));
  PetscCall(PetscObjectSetOptionsPrefix((PetscObject) mp, "cloth_"));
  PetscCall(MatPartitioningSetFromOptions(mp));
  PetscCall(MatPartitioningApply(mp, &is));
  PetscCall(PetscMalloc1(nv + 1, &part));
  PetscCall(ISGetIndices(is, &p));
  PetscCall(PetscArraycpy(part, p, nv));
  PetscCall(ISRestoreIndices(is, &p));
  PetscCall(ISDestroy(&is));
  PetscCall(MatPartitioningDestroy(&mp));
  PetscCall(MatDestroy(&adj));
  PetscCall(PartitionFillEmptyParallel(comm, nv, vstart, part));
  for (PetscInt k = 0; k < lx * ly; k++) dest[k] = vid[k] >= 0 ? part[vid[k] - vstart] : rank;
  PetscCall(PetscFree(part));
  PetscCall(PetscFree(vid));
  PetscFunctionReturn(0);
}

/* The partitioners of this build. */
static const struct {
  const char *name;
  PartitionFn fn;
} partitioners[] = {
  {"dmda", PartitionDMDA},
  {"metis", PartitionMetis},
#if defined(PETSC_HAVE_PTSCOTCH)
  {"ptscotch", PartitionMat},
#endif
#if defined(PETSC_HAVE_PARMETIS)
  {"parmetis", PartitionMat},
#endif
};

#define NPARTITIONERS ((PetscInt) (sizeof partitioners / sizeof partitioners[0]))

PetscErrorCode PartitionList(char *list, size_t len)
{
  PetscFunctionBeginUser;
  list[0] = 0;
  for (PetscInt k = 0; k < NPARTITIONERS; k++) {
    if (k) PetscCall(PetscStrlcat(list, ", ", len));
    PetscCall(PetscStrlcat(list, partitioners[k].name, len));
  }
  PetscFunctionReturn(0);
}

static PartitionFn PartitionFind(const char *type)
{
  for (PetscInt k = 0; k < NPARTITIONERS; k++) {
    PetscBool same;
    if (PetscStrcmp(type, partitioners[k].name, &same) || !same) continue;
    return partitioners[k].fn;
  }
  return NULL;
}

PetscErrorCode PartitionKnown(const char *type, PetscBool *known)
{
  PetscFunctionBeginUser;
  *known = (PetscBool) (PartitionFind(type) != NULL);
  PetscFunctionReturn(0);
}

PetscErrorCode PartitionUsable(const char *type, PetscBool *usable)
{
  PetscBool scotch;

  PetscFunctionBeginUser;
  PetscCall(PartitionKnown(type, usable));
  PetscCall(PetscStrcmp(type, "ptscotch", &scotch));
  if (*usable && scotch) *usable = ScotchIndicesMatch();
  PetscFunctionReturn(0);
}

PetscBool PartitionIsGraph(const char *type) { return (PetscBool) (PartitionFind(type) != PartitionDMDA); }

PetscErrorCode PartitionDestinations(MPI_Comm comm, const char *type, const PartitionBlocks *b, PetscBool (*active)(void *, PetscInt, PetscInt), PetscInt (*weight)(void *, PetscInt, PetscInt), void *ctx, PetscInt *dest)
{
  PartitionFn fn = PartitionFind(type);
  PetscMPIInt size, rank;

  PetscFunctionBeginUser;
  PetscCheck(fn, comm, PETSC_ERR_USER_INPUT, "Unknown partitioner %s", type);
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  if (fn != PartitionDMDA) { /* every rank gets part of the cloth */
    PetscInt64 nactive = 0;
    PetscInt   i0, i1, j0, j1;
    HomeBlock(b, rank, &i0, &i1, &j0, &j1);
    for (PetscInt j = j0; j < j1; j++)
      for (PetscInt i = i0; i < i1; i++) nactive += active(ctx, i, j);
    PetscCall(MPIU_Allreduce(MPI_IN_PLACE, &nactive, 1, MPIU_INT64, MPI_SUM, comm));
    PetscCheck(nactive >= size, comm, PETSC_ERR_USER_INPUT, "-cloth_partition %s gives every rank part of the cloth: %d ranks need at least as many active particles, and this cloth has %" PetscInt64_FMT "; run on fewer ranks", type, (int) size,
               nactive);
    if (size == 1) fn = PartitionDMDA; /* one part: the home block */
  }
  PetscCall(fn(comm, type, b, active, weight, ctx, dest));
  if (fn != PartitionDMDA) {
    PetscCall(PartitionRename(comm, b, active, ctx, dest));
    PetscCall(PartitionSpreadInactive(comm, b, active, ctx, dest));
  }
  PetscFunctionReturn(0);
}
