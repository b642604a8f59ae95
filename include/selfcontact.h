/* Self-contact: the cloth does not pass through itself (src/selfcontact/).
 *
 * The cloth's surface is its lattice cells, two triangles each (split along the
 * diagonal (i,j)-(i+1,j+1)). After every step, whatever the scheme, a velocity
 * filter in the manner of Bridson, Fedkiw & Anderson (2002) acts on the step's
 * motion from x0 (start) to x (end):
 *   1. proximity: every point-triangle and edge-edge pair closer than the thickness
 *      at the start of the step loses its approaching relative velocity (an
 *      inelastic impulse, with Coulomb friction bounded by it) and is pushed apart
 *      in position towards the thickness (at most a quarter of it per step);
 *   2. collisions: every pair that the remaining motion would still make cross
 *      (continuous detection: the coplanarity cubic) gets the inelastic impulse that
 *      stops its relative normal motion if that moves the pair by at most the
 *      thickness; repeated -contact_self_its times;
 *   3. fail-safe: the particles of pairs that still collide are merged into rigid
 *      impact zones, each moving rigidly over the step with its particles' linear
 *      and angular momentum, until no pair collides (-contact_self_failsafe freeze:
 *      stopped at x0 instead).
 * An impulse changes the velocity and the position it leads to (x = x0 + h vbar):
 * dx = h dv. Candidate pairs come from a spatial hash (or CGAL's box intersection)
 * over boxes of the step's sweep; pairs that share a particle are not candidates.
 *
 * Each rank holds its own particles and a geometric halo (the triangles near its
 * own, moved by a PetscSF) and evaluates the pairs with one of its own particles;
 * groups of contacts across ranks are gathered and taken on every rank in one
 * order: the result is that of one rank, on any partition (README). Collective. */
#pragma once

#include <cloth.h>

typedef struct _p_SelfContact *SelfContact;

typedef struct {
  PetscInt  pairs;        /* pairs closer than the thickness at the start of the last step */
  PetscInt  collisions;   /* collision impulses since the start of the run */
  PetscInt  failsafe;     /* particles put in impact zones (or stopped) by the fail-safe since the start */
  PetscInt  broad_phases; /* candidate lists built */
  PetscInt  halo;         /* the largest halo of a rank at the last list, particles (0 on one rank) */
  PetscInt  gathered;     /* pairs of contact groups across ranks, gathered on every rank, since the start */
  PetscInt  failsafe_steps; /* steps in which the fail-safe ran */
  PetscReal thickness;    /* m */
} SelfContactStats;

/* -contact_self, -contact_self_thickness, -contact_self_friction, -contact_self_its,
 * -contact_self_margin, -contact_self_failsafe, -contact_self_broad_phase.
 * Create is not collective; the others are. SelfContactSetUp after ClothSetUp. */
PETSC_EXTERN PetscErrorCode SelfContactCreate(MPI_Comm, Cloth, SelfContact *);
PETSC_EXTERN PetscErrorCode SelfContactSetFromOptions(SelfContact);
PETSC_EXTERN PetscErrorCode SelfContactSetUp(SelfContact);
PETSC_EXTERN PetscErrorCode SelfContactView(SelfContact, PetscViewer);
PETSC_EXTERN PetscErrorCode SelfContactDestroy(SelfContact *);
/* Was -contact_self given (true)? Not collective. */
PETSC_EXTERN PetscErrorCode SelfContactEnabled(SelfContact, PetscBool *);
/* Start of a step: the positions x (owned-particle order) it starts from. */
PETSC_EXTERN PetscErrorCode SelfContactBeginStep(SelfContact, const PetscScalar *x);
/* End of the step of length h: filter the owned particles' end positions x and
 * velocities v in place; changed: whether any pair acted (the same on every rank). */
PETSC_EXTERN PetscErrorCode SelfContactFilter(SelfContact, PetscReal h, PetscScalar *x, PetscScalar *v, PetscBool *changed);
PETSC_EXTERN PetscErrorCode SelfContactGetStats(SelfContact, SelfContactStats *);
