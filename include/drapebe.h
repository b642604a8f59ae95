/* The TS type "drapebe" (src/integrate/drapebe.c): drape's backward Euler in the
 * paper's form (scheme 4: A dv = b, SNES + KSP CG on an assembled matrix, contact
 * as constraints of the step). PETSc's own "beuler" integrates a first-order system
 * through an IFunction and keeps its meaning.
 *
 * The setters and getters do nothing on a TS of another type (the impulse and the
 * statistics are then zero), except TSDrapeBESetCloth, which the TS keeps whatever
 * its type, so that it can be given before TSSetFromOptions chooses the type. */
#pragma once

#include <petscts.h>
#include <cloth.h>
#include <contactsolve.h>
#include <selfcontact.h>

#define TSDRAPEBE "drapebe"
/* drapebe's default PC type: a placeholder meaning "drape chooses" (block
 * Jacobi/ICC(0), giving way to multigrid), replaced at TSSetUp; -pc_type gives
 * another. Registered by DrapeTSRegister. */
#define PCDRAPE "drape"
/* drapebe's default TSAdapt type (src/integrate/adapt.c): steps of -ts_dt, cut by
 * TSAdaptCheckStage after a failed solve, grown back after four accepted steps
 * (later back to a size that failed), and grown beyond -ts_dt while the cloth
 * settles (TSAdaptDrapeSetSettled). Registered by DrapeTSRegister. */
#define TSADAPTDRAPE "drape"

/* Register the TS type with TSRegister(), PCDRAPE with PCRegister() and
 * TSADAPTDRAPE with TSAdaptRegister() (again: no harm). Not collective. */
PETSC_EXTERN PetscErrorCode DrapeTSRegister(void);
/* TSAdaptRegister() of TSADAPTDRAPE alone. Not collective. */
PETSC_EXTERN PetscErrorCode DrapeTSAdaptRegister(void);
/* The step a TSADAPTDRAPE adapt grows back to after a failure (drapebe's TSSetUp
 * gives -ts_dt); it also forgets the failures so far. Does nothing for another
 * type. Logically collective on TSAdapt. */
PETSC_EXTERN PetscErrorCode TSAdaptDrapeSetStep(TSAdapt, PetscReal);
/* Is the cloth settling (its kinetic energy below -drape_settle_tol long enough,
 * rest.h)? Then a TSADAPTDRAPE adapt grows the step up to
 * -ts_adapt_drape_settle_factor x the step asked for; when it is no longer settling,
 * the next step is the one asked for. Does nothing for another type. Logically
 * collective on TSAdapt. */
PETSC_EXTERN PetscErrorCode TSAdaptDrapeSetSettled(TSAdapt, PetscBool);
/* The step just accepted counts as failed (drapebe cuts the next one after it, and
 * counts a failed solve): if it cleared the record of failed steps, the record stands.
 * Does nothing for another type. Logically collective on TSAdapt. */
PETSC_EXTERN PetscErrorCode TSAdaptDrapeCutAfter(TSAdapt);
/* The step asked for and the largest step taken (0, 0 for another type). Not
 * collective. */
PETSC_EXTERN PetscErrorCode TSAdaptDrapeGetSteps(TSAdapt, PetscReal *dt, PetscReal *largest);
/* The cloth whose motion the TS integrates (required by TSSetUp). Give it before
 * TSSetFromOptions: its defaults follow the cloth (-snes_type newtonls with bending
 * friction), and the options override them. Logically collective on TS. */
PETSC_EXTERN PetscErrorCode TSDrapeBESetCloth(TS, Cloth);
/* Contact with the solid as constraints of the step (include/contactsolve.h; NULL:
 * none), set up by TSSetUp. Logically collective on TS. */
PETSC_EXTERN PetscErrorCode TSDrapeBESetContact(TS, ContactSolve);
/* Self-contact's close pairs in the step's solve (include/selfcontact.h; NULL:
 * none). Logically collective on TS. */
PETSC_EXTERN PetscErrorCode TSDrapeBESetSelfContact(TS, SelfContact);
/* Omega_max of the cloth at the start (rad/s): with (h Omega_max)^2 the default
 * preconditioner is chosen (block Jacobi/ICC or algebraic multigrid); without it
 * the TS estimates Omega_max itself. Logically collective on TS (the same value on
 * every rank). */
PETSC_EXTERN PetscErrorCode TSDrapeBESetStiffness(TS, PetscReal);
/* The state was changed after the last step by more than the landing on the solid
 * (the self-contact filter), adding `added` J of mechanical energy: the energy check
 * of the next step starts from it, and the next step is cut when `added` is more
 * than that check allows a step. Logically collective on TS. */
PETSC_EXTERN PetscErrorCode TSDrapeBEStateChanged(TS, PetscReal added);
/* Impulse (N s) the contact constraints gave this rank's particles in the last
 * step. Not collective. */
PETSC_EXTERN PetscErrorCode TSDrapeBEGetContactImpulse(TS, PetscReal[3]);
/* Solves made and steps rejected so far, and the last failed solve in words (NULL
 * or empty: none). Not collective (the same on every rank). */
PETSC_EXTERN PetscErrorCode TSDrapeBEGetStatistics(TS, PetscInt *solves, PetscInt *rejected, const char **failure);
/* The step at which drape's block Jacobi/ICC(0) gave way to multigrid (-1: it did
 * not, or the options chose the preconditioner), the steps TSAdapt rejected for
 * their local error (-ts_adapt_type basic), and the steps cut because the changes
 * after the step before (the self-contact filter, TSDrapeBEStateChanged) added
 * mechanical energy, and those cut because the step before added more than
 * -drape_energy_rise. Not collective (the same on every rank). */
PETSC_EXTERN PetscErrorCode TSDrapeBEGetStepHistory(TS, PetscInt *pc_switched, PetscInt *error_rejected, PetscInt *filter_cut, PetscInt *rise_cut);
/* Steps solved with the matrix of an earlier step (-drape_matrix_keep), and tries
 * refused (made again with a new matrix). Not collective (the same on every rank). */
PETSC_EXTERN PetscErrorCode TSDrapeBEGetMatrixKept(TS, PetscInt *kept, PetscInt *refused);
/* The step at which drape's block IC(0) took its level-1 fill for the rest of the
 * run (-1: never, or drape did not choose the preconditioner). Not collective. */
PETSC_EXTERN PetscErrorCode TSDrapeBEGetFillStep(TS, PetscInt *fill_step);
