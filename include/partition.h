/* Which rank owns which particle: the DMDA's block decomposition or a METIS k-way
 * partition of the graph of active particles and their 12 interactions. The
 * physics kernels never see this: the Cloth turns the owner array into local
 * particle lists, element lists, a ghost scatter and a local-to-global map. */
#pragma once

#include <petscdm.h>

typedef enum {
  PARTITION_DMDA,
  PARTITION_METIS
} PartitionType;

PETSC_EXTERN const char *const PartitionTypes[];

/* owner[j * Mx + i] = rank owning lattice particle (i, j), on every rank. weight
 * (may be NULL: all 1) is the work of a particle for METIS's balance. Collective
 * (METIS runs on rank 0, which broadcasts the owners). */
PETSC_EXTERN PetscErrorCode PartitionOwners(MPI_Comm, PartitionType, DM da, PetscInt Mx, PetscInt My, PetscBool (*active)(void *, PetscInt, PetscInt), void *ctx, const PetscInt *weight, PetscInt *owner);
