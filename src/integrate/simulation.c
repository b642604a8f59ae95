#define _POSIX_C_SOURCE 200809L /* sigaction */
/* The simulation driver: state vector, TS set-up and the time loop.
 *
 * Data flows one way: options -> cloth (lattice, material, pins) -> state U ->
 * TS -> monitor (divergence check, output, progress). The integrator is whatever
 * -ts_type says; drape supplies
 *   - the first-order right-hand side G(U) = [v; F(x, v)/m] for explicit TS types
 *     (euler = paper scheme 2, rk, ssp);
 *   - the "position" and "momentum" splits for basicsymplectic (scheme 3: velocity
 *     first; the momentum update sees the current velocity for the damping force);
 *   - its own TS type drapebe (scheme 4, see drapebe.c).
 * The features around the loop are objects it calls, each with its options, state
 * and view: restart (output.h), the rest test (rest.h), the Cusick analysis
 * (analysis.h), the stability estimate (stability.h). A number the run prints is
 * reported by the same call (ReportView*, report.h). */
#include <petsc/private/tsimpl.h>
#include <simulation.h>
#include <drapebe.h>
#include <sbaijmult.h>
#include <stability.h>
#include <output.h>
#include <report.h>
#include <solid.h>
#include <contactsolve.h>
#include <selfcontact.h>
#include <analysis.h>
#include <drape.h>
#include "rest.h"
#include <unistd.h>
#include <signal.h>

/* SIGTERM/SIGINT (a batch system's wall-time limit, Ctrl-C), SIGHUP (the terminal or
 * ssh session closed) and SIGPIPE (the reader of stdout gone): finish the step, write
 * a checkpoint frame, stop cleanly. */
static volatile sig_atomic_t caught_signal = 0;
static void                  SignalHandler(int sig) { caught_signal = sig; }
static const char           *SignalName(int sig) { return sig == SIGTERM ? "SIGTERM" : sig == SIGINT ? "SIGINT" : sig == SIGHUP ? "SIGHUP" : sig == SIGPIPE ? "SIGPIPE" : ""; }

/* During the time loop: the four signals above stop it at the next step. After it,
 * SIGPIPE stays ignored (a closed stdout must not kill the run before its summary
 * and last frame are in the file: the prints then fail quietly), the others are
 * back to their defaults. */
static void SignalsCatch(PetscBool on)
{
  static const int signals[] = {SIGTERM, SIGINT, SIGHUP, SIGPIPE};

  for (size_t i = 0; i < sizeof signals / sizeof signals[0]; i++) {
    struct sigaction action;
    memset(&action, 0, sizeof action);
    (void) sigemptyset(&action.sa_mask);
    /* a second SIGTERM, SIGINT or SIGHUP ends the run at once (the handler is reset by
     * the first); every write to a closed stdout raises SIGPIPE again: it stays */
    action.sa_flags   = SA_RESTART | (signals[i] == SIGPIPE ? 0 : SA_RESETHAND);
    action.sa_handler = on ? SignalHandler : signals[i] == SIGPIPE ? SIG_IGN : SIG_DFL;
    (void) sigaction(signals[i], &action, NULL);
  }
}

/* What the frames say about contact with the solid since the last frame. */
typedef struct {
  PetscReal depth;          /* deepest penetration, m */
  PetscInt  count;          /* particles in contact after the last step */
  PetscReal impulse[3], t0; /* impulse on this rank's particles since t0, N s */
} ContactTally;

struct _p_Simulation {
  MPI_Comm        comm;
  Cloth           cloth;
  Solid           solid;
  Contact         contact;    /* NULL when the scene has no solid */
  ContactSolve    solve;      /* contact inside drapebe's step (contactsolve.h); NULL when contact is */
  SelfContact     self;       /* NULL without -contact_self */
  PetscBool      *held;       /* owned particles sticky contact holds after the step (for the self-contact filter) */
  PetscScalar    *unfiltered; /* drapebe, soft self-contact penalties: the state before the projection and the filter, for the energy they add */
  ContactTally    tally;
  RestTest        rest;    /* the run ends at rest (rest.h) */
  Cusick          cusick;  /* the Cusick analysis at the end (analysis.h) */
  Restart         restart; /* -restart (output.h) */
  Output          output;
  Report          report; /* start-up numbers and summary by name (HDF5 attributes, -drape_json) */
  PetscBool       json, progress, summary, help;
  TS              ts;
  Vec             U;
  IS              is_x, is_v;
  PetscInt        n;  /* 3 x owned particles */
  PetscReal       t0; /* time and step this run starts from (a restart's frame) */
  PetscInt        step0;
  StabilityLimits limits;
  PetscInt        stability_its;
  PetscInt        interrupted; /* signal that stopped the run */
  /* divergence checks */
  PetscReal divergence_factor;
  PetscReal max_strain, strain_last; /* bound, and the largest strain at the last full check */
  PetscBool baseline;                /* energy0 set */
  PetscReal energy0, energy_scale;
  /* progress */
  PetscReal      wall0, wall_last;
  PetscLogDouble rss0; /* resident memory before the set-up, bytes */
  PetscLogDouble cpu0; /* this rank's CPU time then, s              */
};

static const char *const supported_types[] = {TSEULER, TSBASICSYMPLECTIC, TSDRAPEBE, TSRK, TSSSP, NULL};

static PetscErrorCode RHSFirstOrder(TS ts, PetscReal t, Vec U, Vec G, void *ctx)
{
  Simulation         sim = (Simulation) ctx;
  const PetscScalar *u;
  PetscScalar       *g;

  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(U, &u));
  PetscCall(VecGetArray(G, &g));
  PetscCall(PetscArraycpy(g, u + sim->n, sim->n));
  PetscCall(ClothComputeAcceleration(sim->cloth, u, u + sim->n, g + sim->n));
  PetscCall(VecRestoreArray(G, &g));
  PetscCall(VecRestoreArrayRead(U, &u));
  PetscFunctionReturn(0);
}

/* position split: dx/dt = v */
static PetscErrorCode RHSPosition(TS ts, PetscReal t, Vec V, Vec G, void *ctx)
{
  PetscFunctionBeginUser;
  PetscCall(VecCopy(V, G));
  PetscFunctionReturn(0);
}

/* momentum split: dv/dt = F(x, v)/m. TSBASICSYMPLECTIC passes x only; the splits
 * are contiguous views of U, so U holds the current v. */
static PetscErrorCode RHSMomentum(TS ts, PetscReal t, Vec X, Vec A, void *ctx)
{
  Simulation         sim = (Simulation) ctx;
  const PetscScalar *x, *u;
  PetscScalar       *a;

  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(X, &x));
  PetscCall(VecGetArrayRead(sim->U, &u));
  PetscCall(VecGetArray(A, &a));
  PetscCall(ClothComputeAcceleration(sim->cloth, x, u + sim->n, a));
  PetscCall(VecRestoreArray(A, &a));
  PetscCall(VecRestoreArrayRead(sim->U, &u));
  PetscCall(VecRestoreArrayRead(X, &x));
  PetscFunctionReturn(0);
}

/* -ts_type basicsymplectic, drape's own. PETSc's TSBASICSYMPLECTIC keeps a work
 * copy of the whole state (x, v: 48 bytes a particle) and copies v into it before
 * every position update; drape's position split is dx/dt = v (RHSPosition), so here
 * the position update reads v in place and only the acceleration needs room (24
 * bytes a particle). The same schemes (-ts_basicsymplectic_type 1: symplectic Euler,
 * 2: velocity Verlet, 3, 4), stages, coefficients and AXPYs as PETSc's, so the same
 * frames bit for bit; registered under PETSc's name, so every test of the type and
 * TSBasicSymplecticSetType/GetType keep working. No interpolation (drape lands on
 * -ts_max_time by TS_EXACTFINALTIME_MATCHSTEP). */
#define SYMPLECTIC_CBRT2 1.2599210498948731647672106
static const struct {
  const char *name;
  PetscInt    s;
  PetscReal   c[4], d[4]; /* velocity and position coefficients of each stage */
} symplectic_schemes[] = {
  {TSBASICSYMPLECTICSIEULER, 1, {1.0}, {1.0}},
  {TSBASICSYMPLECTICVELVERLET, 2, {0, 1.0}, {0.5, 0.5}},
  {TSBASICSYMPLECTIC3, 3, {1, -2.0 / 3.0, 2.0 / 3.0}, {-1.0 / 24.0, 3.0 / 4.0, 7.0 / 24.0}},
  {TSBASICSYMPLECTIC4,
   4,
   {1.0 / 2.0 / (2.0 - SYMPLECTIC_CBRT2), (1.0 - SYMPLECTIC_CBRT2) / 2.0 / (2.0 - SYMPLECTIC_CBRT2), (1.0 - SYMPLECTIC_CBRT2) / 2.0 / (2.0 - SYMPLECTIC_CBRT2), 1.0 / 2.0 / (2.0 - SYMPLECTIC_CBRT2)},
   {1.0 / (2.0 - SYMPLECTIC_CBRT2), -SYMPLECTIC_CBRT2 / (2.0 - SYMPLECTIC_CBRT2), 1.0 / (2.0 - SYMPLECTIC_CBRT2), 0}},
};
#define SYMPLECTIC_NSCHEMES ((PetscInt) (sizeof symplectic_schemes / sizeof symplectic_schemes[0]))

typedef struct {
  PetscInt scheme; /* index into symplectic_schemes */
  IS       is_x, is_v;
  TS       momentum; /* the sub-TS of the "momentum" split: its RHS is the acceleration */
  Vec      A;        /* acceleration, 3 per owned particle: only where the cloth cannot fuse kick and drift (ClothKickDrift) */
} TS_Symplectic;

static PetscErrorCode TSStep_Symplectic(TS ts)
{
  TS_Symplectic  *sy = (TS_Symplectic *) ts->data;
  const PetscInt  k  = sy->scheme;
  Simulation      sim;
  const PetscReal h = ts->time_step;
  Vec             x, v;
  PetscBool       ok = PETSC_TRUE;

  PetscFunctionBeginUser;
  PetscCall(TSGetApplicationContext(ts, &sim));
  PetscCall(VecGetSubVector(ts->vec_sol, sy->is_x, &x));
  PetscCall(VecGetSubVector(ts->vec_sol, sy->is_v, &v));
  for (PetscInt i = 0; i < symplectic_schemes[k].s && ok; i++) {
    PetscCall(TSPreStage(ts, ts->ptime));
    PetscBool fused = PETSC_FALSE;
    if (symplectic_schemes[k].c[i]) { /* the kick, and the drift with it in one pass where the cloth can (ClothKickDrift) */
      PetscScalar *xa, *va;
      PetscCall(VecGetArray(x, &xa));
      PetscCall(VecGetArray(v, &va));
      PetscCall(ClothKickDrift(sim->cloth, xa, va, symplectic_schemes[k].c[i] * h, symplectic_schemes[k].d[i] * h, &fused));
      PetscCall(VecRestoreArray(v, &va));
      PetscCall(VecRestoreArray(x, &xa));
      if (!fused) {
        if (!sy->A) PetscCall(VecDuplicate(v, &sy->A));
        PetscCall(TSComputeRHSFunction(sy->momentum, ts->ptime, x, sy->A));
        PetscCall(VecAXPY(v, symplectic_schemes[k].c[i] * h, sy->A));
      }
    }
    if (symplectic_schemes[k].d[i]) {
      if (!fused) PetscCall(VecAXPY(x, symplectic_schemes[k].d[i] * h, v));
      ts->ptime += symplectic_schemes[k].d[i] * h;
    }
    PetscCall(TSPostStage(ts, ts->ptime, 0, &ts->vec_sol));
    PetscCall(TSAdaptCheckStage(ts->adapt, ts, ts->ptime, ts->vec_sol, &ok));
    if (!ok) ts->reason = TS_DIVERGED_STEP_REJECTED;
  }
  PetscCall(VecRestoreSubVector(ts->vec_sol, sy->is_x, &x));
  PetscCall(VecRestoreSubVector(ts->vec_sol, sy->is_v, &v));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSSetUp_Symplectic(TS ts)
{
  TS_Symplectic *sy = (TS_Symplectic *) ts->data;

  PetscFunctionBeginUser;
  PetscCall(TSRHSSplitGetIS(ts, "position", &sy->is_x));
  PetscCall(TSRHSSplitGetIS(ts, "momentum", &sy->is_v));
  PetscCall(TSRHSSplitGetSubTS(ts, "momentum", &sy->momentum));
  PetscCheck(sy->is_x && sy->is_v && sy->momentum, PetscObjectComm((PetscObject) ts), PETSC_ERR_ORDER, "-ts_type basicsymplectic needs the position and momentum splits (TSRHSSplitSetIS, TSRHSSplitSetRHSFunction)");
  PetscCheck(ts->exact_final_time != TS_EXACTFINALTIME_INTERPOLATE, PetscObjectComm((PetscObject) ts), PETSC_ERR_USER_INPUT,
             "-ts_exact_final_time interpolate is not available with -ts_type basicsymplectic (drape's keeps no copy of the previous state to interpolate from); use matchstep (the default) or stepover");
  PetscCall(TSGetAdapt(ts, &ts->adapt));
  PetscCall(TSAdaptCandidatesClear(ts->adapt)); /* fixed steps */
  PetscFunctionReturn(0);
}

static PetscErrorCode TSReset_Symplectic(TS ts)
{
  TS_Symplectic *sy = (TS_Symplectic *) ts->data;

  PetscFunctionBeginUser;
  PetscCall(VecDestroy(&sy->A));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSSymplecticSetType(TS ts, TSBasicSymplecticType type)
{
  TS_Symplectic *sy    = (TS_Symplectic *) ts->data;
  PetscBool      match = PETSC_FALSE;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < SYMPLECTIC_NSCHEMES && !match; k++) {
    PetscCall(PetscStrcmp(symplectic_schemes[k].name, type, &match));
    if (match) sy->scheme = k;
  }
  PetscCheck(match, PetscObjectComm((PetscObject) ts), PETSC_ERR_ARG_UNKNOWN_TYPE, "-ts_basicsymplectic_type %s is not one of 1 (symplectic Euler), 2 (velocity Verlet), 3, 4", type);
  PetscFunctionReturn(0);
}

static PetscErrorCode TSSymplecticGetType(TS ts, TSBasicSymplecticType *type)
{
  PetscFunctionBeginUser;
  *type = symplectic_schemes[((TS_Symplectic *) ts->data)->scheme].name;
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDestroy_Symplectic(TS ts)
{
  PetscFunctionBeginUser;
  PetscCall(TSReset_Symplectic(ts));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSBasicSymplecticSetType_C", NULL));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSBasicSymplecticGetType_C", NULL));
  PetscCall(PetscFree(ts->data));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSSetFromOptions_Symplectic(TS ts, PetscOptionItems *PetscOptionsObject)
{
  TS_Symplectic *sy = (TS_Symplectic *) ts->data;
  const char    *names[SYMPLECTIC_NSCHEMES];
  PetscInt       choice = sy->scheme;
  PetscBool      set;

  PetscFunctionBeginUser;
  for (PetscInt k = 0; k < SYMPLECTIC_NSCHEMES; k++) names[k] = symplectic_schemes[k].name;
  PetscOptionsHeadBegin(PetscOptionsObject, "Basic symplectic integrator options (drape's: no work copy of the state)");
  PetscCall(PetscOptionsEList("-ts_basicsymplectic_type", "Scheme: 1 symplectic Euler, 2 velocity Verlet, 3 or 4 (orders)", "TSBasicSymplecticSetType", names, SYMPLECTIC_NSCHEMES, names[sy->scheme], &choice, &set));
  if (set) sy->scheme = choice;
  PetscOptionsHeadEnd();
  PetscFunctionReturn(0);
}

static PetscErrorCode TSCreate_Symplectic(TS ts)
{
  TS_Symplectic *sy;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&sy));
  ts->data                = (void *) sy;
  ts->ops->setup          = TSSetUp_Symplectic;
  ts->ops->step           = TSStep_Symplectic;
  ts->ops->reset          = TSReset_Symplectic;
  ts->ops->destroy        = TSDestroy_Symplectic;
  ts->ops->setfromoptions = TSSetFromOptions_Symplectic;
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSBasicSymplecticSetType_C", TSSymplecticSetType));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSBasicSymplecticGetType_C", TSSymplecticGetType));
  PetscFunctionReturn(0);
}

/* Land exactly on -ts_max_time (TS_EXACTFINALTIME_MATCHSTEP) for every TS type:
 * drape's basicsymplectic never calls TSAdaptChoose, which clips the step of the
 * others (euler, rk, ssp, drapebe) before this finds anything to clip. A step that
 * ends within round-off of the end keeps its size (so a run stopped at t and one
 * that went on take bitwise the same steps: tests/test_restart.py compares them
 * exactly) and PostStep snaps the time; accumulated round-off never adds a spurious
 * extra step. Not moved into a TSAdapt for basicsymplectic too: PETSc 3.18's
 * TSAdaptChoose clips any overshoot, round-off included (drapebe's last step became
 * tmax - t instead of h, 1e-16 apart, when its TSAdapt took over its steps), and
 * its matchstepfac rules, without a setter, lengthen a last step by up to 1 % and
 * halve the two last ones. */
static PetscErrorCode PreStep(TS ts)
{
  PetscReal              t, dt, tmax, rest;
  TSExactFinalTimeOption eftopt;

  PetscFunctionBeginUser;
  {
    /* self-contact filters the motion from the step's start: whatever the final-time option */
    Simulation         s;
    const PetscScalar *u;
    PetscCall(TSGetApplicationContext(ts, &s));
    if (s->self) {
      PetscCall(VecGetArrayRead(s->U, &u));
      PetscCall(SelfContactBeginStep(s->self, u));
      PetscCall(VecRestoreArrayRead(s->U, &u));
    }
  }
  PetscCall(TSGetExactFinalTime(ts, &eftopt));
  if (eftopt != TS_EXACTFINALTIME_MATCHSTEP) PetscFunctionReturn(0);
  PetscCall(TSGetTime(ts, &t));
  PetscCall(TSGetTimeStep(ts, &dt));
  PetscCall(TSGetMaxTime(ts, &tmax));
  rest = tmax - t;
  if (rest > 0 && dt > rest * (1 + 1e-8)) PetscCall(TSSetTimeStep(ts, rest));
  PetscFunctionReturn(0);
}

/* After every step, whatever the scheme: contact (project particles that reached
 * the solid back onto its contact surface, constrain their velocity), self-contact's
 * filter, and the rest test (rest.h) that ends a draping run by itself. */
static PetscErrorCode PostStep(TS ts)
{
  Simulation       s;
  PetscScalar     *u;
  const PetscBool *pinned;
  const PetscReal *mass;
  PetscReal        t;

  PetscFunctionBeginUser;
  PetscCall(TSGetApplicationContext(ts, &s));
  PetscCall(ClothGetMasses(s->cloth, &mass, &pinned));
  {
    PetscReal tmax, dt, t0;
    PetscCall(TSGetTime(ts, &t));
    PetscCall(TSGetPrevTime(ts, &t0));
    PetscCall(TSGetMaxTime(ts, &tmax));
    dt = t - t0;
    if (PetscAbsReal(t - tmax) <= 1e-8 * dt) {
      PetscCall(TSSetTime(ts, tmax));
      PetscCall(TSSetConvergedReason(ts, TS_CONVERGED_TIME));
    }
  }
  {
    PetscMPIInt sig = (PetscMPIInt) caught_signal, any;
    PetscCallMPI(MPI_Allreduce(&sig, &any, 1, MPI_INT, MPI_MAX, s->comm));
    if (any) {
      s->interrupted = any;
      PetscCall(TSSetConvergedReason(ts, TS_CONVERGED_USER));
    }
  }
  PetscCall(VecGetArray(s->U, &u));
  /* drapebe cuts the next step when the filter (and the projection before it) added
   * energy after a step whose self-contact penalties were soft against the cloth
   * (TSDrapeBEStateChanged, SelfContactSolveSoft): the state before them is kept */
  PetscBool watch = PETSC_FALSE;
  if (s->self) {
    PetscBool implicit;
    PetscCall(PetscObjectTypeCompare((PetscObject) ts, TSDRAPEBE, &implicit));
    if (implicit) {
      PetscReal t0;
      ClothInfo info;
      PetscCall(TSGetPrevTime(ts, &t0));
      PetscCall(TSGetTime(ts, &t));
      PetscCall(ClothGetInfo(s->cloth, &info));
      PetscCall(SelfContactSolveSoft(s->self, t - t0, PetscMax(info.stretch[0], info.stretch[1]), &watch));
    }
    if (watch) {
      if (!s->unfiltered) PetscCall(PetscMalloc1(2 * s->n + 1, &s->unfiltered));
      PetscCall(PetscArraycpy(s->unfiltered, u, 2 * s->n));
    }
  }
  if (s->contact) {
    PetscReal depth, h = 0, t0;
    PetscBool velocity_first;
    /* symplectic Euler: the projection is its contact, and the position follows the
     * corrected velocity; backward Euler made its contacts constraints of the step and
     * leaves the projection the shallow ones, lifted along the normal only */
    PetscCall(PetscObjectTypeCompare((PetscObject) ts, TSBASICSYMPLECTIC, &velocity_first));
    if (velocity_first) {
      PetscCall(TSGetPrevTime(ts, &t0));
      PetscCall(TSGetTime(ts, &t));
      h = t - t0;
    }
    PetscReal j[3];
    PetscCall(TSDrapeBEGetContactImpulse(ts, j));
    for (PetscInt d = 0; d < 3; d++) s->tally.impulse[d] += j[d];
    PetscCall(ContactProject(s->contact, s->n / 3, u, u + s->n, mass, pinned, h, &depth, &s->tally.count, s->tally.impulse, s->held));
    s->tally.depth = PetscMax(s->tally.depth, depth);
  }
  if (s->self) { /* last: the step ends without the cloth crossing itself */
    PetscReal t0;
    PetscCall(TSGetPrevTime(ts, &t0));
    PetscCall(TSGetTime(ts, &t));
    PetscBool changed;
    PetscCall(SelfContactSetHeld(s->self, s->held));
    PetscCall(SelfContactFilter(s->self, t - t0, u, u + s->n, &changed));
    if (changed) {
      PetscReal added = 0;
      if (watch) {
        ClothEnergies before, after;
        PetscCall(ClothComputeEnergies(s->cloth, s->unfiltered, s->unfiltered + s->n, &before));
        PetscCall(ClothComputeEnergies(s->cloth, u, u + s->n, &after));
        added = ClothEnergyMechanical(&after) - ClothEnergyMechanical(&before);
      }
      PetscCall(TSDrapeBEStateChanged(ts, added));
    }
  }
  PetscCall(ClothUpdatePlasticState(s->cloth, u)); /* the step's final place: the bending friction's sliders follow */
  {
    PetscBool at_rest, settled;
    TSAdapt   adapt;
    PetscCall(TSGetTime(ts, &t));
    PetscCall(RestTestUpdate(s->rest, s->cloth, u + s->n, t, &at_rest, &settled));
    if (at_rest) PetscCall(TSSetConvergedReason(ts, TS_CONVERGED_USER));
    PetscCall(TSGetAdapt(ts, &adapt));
    PetscCall(TSAdaptDrapeSetSettled(adapt, settled)); /* drapebe's step may grow (adapt.c); no-op for the other adapt types */
  }
  PetscCall(VecRestoreArray(s->U, &u));
  PetscFunctionReturn(0);
}

PetscErrorCode SimulationCreate(MPI_Comm comm, Simulation *sim)
{
  Simulation s;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&s));
  PetscCall(PetscMemoryGetCurrentUsage(&s->rss0));
  PetscCall(ReportCPUTime(&s->cpu0));
  s->comm              = comm;
  s->stability_its     = 30;
  s->divergence_factor = 1.0;
  s->max_strain        = 1.0;
  s->summary           = PETSC_TRUE;
  {
    /* a progress line only on an interactive terminal: Open MPI gives its ranks a pty
     * even when mpirun's output goes to a batch log, so not under an MPI launcher */
    PetscMPIInt size;
    PetscCallMPI(MPI_Comm_size(comm, &size));
    s->progress = (PetscBool) (size == 1 && isatty(1) && !getenv("CI") && !getenv("OMPI_COMM_WORLD_SIZE") && !getenv("PMI_SIZE") && !getenv("PMIX_RANK") && !getenv("SLURM_STEP_ID"));
  }
  PetscCall(ClothCreate(comm, &s->cloth));
  PetscCall(SelfContactCreate(comm, s->cloth, &s->self));
  PetscCall(SolidCreate(comm, &s->solid));
  PetscCall(OutputCreate(comm, &s->output));
  PetscCall(ReportCreate(comm, &s->report));
  PetscCall(RestartCreate(comm, &s->restart));
  PetscCall(RestTestCreate(comm, &s->rest));
  PetscCall(CusickCreate(comm, &s->cusick));
  *sim = s;
  PetscFunctionReturn(0);
}

/* Options given for a part the run does not have are refused, as DrapeCheckUnusedOptions
 * refuses those no component reads: the components read theirs whether or not they
 * take part, so the run says here which parts it has. */
static PetscErrorCode RefuseOptions(MPI_Comm comm, const char *const names[], const char why[])
{
  PetscFunctionBeginUser;
  for (const char *const *name = names; *name; name++) {
    PetscBool set;
    PetscCall(PetscOptionsHasName(NULL, NULL, *name, &set)); /* raw: the question is whether it was typed, not its value (which its component read) */
    PetscCheck(!set, comm, PETSC_ERR_USER_INPUT, "%s does not apply to this run: %s", *name, why);
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode CheckOptionsApply(Simulation s)
{
  static const char *const contact[] = {"-contact_mode", "-contact_thickness", "-contact_friction", "-contact_stick_velocity", NULL};
  static const char *const self[]    = {"-contact_self_thickness", "-contact_self_friction",    "-contact_self_margin",    "-contact_self_broad_phase", "-contact_self_failsafe",
                                        "-contact_self_solve",     "-contact_self_solve_edges", "-contact_self_stiffness", "-contact_self_its",         NULL};
  PetscBool                empty, enabled;

  PetscFunctionBeginUser;
  PetscCall(SolidIsEmpty(s->solid, &empty));
  if (empty) PetscCall(RefuseOptions(s->comm, contact, "there is no solid to touch (-solid_type, -solid_file, -solid_floor or -solid_plane)"));
  PetscCall(SelfContactEnabled(s->self, &enabled));
  if (!enabled) PetscCall(RefuseOptions(s->comm, self, "self-contact is off (add -contact_self)"));
  PetscFunctionReturn(0);
}

PetscErrorCode SimulationSetFromOptions(Simulation s)
{
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsHasHelp(NULL, &s->help));
  PetscCall(RestartSetFromOptions(s->restart, s->output)); /* first: the options stored in its file are every component's */
  PetscOptionsBegin(s->comm, NULL, "drape run control", "Simulation");
  PetscCall(PetscOptionsInt("-drape_stability_its", "Most Lanczos steps for the Omega_max estimate printed at start-up (it stops once converged; 0: skip)", "StabilityEstimate", s->stability_its, &s->stability_its, NULL));
  PetscCall(PetscOptionsBool("-drape_stability_reference", "Omega_max by exactly -drape_stability_its Lanczos steps on the elements' full matrices (slow; tests)", "StabilityEstimate", s->limits.reference, &s->limits.reference, NULL));
  PetscCall(
    PetscOptionsReal("-drape_divergence_factor", "Stop when the mechanical energy exceeds its initial value by this many times the run's energy scale (M g L + initial energy)", "SimulationRun", s->divergence_factor, &s->divergence_factor, NULL));
  PetscCall(PetscOptionsReal("-drape_max_strain", "Stop when a lattice edge is stretched by more than this (relative; 1: twice its length)", "SimulationRun", s->max_strain, &s->max_strain, NULL));
  PetscCall(PetscOptionsBool("-drape_progress", "One updating progress line (default: on for a terminal, off in CI)", "SimulationRun", s->progress, &s->progress, NULL));
  PetscCall(PetscOptionsBool("-drape_summary", "One-line summary at the end of the run", "SimulationRun", s->summary, &s->summary, NULL));
  PetscCall(PetscOptionsBool("-drape_json", "Print the run's start-up numbers and summary as one JSON line at the end (the HDF5 file has them as attributes of /)", "SimulationRun", s->json, &s->json, NULL));
  PetscOptionsEnd();
  PetscCall(DrapeCheckInt(s->comm, "-drape_stability_its", s->stability_its, 0, 100000));
  PetscCall(DrapeCheckReal(s->comm, "-drape_divergence_factor", 1, &s->divergence_factor, 1e-12, 1e15, ""));
  PetscCall(DrapeCheckReal(s->comm, "-drape_max_strain", 1, &s->max_strain, 1e-6, 1e6, ""));
  PetscCall(RestTestSetFromOptions(s->rest));
  PetscCall(CusickSetFromOptions(s->cusick));
  PetscCall(DrapeCheckInputFile(s->comm, "-cloth_outline", "cloth outline")); /* before the cloth opens it */
  PetscCall(ClothSetFromOptions(s->cloth));
  PetscCall(SolidSetFromOptions(s->solid));
  PetscCall(ContactCreate(s->comm, s->solid, &s->contact));
  PetscCall(ContactSetFromOptions(s->contact));
  PetscCall(ContactSolveCreate(s->comm, s->contact, s->cloth, &s->solve));
  PetscCall(ContactSolveSetFromOptions(s->solve));
  PetscCall(SelfContactSetFromOptions(s->self));
  PetscCall(OutputSetFromOptions(s->output));
  PetscCall(CheckOptionsApply(s));
  PetscFunctionReturn(0);
}

/* Particle work for METIS: a particle above the solid's footprint will be a
 * contact candidate (queried every step), so it counts double. */
static PetscInt ContactWork(void *ctx, const PetscReal x[3])
{
  Solid     solid = (Solid) ctx;
  PetscReal lo[3] = {x[0], x[1], -PETSC_MAX_REAL}, hi[3] = {x[0], x[1], PETSC_MAX_REAL};
  return SolidBoxNear(solid, lo, hi, 0) ? 2 : 1;
}

/* Contact with the solid only with a solid, self-contact only with -contact_self
 * (its thickness checked against the lattice), and what sticky contact holds for
 * self-contact's filter. */
static PetscErrorCode SimulationSetUpContact(Simulation s)
{
  ClothInfo info;
  PetscBool empty, self;

  PetscFunctionBeginUser;
  PetscCall(ClothGetInfo(s->cloth, &info));
  PetscCall(SolidIsEmpty(s->solid, &empty));
  if (empty) { /* no solid, no contact code */
    PetscCall(ContactSolveDestroy(&s->solve));
    PetscCall(ContactDestroy(&s->contact));
  }
  PetscCall(SelfContactEnabled(s->self, &self));
  if (self) {
    /* a flat cloth's particle lies dx dy / sqrt(dx^2 + dy^2) from its cell's
     * diagonal, a triangle it is no corner of: a thickness beyond that has the
     * cloth at rest inside its own layer, and the filter blows it apart */
    SelfContactStats st;
    const PetscReal  dx = info.spacing[0], dy = info.spacing[1], most = dx * dy / PetscSqrtReal(dx * dx + dy * dy);
    char             got[32], max[32], sx[32], sy[32];
    PetscCall(SelfContactSetUp(s->self));
    PetscCall(SelfContactGetStats(s->self, &st));
    (void) snprintf(max, sizeof max, "%.4g", (double) most); /* C's %g: PETSc's turns 1 into "1." */
    (void) snprintf(sx, sizeof sx, "%.4g", (double) dx);
    (void) snprintf(sy, sizeof sy, "%.4g", (double) dy);
    PetscCheck(st.thickness < most, s->comm, PETSC_ERR_USER_INPUT,
               "-contact_self_thickness %s m is more than this lattice holds: it must be below %s m, the distance at rest from a particle to the diagonal of its cell (spacing %s x %s m), or the flat cloth starts inside its own contact layer and "
               "is blown apart; give less, or 0 (a quarter of the spacing)",
               DrapeFormatReal(st.thickness, got, sizeof got), max, sx, sy);
  } else
    PetscCall(SelfContactDestroy(&s->self)); /* no -contact_self, no self-contact code */
  if (s->self && s->contact) {               /* what sticky contact holds, for the filter */
    ContactMode mode;
    PetscCall(ContactGetMode(s->contact, &mode, NULL));
    if (mode == CONTACT_STICKY) PetscCall(PetscMalloc1(info.nowned + 1, &s->held));
  }
  PetscFunctionReturn(0);
}

/* The state U = [x; v], its splits, the initial state (the flat cloth for the Cusick
 * analysis) or the frame restarted from. */
static PetscErrorCode SimulationSetUpState(Simulation s)
{
  ClothInfo    info;
  PetscInt     rstart;
  PetscScalar *u;

  PetscFunctionBeginUser;
  PetscCall(ClothGetInfo(s->cloth, &info));
  s->n = 3 * info.nowned;
  PetscCall(VecCreateMPI(s->comm, 2 * s->n, PETSC_DETERMINE, &s->U));
  PetscCall(PetscObjectSetName((PetscObject) s->U, "state"));
  PetscCall(VecGetOwnershipRange(s->U, &rstart, NULL));
  PetscCall(ISCreateStride(s->comm, s->n, rstart, 1, &s->is_x));
  PetscCall(ISCreateStride(s->comm, s->n, rstart + s->n, 1, &s->is_v));
  PetscCall(VecGetArray(s->U, &u));
  PetscCall(ClothSetInitialState(s->cloth, u, u + s->n));
  PetscCall(CusickSetUp(s->cusick, s->cloth, s->solid, u));
  PetscCall(RestartLoad(s->restart, s->cloth, s->output, u, u + s->n));
  PetscCall(VecRestoreArray(s->U, &u));
  PetscCall(RestartGetStart(s->restart, &s->t0, &s->step0));
  s->tally.t0 = s->t0;
  PetscFunctionReturn(0);
}

/* -ts_type among drape's integrators, read before TSSetFromOptions sets it: PETSc
 * refuses an unknown type on each rank by itself, and accepts types drape cannot
 * drive. Its own heading in -help (the TS's would hide PETSc's list of -ts_ options). */
static PetscErrorCode CheckTSType(TS ts)
{
  char        want[64];
  const char *prefix;
  PetscBool   set, ok = PETSC_FALSE;
  MPI_Comm    comm = PetscObjectComm((PetscObject) ts);

  PetscFunctionBeginUser;
  PetscCall(TSGetOptionsPrefix(ts, &prefix));
  PetscOptionsBegin(comm, prefix, "drape's integrators", "TS");
  PetscCall(PetscOptionsString("-ts_type", "euler (paper scheme 2), basicsymplectic (scheme 3), drapebe (scheme 4), rk or ssp", "TSSetType", TSBASICSYMPLECTIC, want, sizeof want, &set));
  PetscOptionsEnd();
  for (const char *const *t = supported_types; set && *t; t++) {
    PetscBool match;
    PetscCall(PetscStrcmp(want, *t, &match));
    ok = (PetscBool) (ok || match);
  }
  PetscCheck(!set || ok || strcmp(want, TSBEULER), comm, PETSC_ERR_USER_INPUT,
             "-ts_type beuler is PETSc's backward Euler of a first-order system, which needs an implicit function drape does not provide; the paper's backward Euler (scheme 4) is -ts_type drapebe");
  PetscCheck(!set || ok, comm, PETSC_ERR_USER_INPUT, "-ts_type %s is not supported by drape; use euler (paper scheme 2), basicsymplectic (scheme 3), drapebe (scheme 4), rk or ssp", want);
  PetscFunctionReturn(0);
}

/* The TS: drape's defaults (symplectic Euler, 1e-4 s to 2 s, landing on the end),
 * then the options; the parts its type uses. */
static PetscErrorCode SimulationSetUpTS(Simulation s)
{
  PetscBool restart;

  PetscFunctionBeginUser;
  PetscCall(DrapeTSRegister());
  PetscCall(TSRegister(TSBASICSYMPLECTIC, TSCreate_Symplectic)); /* drape's, in PETSc's place */
  PetscCall(TSCreate(s->comm, &s->ts));
  PetscCall(TSSetApplicationContext(s->ts, s));
  PetscCall(TSSetProblemType(s->ts, TS_NONLINEAR));
  PetscCall(TSSetType(s->ts, TSBASICSYMPLECTIC));
  PetscCall(TSBasicSymplecticSetType(s->ts, TSBASICSYMPLECTICSIEULER));
  PetscCall(TSSetRHSFunction(s->ts, NULL, RHSFirstOrder, s));
  PetscCall(TSRHSSplitSetIS(s->ts, "position", s->is_x));
  PetscCall(TSRHSSplitSetIS(s->ts, "momentum", s->is_v));
  PetscCall(TSRHSSplitSetRHSFunction(s->ts, "position", NULL, RHSPosition, s));
  PetscCall(TSRHSSplitSetRHSFunction(s->ts, "momentum", NULL, RHSMomentum, s));
  PetscCall(TSSetMaxTime(s->ts, 2.0));
  PetscCall(TSSetMaxSteps(s->ts, PETSC_MAX_INT));
  PetscCall(TSSetTimeStep(s->ts, 1e-4));
  PetscCall(TSSetExactFinalTime(s->ts, TS_EXACTFINALTIME_MATCHSTEP));
  PetscCall(TSSetSolution(s->ts, s->U));
  PetscCall(TSSetPreStep(s->ts, PreStep));
  PetscCall(TSSetPostStep(s->ts, PostStep));
  PetscCall(TSDrapeBESetCloth(s->ts, s->cloth)); /* before the options: drapebe's defaults follow the cloth */
  PetscCall(CheckTSType(s->ts));
  PetscCall(TSSetFromOptions(s->ts));
  PetscCall(TSSetErrorIfStepFails(s->ts, PETSC_FALSE)); /* drape says why, after TSSolve */
  {
    /* the Hessian's work (the stability estimate, drapebe's matrix and constraints):
     * an explicit run without the estimate never makes it */
    PetscBool implicit;
    PetscCall(PetscObjectTypeCompare((PetscObject) s->ts, TSDRAPEBE, &implicit));
    if (implicit) PetscCall(ClothSetUpImplicit(s->cloth)); /* else at the first Hessian product, if any (small lattices' stability estimate) */
  }
  if (s->solve) PetscCall(TSDrapeBESetContact(s->ts, s->solve));
  if (s->self) {
    PetscBool in_solve, implicit;
    PetscCall(PetscObjectTypeCompare((PetscObject) s->ts, TSDRAPEBE, &implicit));
    PetscCall(SelfContactSetImplicit(s->self, implicit));
    PetscCall(SelfContactSolveEnabled(s->self, &in_solve));
    if (in_solve) PetscCall(TSDrapeBESetSelfContact(s->ts, s->self));
  }
  PetscCall(RestartEnabled(s->restart, &restart));
  if (restart) {
    PetscCall(TSSetTime(s->ts, s->t0));
    PetscCall(TSSetStepNumber(s->ts, s->step0));
  }
  PetscFunctionReturn(0);
}

/* The time options finite, in range, consistent: a run that starts must be able to end. */
static PetscErrorCode SimulationCheckTimes(Simulation s)
{
  PetscReal dt, t0, tmax, atol, rtol;
  PetscInt  max_steps;
  PetscBool restart;
  char      got[32], at[32]; /* values as given (DrapeFormatReal) */

  PetscFunctionBeginUser;
  PetscCall(TSGetTimeStep(s->ts, &dt));
  PetscCall(TSGetTime(s->ts, &t0));
  PetscCall(TSGetMaxTime(s->ts, &tmax));
  PetscCall(TSGetMaxSteps(s->ts, &max_steps));
  PetscCall(DrapeCheckReal(s->comm, "-ts_dt", 1, &dt, 1e-15, 1e3, "s"));
  PetscCall(DrapeCheckReal(s->comm, "-ts_max_time", 1, &tmax, 1e-15, 1e30, "s (1e30: no limit but -ts_max_steps)"));
  PetscCall(DrapeCheckInt(s->comm, "-ts_max_steps", max_steps, 0, PETSC_MAX_INT));
  /* the adaptive schemes' error norm divides by atol + rtol |x|: a tolerance far
   * below double precision's 2.2e-16 overflowed it (PETSc's traceback), and no
   * step can meet it */
  PetscCall(TSGetTolerances(s->ts, &atol, NULL, &rtol, NULL));
  PetscCall(DrapeCheckReal(s->comm, "-ts_atol", 1, &atol, 0, 1e3, "(m, m/s)"));
  PetscCall(DrapeCheckReal(s->comm, "-ts_rtol", 1, &rtol, 0, 1, ""));
  PetscCheck(atol == 0 || atol >= 1e-14, s->comm, PETSC_ERR_USER_INPUT, "-ts_atol %s is below what a step in double precision can meet: give 0 or at least 1e-14 (m, m/s)", DrapeFormatReal(atol, got, sizeof got));
  PetscCheck(rtol == 0 || rtol >= 1e-14, s->comm, PETSC_ERR_USER_INPUT, "-ts_rtol %s is below what a step in double precision can meet (its relative rounding error is 2.2e-16): give 0 or at least 1e-14", DrapeFormatReal(rtol, got, sizeof got));
  PetscCheck(atol > 0 || rtol > 0, s->comm, PETSC_ERR_USER_INPUT, "-ts_atol and -ts_rtol are both 0: the adaptive step's error norm divides by atol + rtol |x|; give one of them at least 1e-14");
  PetscCall(RestartEnabled(s->restart, &restart));
  PetscCheck(tmax > t0, s->comm, PETSC_ERR_USER_INPUT, "-ts_max_time %s s is not after the %s time %s s: nothing to do", DrapeFormatReal(tmax, got, sizeof got), restart ? "restart" : "start", DrapeFormatReal(t0, at, sizeof at));
  {
    const PetscReal tend = PetscMin(tmax, t0 + (PetscReal) max_steps * dt); /* where the run can get to */
    PetscCheck(t0 + dt > t0 && tend + dt > tend, s->comm, PETSC_ERR_USER_INPUT, "-ts_dt %s s is too small to advance the time near t = %s s, where this run ends: time would stand still", DrapeFormatReal(dt, got, sizeof got),
               DrapeFormatReal(tend, at, sizeof at));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SimulationSetUp(Simulation s)
{
  PetscScalar *u;

  PetscFunctionBeginUser;
  PetscCall(SolidSetUp(s->solid));
  PetscCall(ClothSetPartitionWeight(s->cloth, ContactWork, s->solid));
  PetscCall(ClothSetUp(s->cloth));
  PetscCall(SimulationSetUpContact(s));
  PetscCall(SimulationSetUpState(s));
  PetscCall(SimulationSetUpTS(s));
  PetscCall(SimulationCheckTimes(s));
  if (s->contact) {
    PetscCall(VecGetArray(s->U, &u));
    PetscCall(ContactCheckInitial(s->contact, s->n / 3, u));
    PetscCall(VecRestoreArray(s->U, &u));
  }
  /* Omega_max of the initial state: printed with the step limits it implies, and the
   * backward-Euler solver's choice of preconditioner */
  if (s->stability_its > 0) {
    const PetscScalar *x;
    PetscCall(VecGetArrayRead(s->U, &x));
    PetscCall(StabilityEstimate(s->cloth, x, s->stability_its, &s->limits));
    PetscCall(VecRestoreArrayRead(s->U, &x));
    PetscCall(TSDrapeBESetStiffness(s->ts, s->limits.omega));
  } else
    s->limits.symplectic = s->limits.euler = PETSC_INFINITY;
  /* create the solvers now, so their options are read before drape checks for unused ones */
  PetscCall(TSSetUp(s->ts));
  PetscFunctionReturn(0);
}

PetscErrorCode SimulationInterrupted(Simulation s, PetscBool *interrupted, PetscBool *restartable)
{
  PetscFunctionBeginUser;
  *interrupted = (PetscBool) (s->interrupted != 0);
  PetscCall(RestartSupported(s->cloth, restartable));
  PetscFunctionReturn(0);
}

PetscErrorCode SimulationDestroy(Simulation *sim)
{
  Simulation s = *sim;

  PetscFunctionBeginUser;
  if (!s) PetscFunctionReturn(0);
  PetscCall(TSDestroy(&s->ts));
  PetscCall(VecDestroy(&s->U));
  PetscCall(ISDestroy(&s->is_x));
  PetscCall(ISDestroy(&s->is_v));
  PetscCall(OutputDestroy(&s->output));
  PetscCall(ReportDestroy(&s->report));
  PetscCall(RestartDestroy(&s->restart));
  PetscCall(RestTestDestroy(&s->rest));
  PetscCall(CusickDestroy(&s->cusick));
  PetscCall(ContactSolveDestroy(&s->solve));
  PetscCall(ContactDestroy(&s->contact));
  PetscCall(SelfContactDestroy(&s->self));
  PetscCall(PetscFree(s->held));
  PetscCall(PetscFree(s->unfiltered));
  PetscCall(SolidDestroy(&s->solid));
  PetscCall(ClothDestroy(&s->cloth));
  PetscCall(PetscFree(*sim));
  PetscFunctionReturn(0);
}

/* Write a frame of the current state (energies computed only here) with what
 * contact did since the last one: the deepest penetration, the contacts, and the
 * mean force of the solid on the cloth (N, the impulses over the time they took). */
static PetscErrorCode SimulationWriteFrame(Simulation s, PetscInt step, PetscReal t, const PetscScalar *u)
{
  ClothEnergies en;
  PetscReal     sum[3];

  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(drape_log.output, 0, 0, 0, 0));
  PetscCall(ClothComputeEnergies(s->cloth, u, u + s->n, &en));
  en.contact_depth = s->tally.depth;
  en.contact_count = s->tally.count;
  PetscCall(MPIU_Allreduce(s->tally.impulse, sum, 3, MPIU_REAL, MPI_SUM, s->comm));
  for (PetscInt d = 0; d < 3; d++) {
    en.contact_force[d] = t > s->tally.t0 ? sum[d] / (t - s->tally.t0) : 0;
    s->tally.impulse[d] = 0;
  }
  s->tally.t0 = t;
  PetscCall(OutputWriteFrame(s->output, s->cloth, step, t, u, u + s->n, &en));
  s->tally.depth = 0;
  PetscCall(PetscLogEventEnd(drape_log.output, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

/* Divergence: NaN; or the mechanical energy (kinetic + gravitational + stretch +
 * shear + bending) above its initial value by more than factor x scale: damping,
 * friction, pins and fixed solids only remove energy, so a sound step cannot add
 * it; or an edge stretched beyond -drape_max_strain. With full = PETSC_FALSE only
 * the cheap part: finite, and kinetic + gravitational energy (internal energy is
 * never negative) within the same bound. The largest strain of the full check is
 * kept for the summary. */
static PetscErrorCode CheckDivergence(Simulation s, TS ts, PetscInt step, PetscReal t, const PetscScalar *u, PetscBool full)
{
  const PetscReal *mass;
  ClothInfo        info;
  PetscReal        loc[2] = {0, 0}, sum[2], e, strain = 0;
  PetscBool        finite;
  TSType           type;
  PetscReal        dt;
  char             euler[64], what[256];
  PetscBool        implicit = PETSC_FALSE;

  PetscFunctionBeginUser;
  PetscCall(ClothGetMasses(s->cloth, &mass, NULL));
  PetscCall(ClothGetInfo(s->cloth, &info));
  {
    const PetscScalar *restrict x = u, *restrict v = u + s->n;
    const PetscReal g[3] = {info.gravity[0], info.gravity[1], info.gravity[2]};
    for (PetscInt k = 0; k < s->n / 3; k++) {
      const PetscReal m = mass[k];
      for (PetscInt d = 0; d < 3; d++) {
        loc[0] += 0.5 * m * v[3 * k + d] * v[3 * k + d];
        loc[1] -= m * g[d] * x[3 * k + d];
      }
    }
  }
  PetscCall(MPIU_Allreduce(loc, sum, 2, MPIU_REAL, MPI_SUM, s->comm));
  /* a non-finite position or velocity makes its sum non-finite (0 x Inf is NaN too) */
  finite = (PetscBool) !(PetscIsInfOrNanReal(sum[0]) || PetscIsInfOrNanReal(sum[1]));
  e      = sum[0] + sum[1];
  if (full || !s->baseline) {
    ClothEnergies en;
    PetscCall(ClothComputeEnergies(s->cloth, u, u + s->n, &en));
    e += en.stretch + en.shear + en.bend;
    strain         = en.strain_max;
    s->strain_last = strain;
    finite         = (PetscBool) (finite && !PetscIsInfOrNanReal(e));
  }
  if (!s->baseline) {
    const PetscReal g = PetscSqrtReal(PetscSqr(info.gravity[0]) + PetscSqr(info.gravity[1]) + PetscSqr(info.gravity[2]));
    s->baseline       = PETSC_TRUE;
    s->energy0        = e;
    s->energy_scale   = info.mass * g * PetscMax(info.size[0], info.size[1]) + PetscAbsReal(e - sum[1]) + PETSC_SMALL;
    PetscFunctionReturn(0);
  }
  if (finite && e - s->energy0 <= s->divergence_factor * s->energy_scale && !(strain > s->max_strain)) PetscFunctionReturn(0); /* NaN strain: no stretch edges */
  PetscCall(TSGetType(ts, &type));
  PetscCall(TSGetTimeStep(ts, &dt));
  if (s->limits.euler > 0)
    PetscCall(PetscSNPrintf(euler, sizeof euler, "h < %.4e s", (double) s->limits.euler));
  else
    PetscCall(PetscStrcpy(euler, "unstable at every step without damping"));
  if (!finite)
    PetscCall(PetscStrcpy(what, "positions or velocities are not finite"));
  else if (e - s->energy0 > s->divergence_factor * s->energy_scale)
    PetscCall(PetscSNPrintf(what, sizeof what, "the mechanical energy (kinetic, gravitational and elastic) grew by %.3g J, beyond what the start can supply (%.3g J)", (double) (e - s->energy0), (double) (s->divergence_factor * s->energy_scale)));
  else
    PetscCall(PetscSNPrintf(what, sizeof what, "a lattice edge is stretched by %.3g %%, beyond -drape_max_strain %g %% (no fabric in the model's linear range stretches so far; raise the bound if this one really does)", (double) (100 * strain),
                            (double) (100 * s->max_strain)));
  PetscCall(PetscObjectTypeCompare((PetscObject) ts, TSDRAPEBE, &implicit));
  SETERRQ(s->comm, PETSC_ERR_NOT_CONVERGED, "The run diverged at step %" PetscInt_FMT " (t = %g s): %s. Estimated stability limits: symplectic Euler h < %.4e s, explicit Euler %s; this run used -ts_type %s -ts_dt %g. %s", step, (double) t, what,
          (double) s->limits.symplectic, euler, type, (double) dt,
          implicit ? "Reduce -ts_dt: the single linearisation of -snes_type ksponly fails at steps this large for this fabric (or use -snes_type newtonls)" : "Reduce -ts_dt or use -ts_type drapebe");
}

/* Divergence checks: the cheap one every DIVERGENCE_EVERY steps, the full one (an
 * energy evaluation, two thirds of a force evaluation) every DIVERGENCE_FULL steps,
 * before every frame and after the last step (drapebe also checks the mechanical
 * energy of every step itself, and retries a step that added some). */
#define DIVERGENCE_EVERY 8
#define DIVERGENCE_FULL  32

/* The updating progress line: every half second of wall time, and (last) at the end. */
static PetscErrorCode ProgressLine(Simulation s, TS ts, PetscInt step, PetscReal t, PetscBool last)
{
  PetscLogDouble now;
  PetscReal      tmax, t0 = s->t0;
  PetscInt       steps = step - s->step0;

  PetscFunctionBeginUser;
  PetscCall(PetscTime(&now));
  if (!last && (now - s->wall_last <= 0.5 || steps <= 0)) PetscFunctionReturn(0);
  PetscCall(TSGetMaxTime(ts, &tmax));
  s->wall_last = now;
  PetscCall(
    PetscPrintf(s->comm, "\r  t = %.4g / %.4g s, step %" PetscInt_FMT ", %.0f steps/s, %.0f s left   ", (double) t, (double) tmax, step, steps / PetscMax(now - s->wall0, 1e-9), (double) (t > t0 ? (now - s->wall0) * (tmax - t) / (t - t0) : 0)));
  PetscFunctionReturn(0);
}

static PetscErrorCode Monitor(TS ts, PetscInt step, PetscReal t, Vec U, void *ctx)
{
  Simulation         s = (Simulation) ctx;
  const PetscScalar *u;
  PetscBool          due;

  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(U, &u));
  PetscCall(OutputFrameDue(s->output, step, t, &due));
  /* a diverging run is stopped within a few steps and no frame it writes is unchecked */
  if (due || step % DIVERGENCE_EVERY == 0 || !s->baseline) {
    PetscCall(CheckDivergence(s, ts, step, t, u, (PetscBool) (due || step % DIVERGENCE_FULL == 0)));
  }
  if (due) PetscCall(SimulationWriteFrame(s, step, t, u));
  PetscCall(VecRestoreArrayRead(U, &u));
  if (s->progress) PetscCall(ProgressLine(s, ts, step, t, PETSC_FALSE));
  PetscFunctionReturn(0);
}

/* A step above an explicit scheme's limit is allowed (studies need it) but said
 * plainly: explicit Euler's growth can be too slow for the energy check to see
 * within the run, so the start-up line gives the growth per step. */
static PetscErrorCode WarnStepLimit(Simulation s, PetscViewer viewer, TSType type, PetscReal dt, PetscReal tmax)
{
  const PetscReal Om = s->limits.omega;
  PetscReal       t0, steps, c;
  ClothInfo       info;
  PetscBool       euler, symplectic;

  PetscFunctionBeginUser;
  PetscCall(ClothGetInfo(s->cloth, &info));
  c = info.damping;
  PetscCall(PetscStrcmp(type, TSEULER, &euler));
  PetscCall(PetscStrcmp(type, TSBASICSYMPLECTIC, &symplectic));
  PetscCall(TSGetTime(s->ts, &t0));
  {
    PetscInt maxsteps, step;
    PetscCall(TSGetMaxSteps(s->ts, &maxsteps));
    PetscCall(TSGetStepNumber(s->ts, &step));
    steps = PetscMin(PetscCeilReal((tmax - t0) / dt), (PetscReal) (maxsteps - step));
  }
  if (euler && dt > s->limits.euler && 2 * Om > c) {
    /* fastest mode, underdamped: |1 + h mu|^2 = 1 - h c + h^2 Omega^2 per step */
    const PetscReal g = PetscSqrtReal(1 - dt * c + dt * dt * Om * Om);
    PetscCall(ReportViewReal(s->report, viewer, "euler_growth_per_step", "  WARNING: h is above the explicit Euler limit: the fastest mode grows by %.6g per step", g));
    PetscCall(PetscViewerASCIIPrintf(viewer, " (a factor e every %.3g steps; up to %.3g steps in this run). drape stops the run when the growth shows in the energy, which can be late or never for slow growth\n", (double) (1 / PetscLogReal(g)),
                                     (double) steps));
  } else if (symplectic && dt > s->limits.symplectic) {
    PetscCall(PetscViewerASCIIPrintf(viewer, "  WARNING: h is above the symplectic Euler limit: the run will diverge (drape stops it with a message)\n"));
  } else if (symplectic && dt > 0.8 * s->limits.symplectic) {
    PetscCall(
      PetscViewerASCIIPrintf(viewer, "  note: h is within 20%% of the symplectic limit estimated for the initial state; tension as the cloth deforms raises Omega_max, so a run this close can still diverge (0.5 x the limit is a safe choice)\n"));
  }
  PetscFunctionReturn(0);
}

/* drapebe's solver as it is now (SNES, KSP, PC and matrix types, whose product the
 * matrix takes) into the report, and on viewer (NULL: the report only) the line
 * that says it. */
static PetscErrorCode SimulationViewSolver(Simulation s, Report r, PetscViewer viewer)
{
  SNES      snes;
  KSP       ksp;
  PC        pc;
  Mat       J;
  SNESType  st;
  KSPType   kt;
  PCType    pt;
  MatType   mt     = MATAIJ;
  PetscBool drapes = PETSC_FALSE;

  PetscFunctionBeginUser;
  PetscCall(TSGetSNES(s->ts, &snes));
  PetscCall(SNESGetType(snes, &st));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetType(ksp, &kt));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PCGetType(pc, &pt));
  PetscCall(SNESGetJacobian(snes, &J, NULL, NULL, NULL));
  if (J) PetscCall(MatGetType(J, &mt));
  if (J) PetscCall(DrapeMatHasSBAIJProduct(J, &drapes));
  PetscCall(ReportViewString(r, viewer, "snes_type", "  solver: SNES %s", st));
  PetscCall(ReportViewString(r, viewer, "ksp_type", ", KSP %s", kt));
  PetscCall(ReportViewString(r, viewer, "pc_type", ", PC %s", pt));
  PetscCall(ReportViewString(r, viewer, "mat_type", " on an assembled %s matrix (block size 3", mt));
  PetscCall(ReportViewString(r, viewer, "mat_product", ", %s's product)\n", drapes ? "drape" : "PETSc"));
  PetscFunctionReturn(0);
}

/* The cloth's numbers by name (what ClothView prints for people). */
/* A per-rank figure into the report: its sum over ranks and its largest. Collective. */
static PetscErrorCode ReportSumAndMax(Report r, MPI_Comm comm, PetscLogDouble mine, const char sum_name[], const char max_name[])
{
  PetscLogDouble sum, max;

  PetscFunctionBeginUser;
  PetscCall(MPIU_Allreduce(&mine, &sum, 1, MPIU_PETSCLOGDOUBLE, MPI_SUM, comm));
  PetscCall(MPIU_Allreduce(&mine, &max, 1, MPIU_PETSCLOGDOUBLE, MPI_MAX, comm));
  PetscCall(ReportSetReal(r, sum_name, (PetscReal) sum));
  PetscCall(ReportSetReal(r, max_name, (PetscReal) max));
  PetscFunctionReturn(0);
}

static PetscErrorCode SimulationReportCloth(Simulation s)
{
  Report    r = s->report;
  ClothInfo info;

  PetscFunctionBeginUser;
  PetscCall(ClothGetInfo(s->cloth, &info));
  PetscCall(ReportSetInt(r, "lattice_mx", info.Mx));
  PetscCall(ReportSetInt(r, "lattice_my", info.My));
  PetscCall(ReportSetInt(r, "particles", info.nparticles));
  {
    /* what the set-up made, per particle: the resident memory it added on all ranks
     * (lattice, element lists, state, solver work; before the output's buffers) */
    PetscLogDouble rss, mine, sum;
    PetscCall(PetscMemoryGetCurrentUsage(&rss));
    mine = rss - s->rss0;
    PetscCall(MPIU_Allreduce(&mine, &sum, 1, MPIU_PETSCLOGDOUBLE, MPI_SUM, s->comm));
    PetscCall(ReportSetReal(r, "setup_bytes_per_particle", (PetscReal) (sum / info.nparticles)));
  }
  {
    /* the set-up's CPU time, summed over ranks and the busiest rank's: with ranks
     * sharing cores (oversubscribed) its wall time says nothing of a rank's work */
    PetscLogDouble cpu;
    PetscCall(ReportCPUTime(&cpu));
    PetscCall(ReportSumAndMax(r, s->comm, cpu - s->cpu0, "setup_cpu", "setup_cpu_rank_max"));
  }
  PetscCall(ReportSetInt(r, "active_particles", info.nactive));
  PetscCall(ReportSetInt(r, "pinned", info.npinned));
  PetscCall(ReportSetInt(r, "stretch_edges", info.nstretch));
  PetscCall(ReportSetInt(r, "shear_cells", info.nshear));
  PetscCall(ReportSetInt(r, "bending_triples", info.nbend));
  PetscCall(ReportSetString(r, "partition", info.partition));
  PetscCall(ReportSetInt(r, "owned_min", info.owned_min));
  PetscCall(ReportSetInt(r, "owned_max", info.owned_max));
  PetscCall(ReportSetInt(r, "held_min", info.held_min));
  PetscCall(ReportSetInt(r, "held_max", info.held_max));
  PetscCall(ReportSetInt(r, "stretch_edges_cut", info.ncut));
  PetscCall(ReportSetReal(r, "size_warp", info.size[0]));
  PetscCall(ReportSetReal(r, "size_weft", info.size[1]));
  PetscCall(ReportSetReal(r, "mass", info.mass));
  PetscCall(ReportSetReal(r, "density", info.density));
  PetscCall(ReportSetReal(r, "damping", info.damping));
  PetscCall(ReportSetReal(r, "stretch_warp", info.stretch[0]));
  PetscCall(ReportSetReal(r, "stretch_weft", info.stretch[1]));
  PetscCall(ReportSetReal(r, "shear", info.shear));
  PetscCall(ReportSetReal(r, "bend_warp", info.bend[0]));
  PetscCall(ReportSetReal(r, "bend_weft", info.bend[1]));
  PetscCall(ReportSetReal(r, "bend_bias", info.bend[2]));
  PetscCall(ReportSetString(r, "model", info.model));
  PetscCall(ReportSetBool(r, "bend_table", info.bend_table));
  PetscCall(ReportSetReal(r, "bend_hysteresis_warp", info.hysteresis[0]));
  PetscCall(ReportSetReal(r, "bend_hysteresis_weft", info.hysteresis[1]));
  PetscCall(ReportSetReal(r, "hysteresis_stiffness", info.hyst_stiffness));
  PetscCall(ReportSetReal(r, "imperfection", info.imperfection[0]));
  PetscCall(ReportSetReal(r, "imperfection_wavelength", info.imperfection[1]));
  PetscCall(ReportSetInt(r, "imperfection_seed", info.imperfection_seed));
  PetscFunctionReturn(0);
}

/* The start-up numbers, for people on viewer and by name in the report, each from
 * one call: the scene, the stability estimate, the integrator and drapebe's solver. */
static PetscErrorCode SimulationViewStart(Simulation s, PetscViewer viewer)
{
  Report      r    = s->report;
  const char *name = NULL;
  TSType      type;
  PetscReal   dt, tmax;
  ClothInfo   info;
  PetscMPIInt size;

  PetscFunctionBeginUser;
  PetscCall(ClothGetInfo(s->cloth, &info));
  PetscCall(TSGetType(s->ts, &type));
  PetscCall(TSGetTimeStep(s->ts, &dt));
  PetscCall(TSGetMaxTime(s->ts, &tmax));
  PetscCallMPI(MPI_Comm_size(s->comm, &size));
  PetscCall(ReportViewString(r, viewer, "drape_version", "drape %s: fabric by the particle method\n", DRAPE_VERSION));
  PetscCall(ReportSetInt(r, "ranks", size));
  PetscCall(SimulationReportCloth(s));
  PetscCall(ClothView(s->cloth, viewer));
  PetscCall(SolidView(s->solid, viewer));
  if (s->contact) PetscCall(ContactView(s->contact, viewer));
  if (s->self) PetscCall(SelfContactView(s->self, viewer));
  if (s->stability_its > 0) PetscCall(StabilityView(&s->limits, info.damping, r, viewer));
  if (!strcmp(type, TSBASICSYMPLECTIC)) PetscCall(TSBasicSymplecticGetType(s->ts, (TSBasicSymplecticType *) &name));
  PetscCall(ReportViewString(r, viewer, "ts_type", "Integrator: -ts_type %s", type));
  if (name) PetscCall(PetscViewerASCIIPrintf(viewer, " -ts_basicsymplectic_type %s", name));
  PetscCall(ReportViewReal(r, viewer, "dt", ", h = %g s", dt));
  if (s->stability_its > 0) {
    PetscBool explicit_euler;
    PetscCall(PetscStrcmp(type, TSEULER, &explicit_euler));
    if (explicit_euler && s->limits.euler > 0 && s->limits.euler < PETSC_INFINITY)
      PetscCall(PetscViewerASCIIPrintf(viewer, " (%.3g x the explicit Euler limit)", (double) (dt / s->limits.euler)));
    else if (!explicit_euler && s->limits.symplectic < PETSC_INFINITY)
      PetscCall(PetscViewerASCIIPrintf(viewer, " (%.3g x the symplectic limit)", (double) (dt / s->limits.symplectic)));
  }
  PetscCall(ReportViewReal(r, viewer, "t_max", ", to t = %g s\n", tmax));
  if (s->stability_its > 0) PetscCall(WarnStepLimit(s, viewer, type, dt, tmax));
  if (!strcmp(type, TSDRAPEBE)) PetscCall(SimulationViewSolver(s, r, viewer));
  PetscFunctionReturn(0);
}

/* The end of the run, for people on viewer (NULL: no summary line) and by name in
 * the report, each number from one call. */
static PetscErrorCode SimulationViewSummary(Simulation s, PetscViewer viewer, PetscLogDouble wall_loop, PetscLogDouble cpu_loop)
{
  const PetscReal mywall = (PetscReal) wall_loop, mycpu = (PetscReal) cpu_loop;
  Report          r = s->report;
  PetscInt        steps, run, its, solves, rejected;
  PetscReal       t, wall, cpu, cpu_max, psteps;
  ClothInfo       info;

  PetscFunctionBeginUser;
  PetscCall(ClothGetInfo(s->cloth, &info));
  PetscCall(TSGetStepNumber(s->ts, &steps));
  PetscCall(TSGetTime(s->ts, &t));
  PetscCall(TSGetKSPIterations(s->ts, &its));
  PetscCall(TSDrapeBEGetStatistics(s->ts, &solves, &rejected, NULL));
  run = steps - s->step0;                                                     /* steps taken by this run */
  PetscCall(MPIU_Allreduce(&mywall, &wall, 1, MPIU_REAL, MPIU_MAX, s->comm)); /* the job's, the same on every rank */
  /* CPU time of the time loop: the sum over ranks (the CPU seconds the job used; MPI's
   * waits count, as Open MPI spins in them) and the busiest rank's */
  PetscCall(MPIU_Allreduce(&mycpu, &cpu, 1, MPIU_REAL, MPIU_SUM, s->comm));
  PetscCall(MPIU_Allreduce(&mycpu, &cpu_max, 1, MPIU_REAL, MPIU_MAX, s->comm));
  psteps = (PetscReal) run * info.nparticles;
  PetscCall(ReportViewInt(r, viewer, "steps", "Summary: %" PetscInt_FMT " steps", run));
  PetscCall(ReportSetInt(r, "step", steps));
  PetscCall(ReportViewReal(r, viewer, "t", " to t = %g s", t));
  PetscCall(ReportViewReal(r, viewer, "wall", " in %.3f s wall", wall));
  PetscCall(ReportViewReal(r, viewer, "particle_steps_per_s", ", %.4e particle-steps/s", wall > 0 ? psteps / wall : 0));
  PetscCall(ReportViewReal(r, viewer, "cpu", "; %.3f s CPU (all ranks)", cpu));
  PetscCall(ReportSetReal(r, "cpu_rank_max", cpu_max));
  {
    /* peak resident memory (VmHWM), summed over ranks and the largest rank's: the
     * scripts' and tests' memory figures, free of how the process was launched */
    PetscLogDouble peak;
    PetscCall(ReportPeakMemory(&peak));
    PetscCall(ReportSumAndMax(r, s->comm, peak, "memory_peak", "memory_peak_rank_max"));
  }
  PetscCall(ReportViewReal(r, viewer, "particle_steps_per_cpu_s", ", %.4e particle-steps per CPU second", cpu > 0 ? psteps / cpu : 0));
  PetscCall(ReportViewReal(r, its > 0 ? viewer : NULL, "cg_per_step", ", %.2f CG iterations per step", (PetscReal) its / PetscMax(run, 1)));
  PetscCall(ReportViewReal(r, solves > run ? viewer : NULL, "solves_per_step", ", %.2f solves per step", (PetscReal) solves / PetscMax(run, 1)));
  PetscCall(ReportViewInt(r, rejected ? viewer : NULL, "steps_retried", ", %" PetscInt_FMT " steps retried at a smaller step", rejected));
  {
    TSAdapt   adapt;
    PetscReal dt, largest;
    PetscCall(TSGetAdapt(s->ts, &adapt));
    PetscCall(TSAdaptDrapeGetSteps(adapt, &dt, &largest)); /* 0, 0 unless drape's adapt type */
    if (largest > 0) PetscCall(ReportViewReal(r, largest > dt * (1 + 1e-12) ? viewer : NULL, "dt_largest", ", steps up to %g s as the cloth settled", largest));
  }
  {
    PetscInt  switched, error_rejected, filter_cut, rise_cut;
    PetscBool implicit;
    PetscCall(PetscObjectTypeCompare((PetscObject) s->ts, TSDRAPEBE, &implicit));
    PetscCall(TSDrapeBEGetStepHistory(s->ts, &switched, &error_rejected, &filter_cut, &rise_cut));
    if (implicit) PetscCall(ReportSetInt(r, "pc_switched_step", switched)); /* -1: block Jacobi/ICC(0) throughout, or the options' choice */
    if (implicit) {
      PetscInt fill;
      PetscCall(TSDrapeBEGetFillStep(s->ts, &fill));
      PetscCall(ReportViewInt(r, fill >= 0 ? viewer : NULL, "pc_fill_step", ", block IC(1) from step %" PetscInt_FMT, fill)); /* -1: IC(0) throughout */
    }
    if (implicit && switched >= 0) PetscCall(SimulationViewSolver(s, r, NULL)); /* the report's solver is the one the run ended with (the start-up line said the first) */
    if (implicit) {
      PetscInt kept, refused;
      PetscCall(TSDrapeBEGetMatrixKept(s->ts, &kept, &refused));
      PetscCall(ReportViewInt(r, kept ? viewer : NULL, "steps_matrix_kept", ", %" PetscInt_FMT " steps with an earlier step's matrix", kept));
      PetscCall(ReportSetInt(r, "matrix_keep_refused", refused));
    }
    PetscCall(ReportViewInt(r, error_rejected ? viewer : NULL, "steps_rejected_error", ", %" PetscInt_FMT " steps rejected for their local error", error_rejected));
    PetscCall(ReportViewInt(r, filter_cut ? viewer : NULL, "steps_cut_filter", ", %" PetscInt_FMT " steps cut after the self-contact filter added energy", filter_cut));
    PetscCall(ReportViewInt(r, rise_cut ? viewer : NULL, "steps_cut_energy", ", %" PetscInt_FMT " steps cut after a step that added energy", rise_cut));
  }
  if (PetscIsNanReal(s->strain_last)) {
    PetscCall(ReportSetReal(r, "strain_max", s->strain_last));
    if (viewer) PetscCall(PetscViewerASCIIPrintf(viewer, "; no stretch edges\n"));
  } else
    PetscCall(ReportViewPercent(r, viewer, "strain_max", "; largest edge strain %.3g %%\n", s->strain_last));
  if (info.hysteresis[0] > 0 || info.hysteresis[1] > 0) {
    PetscInt np;
    PetscCall(ClothGetPlasticCount(s->cloth, &np));
    PetscCall(ReportSetInt(r, "hysteresis_plastic_triples", np)); /* triples whose yarns slid and stayed */
  }
  PetscCall(ReportSetString(r, "stopped_by", SignalName((int) s->interrupted)));
  PetscCall(ReportSetBool(r, "self_contact", (PetscBool) !!s->self));
  if (s->self) {
    SelfContactStats st;
    PetscCall(SelfContactGetStats(s->self, &st));
    PetscCall(ReportSetReal(r, "self_contact_thickness", st.thickness));
    PetscCall(ReportSetInt(r, "self_contact_pairs", st.pairs));
    PetscCall(ReportSetInt(r, "self_collisions", st.collisions));
    PetscCall(ReportSetInt(r, "self_failsafe", st.failsafe));
    PetscCall(ReportSetInt(r, "self_broad_phases", st.broad_phases));
    PetscCall(ReportSetInt(r, "self_near_lists", st.near_lists));
    PetscCall(ReportSetInt(r, "self_live_lists", st.live_lists));
    PetscCall(ReportSetReal(r, "self_near_within", st.near_pairs > 0 ? st.near_within / st.near_pairs : 0));
    PetscCall(ReportSetInt(r, "self_halo_max", st.halo));
    PetscCall(ReportSetInt(r, "self_gathered", st.gathered));
    PetscCall(ReportSetInt(r, "self_failsafe_steps", st.failsafe_steps));
    PetscCall(ReportSetInt(r, "self_solve_pairs_max", st.solve_pairs_max));
  }
  PetscFunctionReturn(0);
}

/* TSSolve ended: a failed step is an error with the reason; the last state is
 * checked and written as a frame if it is not one yet. */
static PetscErrorCode SimulationEndLoop(Simulation s)
{
  TSConvergedReason  reason;
  const char        *failure;
  const PetscScalar *u;
  PetscReal          t;
  PetscInt           steps, last;
  PetscBool          enabled;

  PetscFunctionBeginUser;
  PetscCall(TSGetConvergedReason(s->ts, &reason));
  PetscCall(TSGetTime(s->ts, &t));
  PetscCall(TSDrapeBEGetStatistics(s->ts, NULL, NULL, &failure));
  if (reason == TS_DIVERGED_STEP_REJECTED && !(failure && failure[0])) { /* rejected for its local error estimate, not for a failed solve: a smaller -ts_dt does not help */
    TSAdapt   adapt;
    PetscBool by_error, be;
    PetscCall(TSGetAdapt(s->ts, &adapt));
    PetscCall(PetscObjectTypeCompareAny((PetscObject) adapt, &by_error, TSADAPTBASIC, TSADAPTDSP, TSADAPTGLEE, ""));
    PetscCall(PetscObjectTypeCompare((PetscObject) s->ts, TSDRAPEBE, &be));
    PetscCheck(!by_error, s->comm, PETSC_ERR_NOT_CONVERGED,
               "The run stopped at t = %g s: TSAdapt rejected the step for its local error estimate more than -ts_max_reject (%" PetscInt_FMT
               ") times in a row (DIVERGED_STEP_REJECTED). Loosen -ts_atol and -ts_rtol, or allow more rejections with -ts_max_reject%s",
               (double) t, s->ts->max_reject, be ? ", or let drape choose the step (-ts_adapt_type drape, drapebe's default)" : "");
  }
  PetscCheck(reason >= 0, s->comm, PETSC_ERR_NOT_CONVERGED, "The run stopped at t = %g s: %s%s (%s). Reduce -ts_dt, or allow more retries at smaller steps with -ts_max_reject and -ts_max_snes_failures", (double) t,
             failure && failure[0] ? failure : "a step failed", failure && failure[0] ? ", and so did its retries at smaller steps" : "", TSConvergedReasons[reason]);
  PetscCall(TSGetStepNumber(s->ts, &steps));
  PetscCall(OutputLastStep(s->output, &last));
  PetscCall(OutputEnabled(s->output, &enabled));
  PetscCall(VecGetArrayRead(s->U, &u));
  PetscCall(CheckDivergence(s, s->ts, steps, t, u, PETSC_TRUE));
  if (enabled && last != steps) PetscCall(SimulationWriteFrame(s, steps, t, u));
  PetscCall(VecRestoreArrayRead(s->U, &u));
  if (s->progress) {
    PetscCall(ProgressLine(s, s->ts, steps, t, PETSC_TRUE));
    PetscCall(PetscPrintf(s->comm, "\n"));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode SimulationRun(Simulation s)
{
  PetscViewer        viewer = PETSC_VIEWER_STDOUT_(s->comm);
  PetscLogDouble     wall1, cpu0, cpu1; /* wall clock at the loop's end; this rank's CPU time at its start and end */
  const PetscScalar *u;
  PetscBool          enabled, at_rest;

  PetscFunctionBeginUser;
  PetscCall(SimulationViewStart(s, viewer));
  PetscCall(DrapeCheckUnusedOptions(s->comm));
  if (s->help) PetscFunctionReturn(0);
  PetscCall(OutputEnabled(s->output, &enabled));
  if (enabled) {
    PetscCall(OutputOpen(s->output, s->cloth, s->solid));
    PetscCall(OutputWriteReport(s->output, s->report));
  }
  PetscCall(TSMonitorSet(s->ts, Monitor, s, NULL));
  SignalsCatch(PETSC_TRUE);
  PetscCall(PetscTime(&s->wall0));
  PetscCall(ReportCPUTime(&cpu0));
  s->wall_last = s->wall0;
  PetscCall(PetscLogStagePush(drape_log.timeloop));
  PetscCall(TSSolve(s->ts, s->U));
  PetscCall(PetscLogStagePop());
  PetscCall(PetscTime(&wall1));
  PetscCall(ReportCPUTime(&cpu1));
  PetscCall(SimulationEndLoop(s));
  SignalsCatch(PETSC_FALSE);
  PetscCall(RestTestView(s->rest, s->report, viewer));
  if (s->interrupted) {
    PetscInt  step;
    PetscReal t;
    PetscCall(TSGetStepNumber(s->ts, &step));
    PetscCall(TSGetTime(s->ts, &t));
    PetscCall(RestartViewStop(s->restart, s->cloth, s->output, viewer, SignalName((int) s->interrupted), step, t));
  }
  PetscCall(RestTestAtRest(s->rest, &at_rest));
  PetscCall(VecGetArrayRead(s->U, &u));
  PetscCall(CusickView(s->cusick, s->cloth, u, at_rest, s->report, viewer));
  PetscCall(VecRestoreArrayRead(s->U, &u));
  PetscCall(SimulationViewSummary(s, s->summary ? viewer : NULL, wall1 - s->wall0, cpu1 - cpu0));
  if (enabled) PetscCall(OutputWriteReport(s->output, s->report));
  if (s->json) PetscCall(ReportPrintJSON(s->report));
  PetscFunctionReturn(0);
}
