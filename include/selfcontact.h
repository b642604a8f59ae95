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
 * order: the result is that of one rank, on any partition (docs/contact.md). Collective. */
#pragma once

#include <cloth.h>

typedef struct _p_SelfContact *SelfContact;

typedef struct {
  PetscInt  pairs;           /* pairs closer than the thickness at the start of the last step */
  PetscInt  collisions;      /* collision impulses since the start of the run */
  PetscInt  failsafe;        /* particles put in impact zones (or stopped) by the fail-safe since the start */
  PetscInt  broad_phases;    /* candidate lists built */
  PetscInt  near_lists;      /* near lists made from them */
  PetscInt  live_lists;      /* passes that took the live list (the motion too fast for a near list; NearLive) */
  PetscInt  halo;            /* the largest halo of a rank at the last list, particles (0 on one rank) */
  PetscInt  gathered;        /* pairs of contact groups across ranks, gathered on every rank, since the start */
  PetscInt  failsafe_steps;  /* steps in which the fail-safe ran */
  PetscInt  solve_pairs_max; /* the most pairs pressing in one implicit solve since the start (-contact_self_solve) */
  PetscReal near_pairs;      /* the pairs of the near lists taken from (proximity passes, the implicit solve's search), summed over them and the ranks */
  PetscReal near_within;     /* of those, the pairs taken (the ones the motion may have brought within reach) */
  PetscReal thickness;       /* m */
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
/* The owned particles the solid holds (sticky contact) for the next SelfContactFilter
 * (NULL: none): the filter does not move them, as it does not move pinned ones. The
 * sticky constraint fixes a particle's velocity, not its place: a held particle the
 * filter moved would stay where it was moved, step after step. Not collective. */
PETSC_EXTERN PetscErrorCode SelfContactSetHeld(SelfContact, const PetscBool held[]);
PETSC_EXTERN PetscErrorCode SelfContactGetStats(SelfContact, SelfContactStats *);
/* The steps are implicit (TSDRAPEBE): unless -contact_self_margin was given, the
 * candidate list's margin is half a thickness instead of one (SelfContactCreate).
 * Before the first step. Not collective. */
PETSC_EXTERN PetscErrorCode SelfContactSetImplicit(SelfContact, PetscBool);

/* Self-contact inside an implicit step (TSDRAPEBE; src/selfcontact/implicit.c).
 * Every candidate pair within reach of the thickness H at the start of the step
 * (x0), or at the end of its free motion x0 + h v0, becomes a one-sided penalty
 * of the step: with its closest points' weights w_i and unit normal n fixed at x0,
 * its gap is C(x) = sum_i w_i n.x_i, and it pushes, while active, with the force
 * f_i = k (g - C(x)) w_i n on particle i: the gradient of k/2 (g - C)^2, whose
 * Hessian k (w (x) n)(w (x) n)^T is positive semi-definite (no projection). Its
 * rest gap g = min(H, C(x0)) holds a pair already inside the layer where it is
 * (the filter after the step pushes it out in position, without velocity). An
 * active set, like the solid's: active are the pairs whose free motion ends below
 * g; after a solve, a pair the step carries below g joins, and an active one that
 * ends above g (pulled, not pushed) is released, once a step.
 * SolveBegin: collective; x0, v0 owned. SolveEnabled: -contact_self_solve was not
 * turned off (not collective). */
PETSC_EXTERN PetscErrorCode SelfContactSolveEnabled(SelfContact, PetscBool *);
/* Whether the penalties of a step of h are soft against a cloth of stretch
 * rigidity `rigidity` (N/m): at their default stiffness (no -contact_self_stiffness,
 * -contact_self_solve on), 10 m/h^2 below 1/32 of it. Not collective (the same on
 * every rank). */
PETSC_EXTERN PetscErrorCode SelfContactSolveSoft(SelfContact, PetscReal h, PetscReal rigidity, PetscBool *soft);
PETSC_EXTERN PetscErrorCode SelfContactSolveBegin(SelfContact, PetscReal h, const PetscScalar *x0, const PetscScalar *v0);
/* The solid contact's constraints of the step (owned; NULL: none): the pairs' rows
 * and columns of the matrix are filtered like the cloth's. Collective. */
PETSC_EXTERN PetscErrorCode SelfContactSolveSetConstraints(SelfContact, const ClothConstraint type[], const PetscReal normal[]);
/* a += f/m for the owned particles, f the active pairs' forces at owned positions x. Collective. */
PETSC_EXTERN PetscErrorCode SelfContactSolveAddAcceleration(SelfContact, const PetscScalar *x, PetscScalar *a);
/* The active pairs' Hessian blocks (constraint-filtered; zero for the inactive):
 * rows (owned particle index), columns (global block index), 9 values each. */
PETSC_EXTERN PetscErrorCode SelfContactSolveGetBlocks(SelfContact, PetscInt *n, const PetscInt **rows, const PetscInt **cols, const PetscReal **vals);
/* After a solve that ends at owned positions x: counts the pairs pressing in it and,
 * if another solve follows (apply), changes the active set; *changes: how many
 * pairs change (the same on every rank). Collective. */
PETSC_EXTERN PetscErrorCode SelfContactSolveUpdate(SelfContact, const PetscScalar *x, PetscBool apply, PetscInt *changes);
