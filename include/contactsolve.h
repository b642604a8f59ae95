/* Contact with the solid inside an implicit step (TSDRAPEBE; src/solid/contactsolve.c).
 *
 * Contact with the solid is a constraint of the step, found by an active set made
 * consistent with the motion it allows (Baraff & Witkin's filtered system, with
 * unilateral release as in Bridson, Fedkiw & Anderson 2002; friction smoothed and
 * lagged as in Li et al. 2020, IPC):
 *   - constrained are the particles within the contact thickness of the solid at the
 *     start of the step (but those that lifted off and have not left the layer
 *     since: the shallow contacts at the edge of a contact region), those that
 *     falling freely would land in the step, and those that a solve of the step
 *     carries into the layer: their normal velocity is prescribed so that the step
 *     ends on the contact surface (the plane through the closest point). Sticky
 *     contact fixes them (tangential velocity zero too); frictionless contact and
 *     friction let them slide;
 *   - with S_i the projector onto particle i's free directions (0 when fixed, I - n n^T
 *     when sliding), the unknown is w with dv = S w + z, z making the prescribed
 *     components right, and the step solves S R(dv) + (I - S) D w = 0, whose matrix
 *     S A S + (I - S) D stays SPD for CG (D: ClothSetConstraints);
 *   - after a solve, the impulse p = M (v+ - v) - h F each constraint carried decides
 *     whether it lets go: a particle that, released alone, would lift off the
 *     surface is released (contact is unilateral). The TS solves the step again
 *     until no constraint comes or goes (-drape_contact_its bounds the solves; a
 *     particle is released at most once a step, so they cannot cycle). With
 *     -contact_release_next such a particle is held to the end of the step and
 *     free from the next one on (Baraff & Witkin 1998): a release then asks for no
 *     further solve, only a landing does;
 *   - friction (Coulomb, mu) acts on sliding particles inside the solve as a force of
 *     magnitude mu f_n against the sliding velocity, f_n the normal force of the
 *     previous step: linearised about that step's sliding direction, and below the
 *     sliding speed -contact_stick_velocity a viscous force mu f_n v/eps that holds
 *     the particle (static friction, creeping at most eps tan(alpha)/mu). Its
 *     Jacobian, PSD, joins the matrix;
 *   - a particle that ends the step on the surface keeps no velocity into it (an
 *     inelastic landing), and none at all when fixed.
 *
 * The TS type keeps the step (form, solve, adapt) and calls, per step:
 * ContactSolveBegin; for each solve ContactSolveTrialVelocity (in its
 * residual and Jacobian), ContactSolveResidual, and after it
 * ContactSolveUpdate; ContactSolveAccept for the accepted step. Arrays
 * are of the owned particles, 3 entries each. Nothing here knows the partition. */
#pragma once

#include <cloth.h>
#include <solid.h>

typedef struct _p_ContactSolve *ContactSolve;

/* -contact_stick_velocity, -contact_release_next. Create and Destroy are not collective; SetFromOptions,
 * SetUp (after ClothSetUp; again after a TS reset: the state starts anew) and View
 * (the options, and the active set's changes so far) are. */
PETSC_EXTERN PetscErrorCode ContactSolveCreate(MPI_Comm, Contact, Cloth, ContactSolve *);
PETSC_EXTERN PetscErrorCode ContactSolveSetFromOptions(ContactSolve);
PETSC_EXTERN PetscErrorCode ContactSolveSetUp(ContactSolve);
PETSC_EXTERN PetscErrorCode ContactSolveView(ContactSolve, PetscViewer);
PETSC_EXTERN PetscErrorCode ContactSolveDestroy(ContactSolve *);
/* Start of a step of length h from x0, v0 (kept until ContactSolveAccept):
 * the constraints at the start. *pc_changes: particles (all ranks) whose constraint
 * differs from that when the preconditioner was last built. Collective. */
PETSC_EXTERN PetscErrorCode ContactSolveBegin(ContactSolve, PetscReal h, const PetscScalar *x0, const PetscScalar *v0, PetscInt *pc_changes);
/* The constraints for ClothSetConstraints: type NULL when no particle on any rank is
 * constrained; block (friction's Jacobian) NULL unless -contact_mode friction. Not
 * collective. */
PETSC_EXTERN PetscErrorCode ContactSolveGetConstraints(ContactSolve, const ClothConstraint **type, const PetscReal **normal, const PetscReal **block);
/* The preconditioner was built now: later changes are counted from these constraints. */
PETSC_EXTERN PetscErrorCode ContactSolveSetPreconditioned(ContactSolve);
/* The trial velocity v = v0 + dv (pinned excepted), given by the TS, made v0 + S dv + z
 * for the constrained particles. Not collective. */
PETSC_EXTERN PetscErrorCode ContactSolveTrialVelocity(ContactSolve, const PetscScalar *dv, PetscScalar *v);
/* The residual r = M (v - v0) - h F of the TS made S (r - h f) + (I - S) D w for the
 * constrained particles, f their friction at the trial velocity v. Not collective. */
PETSC_EXTERN PetscErrorCode ContactSolveResidual(ContactSolve, const PetscScalar *dv, const PetscScalar *v, PetscScalar *r);
/* After a solve that ends at x with velocity v and accelerations a = F(x, v)/m:
 * constrain the free particles the step carries deep into the contact layer and
 * release the constraints that would let their particle lift off (from the next
 * step on with -contact_release_next: not a change). *changes: how
 * many (all ranks); *pc_changes as for Begin when there are changes, 0 otherwise.
 * Collective. */
PETSC_EXTERN PetscErrorCode ContactSolveUpdate(ContactSolve, const PetscScalar *x, const PetscScalar *v, const PetscScalar *a, PetscInt *changes, PetscInt *pc_changes);
/* The accepted step's velocity v (accelerations a, needed only when constrained):
 * a constrained particle keeps no velocity into the surface (none when fixed); its
 * normal force and sliding velocity go to the next step's friction; the impulse the
 * constraints gave. Not collective. */
PETSC_EXTERN PetscErrorCode ContactSolveAccept(ContactSolve, PetscScalar *v, const PetscScalar *a);
/* Impulse (N s) the constraints gave this rank's particles in the last accepted step. */
PETSC_EXTERN PetscErrorCode ContactSolveGetImpulse(ContactSolve, PetscReal impulse[3]);
