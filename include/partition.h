/* Which rank owns which particle. Every rank starts from its block of the DMDA (its
 * "home" block: no rank ever holds an array of the whole lattice for it, the blocks
 * being known on every rank from the DMDA's ownership ranges); a partitioner gives
 * each particle of the home block the rank that will own it: the home rank itself
 * (dmda), a part of a serial METIS k-way partition (metis: the whole graph on rank
 * 0), or a part of a parallel partition through PETSc's MatPartitioning (ptscotch,
 * parmetis where PETSc has them: the graph of 2 x 2 tiles of particles distributed
 * as a MATMPIADJ, each rank building its home block's rows). The physics kernels
 * never see this: the Cloth turns the destinations into local particle lists,
 * element lists, a ghost scatter and a local-to-global map. */
#pragma once

#include <petscdm.h>

/* The DMDA's blocks of a lattice: rank (pj m + pi) holds columns x0[pi] to
 * x0[pi + 1] - 1 and rows y0[pj] to y0[pj + 1] - 1; col and row: the block column
 * (row) of each lattice column (row), Mx + My integers. */
typedef struct {
  PetscInt  Mx, My, m, n;
  PetscInt *x0, *y0, *col, *row;
} PartitionBlocks;

PETSC_EXTERN PetscErrorCode PartitionBlocksCreate(DM da, PartitionBlocks *);
PETSC_EXTERN PetscErrorCode PartitionBlocksDestroy(PartitionBlocks *);

/* The home rank of lattice particle (i, j), and its number in the DMDA's global
 * (block by block) order. */
static inline PetscMPIInt PartitionBlockRank(const PartitionBlocks *b, PetscInt i, PetscInt j) { return (PetscMPIInt) (b->row[j] * b->m + b->col[i]); }
static inline PetscInt    PartitionBlockNumber(const PartitionBlocks *b, PetscInt i, PetscInt j)
{
  const PetscInt pi = b->col[i], pj = b->row[j], lx = b->x0[pi + 1] - b->x0[pi], ly = b->y0[pj + 1] - b->y0[pj];
  return b->y0[pj] * b->Mx + ly * b->x0[pi] + (j - b->y0[pj]) * lx + (i - b->x0[pi]);
}

/* The names -cloth_partition accepts with this build (dmda, metis, and the
 * MatPartitioning types PETSc was configured with: ptscotch, parmetis), comma
 * separated. Not collective. */
PETSC_EXTERN PetscErrorCode PartitionList(char *, size_t);
/* Is `type` one of them? Not collective. */
PETSC_EXTERN PetscErrorCode PartitionKnown(const char *type, PetscBool *);
/* Is `type` one of them, and one that runs with this build (PT-Scotch's index width
 * matching PETSc's)? Not collective. */
PETSC_EXTERN PetscErrorCode PartitionUsable(const char *type, PetscBool *);
/* Is `type` a partition of the interaction graph (every partitioner but dmda)? */
PETSC_EXTERN PetscBool PartitionIsGraph(const char *type);

/* dest[k]: the rank that will own the k-th particle of this rank's home block (its
 * block's particles row by row). Only active particles (active(ctx, i, j)) are
 * vertices of the graph, weighing weight(ctx, i, j) (weight NULL: 1 each). A graph
 * partition's parts are named (numbered as ranks) after the home blocks they take
 * most of, and its inactive particles are shared equally among the ranks; with the
 * DMDA's blocks they stay at home. Collective. */
PETSC_EXTERN PetscErrorCode PartitionDestinations(MPI_Comm, const char *type, const PartitionBlocks *, PetscBool (*active)(void *, PetscInt, PetscInt), PetscInt (*weight)(void *, PetscInt, PetscInt), void *ctx, PetscInt *dest);
