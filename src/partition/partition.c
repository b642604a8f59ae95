/* Particle ownership: DMDA blocks or METIS k-way. */
#include <partition.h>
#include <petscdmda.h>
#include <metis.h>

const char *const PartitionTypes[] = {"dmda", "metis", "PartitionType", "PARTITION_", NULL};

/* The 12 interaction neighbours of the paper (Fig. 2): stretch, shear, bending. */
static const PetscInt stencil[12][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {-1, 1}, {1, -1}, {-1, -1}, {2, 0}, {-2, 0}, {0, 2}, {0, -2}};

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

static PetscErrorCode PartitionMetis(MPI_Comm comm, PetscInt Mx, PetscInt My, PetscBool (*active)(void *, PetscInt, PetscInt), void *ctx, const PetscInt *weight, PetscInt *owner)
{
  PetscMPIInt size, rank, count;
  PetscInt    N = Mx * My;

  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  /* METIS numbers vertices and links with its own idx_t (32 bits in Debian's METIS,
   * whatever PetscInt is): every rank refuses a graph it cannot number */
  PetscCheck(12 * (PetscInt64) N <= (PetscInt64) IDX_MAX, comm, PETSC_ERR_SUP,
             "-cloth_partition metis cannot partition a %" PetscInt_FMT " x %" PetscInt_FMT " lattice: its particle graph (up to 12 links per particle) exceeds METIS's %d-bit indices; use -cloth_partition dmda", Mx, My, IDXTYPEWIDTH);
  PetscCall(PetscMPIIntCast(N, &count));
  if (!rank) {
    idx_t *vertex, *xadj, *adjncy, *part, *vwgt, nv = 0, ne = 0, ncon = 1, nparts = size, objval, options[METIS_NOPTIONS];
    PetscCall(PetscMalloc5(N, &vertex, N + 1, &xadj, 12 * N + 1, &adjncy, N + 1, &part, N + 1, &vwgt));
    for (PetscInt n = 0; n < N; n++) {
      vertex[n] = active(ctx, n % Mx, n / Mx) ? nv++ : -1;
      if (vertex[n] >= 0) vwgt[vertex[n]] = weight ? (idx_t) weight[n] : 1;
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
    /* inactive particles (outside the cloth's outline) do no work: blocks */
    for (PetscInt n = 0; n < N; n++) owner[n] = vertex[n] >= 0 ? (PetscInt) part[vertex[n]] : (PetscInt) ((n * (PetscInt64) size) / N);
    PetscCall(PetscFree5(vertex, xadj, adjncy, part, vwgt));
  }
  PetscCallMPI(MPI_Bcast(owner, count, MPIU_INT, 0, comm));
  PetscFunctionReturn(0);
}

PetscErrorCode PartitionOwners(MPI_Comm comm, PartitionType type, DM da, PetscInt Mx, PetscInt My, PetscBool (*active)(void *, PetscInt, PetscInt), void *ctx, const PetscInt *weight, PetscInt *owner)
{
  PetscFunctionBeginUser;
  if (type == PARTITION_METIS) {
    PetscMPIInt size;
    PetscInt64  nactive = 0;
    PetscCallMPI(MPI_Comm_size(comm, &size));
    for (PetscInt j = 0; j < My; j++)
      for (PetscInt i = 0; i < Mx; i++) nactive += active(ctx, i, j);
    PetscCheck(nactive >= size, comm, PETSC_ERR_USER_INPUT, "-cloth_partition metis gives every rank part of the cloth: %d ranks need at least as many active particles, and this cloth has %" PetscInt64_FMT "; run on fewer ranks", (int) size,
               nactive);
    PetscCall(PartitionMetis(comm, Mx, My, active, ctx, weight, owner));
  } else {
    const PetscInt *lx, *ly;
    PetscInt        m, n;
    PetscCall(DMDAGetInfo(da, NULL, NULL, NULL, NULL, &m, &n, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
    PetscCall(DMDAGetOwnershipRanges(da, &lx, &ly, NULL));
    for (PetscInt pj = 0, j0 = 0; pj < n; j0 += ly[pj++])
      for (PetscInt pi = 0, i0 = 0; pi < m; i0 += lx[pi++])
        for (PetscInt j = j0; j < j0 + ly[pj]; j++)
          for (PetscInt i = i0; i < i0 + lx[pi]; i++) owner[j * Mx + i] = pj * m + pi;
  }
  PetscFunctionReturn(0);
}
