/* Private to src/selfcontact/: the cloth's surface as triangles of lattice
 * particles, in natural lattice order (index j Mx + i) on every rank. */
#pragma once

#include <selfcontact.h>

typedef struct {
  PetscInt  nv, nt, ne;
  PetscInt *vert; /* particles that belong to a triangle               */
  PetscInt *tri;  /* 3 particles each: two per lattice cell of the cloth */
  PetscInt *edge; /* 2 particles each: the triangles' edges, once       */
} SelfMesh;

/* CGAL's box intersection (broadphase.cxx). Candidate pairs whose boxes (start and end positions, grown by r) overlap, sorted,
 * none sharing a particle: point-triangle (vertex, triangle) and edge-edge (e, f), e < f.
 * The pair arrays are PetscMalloc'ed (2 entries per pair). Not collective. */
PETSC_EXTERN PetscErrorCode SelfBroadPhase(const SelfMesh *, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscInt *npt, PetscInt **pt, PetscInt *nee, PetscInt **ee);
/* The same pairs, in the same order, by a uniform spatial hash (hashgrid.c). */
PETSC_EXTERN PetscErrorCode SelfBroadPhaseHash(const SelfMesh *, const PetscReal *x0, const PetscReal *x1, PetscReal r, PetscInt *npt, PetscInt **pt, PetscInt *nee, PetscInt **ee);
