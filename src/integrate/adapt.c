/* The TSAdapt type "drape" (TSADAPTDRAPE), drapebe's default: fixed steps of -ts_dt,
 * cut after a failed solve and grown back.
 *
 * A step whose solve fails is cut by TSAdaptCheckStage (PETSc's: to
 * -ts_adapt_scale_solve_failed, a quarter, of itself) and tried again; this type
 * counts those failures (ts->num_snes_failures, which TSAdaptCheckStage keeps) and,
 * at each accepted step, chooses the next: after four accepted steps the step
 * doubles, up to the step asked for (TSAdaptDrapeSetStep), but back to a size that
 * failed only after 8, 16, ... 1024 steps, doubling with each failure at that size
 * (a step that cannot be taken is not tried again every few steps). It never rejects
 * a step for its error (-ts_adapt_type basic does, TSEvaluateWLTE_DrapeBE).
 *
 * The end of the run (-ts_max_time, TS_EXACTFINALTIME_MATCHSTEP) is not this type's:
 * see PreStep in simulation.c. TSAdaptChoose clips a step that would pass the end;
 * its rules for the steps before it (lengthen a last step by up to 1 %, halve the
 * two last ones) are turned off here (matchstepfac), as drape's steps stay -ts_dt
 * until the end. */
#include <petsc/private/tsimpl.h>
#include <drapebe.h>

typedef struct {
  PetscReal dt;       /* the step asked for (-ts_dt): growth stops there */
  PetscReal h_failed; /* the smallest step that failed since a step that large last succeeded */
  PetscInt  wait;     /* accepted steps before the step grows back to h_failed or beyond */
  PetscInt  accepted; /* accepted steps since the step was last cut or grown */
  PetscInt  failures; /* ts->num_snes_failures at the last accepted step */
} TSAdapt_Drape;

static PetscErrorCode TSAdaptChoose_Drape(TSAdapt adapt, TS ts, PetscReal h, PetscInt *next_sc, PetscReal *next_h, PetscBool *accept, PetscReal *wlte, PetscReal *wltea, PetscReal *wlter)
{
  TSAdapt_Drape *d = (TSAdapt_Drape *) adapt->data;
  PetscInt       failed;

  PetscFunctionBeginUser;
  *accept  = PETSC_TRUE; /* no error estimate: every step that was solved is taken */
  *next_sc = 0;
  *wlte = *wltea = *wlter = -1;
  if (d->dt <= 0) d->dt = h; /* TSAdaptDrapeSetStep not called: the first step */
  /* the failed solves of this step, each at 1/scale_solve_failed of the next (exact for
   * the default quarter), in the order they were tried */
  failed = ts->num_snes_failures - d->failures;
  for (PetscInt k = failed; k > 0; k--) {
    PetscReal f = h;
    for (PetscInt j = 0; j < k; j++) f /= adapt->scale_solve_failed;
    d->accepted = 0;
    if (f < d->h_failed)
      d->h_failed = f;
    else
      d->wait = PetscMin(2 * d->wait, 1024); /* it failed again at that size */
  }
  d->failures = ts->num_snes_failures;
  if (h >= d->h_failed) {
    d->h_failed = PETSC_MAX_REAL;
    d->wait     = 4;
  }
  *next_h = h;
  if (h < d->dt && ++d->accepted >= (2 * h >= d->h_failed ? d->wait : 4)) {
    *next_h     = PetscMin(2 * h, d->dt);
    d->accepted = 0;
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptDestroy_Drape(TSAdapt adapt)
{
  PetscFunctionBeginUser;
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeSetStep_C", NULL));
  PetscCall(PetscFree(adapt->data));
  adapt->matchstepfac[0] = 0.01; /* PETSc's (TSAdaptCreate), for a type set after this one */
  adapt->matchstepfac[1] = 2.0;
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptView_Drape(TSAdapt adapt, PetscViewer viewer)
{
  TSAdapt_Drape *d = (TSAdapt_Drape *) adapt->data;
  PetscBool      isascii;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) viewer, PETSCVIEWERASCII, &isascii));
  if (isascii) PetscCall(PetscViewerASCIIPrintf(viewer, "  fixed steps of %g s, cut after a failed solve and grown back\n", (double) d->dt));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptDrapeSetStep_Drape(TSAdapt adapt, PetscReal dt)
{
  TSAdapt_Drape *d = (TSAdapt_Drape *) adapt->data;

  PetscFunctionBeginUser;
  d->dt       = dt;
  d->h_failed = PETSC_MAX_REAL;
  d->wait     = 4;
  d->accepted = 0;
  d->failures = 0;
  PetscFunctionReturn(0);
}

PetscErrorCode TSAdaptDrapeSetStep(TSAdapt adapt, PetscReal dt)
{
  PetscFunctionBeginUser;
  PetscTryMethod(adapt, "TSAdaptDrapeSetStep_C", (TSAdapt, PetscReal), (adapt, dt));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptCreate_Drape(TSAdapt adapt)
{
  TSAdapt_Drape *d;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&d));
  adapt->data            = d;
  adapt->ops->choose     = TSAdaptChoose_Drape;
  adapt->ops->destroy    = TSAdaptDestroy_Drape;
  adapt->ops->view       = TSAdaptView_Drape;
  adapt->matchstepfac[0] = -1; /* TSAdaptChoose's "1 + matchstepfac[0]": 0, no last step lengthened */
  adapt->matchstepfac[1] = 0;  /* no two last steps halved */
  d->h_failed            = PETSC_MAX_REAL;
  d->wait                = 4;
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeSetStep_C", TSAdaptDrapeSetStep_Drape));
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeTSAdaptRegister(void)
{
  PetscFunctionBeginUser;
  PetscCall(TSAdaptRegister(TSADAPTDRAPE, TSAdaptCreate_Drape));
  PetscFunctionReturn(0);
}
