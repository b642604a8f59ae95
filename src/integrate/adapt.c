/* The TSAdapt type "drape" (TSADAPTDRAPE), drapebe's default: steps of -ts_dt, cut
 * after a failed solve and grown back, and grown beyond -ts_dt while the cloth
 * settles.
 *
 * A step whose solve fails is cut by TSAdaptCheckStage (PETSc's: to
 * -ts_adapt_scale_solve_failed, a quarter, of itself) and tried again; this type
 * counts those failures (ts->num_snes_failures, which TSAdaptCheckStage keeps) and,
 * at each accepted step, chooses the next: after four accepted steps the step
 * doubles, up to the step asked for (TSAdaptDrapeSetStep), but back to a size that
 * failed only after 8, 16, ... 1024 steps, doubling with each failure at that size
 * (a step that cannot be taken is not tried again every few steps). It never rejects
 * a step for its error (-ts_adapt_type basic does, TSEvaluateWLTE_DrapeBE). drapebe
 * also cuts the step after an accepted one that added energy or whose self-contact
 * filter did (BECutNextStep), counted as a failure of that accepted step
 * (TSAdaptDrapeCutAfter): a step as large as one that failed clears the record only
 * if no such cut follows it. (Cleared at once, the record was cleared by the very
 * step that added the energy, so its wait never doubled and every retry came after 4
 * steps at half the size: the sphere drop at 2e-2 s made 9 cuts in 140 steps, now 5
 * in 121. The hang at 64^2 settling with steps up to 1 s, factor 100, still gains
 * energy at steps from 0.04 s once settled and is not at rest by t = 60 s: 55 cuts
 * against 66.)
 *
 * Settling (TSAdaptDrapeSetSettled: the run's rest test, rest.h, found the kinetic
 * energy below -drape_settle_tol for -drape_rest_time): the ceiling becomes
 * -ts_adapt_drape_settle_factor x -ts_dt, reached by the same doublings, each only
 * after a step that took at most SETTLE_MAX_ITS linear iterations (CG's iterations
 * grow with the step: beyond that, a larger step would not be cheaper per simulated
 * second, and at 300 drape's block IC(0) gives way to multigrid, drapebe.c). The
 * first step after the kinetic energy rises above the tolerance again is -ts_dt.
 * Large steps damp the cloth's swing numerically, so the growth waits for the swing
 * that decides the folds to have died down (rest.c). Whether a run grows its step is
 * a function of its state alone: the same on any number of ranks.
 *
 * The end of the run (-ts_max_time, TS_EXACTFINALTIME_MATCHSTEP) is not this type's:
 * see PreStep in simulation.c. TSAdaptChoose clips a step that would pass the end;
 * its rules for the steps before it (lengthen a last step by up to 1 %, halve the
 * two last ones) are turned off here (matchstepfac): drape's steps change by the
 * rules above alone. */
#include <petsc/private/tsimpl.h>
#include <drapebe.h>
#include <drape.h>

#define SETTLE_MAX_ITS 100

typedef struct {
  PetscReal dt;       /* the step asked for (-ts_dt): growth stops there unless settled */
  PetscReal factor;   /* settled: growth stops at factor x dt (1: never beyond dt) */
  PetscBool settled;  /* TSAdaptDrapeSetSettled */
  PetscInt  ksp_its;  /* ts->ksp_its at the last accepted step */
  PetscReal h_grown;  /* the largest step taken */
  PetscReal h_failed; /* the smallest step that failed since a step that large last succeeded */
  PetscInt  wait;     /* accepted steps before the step grows back to h_failed or beyond */
  PetscBool cleared;  /* the last accepted step cleared h_failed and wait, ... */
  PetscReal h_kept;   /* ... whose values before it were these (restored if a cut follows it) */
  PetscInt  wait_kept;
  PetscInt  accepted; /* accepted steps since the step was last cut or grown */
  PetscInt  failures; /* ts->num_snes_failures at the last accepted step */
} TSAdapt_Drape;

static PetscErrorCode TSAdaptChoose_Drape(TSAdapt adapt, TS ts, PetscReal h, PetscInt *next_sc, PetscReal *next_h, PetscBool *accept, PetscReal *wlte, PetscReal *wltea, PetscReal *wlter)
{
  TSAdapt_Drape *d = (TSAdapt_Drape *) adapt->data;
  PetscInt       failed, its;
  PetscReal      ceiling;

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
  d->cleared  = (PetscBool) (h >= d->h_failed);
  if (d->cleared) {
    d->h_kept    = d->h_failed;
    d->wait_kept = d->wait;
    d->h_failed  = PETSC_MAX_REAL;
    d->wait      = 4;
  }
  its        = ts->ksp_its - d->ksp_its; /* this step's, the failed tries included */
  d->ksp_its = ts->ksp_its;
  d->h_grown = PetscMax(d->h_grown, h);
  ceiling    = d->settled ? d->factor * d->dt : d->dt;
  *next_h    = h;
  if (h > ceiling) { /* no longer settled: back to the step asked for */
    *next_h     = ceiling;
    d->accepted = 0;
  } else if (h < ceiling && ++d->accepted >= (2 * h >= d->h_failed ? d->wait : 4) && (2 * h <= d->dt || its <= SETTLE_MAX_ITS)) {
    *next_h     = PetscMin(2 * h, ceiling);
    d->accepted = 0;
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptDestroy_Drape(TSAdapt adapt)
{
  PetscFunctionBeginUser;
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeSetStep_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeSetSettled_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeGetSteps_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeCutAfter_C", NULL));
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
  if (isascii) PetscCall(PetscViewerASCIIPrintf(viewer, "  steps of %g s, cut after a failed solve and grown back, up to %g s while the cloth settles\n", (double) d->dt, (double) (d->factor * d->dt)));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptDrapeCutAfter_Drape(TSAdapt adapt)
{
  TSAdapt_Drape *d = (TSAdapt_Drape *) adapt->data;

  PetscFunctionBeginUser;
  if (d->cleared) { /* the step that cleared the record failed after all: the record stands (and its wait doubles at the failure, TSAdaptChoose_Drape) */
    d->h_failed = d->h_kept;
    d->wait     = d->wait_kept;
    d->cleared  = PETSC_FALSE;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode TSAdaptDrapeCutAfter(TSAdapt adapt)
{
  PetscFunctionBeginUser;
  PetscTryMethod(adapt, "TSAdaptDrapeCutAfter_C", (TSAdapt), (adapt));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptDrapeSetStep_Drape(TSAdapt adapt, PetscReal dt)
{
  TSAdapt_Drape *d = (TSAdapt_Drape *) adapt->data;

  PetscFunctionBeginUser;
  d->dt       = dt;
  d->h_failed = PETSC_MAX_REAL;
  d->wait     = 4;
  d->cleared  = PETSC_FALSE;
  d->accepted = 0;
  d->failures = 0;
  d->ksp_its  = 0;
  d->settled  = PETSC_FALSE;
  PetscFunctionReturn(0);
}

PetscErrorCode TSAdaptDrapeSetStep(TSAdapt adapt, PetscReal dt)
{
  PetscFunctionBeginUser;
  PetscTryMethod(adapt, "TSAdaptDrapeSetStep_C", (TSAdapt, PetscReal), (adapt, dt));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptDrapeSetSettled_Drape(TSAdapt adapt, PetscBool settled)
{
  TSAdapt_Drape *d = (TSAdapt_Drape *) adapt->data;

  PetscFunctionBeginUser;
  d->settled = settled;
  PetscFunctionReturn(0);
}

PetscErrorCode TSAdaptDrapeSetSettled(TSAdapt adapt, PetscBool settled)
{
  PetscFunctionBeginUser;
  PetscTryMethod(adapt, "TSAdaptDrapeSetSettled_C", (TSAdapt, PetscBool), (adapt, settled));
  PetscFunctionReturn(0);
}

PetscErrorCode TSAdaptDrapeGetSteps(TSAdapt adapt, PetscReal *dt, PetscReal *largest)
{
  PetscFunctionBeginUser;
  *dt = *largest = 0;
  PetscTryMethod(adapt, "TSAdaptDrapeGetSteps_C", (TSAdapt, PetscReal *, PetscReal *), (adapt, dt, largest));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptDrapeGetSteps_Drape(TSAdapt adapt, PetscReal *dt, PetscReal *largest)
{
  TSAdapt_Drape *d = (TSAdapt_Drape *) adapt->data;

  PetscFunctionBeginUser;
  *dt      = d->dt;
  *largest = d->h_grown;
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptSetFromOptions_Drape(TSAdapt adapt, PetscOptionItems *PetscOptionsObject)
{
  TSAdapt_Drape *d = (TSAdapt_Drape *) adapt->data;

  PetscFunctionBeginUser;
  PetscOptionsHeadBegin(PetscOptionsObject, "drape's step: -ts_dt, cut after a failed solve, grown while the cloth settles");
  PetscCall(PetscOptionsReal("-ts_adapt_drape_settle_factor", "Largest step while the cloth settles (-drape_settle_tol), as a multiple of -ts_dt (1: -ts_dt throughout)", "TSAdaptDrapeSetSettled", d->factor, &d->factor, NULL));
  PetscOptionsHeadEnd();
  PetscCall(DrapeCheckReal(PetscObjectComm((PetscObject) adapt), "-ts_adapt_drape_settle_factor", 1, &d->factor, 1, 1e6, ""));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSAdaptCreate_Drape(TSAdapt adapt)
{
  TSAdapt_Drape *d;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&d));
  adapt->data                = d;
  adapt->ops->choose         = TSAdaptChoose_Drape;
  adapt->ops->destroy        = TSAdaptDestroy_Drape;
  adapt->ops->view           = TSAdaptView_Drape;
  adapt->ops->setfromoptions = TSAdaptSetFromOptions_Drape;
  adapt->matchstepfac[0]     = -1; /* TSAdaptChoose's "1 + matchstepfac[0]": 0, no last step lengthened */
  adapt->matchstepfac[1]     = 0;  /* no two last steps halved */
  d->h_failed                = PETSC_MAX_REAL;
  d->wait                    = 4;
  d->factor                  = 10;
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeSetStep_C", TSAdaptDrapeSetStep_Drape));
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeSetSettled_C", TSAdaptDrapeSetSettled_Drape));
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeGetSteps_C", TSAdaptDrapeGetSteps_Drape));
  PetscCall(PetscObjectComposeFunction((PetscObject) adapt, "TSAdaptDrapeCutAfter_C", TSAdaptDrapeCutAfter_Drape));
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeTSAdaptRegister(void)
{
  PetscFunctionBeginUser;
  PetscCall(TSAdaptRegister(TSADAPTDRAPE, TSAdaptCreate_Drape));
  PetscFunctionReturn(0);
}
