/* drape's backward Euler in the paper's form (scheme 4, Baraff & Witkin 1998): the
 * TS type "drapebe" (TSDRAPEBE). PETSc's own "beuler" integrates a first-order
 * system through an IFunction and keeps its meaning.
 *
 * The unknown of each step is the velocity change dv (3 per particle). The
 * backward-Euler equations
 *     R(dv) = M dv - h F(x + h (v + dv), v + dv) = 0
 * are handed to SNES; its Jacobian
 *     A = M - h dF/dv - h^2 dF/dx = (1 + h c) M + h^2 H
 * (H the SPD-projected Hessian of the internal energy, c the mass-proportional
 * damping) is assembled and KSP CG solves with it. -snes_type ksponly (the default)
 * takes the single Newton step from dv = 0: the paper's linearised step;
 * -snes_type newtonls iterates to the full backward-Euler solution (the default
 * with bending friction, -cloth_bend_hysteresis). Pinned particles
 * keep dv = 0 (their rows and columns are removed). Then v += dv and x += h v.
 *
 * Contact with the solid is a constraint of the step (ContactSolve,
 * include/contactsolve.h: the constrained particles' trial velocity, their rows of
 * the residual and the matrix, the active set after each solve, friction, the
 * landing); the step is solved again until no constraint comes or goes
 * (-drape_contact_its bounds the solves), and likewise for self-contact's pairs
 * (include/selfcontact.h). The impulses the constraints gave the cloth are what
 * TSDrapeBEGetContactImpulse() returns.
 *
 * A step whose solve fails (SNES or KSP diverged) is rejected and retried at a
 * quarter of the step through TSAdaptCheckStage (-ts_max_reject rejections per
 * step, -ts_max_snes_failures failures per run, unlimited by default); TSAdapt
 * chooses the next step (TSAdaptChoose): drape's type (TSADAPTDRAPE, the
 * default, src/integrate/adapt.c) doubles it again after four accepted steps, up to
 * the -ts_dt asked for, but back to a size that failed only after 8, 16, ... 1024
 * steps; -ts_adapt_type basic chooses it from the local error. A step that adds
 * mechanical energy fails the same way (BECheckEnergy), and a step after one whose
 * self-contact filter added energy is cut before it is tried (BECheckFilter). */
#include <petsc/private/tsimpl.h>
#include <petsc/private/kspimpl.h> /* KSP's norm type as the options left it (KSPGetNormType resolves the default) */
#include <pcblockicc.h>
#include <pclatticemg.h>
#include <sbaijmult.h>
#include <drapebe.h>
#include <stability.h>
#include <drape.h>

static PetscErrorCode TSDrapeBEGetCloth(TS, Cloth *);

#define BE_START_MAX     8 /* -drape_start_history at most */
#define BE_START_HISTORY 3 /* its default (BEStartCombination) */

typedef struct {
  Cloth              cloth;
  ContactSolve       contact;                                         /* NULL: no solid */
  SelfContact        self;                                            /* NULL: no self-contact in the solve */
  MatType            mattype;                                         /* of J (a new J when self-contact needs more blocks) */
  Vec                U0;                                              /* the state at the start of the step */
  Vec                DV, R, W;                                        /* W: work vector of the CG start */
  PetscInt           start_k;                                         /* -drape_start_history: CG starts from the best combination of the last start_k solutions */
  PetscInt           nhist;                                           /* earlier solutions held in hist */
  Vec                hist[BE_START_MAX - 1], Ahist[BE_START_MAX - 1]; /* earlier solutions, newest first, and their products with hist_mat */
  Vec                Ax;                                              /* the product of the last solution, to join Ahist */
  PetscObjectId      hist_mat;                                        /* the matrix Ahist was made with (0: none) */
  PetscObjectState   hist_state;                                      /* its state then: a kept matrix reuses them */
  Vec                nullvec[6];                                      /* near null space (BENearNullSpace; made at its first use) */
  Mat                J;
  PC                 pc; /* the linear solve's preconditioner */
  PetscScalar       *xt, *vt, *at;
  const PetscScalar *x0, *v0;
  const PetscReal   *mass;
  const PetscBool   *pinned;
  PetscInt           n;               /* 3 x owned particles */
  PetscInt           nparticles;      /* on all ranks */
  PetscReal          h, damping, g;   /* g: |gravity|, m/s^2 */
  PetscReal          weight;          /* |M g| over the free particles (CG's absolute tolerance: rtol h weight), N */
  PetscReal          mass_min;        /* the smallest free particle's mass, kg */
  PetscReal          solve_error;     /* -drape_solve_error: CG's error bound as a fraction of the step's local error (0: rtol alone) */
  PetscBool          solve_error_set; /* given in the options */
  PetscReal          omega;           /* Omega_max of the cloth at the start, rad/s (0: unknown) */
  PetscInt           contact_its;     /* solves allowed per step, for the solid's and self-contact's active sets */
  /* preconditioner */
  PetscInt  pc_lag, lag; /* rebuild every pc_lag steps (ksponly, iterative KSP); lag: where it applies */
  PetscInt  pc_overlap;  /* on several ranks, block IC(0) on each rank's block grown by this many layers of the matrix's graph (restricted additive Schwarz); 0: block Jacobi */
  PetscBool pc_stale;    /* rebuild it: the solid's constraints changed since it was built, or a step failed */
  PetscBool pc_amg;      /* it is algebraic multigrid (costly to build) */
  PetscBool pc_auto;     /* drape chose it (the PC's type was still PCDRAPE at TSSetUp): block IC(0) gives way to multigrid when it fails or is slow */
  PetscBool sub_factor;  /* -sub_pc_type lu, ilu or asm: block Jacobi's blocks need AIJ */
  PetscInt  pc_switched; /* the step at which it gave way (-1: never) */
  PetscReal its_mean;    /* CG iterations a solve, a moving mean (BEWatchIterations) */
  PetscReal mg_its;      /* -drape_mg_its: past this mean block IC gives way to multigrid on the lattice (0: never; -1, not given: drape's choice) */
  PetscInt  its_solves;  /* solves in it */
  PetscInt  lits_fresh;  /* CG iterations of the last solve with a fresh block IC (-1: none yet; BEWatchIterations) */
  PetscInt  fill_step;   /* the step at which block IC(0) took its level-1 fill (-1: never; BEUseFill) */
  PetscBool fill_auto;   /* the options did not give the fill (-pc_blockicc_levels, -sub_pc_blockicc_levels) */
  PetscInt  lits;        /* CG iterations of the last solve */
  PetscBool ksp_failed;  /* the last solve failed in KSP (a failure the preconditioner may cause; implies it failed) */
  /* the matrix kept from an earlier step (-drape_matrix_keep, BEStep) */
  PetscBool keep;                                     /* the option */
  PetscBool ksponly;                                  /* the single linearisation (SNES ksponly): the only solve a matrix may be kept for */
  PetscBool hybrid_auto;                              /* drape switched the lattice multigrid to its hybrid cycle (BEStepSolves) */
  PetscInt  hybrid_step, hybrid_wait, hybrid_backoff; /* the step it did, rebuilds before the V-cycle is tried again, and the next wait */
  PetscReal asm_h;                                    /* the step the matrix was assembled at; 0: none, or a new matrix since (BEUseMultigrid) */
  PetscInt  keep_wait, keep_backoff;                  /* steps before the next try after a refused one, and the next wait */
  PetscInt  nkept, nrefused;                          /* steps made with a kept matrix, and tries refused */
  PetscInt  max_its;                                  /* -ksp_max_it (ICC(0) chosen by drape stops at BE_ICC_MAX_ITS) */
  /* step control: TSAdapt's (src/integrate/adapt.c: TSADAPTDRAPE, the default) */
  PetscReal next_h;                                               /* TSAdapt's choice for the next step */
  PetscReal ksp_atol, snes_atol;                                  /* drape's defaults of the absolute tolerances (TSCreate_DrapeBE) */
  PetscBool snes_atol_set;                                        /* the options changed SNES's absolute tolerance: drape does not set it */
  PetscReal energy, energy_free, energy_trial, energy_free_trial; /* BECheckEnergy */
  PetscReal energy_scale;                                         /* M g L */
  PetscReal rise_trial, rise_cut;                                 /* BECheckRise */
  PetscInt  nrising;
  PetscBool have_energy;
  PetscReal filter_added; /* mechanical energy the changes after the last step added (TSDrapeBEStateChanged), J */
  Vec       E;            /* work vector of the local error estimate (TSEvaluateWLTE_DrapeBE) */
  /* statistics */
  PetscInt nsolves, nrejected, nlte; /* nlte: steps rejected by TSAdapt for their local error */
  PetscInt nfilter;                  /* steps cut because the state changes after the last one added energy (BECheckFilter) */
  char     failure[512];             /* the last failed solve, for the error message */
} TS_DrapeBE;

/* Trial state of the step: v_t = v0 + S dv + z (the solid's constraints S, z:
 * ContactSolveTrialVelocity), x_t = x0 + h v_t; pinned particles
 * stay put whatever dv holds, so R of the free particles does not depend on their dv
 * (the eliminated rows and columns of the matrix). */
static PetscErrorCode TrialState(TS_DrapeBE *be, Vec DV)
{
  const PetscScalar *dv;

  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(DV, &dv));
  for (PetscInt i = 0; i < be->n; i++) be->vt[i] = be->v0[i] + (be->pinned[i / 3] ? 0 : dv[i]);
  if (be->contact) PetscCall(ContactSolveTrialVelocity(be->contact, dv, be->vt));
  for (PetscInt i = 0; i < be->n; i++) be->xt[i] = be->x0[i] + be->h * be->vt[i];
  PetscCall(VecRestoreArrayRead(DV, &dv));
  PetscFunctionReturn(0);
}

/* be->at: the accelerations at the trial state, the self-contact penalties' with
 * the cloth's. */
static PetscErrorCode BEAcceleration(TS_DrapeBE *be)
{
  PetscFunctionBeginUser;
  PetscCall(ClothComputeAcceleration(be->cloth, be->xt, be->vt, be->at));
  if (be->self) PetscCall(SelfContactSolveAddAcceleration(be->self, be->xt, be->at));
  PetscFunctionReturn(0);
}

static PetscErrorCode BEFunction(SNES snes, Vec DV, Vec R, void *ctx)
{
  TS_DrapeBE        *be = (TS_DrapeBE *) ctx;
  const PetscScalar *dv;
  PetscScalar       *r;

  PetscFunctionBeginUser;
  PetscCall(TrialState(be, DV));
  PetscCall(BEAcceleration(be));
  PetscCall(VecGetArrayRead(DV, &dv));
  PetscCall(VecGetArray(R, &r));
  for (PetscInt i = 0; i < be->n; i++) r[i] = be->mass[i / 3] * (be->pinned[i / 3] ? dv[i] : be->vt[i] - be->v0[i] - be->h * be->at[i]);
  if (be->contact) PetscCall(ContactSolveResidual(be->contact, dv, be->vt, r)); /* the constrained particles' rows */
  PetscCall(VecRestoreArray(R, &r));
  PetscCall(VecRestoreArrayRead(DV, &dv));
  PetscFunctionReturn(0);
}

static PetscErrorCode BEJacobian(SNES snes, Vec DV, Mat J, Mat P, void *ctx)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ctx;

  PetscFunctionBeginUser;
  PetscCall(TrialState(be, DV));
  PetscCall(ClothAssembleMatrix(be->cloth, be->xt, 1 + be->h * be->damping, be->h * be->h, P));
  be->asm_h = be->h;
  if (J != P) {
    PetscCall(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  }
  PetscFunctionReturn(0);
}

/* The solid's constraints to the Cloth's matrix and to self-contact's pairs; the
 * preconditioner is stale when they changed (pc_changes particles) since it was
 * built. Collective. */
static PetscErrorCode BESetConstraints(TS_DrapeBE *be, PetscInt pc_changes)
{
  const ClothConstraint *type;
  const PetscReal       *normal, *block;

  PetscFunctionBeginUser;
  PetscCall(ContactSolveGetConstraints(be->contact, &type, &normal, &block));
  PetscCall(ClothSetConstraints(be->cloth, type, normal, block));
  if (be->self) PetscCall(SelfContactSolveSetConstraints(be->self, type, normal));
  PetscCall(PCLatticeMGSetConstraints(be->pc, type, normal)); /* its interpolation's filter */
  /* a constraint that comes or goes changes its row of the matrix, and a factorisation
   * (ICC) of the old one is then a poor preconditioner: rebuilt (cheap); an algebraic
   * multigrid hierarchy, costly to build, copes with a few particles more or less in
   * contact and is rebuilt after a landing (more than 1 % of the particles) */
  be->pc_stale = (PetscBool) (be->pc_stale || pc_changes > (be->pc_amg ? PetscMax(8, be->nparticles / 100) : 0));
  PetscFunctionReturn(0);
}

/* The preconditioner, unless the options chose one: the solves choose it. Block
 * IC(0) of each rank's block (PCBLOCKICC, include/pcblockicc.h: PETSc's ICC(0)
 * where that is positive definite, compensated where it is not, so it never stops
 * CG as an indefinite preconditioner; PETSc's ICC(0) did on the Cusick scene at
 * 161^2, where the out-of-plane bending defeats IC(0): BENCHMARKS.md) is cheap to
 * build (and to rebuild when contacts change), and
 * one of its CG iterations costs about a 20th of one preconditioned by an ML
 * V-cycle (12 fine-grid products and SOR sweeps: the hang at 64^2 and 1e-2 s, 65
 * against 7.5 iterations a step, 62 against 194 ms a step, BENCHMARKS.md). Its
 * iterations grow with the lattice and the stiffness of the step, (h
 * Omega_max)^2: then smoothed-aggregation multigrid
 * with the cloth's rigid-body modes (BENearNullSpace) wins, ML where PETSc has it,
 * GAMG otherwise. So the run starts with ICC(0) unless the step is stiffer than
 * BE_AMG_STIFFNESS, and gives way to multigrid for the rest of the run at the
 * first solve that fails or takes more than BE_ICC_MAX_ITS iterations with a
 * fresh factorisation (BEUseMultigrid); that solve is made again at the same step.
 * 300: where ICC(0) and ML break even on the hang at 128^2 (266 ICC(0) iterations
 * a step still took 20.8 CPU s against ML's 30.1 at 23.8 iterations).
 * A fixed rule on (h Omega)^2 alone (2e3 until 2026-11-25) chose ML where ICC(0)
 * was 1.4-3 x faster (the hang at 128^2 up to 3.2e4; the Cusick scene at 121^2 and
 * 161^2), and ICC(0) where it failed.
 * On one rank the multigrid is the lattice's own (PCLATTICEMG, BEUseLatticeMG):
 * from the start above BE_AMG_STIFFNESS (the hang at 241^2 and 1e-2 s: 19 CPU s and
 * 244 MB against ML's 95 s and 601 MB), after a failed or slow solve, and once block
 * IC takes more than -drape_mg_its (BE_MG_ITS) iterations a solve (BEWatchIterations);
 * ML where the lattice multigrid fails too. On several ranks the same, except from
 * the start above BE_AMG_STIFFNESS on a lattice of fewer than BE_MG_LARGE particles:
 * ML there (the stiff hang at 65^2 and 1e-2 s on two ranks: ML 23 CG iterations a
 * step, the lattice multigrid 36), where its 12.8 kB a particle do not matter; and
 * on more than BE_MG_RANKS ranks additive Schwarz, then ML, as before: there the
 * multigrid's coarse levels, whole on every rank, would outweigh a rank's share. */
#define BE_AMG_STIFFNESS 5e4
#define BE_MG_LARGE      40000 /* particles: a large lattice (BEWatchIterations; on several ranks, BEChoosePreconditioner) */
/* drape chooses the lattice multigrid on at most BE_MG_RANKS ranks: each holds its
 * coarse levels whole, about 210 B a particle of the lattice (a quarter of the nodes,
 * 13 single-precision blocks each, with their inverses, vectors and the coarser
 * levels), a quarter of a rank's share of drapebe's 3 kB at 4 */
#define BE_MG_RANKS    4
#define BE_ICC_MAX_ITS 300
#define BE_MG_ITS      40

static PetscErrorCode BESetMultigrid(PC pc)
{
  PCType type = PCGAMG;

  PetscFunctionBeginUser;
#if defined(PETSC_HAVE_ML)
  type = PCML;
#endif
  PetscCall(PCSetType(pc, type));
  if (!strcmp(type, PCML)) {
    /* drop weak connections (anisotropy of a draped cloth): fewer iterations. A
     * write into the options database, made only when the user gave no
     * -pc_ml_Threshold, because PETSc 3.18's ML has no other way in: its threshold
     * is a field of a struct private to ml.c, read only by PCSetFromOptions_ML
     * (there is no PCMLSetThreshold nor a composed function), and giving the PC its
     * own database (PetscObjectSetOptions) would hide the user's other -pc_ml_ and
     * -mg_ options from it and leave them unused */
    char      name[256];
    PetscBool set;
    PetscCall(PetscSNPrintf(name, sizeof name, "-%spc_ml_Threshold", ((PetscObject) pc)->prefix ? ((PetscObject) pc)->prefix : ""));
    PetscCall(PetscOptionsHasName(NULL, NULL, name, &set));
    if (!set) PetscCall(PetscOptionsSetValue(NULL, name, "0.02"));
  }
  PetscFunctionReturn(0);
}

/* The PC type "drape" (PCDRAPE), drapebe's default: a placeholder meaning "drape
 * chooses", replaced at TSSetUp (BEChoosePreconditioner). -pc_type gives any other,
 * and PCSetFromOptions leaves this one when it is not given: so whether the options
 * chose the preconditioner is the PC's own type, not a question to the options
 * database. It has no methods: a solve never sees it. */
static PetscErrorCode PCCreate_Drape(PC pc)
{
  PetscFunctionBeginUser;
  PetscFunctionReturn(0);
}

/* On several ranks, block Jacobi's blocks (each rank's rows) lose the coupling
 * across the cut, and CG pays for it: the hang at 512^2 took 4.35 iterations a step
 * on two ranks against 3.175 on one (BENCHMARKS.md, "Two ranks at 512^2"). So
 * drape's default there is restricted additive Schwarz (PCASM, restrict): each
 * rank's rows grown by -drape_pc_overlap layers of the matrix's graph
 * (MatIncreaseOverlap), their SBAIJ submatrix factored by block IC(0), the result
 * kept on the rank's own rows only; overlap 2 gave one rank's 3.175. The blocks'
 * PC: block IC(0), set here (PCASM calls this after creating the blocks' KSPs and
 * before their KSPSetFromOptions, so -sub_pc_type still chooses another) on
 * symmetric storage, left to PETSc on other storage. */
static PetscErrorCode BESubBlockICC(PC pc, PetscInt nsub, const IS row[], const IS col[], Mat sub[], void *ctx)
{
  KSP      *ksp;
  PetscInt  n;
  PC        subpc;
  PetscBool sbaij;
  PCType    type;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) pc, PCASM, &sbaij)); /* -pc_type may have replaced drape's PCASM */
  if (!sbaij) PetscFunctionReturn(0);
  PetscCall(PCASMGetSubKSP(pc, &n, NULL, &ksp));
  for (PetscInt i = 0; i < n && i < nsub; i++) {
    PetscCall(KSPGetPC(ksp[i], &subpc));
    PetscCall(PCGetType(subpc, &type));
    PetscCall(PetscObjectTypeCompare((PetscObject) sub[i], MATSEQSBAIJ, &sbaij));
    if (!type && sbaij) PetscCall(PCSetType(subpc, PCBLOCKICC));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode BEChoosePreconditioner(TS ts, TS_DrapeBE *be, PC pc)
{
  PCType      type = PCBLOCKICC;
  PetscBool   typed;
  PetscMPIInt size;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) pc, PCDRAPE, &be->pc_auto));
  if (!be->pc_auto) PetscFunctionReturn(0);
  if (be->omega <= 0) { /* not given: estimate it (the start-up estimate takes more iterations) */
    StabilityLimits    lim = {0};
    const PetscScalar *u;
    PetscCall(VecGetArrayRead(ts->vec_sol, &u));
    PetscCall(StabilityEstimate(be->cloth, u, 10, &lim));
    PetscCall(VecRestoreArrayRead(ts->vec_sol, &u));
    be->omega = lim.omega;
  }
  PetscCallMPI(MPI_Comm_size(PetscObjectComm((PetscObject) ts), &size));
  if (PetscSqr(ts->time_step * be->omega) > BE_AMG_STIFFNESS && (size == 1 || (be->nparticles >= BE_MG_LARGE && size <= BE_MG_RANKS)))
    PetscCall(PCSetType(pc, PCLATTICEMG));
  else if (PetscSqr(ts->time_step * be->omega) > BE_AMG_STIFFNESS)
    PetscCall(BESetMultigrid(pc));
  else if (size > 1 && be->pc_overlap > 0) { /* block IC(0) on overlapping blocks (BESubBlockICC) */
    PetscCall(PCSetType(pc, PCASM));
    PetscCall(PCASMSetType(pc, PC_ASM_RESTRICT));
    PetscCall(PCASMSetOverlap(pc, be->pc_overlap));
    PetscCall(PCSetModifySubMatrices(pc, BESubBlockICC, NULL));
  } else
    PetscCall(PCSetType(pc, type));
  PetscCall(PCSetFromOptions(pc));
  /* the chosen type's own options are read by PCSetFromOptions, which reads -pc_type
   * too: -pc_type drape, typed, would put the placeholder back */
  PetscCall(PetscObjectTypeCompare((PetscObject) pc, PCDRAPE, &typed));
  PetscCheck(!typed, PetscObjectComm((PetscObject) ts), PETSC_ERR_USER_INPUT, "-pc_type %s is drapebe's default, not a preconditioner to ask for: leave -pc_type out to let the solves choose, or give one of PETSc's (bjacobi, ml, gamg, lu, ...)",
             PCDRAPE);
  PetscFunctionReturn(0);
}

/* Block IC(0), chosen by drape, gives way to multigrid (BEChoosePreconditioner):
 * the matrix becomes AIJ, the preconditioner is built anew. Collective. */
static PetscErrorCode BEUseMultigrid(TS ts, TS_DrapeBE *be)
{
  SNES snes;
  KSP  ksp;
  PC   pc;
  Mat  J;
  char was[64];

  PetscFunctionBeginUser;
  PetscCall(TSGetSNES(ts, &snes));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PetscStrncpy(was, ((PetscObject) pc)->type_name, sizeof was));
  PetscCall(PCReset(pc));
  PetscCall(BESetMultigrid(pc));
  PetscCall(PCSetFromOptions(pc));
  PetscCall(KSPSetTolerances(ksp, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT, be->max_its));
  be->pc_amg      = PETSC_TRUE;
  be->mattype     = MATAIJ;
  be->pc_stale    = PETSC_TRUE;
  be->pc_switched = ts->steps;
  PetscCall(ClothCreateMatrix(be->cloth, be->mattype, &J));
  PetscCall(DrapeMatUseSBAIJProduct(J));
  PetscCall(SNESSetJacobian(snes, J, J, BEJacobian, be));
  PetscCall(MatDestroy(&be->J));
  be->J     = J;
  be->asm_h = 0;
  PetscCall(PetscPrintf(PetscObjectComm((PetscObject) ts), "note: at step %" PetscInt_FMT " (t = %g s) CG with %s %s; the run goes on with algebraic multigrid (%s)\n", ts->steps, (double) ts->ptime,
                        strcmp(was, PCLATTICEMG) ? "block IC" : "the lattice multigrid", be->lits >= BE_ICC_MAX_ITS ? "reached " PetscStringize(BE_ICC_MAX_ITS) " iterations" : "failed", ((PetscObject) pc)->type_name));
  PetscFunctionReturn(0);
}

/* The lattice (and which rows are pinned) to a lattice multigrid PC; nothing for
 * another type. Not collective. */
static PetscErrorCode BELatticeMGSetLattice(TS_DrapeBE *be, PC pc)
{
  ClothInfo       info;
  const PetscInt *natural;

  PetscFunctionBeginUser;
  PetscCall(ClothGetInfo(be->cloth, &info));
  PetscCall(ClothGetNatural(be->cloth, &natural));
  PetscCall(PCLatticeMGSetLattice(pc, info.Mx, info.My, be->n / 3, natural, be->pinned));
  PetscFunctionReturn(0);
}

/* Block IC (on several ranks its additive Schwarz), chosen by drape, gives way to
 * geometric multigrid on the lattice (PCLATTICEMG, include/pclatticemg.h) for the
 * rest of the run: the same
 * SBAIJ matrix, a new preconditioner at the next solve. Why, and when
 * (BEWatchIterations, BEStep): a V-cycle costs about five CG iterations with block
 * IC, and takes 4-5 iterations a step where IC's grow with the lattice and the step
 * (the Cusick scene: 4.1 and 4.4 at 81^2 and 161^2 against 16.5 and 20.0; the hang
 * at 48^2 and 1e-2 s: 5.2 against 66, half the CPU time). Collective. */
static PetscErrorCode BEUseLatticeMG(TS ts, TS_DrapeBE *be, const char *why)
{
  PC pc = be->pc;

  PetscFunctionBeginUser;
  PetscCall(PCReset(pc));
  PetscCall(PCSetType(pc, PCLATTICEMG));
  PetscCall(PCSetFromOptions(pc));
  PetscCall(BELatticeMGSetLattice(be, pc));
  if (be->contact) {
    const ClothConstraint *type;
    const PetscReal       *normal;
    PetscCall(ContactSolveGetConstraints(be->contact, &type, &normal, NULL));
    PetscCall(PCLatticeMGSetConstraints(pc, type, normal));
  }
  be->pc_stale    = PETSC_TRUE;
  be->pc_switched = ts->steps;
  PetscCall(PetscPrintf(PetscObjectComm((PetscObject) ts), "note: at step %" PetscInt_FMT " (t = %g s) CG with block IC %s; the run goes on with geometric multigrid on the lattice (%s)\n", ts->steps, (double) ts->ptime, why, PCLATTICEMG));
  PetscFunctionReturn(0);
}

/* The moving mean of CG iterations a solve with drape's block IC (on several ranks,
 * its additive Schwarz); past
 * -drape_mg_its (BE_MG_ITS; over at least 10 solves, or past twice it over 3: the
 * hang at 128^2 and 1e-2 s took 96 a solve from its first, and its 9 steps before the
 * switch cost 2.5 CPU s against 1.0 with the multigrid) block IC gives way to geometric multigrid
 * (BEUseLatticeMG): where IC takes 16.5 a step (the Cusick scene at 81^2) multigrid
 * was 10 % slower, at 20 (161^2) 8 % faster, at 26 (the Cusick scene at 61^2, from
 * step 54) 9 % slower (5.5 % with the W-cycle), at 66 (the hang at 48^2 and 1e-2 s)
 * twice as fast: 40. On a lattice of BE_MG_LARGE particles or more the coarse
 * levels pay sooner: the Cusick scene (denim) at 321^2, whose block IC(1) takes
 * about 30 a solve in its 1 ms phase and reached 40 only in its settled phase,
 * took 1163 CPU s so against 765 s with the multigrid from the start; so there
 * BE_MG_ITS_LARGE, unless -drape_mg_its is given. On two ranks the multigrid takes
 * about twice one rank's iterations (block Jacobi's smoother): at 161^2 (below
 * BE_MG_LARGE) the Cusick scene's additive Schwarz (14.6 a step) was faster than it
 * (3.8), at 321^2 (23.5 against 5.2) slower (BENCHMARKS.md, "The lattice multigrid on
 * two ranks"). Collective (the iterations are every rank's). */
#define BE_MG_ITS_LARGE 20
/* The same threshold on one rank where CG stops at the step's own accuracy
 * (-drape_solve_error, the default; the thresholds above were measured at -ksp_rtol
 * alone; on several ranks, not measured so, 20 stays): block IC
 * then takes 2-3 x fewer iterations a solve (the hang at 121^2 and 2.5 ms: 11.7
 * against 31), the multigrid 2-2.5 a solve, and on a large lattice the multigrid
 * pays from about 8: the Cusick scene (denim) at 321^2 and 0.5 ms to rest, block IC
 * at 12.1 a solve until step 2218 against the multigrid from step 2, 1124 against
 * 953 CPU s (8 folds each, DC 0.5589 and 0.5565); at 161^2 and 1 ms (below
 * BE_MG_LARGE) block IC at 8.6 a solve 135 against 129 s, at 81^2 at 8.7, 21.8
 * against 25.7 (BENCHMARKS.md, "Block IC or the multigrid, at the step's accuracy"). */
#define BE_MG_ITS_LARGE_STEP 8
/* A held block IC is made again once a solve takes this many CG iterations more
 * than the last solve after a fresh factorisation (BEWatchIterations) */
#define BE_LAG_EXTRA_ITS 4

/* BEWatchIterations' threshold: -drape_mg_its if given, else by the lattice's size,
 * where CG stops and the ranks (above) */
static PetscReal BEMGThreshold(const TS_DrapeBE *be, PetscMPIInt size)
{
  if (be->mg_its >= 0) return be->mg_its;
  if (be->nparticles < BE_MG_LARGE) return BE_MG_ITS;
  return be->solve_error > 0 && size == 1 ? BE_MG_ITS_LARGE_STEP : BE_MG_ITS_LARGE;
}

static PetscErrorCode BEWatchIterations(TS ts, TS_DrapeBE *be, PetscBool fresh)
{
  PetscMPIInt size;
  PetscBool   mg;
  PetscReal   limit;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) be->pc, PCLATTICEMG, &mg));
  PetscCallMPI(MPI_Comm_size(PetscObjectComm((PetscObject) ts), &size));
  if (!be->pc_auto || be->pc_amg || mg || size > BE_MG_RANKS) PetscFunctionReturn(0);
  /* a factorisation held from an earlier step (-drape_pc_lag) takes more iterations
   * as the matrix moves away from it: made again at the next step once a solve took
   * more than BE_LAG_EXTRA_ITS more than the one after it was made. Its aged solves
   * had raised the mean past BE_MG_ITS on the hang at 64^2 to rest at step 124,
   * where block IC takes 6 a solve: the multigrid from then on cost 1.1 x the CPU
   * time of block IC until the settled steps (step 422 now; BENCHMARKS.md) */
  if (!fresh && be->lits_fresh >= 0 && be->lits > be->lits_fresh + BE_LAG_EXTRA_ITS) be->pc_stale = PETSC_TRUE;
  if (fresh) be->lits_fresh = be->lits;
  be->its_mean = be->its_solves ? 0.8 * be->its_mean + 0.2 * be->lits : be->lits;
  limit        = BEMGThreshold(be, size);
  be->its_solves++;
  if (limit > 0 && ((be->its_solves >= 10 && be->its_mean > limit) || (be->its_solves >= 3 && be->its_mean > 2 * limit))) {
    char why[128];
    PetscCall(PetscSNPrintf(why, sizeof why, "took %.1f iterations a solve", (double) be->its_mean));
    PetscCall(BEUseLatticeMG(ts, be, why));
  }
  PetscFunctionReturn(0);
}

/* drapebe's preconditioner. Not collective. */
static PetscErrorCode BEGetPC(TS ts, PC *pc)
{
  SNES snes;
  KSP  ksp;

  PetscFunctionBeginUser;
  PetscCall(TSGetSNES(ts, &snes));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetPC(ksp, pc));
  PetscFunctionReturn(0);
}

/* Where drape's block IC lives: pc itself on one rank (*sub NULL), each of this
 * rank's *n blocks of its additive Schwarz or block Jacobi on several. Not
 * collective. */
static PetscErrorCode BEBlockICCs(PC pc, PetscInt *n, KSP **sub)
{
  PetscBool asm_, bjacobi;

  PetscFunctionBeginUser;
  *n   = 0;
  *sub = NULL;
  PetscCall(PetscObjectTypeCompare((PetscObject) pc, PCASM, &asm_));
  PetscCall(PetscObjectTypeCompare((PetscObject) pc, PCBJACOBI, &bjacobi));
  if (asm_)
    PetscCall(PCASMGetSubKSP(pc, n, NULL, sub));
  else if (bjacobi)
    PetscCall(PCBJacobiGetSubKSP(pc, n, NULL, sub));
  PetscFunctionReturn(0);
}

/* Restricted additive Schwarz (drape's choice on several ranks, BESubBlockICC) is
 * no symmetric preconditioner, and CG can stall with it: the Cusick scene at 161^2
 * on two ranks reached BE_ICC_MAX_ITS at step 47 and went on with ML at 2.5 times
 * the CPU time, where the symmetric form (-pc_asm_type basic: the blocks' results
 * added on the overlap) went on at 25 iterations a step. The symmetric form takes
 * more iterations where the restricted one converges (the hang at 512^2: 4.45
 * against 3.17 a step), so drape starts restricted and, at its first failed or slow
 * solve, makes it symmetric for the rest of the run (*switched), before any
 * multigrid. Collective. */
static PetscErrorCode BERestrictedSchwarz(TS ts, PetscBool *switched)
{
  PC        pc;
  PCASMType type;

  PetscFunctionBeginUser;
  PetscCall(BEGetPC(ts, &pc));
  PetscCall(PetscObjectTypeCompare((PetscObject) pc, PCASM, switched));
  if (!*switched) PetscFunctionReturn(0);
  PetscCall(PCASMGetType(pc, &type));
  *switched = (PetscBool) (type == PC_ASM_RESTRICT);
  if (!*switched) PetscFunctionReturn(0);
  PetscCall(PCASMSetType(pc, PC_ASM_BASIC));
  PetscCall(PetscPrintf(PetscObjectComm((PetscObject) ts), "note: at step %" PetscInt_FMT " (t = %g s) CG with restricted additive Schwarz, not symmetric, stalled; the run goes on with its symmetric form (-pc_asm_type basic)\n", ts->steps,
                        (double) ts->ptime));
  PetscFunctionReturn(0);
}

/* Whether drape's block IC(0) compensated its last factorisation on any rank (on
 * several ranks, that of the blocks of its additive Schwarz or block Jacobi).
 * Collective. */
static PetscErrorCode BEICCCompensated(TS ts, PetscBool *compensated)
{
  PC        pc, subpc;
  KSP      *sub;
  PetscInt  n;
  PetscBool any = PETSC_FALSE;

  PetscFunctionBeginUser;
  PetscCall(BEGetPC(ts, &pc));
  PetscCall(BEBlockICCs(pc, &n, &sub));
  if (!sub) {
    PetscCall(PCBlockICCGetCompensated(pc, compensated));
    PetscFunctionReturn(0);
  }
  for (PetscInt i = 0; i < n; i++) {
    PetscBool c;
    PetscCall(KSPGetPC(sub[i], &subpc));
    PetscCall(PCBlockICCGetCompensated(subpc, &c)); /* the block's own communicator */
    any = (PetscBool) (any || c);
  }
  PetscCall(MPIU_Allreduce(&any, compensated, 1, MPIU_BOOL, MPI_LOR, PetscObjectComm((PetscObject) ts)));
  PetscFunctionReturn(0);
}

/* Block IC(0) takes its level-1 fill (IC(1), PCBlockICCSetLevels) for the rest of
 * the run at the first factorisation that had to be compensated (on any rank):
 * IC(0) then dropped more fill than its rows keep, and the compensation that keeps
 * it positive definite makes it a weak preconditioner. The fill it dropped is what
 * IC(1) keeps, and there it factors plainly: the Cusick scene at 161^2, 41.2
 * against 19.9 CG iterations a step and 308 against 255 CPU s to rest. Where IC(0)
 * factors plainly, IC(1) saves fewer iterations than its factor, 2.4 times as many
 * bytes a solve, costs (the Cusick scene at 81^2, 5 % slower; the hang at 48^2 and
 * 1e-2 s, 66 against 50 iterations a step, 9 % slower): BENCHMARKS.md, "Block
 * IC(1)".
 *
 * Level-1 fill for drape's block IC(0): on one rank the PC, on several the blocks of
 * its additive Schwarz (or block Jacobi); the next solve builds it. Collective. */
static PetscErrorCode BEUseFill(TS ts, TS_DrapeBE *be)
{
  PC       pc, subpc;
  KSP     *sub;
  PetscInt n;

  PetscFunctionBeginUser;
  PetscCall(BEGetPC(ts, &pc));
  PetscCall(BEBlockICCs(pc, &n, &sub));
  if (!sub) PetscCall(PCBlockICCSetLevels(pc, 1));
  for (PetscInt i = 0; i < n; i++) {
    PetscCall(KSPGetPC(sub[i], &subpc));
    PetscCall(PCBlockICCSetLevels(subpc, 1));
  }
  be->fill_step = ts->steps;
  be->pc_stale  = PETSC_TRUE;
  PetscFunctionReturn(0);
}

/* CG's start (KSP pre-solve): the combination of the last solves' solutions (the
 * newest, x, still in SNES's update vector, zero when SNES creates it; the earlier
 * ones kept in hist, -drape_start_history in all) closest to A^{-1} b in the energy
 * norm: the Galerkin projection onto their span, the coefficients c solving
 * G c = V^T b with G = V^T A V (for one vector: alpha = (b.x)/(x.Ax)). Never a worse
 * start than zero or than any one of them, however the system changed (contact, a
 * Newton iteration, a retried step), and it holds the extrapolations from the last
 * steps (2 x_{n-1} - x_{n-2}, ...) that a smooth swing follows. As many products as
 * vectors, but with a kept matrix (unchanged since the last start) the earlier
 * solutions' products are still its own: one. G is factored with the vectors in
 * order, newest first, and a vector whose pivot falls below 1e-10 of its own x.Ax
 * (nearly in the span of the newer ones) is left out. Measured (BENCHMARKS.md): the
 * hang at 128^2 (1e-2 s, the lattice multigrid), its swing (the first 300 steps),
 * 1, 2, 3, 4 solutions 9.25, 8.19, 7.52, 7.56 CG iterations a step; the Cusick scene at
 * 81^2 (block IC, the first 0.5 s) 6.10 and 5.87 with 1 and 3, in the same time (a
 * product costs about what the iterations saved; linear and quadratic extrapolation
 * from the last two or three, scaled, took 8.46 and 10.04 on the hang). With
 * -snes_type ksponly only: Newton's (newtonls) solves are of updates within a step,
 * no smooth sequence, and the stiff light cloth of scripts/stability_sweep.py at
 * 0.05 s went 2.4 x slower with three (646 steps retried against 400, by t = 0.17 s
 * against 0.41 in the same 20 s). */
static PetscErrorCode BEStartCombination(TS_DrapeBE *be, Mat A, Vec b, Vec x)
{
  Vec              V[BE_START_MAX], AV[BE_START_MAX];
  PetscScalar      G[BE_START_MAX][BE_START_MAX], rhs[BE_START_MAX], c[BE_START_MAX];
  PetscReal        L[BE_START_MAX][BE_START_MAX], d[BE_START_MAX];
  PetscBool        used[BE_START_MAX];
  PetscInt         kmax, k;
  PetscObjectState state;
  PetscObjectId    id;

  PetscFunctionBeginUser;
  kmax = be->ksponly ? be->start_k : 1; /* Newton's updates within a step are no smooth sequence */
  for (PetscInt i = 0; i < kmax - 1; i++)
    if (!be->hist[i]) { /* made at their first use */
      PetscCall(VecDuplicate(x, &be->hist[i]));
      PetscCall(VecDuplicate(x, &be->Ahist[i]));
    }
  if (kmax > 1 && !be->Ax) PetscCall(VecDuplicate(x, &be->Ax));
  be->nhist = PetscMin(be->nhist, kmax - 1);
  k         = 1 + be->nhist;
  V[0]      = x;
  AV[0]     = kmax > 1 ? be->Ax : be->W;
  for (PetscInt i = 1; i < k; i++) {
    V[i]  = be->hist[i - 1];
    AV[i] = be->Ahist[i - 1];
  }
  /* the earlier solutions' products are still A's when A is the matrix they were
   * made with, unchanged since (a kept matrix): one product a start then */
  PetscCall(PetscObjectStateGet((PetscObject) A, &state));
  PetscCall(PetscObjectGetId((PetscObject) A, &id));
  PetscCall(MatMult(A, x, AV[0]));
  if (id != be->hist_mat || state != be->hist_state)
    for (PetscInt i = 1; i < k; i++) PetscCall(MatMult(A, V[i], AV[i]));
  be->hist_mat   = id;
  be->hist_state = state;
  for (PetscInt i = 0; i < k; i++) PetscCall(VecDotBegin(b, V[i], &rhs[i])); /* one reduction for all */
  for (PetscInt i = 0; i < k; i++)
    for (PetscInt j = 0; j <= i; j++) PetscCall(VecDotBegin(AV[i], V[j], &G[i][j]));
  for (PetscInt i = 0; i < k; i++) PetscCall(VecDotEnd(b, V[i], &rhs[i]));
  for (PetscInt i = 0; i < k; i++)
    for (PetscInt j = 0; j <= i; j++) PetscCall(VecDotEnd(AV[i], V[j], &G[i][j]));
  /* L D L^T of G (its lower triangle), a pivot that is not a positive normal number
   * above 1e-10 of G_jj dropping its vector */
  for (PetscInt j = 0; j < k; j++) {
    PetscReal gjj = PetscRealPart(G[j][j]), dj = gjj;
    for (PetscInt m = 0; m < j; m++)
      if (used[m]) dj -= L[j][m] * L[j][m] * d[m];
    used[j] = (PetscBool) (PetscIsNormalReal(gjj) && gjj > 0 && PetscIsNormalReal(dj) && dj > 1e-10 * gjj);
    d[j]    = used[j] ? dj : 0;
    for (PetscInt i = j + 1; i < k && used[j]; i++) {
      PetscReal lij = PetscRealPart(G[i][j]);
      for (PetscInt m = 0; m < j; m++)
        if (used[m]) lij -= L[i][m] * L[j][m] * d[m];
      L[i][j] = lij / dj;
    }
  }
  for (PetscInt i = 0; i < k; i++) { /* L y = rhs, then D L^T c = y, over the vectors used; any other c 0 */
    PetscReal y = PetscRealPart(rhs[i]);
    for (PetscInt m = 0; m < i && used[i]; m++)
      if (used[m]) y -= L[i][m] * PetscRealPart(c[m]);
    c[i] = used[i] && PetscIsNormalReal(y) ? y : 0;
  }
  for (PetscInt i = k - 1; i >= 0; i--) {
    PetscReal ci = PetscRealPart(c[i]) / (used[i] ? d[i] : 1);
    for (PetscInt m = i + 1; m < k && used[i]; m++)
      if (used[m]) ci -= L[m][i] * PetscRealPart(c[m]);
    c[i] = ci;
  }
  if (kmax > 1) {
    /* the solutions kept for the next start, newest first: x as the last solve left
     * it, and its product, into the oldest's vectors, which move to the front */
    Vec oldest, Aoldest;
    PetscCall(VecSet(be->W, 0.0));
    PetscCall(VecMAXPY(be->W, k, c, V));
    if (be->nhist < kmax - 1) be->nhist++;
    oldest  = be->hist[be->nhist - 1];
    Aoldest = be->Ahist[be->nhist - 1];
    for (PetscInt i = be->nhist - 1; i > 0; i--) {
      be->hist[i]  = be->hist[i - 1];
      be->Ahist[i] = be->Ahist[i - 1];
    }
    PetscCall(VecCopy(x, oldest));
    be->hist[0]  = oldest;
    be->Ahist[0] = be->Ax;
    be->Ax       = Aoldest;
    PetscCall(VecCopy(be->W, x));
  } else
    PetscCall(VecScale(x, c[0]));
  PetscFunctionReturn(0);
}

/* How far CG solves: to |r| <= rtol max(|b|, |h M g|) (BEStep), and no further than
 * the step itself is accurate. Backward Euler's local error in position is about
 * h |dv| / 2 (TSEvaluateWLTE_DrapeBE), and CG's residual r bounds its error in dv by
 * |r| / lambda_min(A) <= |r| / ((1 + h c) m_min) (A = (1 + h c) M + h^2 H, H
 * positive semi-definite, m_min the lightest free particle): so CG also stops once
 * |r| <= eta/2 (1 + h c) m_min |dv|, the solve's error then at most a fraction eta
 * (-drape_solve_error) of the step's, with |dv| estimated by CG's start (the
 * combination above) over the particles no solid constraint holds (as the local
 * error estimate leaves them out: a landing stops its particles at once). The
 * bound is a worst case (the whole residual in the softest mode); measured against
 * the true motion (scripts/rtol_accuracy.py, the hang at 64^2)
 * eta = 0.1 changed the error by +0.9 % at 2 x the symplectic limit and -0.1 % at 10 x
 * (rtol alone: -1.4 % and +0.0 %), with 1.9 and 2.2 x fewer CG iterations; 0.5 and 1
 * added 15 % and 50 % at 2 x. Near rest dv vanishes and rtol's absolute floor takes
 * over again. */
#define BE_SOLVE_ERROR 0.1

static PetscErrorCode BEStartFromLastSolution(KSP ksp, Vec b, Vec x, void *ctx)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ctx;
  Mat         A;
  PetscBool   nonzero;

  PetscFunctionBeginUser;
  PetscCall(KSPGetInitialGuessNonzero(ksp, &nonzero));
  if (!nonzero) PetscFunctionReturn(0);
  PetscCall(KSPGetOperators(ksp, &A, NULL));
  PetscCall(BEStartCombination(be, A, b, x));
  if (be->solve_error > 0 && be->weight > 0) { /* no further than the step is accurate (above) */
    const ClothConstraint *type = NULL;
    const PetscScalar     *xa;
    PetscReal              sq = 0, dv, rtol, atol;
    if (be->contact) PetscCall(ContactSolveGetConstraints(be->contact, &type, NULL, NULL));
    PetscCall(VecGetArrayRead(x, &xa));
    for (PetscInt i = 0; i < be->n; i++) /* the free particles' (a landing stops its particles at once: no step resolves it) */
      if (!type || type[i / 3] == CLOTH_FREE) sq += PetscSqr(PetscRealPart(xa[i]));
    PetscCall(VecRestoreArrayRead(x, &xa));
    PetscCall(MPIU_Allreduce(&sq, &dv, 1, MPIU_REAL, MPIU_SUM, PetscObjectComm((PetscObject) ksp)));
    dv = PetscSqrtReal(dv);
    PetscCall(KSPGetTolerances(ksp, &rtol, &atol, NULL, NULL));
    PetscCall(KSPSetTolerances(ksp, rtol, PetscMax(atol, 0.5 * be->solve_error * (1 + be->h * be->damping) * be->mass_min * dv), PETSC_DEFAULT, PETSC_DEFAULT));
  }
  PetscFunctionReturn(0);
}

/* The near null space of the matrix for smoothed aggregation (PCGAMG): the six
 * rigid-body motions of the cloth at its positions, filtered like the matrix (no
 * component along a constrained direction: those rows are decoupled), orthonormal.
 * Without the filter, contact leaves GAMG twice the iterations (BENCHMARKS.md). */
static PetscErrorCode BENearNullSpace(TS ts, TS_DrapeBE *be)
{
  SNES                   snes;
  KSP                    ksp;
  PC                     pc;
  PetscBool              gamg;
  MatNullSpace           nsp;
  PetscScalar           *u[6];
  PetscReal              c[3] = {0, 0, 0}, csum[3];
  PetscInt               nvec = 0, m = be->n / 3;
  ClothInfo              info;
  const ClothConstraint *type   = NULL; /* the solid's constraints (NULL: none) */
  const PetscReal       *normal = NULL;

  PetscFunctionBeginUser;
  PetscCall(TSGetSNES(ts, &snes));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PetscObjectTypeCompareAny((PetscObject) pc, &gamg, PCGAMG, PCML, ""));
  if (!gamg) PetscFunctionReturn(0);
  PetscCall(ClothGetInfo(be->cloth, &info));
  if (be->contact) PetscCall(ContactSolveGetConstraints(be->contact, &type, &normal, NULL));
  for (PetscInt k = 0; k < m; k++)
    for (PetscInt d = 0; d < 3; d++) c[d] += be->x0[3 * k + d] / info.nparticles;
  PetscCall(MPIU_Allreduce(c, csum, 3, MPIU_REAL, MPI_SUM, PetscObjectComm((PetscObject) ts)));
  for (PetscInt i = 0; i < 6; i++) {
    if (!be->nullvec[i]) PetscCall(VecDuplicate(be->DV, &be->nullvec[i]));
    PetscCall(VecGetArray(be->nullvec[i], &u[i]));
  }
  for (PetscInt k = 0; k < m; k++) {
    const PetscReal *x = be->x0 + 3 * k, r[3] = {x[0] - csum[0], x[1] - csum[1], x[2] - csum[2]}, *n = type ? normal + 3 * k : NULL;
    const PetscReal  mode[6][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, -r[2], r[1]}, {r[2], 0, -r[0]}, {-r[1], r[0], 0}};
    for (PetscInt i = 0; i < 6; i++) {
      PetscReal un = 0;
      if (be->pinned[k] || (type && type[k] == CLOTH_FIXED)) {
        u[i][3 * k] = u[i][3 * k + 1] = u[i][3 * k + 2] = 0;
        continue;
      }
      if (type && type[k] == CLOTH_SLIDE) un = n[0] * mode[i][0] + n[1] * mode[i][1] + n[2] * mode[i][2];
      for (PetscInt d = 0; d < 3; d++) u[i][3 * k + d] = mode[i][d] - (type && type[k] == CLOTH_SLIDE ? un * n[d] : 0);
    }
  }
  for (PetscInt i = 0; i < 6; i++) PetscCall(VecRestoreArray(be->nullvec[i], &u[i]));
  /* modified Gram-Schmidt; a mode the constraints removed is dropped */
  for (PetscInt i = 0; i < 6; i++) {
    PetscReal norm;
    for (PetscInt j = 0; j < nvec; j++) {
      PetscScalar dot;
      PetscCall(VecDot(be->nullvec[i], be->nullvec[j], &dot));
      PetscCall(VecAXPY(be->nullvec[i], -dot, be->nullvec[j]));
    }
    PetscCall(VecNorm(be->nullvec[i], NORM_2, &norm));
    if (norm <= 1e-10 * PetscSqrtReal((PetscReal) info.nparticles)) continue;
    PetscCall(VecScale(be->nullvec[i], 1 / norm));
    if (i != nvec) PetscCall(VecSwap(be->nullvec[i], be->nullvec[nvec]));
    nvec++;
  }
  PetscCall(MatNullSpaceCreate(PetscObjectComm((PetscObject) ts), PETSC_FALSE, nvec, be->nullvec, &nsp));
  PetscCall(MatSetNearNullSpace(be->J, nsp));
  PetscCall(MatNullSpaceDestroy(&nsp));
  PetscFunctionReturn(0);
}

/* One SNES solve for dv from 0; failure (with its reasons) recorded for the message. */
static PetscErrorCode BESolve(TS ts, TS_DrapeBE *be, PetscBool *ok)
{
  SNES                snes;
  KSP                 ksp;
  SNESConvergedReason sreason;
  KSPConvergedReason  kreason;
  PetscInt            its, lits;

  PetscFunctionBeginUser;
  PetscCall(TSGetSNES(ts, &snes));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(VecSet(be->DV, 0.0));
  PetscCall(PetscLogEventBegin(drape_log.linear_solve, 0, 0, 0, 0));
  PetscCall(SNESSolve(snes, NULL, be->DV));
  PetscCall(PetscLogEventEnd(drape_log.linear_solve, 0, 0, 0, 0));
  PetscCall(SNESGetConvergedReason(snes, &sreason));
  PetscCall(SNESGetIterationNumber(snes, &its));
  PetscCall(SNESGetLinearSolveIterations(snes, &lits));
  PetscCall(KSPGetConvergedReason(ksp, &kreason));
  ts->snes_its += its;
  ts->ksp_its += lits;
  be->nsolves++;
  be->lits       = lits;
  be->ksp_failed = (PetscBool) (kreason < 0);
  *ok            = (PetscBool) (sreason > 0 && kreason >= 0);
  if (!*ok) {
    Vec Y;
    PetscCall(PetscSNPrintf(be->failure, sizeof be->failure, "the backward-Euler solve of step %" PetscInt_FMT " (t = %g s, h = %g s) failed: SNES %s, KSP %s after %" PetscInt_FMT " linear iterations", ts->steps, (double) ts->ptime,
                            (double) ts->time_step, SNESConvergedReasons[sreason], KSPConvergedReasons[kreason], lits));
    PetscCall(SNESGetSolutionUpdate(snes, &Y)); /* a failed solve is no start for the next */
    PetscCall(VecSet(Y, 0.0));
    be->nhist = 0;
    if (sreason > 0) { /* KSP failed and SNES did not say so (newtonls can go on): fail the step */
      PetscCall(SNESSetConvergedReason(snes, SNES_DIVERGED_LINEAR_SOLVE));
    }
  }
  PetscFunctionReturn(0);
}

/* Cut the step about to be taken like a failed one: to -ts_adapt_scale_solve_failed
 * of itself, counted as a failed solve of the step before it, so that TSAdapt drape
 * grows it back as after one and waits longer each time that size fails again. */
static PetscErrorCode BECutNextStep(TS ts)
{
  PetscFunctionBeginUser;
  ts->time_step *= ts->adapt->scale_solve_failed;
  ts->num_snes_failures++; /* TSAdapt drape: a failure at the step before the cut */
  PetscCall(TSAdaptDrapeCutAfter(ts->adapt));
  PetscFunctionReturn(0);
}

/* What changes the state after a step, the projection onto the solid and the
 * self-contact filter, is no part of the step's energy check, which starts from the
 * state it leaves. At a step so large that the penalties in the solve are soft
 * against the cloth's stretch (10 m/h^2 below a 32nd of its rigidity:
 * SelfContactSolveSoft), folds pushed by the cloth behind them sink into each other
 * and the filter, pushing the pairs apart in position, stores elastic energy after
 * every step: the sphere drop at 64^2 and 1e-2 s gained 0.02-0.07 J a step that way
 * while each step of the solve lost energy, until the projection joined in and the
 * run diverged (BENCHMARKS.md). So when, after such a step, the filter (and the
 * projection before it) added more than the step's own check allows (1 % of the
 * energy scale; the caller measures it, TSDrapeBEStateChanged), the step about to
 * be taken is cut like a failed one (to -ts_adapt_scale_solve_failed of itself, and
 * counted as a failed solve for TSAdapt drape, which grows it back as after one),
 * where the penalties are stiffer against the cloth. The energy added stays. Not
 * at steps whose penalties are not soft: the filter pushes in position whatever the
 * step, and at ever smaller steps its pushes came ever more often (cut at 0.5 %,
 * the drop's steps fell to 1e-11 s). Collective (the same on every rank). */
static PetscErrorCode BECheckFilter(TS ts, TS_DrapeBE *be)
{
  PetscFunctionBeginUser;
  if (!(be->filter_added > 0.01 * (be->energy_scale + be->energy_free))) PetscFunctionReturn(0);
  if (!be->nfilter)
    PetscCall(PetscPrintf(PetscObjectComm((PetscObject) ts),
                          "note: the self-contact filter (and the projection onto the solid before it) after the step to t = %g s added %.3g J of mechanical energy (the self-contact penalties in the solve are soft against the cloth at this step); "
                          "the next step is cut to h = %g s (further cuts are counted in the summary)\n",
                          (double) ts->ptime, (double) be->filter_added, (double) (ts->time_step * ts->adapt->scale_solve_failed)));
  be->nfilter++;
  be->filter_added = 0;
  PetscCall(BECutNextStep(ts));
  PetscFunctionReturn(0);
}

/* Backward Euler with damping, inelastic contact and friction cannot add mechanical
 * energy (kinetic + gravitational + elastic); its single linearisation can, at a step
 * too large for the fabric's nonlinearity (polyester landing on a sphere at 70 x the
 * symplectic limit gains 17 J in 16 steps). A step that adds more than 1 % of the
 * energy scale (M g L plus the kinetic and elastic energy it starts with) is failed
 * like a diverged solve: TSAdapt retries it at a quarter of the step. The energy
 * at the start of a step is the last accepted trial's (the landing after it only
 * removes kinetic energy), or that of U0 after TSDrapeBEStateChanged() (the
 * self-contact filter moved particles, which can store elastic energy). */
static PetscErrorCode BECheckEnergy(TS ts, TS_DrapeBE *be, PetscBool *ok)
{
  ClothEnergies en;
  PetscReal     e, rise;

  PetscFunctionBeginUser;
  if (!*ok) PetscFunctionReturn(0);
  if (!be->have_energy) { /* the first step: the energy of U0 */
    PetscCall(ClothComputeEnergies(be->cloth, be->x0, be->v0, &en));
    be->energy      = ClothEnergyMechanical(&en);
    be->energy_free = en.kinetic + en.stretch + en.shear + en.bend; /* without gravity's */
    be->have_energy = PETSC_TRUE;
  }
  PetscCall(ClothComputeEnergies(be->cloth, be->xt, be->vt, &en));
  e    = ClothEnergyMechanical(&en);
  rise = e - be->energy;
  if (!(rise <= 0.01 * (be->energy_scale + be->energy_free))) { /* NaN fails too */
    SNES snes;
    PetscCall(TSGetSNES(ts, &snes));
    PetscCall(PetscSNPrintf(be->failure, sizeof be->failure, "the backward-Euler step %" PetscInt_FMT " (t = %g s, h = %g s) added %.3g J of mechanical energy (its single linearisation is poor at this step)", ts->steps, (double) ts->ptime,
                            (double) ts->time_step, (double) rise));
    PetscCall(SNESSetConvergedReason(snes, SNES_DIVERGED_DTOL));
    *ok = PETSC_FALSE;
    PetscFunctionReturn(0);
  }
  be->energy_trial      = e;
  be->energy_free_trial = en.kinetic + en.stretch + en.shear + en.bend;
  be->rise_trial        = rise / (be->energy_scale + be->energy_free);
  PetscFunctionReturn(0);
}

/* A step that added mechanical energy below the failure's 1 % but above
 * -drape_energy_rise (a tenth of it) is kept (rise_trial: the accepted step's, as a
 * fraction of the energy scale), and the step after it is cut like a failed one
 * (BECutNextStep). What it is for: an instability
 * that grows a step at a time under the failure's threshold. The Cusick skirt at
 * 401^2 and 1 ms slapping the pedestal's side (t = 0.166 s) gained 4e-6, 1e-5,
 * 2.5e-5, 5e-5, 1e-4, 2e-4, 3.5e-4 J in successive steps (0.005 % to 0.5 % of the
 * scale, twice as much each step) before a step failed the check at 6.5e-4 J,
 * with edges stretched 22 % by then; at 0.5 ms from the same state it lost energy
 * every step. Collective (the same on every rank). */
static PetscErrorCode BECheckRise(TS ts, TS_DrapeBE *be)
{
  PetscFunctionBeginUser;
  if (!(be->rise_cut > 0 && be->rise_trial > be->rise_cut)) PetscFunctionReturn(0);
  if (!be->nrising)
    PetscCall(PetscPrintf(PetscObjectComm((PetscObject) ts),
                          "note: the backward-Euler step to t = %g s added %.3g %% of the energy scale in mechanical energy (more than -drape_energy_rise %g %%, less than the 1 %% that fails a step); the next step is cut to h = %g s (further cuts "
                          "are counted in the summary)\n",
                          (double) ts->ptime, (double) (100 * be->rise_trial), (double) (100 * be->rise_cut), (double) (ts->time_step * ts->adapt->scale_solve_failed)));
  be->nrising++;
  PetscCall(BECutNextStep(ts));
  PetscFunctionReturn(0);
}

/* The self-contact penalties' blocks to the cloth's matrix; a new matrix (and
 * preconditioner) when a block is outside its pattern. Collective. */
static PetscErrorCode BESelfBlocks(TS ts, TS_DrapeBE *be)
{
  const PetscInt  *rows, *cols;
  const PetscReal *vals;
  PetscInt         n;
  PetscBool        fits;
  PetscMPIInt      all, mine;

  PetscFunctionBeginUser;
  PetscCall(SelfContactSolveGetBlocks(be->self, &n, &rows, &cols, &vals));
  PetscCall(ClothSetExtraBlocks(be->cloth, n, rows, cols, vals, &fits));
  mine = fits;
  PetscCallMPI(MPI_Allreduce(&mine, &all, 1, MPI_INT, MPI_MIN, PetscObjectComm((PetscObject) ts)));
  if (!all) {
    SNES      snes;
    KSP       ksp;
    PC        pc;
    Mat       J;
    PetscBool overlap;
    PetscCall(ClothCreateMatrix(be->cloth, be->mattype, &J));
    PetscCall(DrapeMatUseSBAIJProduct(J));
    PetscCall(TSGetSNES(ts, &snes));
    PetscCall(SNESGetKSP(snes, &ksp));
    PetscCall(KSPGetPC(ksp, &pc));
    PetscCall(PetscObjectTypeCompare((PetscObject) pc, PCASM, &overlap));
    if (overlap) PetscCall(PCReset(pc)); /* its overlap and submatrix are the old pattern's */
    PetscCall(SNESSetJacobian(snes, J, J, BEJacobian, be));
    PetscCall(MatDestroy(&be->J));
    be->J        = J;
    be->pc_stale = PETSC_TRUE;
  }
  PetscFunctionReturn(0);
}

/* A matrix kept from an earlier step (-drape_matrix_keep). Near rest a step moves
 * the particles by a fraction of a micrometre, the matrix A = (1 + h c) M + h^2 H
 * barely changes, and CG takes 0 or 1 iterations: assembling A (and building its
 * preconditioner) is then most of the step (the hang at 128^2 to rest: 444 of its
 * 744 steps so, 17.6 ms of assembly and 8 ms of preconditioner a step against a
 * 5 ms V-cycle; BENCHMARKS.md). So a step may solve with the matrix of an earlier
 * one at the same h, in a scene without the solid or self-contact in its solve
 * (BEStep: a refused try would leave their active sets changed), and is
 * kept only if the backward-Euler residual it leaves, R(dv) at its end (one force
 * evaluation), is within BE_KEEP_SLACK times the tolerance CG solves a fresh step
 * to (rtol times the larger of |R(0)| and |h M g|): the kept matrix adds less to
 * the step's error than the linear solve may. A fresh step's single linearisation
 * is not held to that test (its residual carries the step's nonlinearity too), so
 * a kept step is at least as well solved as a fresh one claims to be. Otherwise
 * (or if its solve fails or is slow) the step is made again from the start with a
 * new matrix, and the next try waits 1, 2, 4 ... 64 steps. Whatever matrix a step
 * solves with, its fixed points are those of R: a kept matrix changes the path to
 * rest about as much as the solve's tolerance does, and not the rest. */
#define BE_KEEP_SLACK    2.0
#define BE_KEEP_MAX_WAIT 64

/* The solves of a step at h = ts->time_step from U0 until the contact constraints
 * are consistent with the motion they allow; with keep, the one solve with the matrix
 * kept from an earlier step (BEStep). *refused: that step did not pass (its solve
 * failed or was slow, or its residual is too large) and must be made again with a
 * new matrix. *ok false: a solve failed. */
static PetscErrorCode BEStepSolves(TS ts, TS_DrapeBE *be, PetscBool keep, PetscBool *ok, PetscBool *refused)
{
  SNES snes;

  PetscFunctionBeginUser;
  *refused = PETSC_FALSE;
  PetscCall(TSGetSNES(ts, &snes));
  if (be->self) PetscCall(SelfContactSolveBegin(be->self, be->h, be->x0, be->v0));
  if (be->contact) {
    PetscInt pc_changes;
    PetscCall(ContactSolveBegin(be->contact, be->h, be->x0, be->v0, &pc_changes));
    PetscCall(BESetConstraints(be, pc_changes));
  }
  if (be->self) PetscCall(BESelfBlocks(ts, be));
  PetscCall(SNESSetLagJacobian(snes, keep ? -1 : 1)); /* -1: SNES takes the matrix it has */
  /* the matrix changes little from step to step: CG keeps the last factorisation as
   * its preconditioner for lag - 1 steps, unless contact constraints came or went
   * (the matrix itself is new every solve, so the answer is not affected) */
  for (PetscInt it = 0;; it++) {
    PetscInt  changes, self_changes = 0;
    PetscBool rebuild = PETSC_TRUE, last;
    if (keep)
      rebuild = PETSC_FALSE; /* the matrix is the preconditioner's */
    else if (be->lag > 1) {
      rebuild = (PetscBool) (be->pc_stale || (it == 0 && ts->steps % be->lag == 0));
      PetscCall(SNESSetLagPreconditioner(snes, rebuild ? 1 : -1));
      be->pc_stale = PETSC_FALSE;
    }
    if (rebuild && be->hybrid_auto && ts->steps > be->hybrid_step && be->hybrid_wait-- <= 0) { /* the V-cycle again (below), not in the step that left it */
      PetscCall(PCLatticeMGSetHybrid(be->pc, PETSC_FALSE));
      be->hybrid_auto = PETSC_FALSE;
    }
    if (rebuild) {
      PetscCall(BENearNullSpace(ts, be));
      if (be->contact) PetscCall(ContactSolveSetPreconditioned(be->contact));
    }
    PetscCall(BESolve(ts, be, ok));
    if (keep && (!*ok || (be->pc_auto && !be->pc_amg && be->lits >= BE_ICC_MAX_ITS))) {
      *refused = PETSC_TRUE;
      break;
    }
    /* the lattice multigrid's V-cycle indefinite: its hybrid cycle is not
     * (PCLatticeMGSetHybrid), the same solve again. The V-cycle's failure is its
     * smoother's, one factorisation of one stiff step's matrix: the V-cycle is
     * tried again at the preconditioner's next rebuild, and after each further
     * failure at the 2nd, 4th ... 64th rebuild after it (the hang at 128^2 to rest:
     * one failure, at step 92; kept to the end, its hybrid cycle took 5.07 CG
     * iterations a step against 4.28 with the V-cycle back) */
    if (be->ksp_failed) { /* a failure in KSP: Newton failing after solves that converged (SNES DIVERGED_LINE_SEARCH, say) is not the preconditioner's doing */
      PetscBool hybrid, allowed;
      PetscCall(PCLatticeMGGetHybrid(be->pc, &hybrid));
      PetscCall(PCLatticeMGHybridAllowed(be->pc, &allowed)); /* the lattice multigrid with its block IC smoother (not sgs: then as any failed solve, below) */
      if (!hybrid && allowed) {
        PetscCall(PCLatticeMGSetHybrid(be->pc, PETSC_TRUE));
        if (!be->hybrid_backoff) /* the first switch */
          PetscCall(PetscPrintf(PetscObjectComm((PetscObject) ts),
                                "note: at step %" PetscInt_FMT
                                " (t = %g s) CG with the lattice multigrid's V-cycle failed (%s); the run goes on with its hybrid cycle, positive definite (-pc_latticemg_hybrid), the V-cycle tried again at later rebuilds of the preconditioner\n",
                                ts->steps, (double) ts->ptime, be->failure));
        be->hybrid_auto    = PETSC_TRUE;
        be->hybrid_step    = ts->steps;
        be->hybrid_wait    = be->hybrid_backoff;
        be->hybrid_backoff = PetscMin(PetscMax(1, 2 * be->hybrid_backoff), 64);
        it--;
        continue;
      }
    }
    if (be->pc_auto && !be->pc_amg && (be->ksp_failed || be->lits >= BE_ICC_MAX_ITS)) { /* block IC (or the lattice multigrid) failed or was slow */
      PetscBool restricted;
      PetscCall(BERestrictedSchwarz(ts, &restricted));
      if (restricted) { /* first its symmetric form (BERestrictedSchwarz), the same blocks */
        it--;
        continue;
      }
      if (rebuild) {
        PetscMPIInt size;
        PetscBool   mg;
        PetscCallMPI(MPI_Comm_size(PetscObjectComm((PetscObject) ts), &size));
        PetscCall(PetscObjectTypeCompare((PetscObject) be->pc, PCLATTICEMG, &mg));
        if (!mg && size <= BE_MG_RANKS)
          PetscCall(BEUseLatticeMG(ts, be, be->lits >= BE_ICC_MAX_ITS ? "reached " PetscStringize(BE_ICC_MAX_ITS) " iterations" : "failed"));
        else
          PetscCall(BEUseMultigrid(ts, be));
      } else
        be->pc_stale = PETSC_TRUE; /* first with a fresh factorisation */
      if (be->self) PetscCall(BESelfBlocks(ts, be));
      it--;
      continue;
    }
    if (!*ok) PetscFunctionReturn(0);
    if (!keep) PetscCall(BEWatchIterations(ts, be, rebuild));                          /* the solves of fresh matrices: the block IC they measure */
    if (rebuild && be->pc_auto && !be->pc_amg && be->fill_auto && be->fill_step < 0) { /* IC(0) compensated: IC(1) from the next solve on */
      PetscBool compensated;
      PetscCall(BEICCCompensated(ts, &compensated));
      if (compensated) PetscCall(BEUseFill(ts, be));
    }
    PetscCall(TrialState(be, be->DV));
    last    = (PetscBool) ((!be->contact && !be->self) || it + 1 >= be->contact_its);
    changes = 0;
    if (be->contact && !last) { /* the solid's active set, from the forces of the solve just made */
      PetscInt pc_changes;
      PetscCall(BEAcceleration(be));
      PetscCall(ContactSolveUpdate(be->contact, be->xt, be->vt, be->at, &changes, &pc_changes));
      if (changes) PetscCall(BESetConstraints(be, pc_changes));
    }
    /* the pairs pressing in this solve are counted; their set changes only if another solve follows */
    if (be->self) PetscCall(SelfContactSolveUpdate(be->self, be->xt, (PetscBool) !last, &self_changes));
    if (last || (!changes && !self_changes)) break;
    if (be->self) PetscCall(BESelfBlocks(ts, be)); /* new pairs, or the solid's constraints filter them anew */
  }
  if (keep && !*refused) { /* the step's backward-Euler residual against the tolerance of a fresh solve */
    KSP       ksp;
    Vec       F;
    PetscReal rtol, atol, r0, r;
    PetscCall(SNESGetKSP(snes, &ksp));
    PetscCall(KSPGetTolerances(ksp, &rtol, &atol, NULL, NULL));
    PetscCall(SNESGetFunction(snes, &F, NULL, NULL)); /* R(0): the single linearisation's right-hand side */
    PetscCall(VecNorm(F, NORM_2, &r0));
    PetscCall(BEFunction(snes, be->DV, be->W, be)); /* R(dv), and the trial state at dv */
    PetscCall(VecNorm(be->W, NORM_2, &r));
    *refused = (PetscBool) !(r <= BE_KEEP_SLACK * PetscMax(rtol * r0, atol));
  }
  if (keep) {
    if (*refused) {
      be->nrefused++;
      be->keep_wait    = be->keep_backoff;
      be->keep_backoff = PetscMin(2 * be->keep_backoff, BE_KEEP_MAX_WAIT);
    } else {
      be->nkept++;
      be->keep_backoff = 1;
    }
  }
  PetscFunctionReturn(0);
}

/* The step at h = ts->time_step from U0 (BEStepSolves), with the matrix of an
 * earlier step where it passes, and its energy check. *ok false: a solve failed. */
static PetscErrorCode BEStep(TS ts, TS_DrapeBE *be, PetscBool *ok)
{
  SNES      snes;
  PetscBool refused = PETSC_FALSE, try_keep;

  PetscFunctionBeginUser;
  PetscCall(TSGetSNES(ts, &snes));
  if (be->weight > 0) {
    KSP       ksp;
    PetscReal rtol;
    PetscCall(SNESGetKSP(snes, &ksp));
    PetscCall(KSPGetTolerances(ksp, &rtol, NULL, NULL, NULL));
    PetscCall(KSPSetTolerances(ksp, rtol, rtol * be->h * be->weight, PETSC_DEFAULT, PETSC_DEFAULT));
    /* Newton (-snes_type newtonls) cannot make the residual smaller than the linear
     * solves do: it stops there too, unless -snes_atol says otherwise */
    if (!be->snes_atol_set) PetscCall(SNESSetTolerances(snes, rtol * be->h * be->weight, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT));
  }
  /* not with the solid nor self-contact in the solve: a try's active-set update
   * leaves state for the next step's start (a particle lifted or landed), which a
   * refused try must not */
  try_keep = (PetscBool) (be->keep && be->ksponly && !be->contact && !be->self && be->asm_h == be->h && !be->pc_stale);
  if (try_keep && be->keep_wait > 0) { /* a try was refused not long ago */
    be->keep_wait--;
    try_keep = PETSC_FALSE;
  }
  if (try_keep) PetscCall(BEStepSolves(ts, be, PETSC_TRUE, ok, &refused));
  if (!try_keep || refused) PetscCall(BEStepSolves(ts, be, PETSC_FALSE, ok, &refused));
  PetscCall(BECheckEnergy(ts, be, ok));
  PetscFunctionReturn(0);
}

/* The accepted step into U: x = x0 + h v_t, and the velocity v_t that the solid's
 * constraints leave (ContactSolveAccept: no velocity into the surface). */
static PetscErrorCode BEAccept(TS ts, TS_DrapeBE *be)
{
  PetscScalar *u;

  PetscFunctionBeginUser;
  PetscCall(VecGetArray(ts->vec_sol, &u));
  for (PetscInt i = 0; i < be->n; i++) u[i] = be->x0[i] + be->h * be->vt[i];
  if (be->contact) { /* after x: a landing changes the velocity, not the position */
    const ClothConstraint *type;
    PetscCall(ContactSolveGetConstraints(be->contact, &type, NULL, NULL));
    if (type) PetscCall(BEAcceleration(be)); /* the constraints' impulses */
    PetscCall(ContactSolveAccept(be->contact, be->vt, be->at));
  }
  for (PetscInt i = 0; i < be->n; i++) u[be->n + i] = be->vt[i];
  PetscCall(VecRestoreArray(ts->vec_sol, &u));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSStep_DrapeBE(TS ts)
{
  TS_DrapeBE        *be = (TS_DrapeBE *) ts->data;
  const PetscScalar *u0;
  PetscBool          ok = PETSC_FALSE, accept = PETSC_FALSE, failed;
  PetscInt           rejections = 0;

  PetscFunctionBeginUser;
  PetscCall(VecCopy(ts->vec_sol, be->U0));
  PetscCall(VecGetArrayRead(be->U0, &u0));
  be->x0 = u0;
  be->v0 = u0 + be->n;
  PetscCall(BECheckFilter(ts, be));
  PetscCall(BECheckRise(ts, be));
  while (!accept) {
    be->h = ts->time_step;
    PetscCall(TSPreStage(ts, ts->ptime + ts->time_step));
    PetscCall(BEStep(ts, be, &ok));
    /* a failed solve: TSAdapt cuts the step (scale_solve_failed), or stops the run
     * after -ts_max_snes_failures failures */
    PetscCall(TSAdaptCheckStage(ts->adapt, ts, ts->ptime + ts->time_step, ts->vec_sol, &accept));
    failed = (PetscBool) !accept;
    if (accept) { /* the solve succeeded: TSAdapt chooses the next step (drape's: growth after a failure; basic: from the local error, and may reject this one) */
      PetscInt scheme;
      PetscCall(TSAdaptChoose(ts->adapt, ts, ts->time_step, &scheme, &be->next_h, &accept));
      if (!accept) { /* too large for the tolerances: again, at the step TSAdapt chose */
        ts->time_step = be->next_h;
        be->nlte++;
      }
    }
    if (accept) break;
    ts->reject++;
    if (failed) {
      be->nrejected++;
      be->pc_stale = PETSC_TRUE; /* the failed preconditioner is no start for the smaller step */
    }
    if (!ts->reason && ts->max_reject >= 0 && ++rejections > ts->max_reject) ts->reason = TS_DIVERGED_STEP_REJECTED;
    if (ts->reason) {
      PetscCall(VecRestoreArrayRead(be->U0, &u0));
      PetscFunctionReturn(0);
    }
    if (failed && be->nrejected == 1) PetscCall(PetscPrintf(PetscObjectComm((PetscObject) ts), "note: %s; the step is retried at h = %g s (further retries are counted in the summary)\n", be->failure, (double) ts->time_step));
  }
  PetscCall(BEAccept(ts, be));
  be->energy      = be->energy_trial;
  be->energy_free = be->energy_free_trial;
  PetscCall(VecRestoreArrayRead(be->U0, &u0));
  ts->ptime += ts->time_step;
  PetscCall(TSPostStage(ts, ts->ptime, 0, &ts->vec_sol));
  ts->time_step = be->next_h; /* TSAdapt owns the step */
  PetscFunctionReturn(0);
}

/* The step's local error, for TSAdapt (-ts_adapt_type basic; -ts_atol, -ts_rtol in
 * metres): backward Euler's position x0 + h v1 against the trapezoidal rule's
 * x0 + h (v0 + v1) / 2, that is h (v1 - v0) / 2 = h^2 a / 2 + O(h^3), second order
 * in h. The particles a solid's constraint holds are left out (a landing changes
 * the velocity at once: no step would resolve it), and so are the velocities (the
 * drapes' question is where the cloth comes to rest). Collective. */
static PetscErrorCode TSEvaluateWLTE_DrapeBE(TS ts, NormType wnormtype, PetscInt *order, PetscReal *wlte)
{
  TS_DrapeBE            *be   = (TS_DrapeBE *) ts->data;
  const ClothConstraint *type = NULL;
  PetscScalar           *e;
  PetscReal              wltea, wlter;

  PetscFunctionBeginUser;
  if (!be->E) PetscCall(VecDuplicate(ts->vec_sol, &be->E));
  if (be->contact) PetscCall(ContactSolveGetConstraints(be->contact, &type, NULL, NULL));
  PetscCall(VecGetArray(be->E, &e));
  for (PetscInt i = 0; i < be->n; i++) {
    e[i]         = be->x0[i] + (type && type[i / 3] != CLOTH_FREE ? 0 : 0.5 * be->h * (be->vt[i] - be->v0[i]));
    e[be->n + i] = be->v0[i];
  }
  PetscCall(VecRestoreArray(be->E, &e));
  PetscCall(TSErrorWeightedNorm(ts, be->U0, be->E, wnormtype, wlte, &wltea, &wlter));
  *order = 2;
  PetscFunctionReturn(0);
}

static PetscErrorCode TSSetUp_DrapeBE(TS ts)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ts->data;
  SNES        snes;
  ClothInfo   info;
  TSAdapt     adapt;

  PetscFunctionBeginUser;
  PetscCall(TSDrapeBEGetCloth(ts, &be->cloth));
  PetscCheck(be->cloth, PetscObjectComm((PetscObject) ts), PETSC_ERR_ARG_WRONGSTATE, "TS type %s needs the cloth: call TSDrapeBESetCloth()", TSDRAPEBE);
  PetscCall(ClothGetInfo(be->cloth, &info));
  PetscCall(ClothGetMasses(be->cloth, &be->mass, &be->pinned));
  be->damping      = info.damping;
  be->n            = 3 * info.nowned;
  be->nparticles   = info.nparticles;
  be->g            = PetscSqrtReal(PetscSqr(info.gravity[0]) + PetscSqr(info.gravity[1]) + PetscSqr(info.gravity[2]));
  be->energy_scale = info.mass * be->g * PetscMax(info.size[0], info.size[1]);
  be->have_energy  = PETSC_FALSE;
  be->filter_added = 0;
  PetscCall(TSGetAdapt(ts, &adapt));
  PetscCall(TSAdaptDrapeSetStep(adapt, ts->time_step)); /* the step asked for: a step cut after a failure grows back to it */
  PetscCall(ClothCreateVector(be->cloth, &be->DV));
  PetscCall(VecDuplicate(be->DV, &be->R));
  PetscCall(VecDuplicate(be->DV, &be->W));
  PetscCall(VecDuplicate(ts->vec_sol, &be->U0));
  PetscCall(TSGetSNES(ts, &snes));
  {
    KSP       ksp;
    PC        pc;
    PetscBool sbaij, ksponly, preonly;
    PetscCall(SNESGetKSP(snes, &ksp));
    PetscCall(KSPGetPC(ksp, &pc));
    PetscCall(BEChoosePreconditioner(ts, be, pc));
    { /* the fill given is the fill kept */
      const char *prefix;
      PetscBool   given, sub_given;
      PetscCall(KSPGetOptionsPrefix(ksp, &prefix));
      PetscCall(PetscOptionsHasName(NULL, prefix, "-pc_blockicc_levels", &given));
      PetscCall(PetscOptionsHasName(NULL, prefix, "-sub_pc_blockicc_levels", &sub_given));
      be->fill_auto = (PetscBool) !(given || sub_given);
    }
    /* symmetric block storage (half the matrix: faster products and factorisation)
     * for the preconditioners that take it, AIJ for the others */
    PetscCall(PetscObjectTypeCompareAny((PetscObject) pc, &sbaij, PCBJACOBI, PCICC, PCBLOCKICC, PCLATTICEMG, PCCHOLESKY, PCJACOBI, PCNONE, ""));
    if (!sbaij && be->pc_auto) PetscCall(PetscObjectTypeCompare((PetscObject) pc, PCASM, &sbaij)); /* drape's overlapping blocks: block IC(0) */
    if (sbaij && be->sub_factor) sbaij = PETSC_FALSE;                                              /* block Jacobi's blocks: not with an LU or ILU of their own */
    PetscCall(PetscObjectTypeCompareAny((PetscObject) pc, &be->pc_amg, PCGAMG, PCML, PCHYPRE, PCHMG, ""));
    be->mattype = sbaij ? MATSBAIJ : MATAIJ;
    PetscCall(KSPGetTolerances(ksp, NULL, NULL, NULL, &be->max_its));
    if (be->pc_auto && !be->pc_amg) PetscCall(KSPSetTolerances(ksp, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT, PetscMin(be->max_its, BE_ICC_MAX_ITS)));
    PetscCall(ClothCreateMatrix(be->cloth, be->mattype, &be->J));
    PetscCall(DrapeMatUseSBAIJProduct(be->J));
    be->pc = pc;
    PetscCall(BELatticeMGSetLattice(be, pc)); /* when it is geometric multigrid */
    if (be->pc_auto && !be->pc_amg) {         /* -drape_mat_type chose a storage block IC(0) does not factor: PETSc's block Jacobi/ILU(0) */
      PetscBool sym;
      PetscCall(PetscObjectTypeCompareAny((PetscObject) be->J, &sym, MATSEQSBAIJ, MATMPISBAIJ, ""));
      if (!sym) {
        PetscCall(PCSetModifySubMatrices(pc, NULL, NULL));
        PetscCall(PCSetType(pc, PCBJACOBI));
      }
    }
    /* the preconditioner lags with the single linearisation and an iterative KSP; a
     * direct solve (-ksp_type preonly) may not lag its factorisation, which is then
     * the solve itself, and takes no start (PETSc refuses one) */
    PetscCall(PetscObjectTypeCompare((PetscObject) snes, SNESKSPONLY, &ksponly));
    PetscCall(PetscObjectTypeCompare((PetscObject) ksp, KSPPREONLY, &preonly));
    if (preonly) { /* one application of the preconditioner is the solve: it must be a direct one */
      PetscBool direct;
      PCType    type;
      PetscCall(PetscObjectTypeCompareAny((PetscObject) pc, &direct, PCLU, PCCHOLESKY, PCREDUNDANT, PCSVD, PCQR, ""));
      PetscCall(PCGetType(pc, &type));
      PetscCheck(direct, PetscObjectComm((PetscObject) ts), PETSC_ERR_USER_INPUT,
                 "-ksp_type preonly applies the preconditioner once instead of solving, and -pc_type %s is not a direct solver: the step would not be solved (the cloth would barely move); use -ksp_type preonly with -pc_type lu or cholesky, or an "
                 "iterative -ksp_type (cg, the default)",
                 type ? type : "(none)");
    }
    be->lag = ksponly && !preonly ? be->pc_lag : 1;
    if (preonly) PetscCall(KSPSetInitialGuessNonzero(ksp, PETSC_FALSE));
    { /* a -ksp_rtol given is the solve asked for: no looser, unless -drape_solve_error is given too */
      const char *prefix;
      PetscBool   given;
      PetscCall(KSPGetOptionsPrefix(ksp, &prefix));
      PetscCall(PetscOptionsHasName(NULL, prefix, "-ksp_rtol", &given));
      if (given && !be->solve_error_set) be->solve_error = 0;
    }
    be->ksponly = ksponly;
    { /* Newton's line search, unless -snes_linesearch_type chose one: R(dv) is the
       * gradient of the step's incremental potential, and the matrix (SPD-projected)
       * is not R's Jacobian where edges are compressed, so its direction need not
       * decrease |R|: PETSc's default, backtracking on |R|^2 (bt), failed near
       * convergence and cut the step again and again (a stiff light fabric at 0.05 s
       * crawled to t = 1 s in 38005 steps). The critical-point search (cp) finds
       * where the potential's slope along the direction, R . dv, vanishes: the SPD
       * matrix makes dv a descent direction of the potential (the same fabric: 25
       * steps). */
      const char *prefix;
      PetscBool   given, newtonls;
      PetscCall(SNESGetOptionsPrefix(snes, &prefix));
      PetscCall(PetscOptionsHasName(NULL, prefix, "-snes_linesearch_type", &given));
      PetscCall(PetscObjectTypeCompare((PetscObject) snes, SNESNEWTONLS, &newtonls));
      if (newtonls && !given) {
        SNESLineSearch ls;
        PetscCall(SNESGetLineSearch(snes, &ls));
        PetscCall(SNESLineSearchSetType(ls, SNESLINESEARCHCP));
      }
    }
    /* CG stops at rtol times the larger of |b| and the step's weight impulse |h M g|
     * (both unpreconditioned, so the test means the same whatever the
     * preconditioner): near rest b vanishes, and a test relative to it alone would
     * solve ever more exactly for an update that no longer matters. Unless the
     * options changed the norm or the absolute tolerance from drape's defaults
     * (TSCreate_DrapeBE; TSSetFromOptions has read them into the KSP and SNES). */
    {
      PetscBool set_atol, set_norm;
      PetscReal msq = 0, sum, atol;
      PetscCall(KSPGetTolerances(ksp, NULL, &atol, NULL, NULL));
      set_atol = (PetscBool) (atol != be->ksp_atol);
      set_norm = (PetscBool) (ksp->normtype != KSP_NORM_DEFAULT);
      PetscCall(SNESGetTolerances(snes, &atol, NULL, NULL, NULL, NULL));
      be->snes_atol_set = (PetscBool) (atol != be->snes_atol);
      PetscReal mmin    = PETSC_MAX_REAL;
      for (PetscInt k = 0; k < be->n / 3; k++)
        if (!be->pinned[k]) {
          msq += PetscSqr(be->mass[k]);
          mmin = PetscMin(mmin, be->mass[k]);
        }
      PetscCall(MPIU_Allreduce(&msq, &sum, 1, MPIU_REAL, MPI_SUM, PetscObjectComm((PetscObject) ts)));
      PetscCall(MPIU_Allreduce(&mmin, &be->mass_min, 1, MPIU_REAL, MPI_MIN, PetscObjectComm((PetscObject) ts)));
      be->weight = set_atol || set_norm || preonly ? 0 : PetscSqrtReal(sum) * be->g;
      if (be->weight > 0) PetscCall(KSPSetNormType(ksp, KSP_NORM_UNPRECONDITIONED));
    }
  }
  PetscCall(PetscMalloc3(be->n, &be->xt, be->n, &be->vt, be->n, &be->at));
  if (be->contact) PetscCall(ContactSolveSetUp(be->contact));
  PetscCall(SNESSetFunction(snes, be->R, BEFunction, be));
  PetscCall(SNESSetJacobian(snes, be->J, be->J, BEJacobian, be));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSReset_DrapeBE(TS ts)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ts->data;

  PetscFunctionBeginUser;
  PetscCall(VecDestroy(&be->U0));
  for (PetscInt i = 0; i < 6; i++) PetscCall(VecDestroy(&be->nullvec[i]));
  PetscCall(VecDestroy(&be->DV));
  PetscCall(VecDestroy(&be->R));
  PetscCall(VecDestroy(&be->W));
  for (PetscInt i = 0; i < BE_START_MAX - 1; i++) {
    PetscCall(VecDestroy(&be->hist[i]));
    PetscCall(VecDestroy(&be->Ahist[i]));
  }
  PetscCall(VecDestroy(&be->Ax));
  be->nhist    = 0;
  be->hist_mat = 0;
  PetscCall(MatDestroy(&be->J));
  PetscCall(VecDestroy(&be->E));
  PetscCall(PetscFree3(be->xt, be->vt, be->at));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDrapeBESetContact_DrapeBE(TS ts, ContactSolve contact)
{
  PetscFunctionBeginUser;
  ((TS_DrapeBE *) ts->data)->contact = contact;
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDrapeBESetSelfContact_DrapeBE(TS ts, SelfContact self)
{
  PetscFunctionBeginUser;
  ((TS_DrapeBE *) ts->data)->self = self;
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDrapeBEGetContactImpulse_DrapeBE(TS ts, PetscReal impulse[3])
{
  TS_DrapeBE *be = (TS_DrapeBE *) ts->data;

  PetscFunctionBeginUser;
  if (be->contact) PetscCall(ContactSolveGetImpulse(be->contact, impulse));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDrapeBEGetStatistics_DrapeBE(TS ts, PetscInt *solves, PetscInt *rejected, const char **failure)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ts->data;

  PetscFunctionBeginUser;
  if (solves) *solves = be->nsolves;
  if (rejected) *rejected = be->nrejected;
  if (failure) *failure = be->failure;
  PetscFunctionReturn(0);
}

/* The cloth rides with the TS in a container, whatever the TS's type: it is given
 * before TSSetFromOptions chooses the type, and the type's defaults follow it. */
PetscErrorCode TSDrapeBESetCloth(TS ts, Cloth cloth)
{
  PetscContainer container;

  PetscFunctionBeginUser;
  PetscCall(PetscContainerCreate(PetscObjectComm((PetscObject) ts), &container));
  PetscCall(PetscContainerSetPointer(container, cloth));
  PetscCall(PetscObjectCompose((PetscObject) ts, "TSDrapeBECloth", (PetscObject) container));
  PetscCall(PetscContainerDestroy(&container));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDrapeBESetStiffness_DrapeBE(TS ts, PetscReal omega)
{
  PetscFunctionBeginUser;
  ((TS_DrapeBE *) ts->data)->omega = omega;
  PetscFunctionReturn(0);
}

PetscErrorCode TSDrapeBESetStiffness(TS ts, PetscReal omega)
{
  PetscFunctionBeginUser;
  PetscTryMethod(ts, "TSDrapeBESetStiffness_C", (TS, PetscReal), (ts, omega));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDrapeBEStateChanged_DrapeBE(TS ts, PetscReal added)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ts->data;

  PetscFunctionBeginUser;
  be->have_energy  = PETSC_FALSE;
  be->filter_added = added;
  PetscFunctionReturn(0);
}

PetscErrorCode TSDrapeBEStateChanged(TS ts, PetscReal added)
{
  PetscFunctionBeginUser;
  PetscTryMethod(ts, "TSDrapeBEStateChanged_C", (TS, PetscReal), (ts, added));
  PetscFunctionReturn(0);
}

PetscErrorCode TSDrapeBESetContact(TS ts, ContactSolve contact)
{
  PetscFunctionBeginUser;
  PetscTryMethod(ts, "TSDrapeBESetContact_C", (TS, ContactSolve), (ts, contact));
  PetscFunctionReturn(0);
}

PetscErrorCode TSDrapeBESetSelfContact(TS ts, SelfContact self)
{
  PetscFunctionBeginUser;
  PetscTryMethod(ts, "TSDrapeBESetSelfContact_C", (TS, SelfContact), (ts, self));
  PetscFunctionReturn(0);
}

PetscErrorCode TSDrapeBEGetContactImpulse(TS ts, PetscReal impulse[3])
{
  PetscFunctionBeginUser;
  impulse[0] = impulse[1] = impulse[2] = 0;
  PetscTryMethod(ts, "TSDrapeBEGetContactImpulse_C", (TS, PetscReal *), (ts, impulse));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDrapeBEGetFillStep_DrapeBE(TS ts, PetscInt *fill_step)
{
  PetscFunctionBeginUser;
  *fill_step = ((TS_DrapeBE *) ts->data)->fill_step;
  PetscFunctionReturn(0);
}

PetscErrorCode TSDrapeBEGetFillStep(TS ts, PetscInt *fill_step)
{
  PetscFunctionBeginUser;
  *fill_step = -1;
  PetscTryMethod(ts, "TSDrapeBEGetFillStep_C", (TS, PetscInt *), (ts, fill_step));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDrapeBEGetStepHistory_DrapeBE(TS ts, PetscInt *pc_switched, PetscInt *error_rejected, PetscInt *filter_cut, PetscInt *rise_cut)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ts->data;

  PetscFunctionBeginUser;
  if (pc_switched) *pc_switched = be->pc_switched;
  if (error_rejected) *error_rejected = be->nlte;
  if (filter_cut) *filter_cut = be->nfilter;
  if (rise_cut) *rise_cut = be->nrising;
  PetscFunctionReturn(0);
}

PetscErrorCode TSDrapeBEGetStepHistory(TS ts, PetscInt *pc_switched, PetscInt *error_rejected, PetscInt *filter_cut, PetscInt *rise_cut)
{
  PetscFunctionBeginUser;
  if (pc_switched) *pc_switched = -1;
  if (error_rejected) *error_rejected = 0;
  if (filter_cut) *filter_cut = 0;
  if (rise_cut) *rise_cut = 0;
  PetscTryMethod(ts, "TSDrapeBEGetStepHistory_C", (TS, PetscInt *, PetscInt *, PetscInt *, PetscInt *), (ts, pc_switched, error_rejected, filter_cut, rise_cut));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSDrapeBEGetMatrixKept_DrapeBE(TS ts, PetscInt *kept, PetscInt *refused)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ts->data;

  PetscFunctionBeginUser;
  if (kept) *kept = be->nkept;
  if (refused) *refused = be->nrefused;
  PetscFunctionReturn(0);
}

PetscErrorCode TSDrapeBEGetMatrixKept(TS ts, PetscInt *kept, PetscInt *refused)
{
  PetscFunctionBeginUser;
  if (kept) *kept = 0;
  if (refused) *refused = 0;
  PetscTryMethod(ts, "TSDrapeBEGetMatrixKept_C", (TS, PetscInt *, PetscInt *), (ts, kept, refused));
  PetscFunctionReturn(0);
}

PetscErrorCode TSDrapeBEGetStatistics(TS ts, PetscInt *solves, PetscInt *rejected, const char **failure)
{
  PetscFunctionBeginUser;
  if (solves) *solves = 0;
  if (rejected) *rejected = 0;
  if (failure) *failure = NULL;
  PetscTryMethod(ts, "TSDrapeBEGetStatistics_C", (TS, PetscInt *, PetscInt *, const char **), (ts, solves, rejected, failure));
  PetscFunctionReturn(0);
}

/* The cloth TSDrapeBESetCloth gave the TS (NULL: none). */
static PetscErrorCode TSDrapeBEGetCloth(TS ts, Cloth *cloth)
{
  PetscContainer container;

  PetscFunctionBeginUser;
  *cloth = NULL;
  PetscCall(PetscObjectQuery((PetscObject) ts, "TSDrapeBECloth", (PetscObject *) &container));
  if (container) PetscCall(PetscContainerGetPointer(container, (void **) cloth));
  PetscFunctionReturn(0);
}

static const char *const methods[] = {"TSDrapeBESetContact_C",     "TSDrapeBESetSelfContact_C", "TSDrapeBESetStiffness_C", "TSDrapeBEGetContactImpulse_C", "TSDrapeBEGetStatistics_C",
                                      "TSDrapeBEGetStepHistory_C", "TSDrapeBEGetFillStep_C",    "TSDrapeBEStateChanged_C", "TSDrapeBEGetMatrixKept_C"};

static PetscErrorCode TSDestroy_DrapeBE(TS ts)
{
  PetscFunctionBeginUser;
  for (size_t i = 0; i < sizeof methods / sizeof methods[0]; i++) PetscCall(PetscObjectComposeFunction((PetscObject) ts, methods[i], NULL));
  PetscCall(TSReset_DrapeBE(ts));
  PetscCall(PetscFree(ts->data));
  PetscFunctionReturn(0);
}

static PetscErrorCode TSSetFromOptions_DrapeBE(TS ts, PetscOptionItems *PetscOptionsObject)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ts->data;
  PetscBool   mg_its_set;

  PetscFunctionBeginUser;
  PetscOptionsHeadBegin(PetscOptionsObject, "drape backward Euler");
  PetscCall(PetscOptionsReal("-drape_mg_its",
                             "On one rank, drape's block IC gives way to geometric multigrid on the lattice once CG takes more than this many iterations a solve (a moving mean; 0: never; not given: " PetscStringize(BE_MG_ITS) ", and " PetscStringize(
                               BE_MG_ITS_LARGE) " on a lattice of " PetscStringize(BE_MG_LARGE) " particles or more)",
                             "TSStep_DrapeBE", be->mg_its, &be->mg_its, &mg_its_set));
  PetscCall(PetscOptionsInt("-drape_pc_lag", "Rebuild the preconditioner every this many steps (with -snes_type ksponly and an iterative KSP; 1: every step)", "TSStep_DrapeBE", be->pc_lag, &be->pc_lag, NULL));
  PetscCall(PetscOptionsInt("-drape_pc_overlap",
                            "On several ranks, drape's default preconditioner factors each rank's rows grown by this many layers of the matrix's graph (restricted additive Schwarz with block IC(0)); 0: each rank's rows alone (block Jacobi)",
                            "BEChoosePreconditioner", be->pc_overlap, &be->pc_overlap, NULL));
  PetscCall(
    PetscOptionsReal("-drape_solve_error", "CG also stops once its error bound is below this fraction of the step's local error estimate (0: at -ksp_rtol alone)", "BEStartFromLastSolution", be->solve_error, &be->solve_error, &be->solve_error_set));
  PetscCall(PetscOptionsInt("-drape_start_history", "CG starts from the combination of the last this many solutions closest to the step's in the energy norm (1: the last solution, scaled; with -snes_type ksponly)", "BEStartFromLastSolution",
                            be->start_k, &be->start_k, NULL));
  PetscCall(PetscOptionsBool("-drape_matrix_keep",
                             "A step may solve with an earlier step's matrix (same step size; not with the solid or self-contact in the solve) where the backward-Euler residual it leaves passes the linear solve's tolerance (with -snes_type ksponly)",
                             "BEStep", be->keep, &be->keep, NULL));
  PetscCall(PetscOptionsInt("-drape_contact_its", "Solves per step at most to make the contact constraints consistent with the motion (1: constraints found at the start of the step only)", "TSStep_DrapeBE", be->contact_its, &be->contact_its, NULL));
  PetscCall(PetscOptionsReal("-drape_energy_rise",
                             "A step that adds more mechanical energy than this fraction of the energy scale (M g L plus the cloth's energy without gravity) is kept, and the next step is cut (0: never; 1e-2 fails the step itself)", "BECheckRise",
                             be->rise_cut, &be->rise_cut, NULL));
  {
    /* block Jacobi's blocks with a factorisation of their own need AIJ (SBAIJ has
     * only Cholesky and ICC): the matrix's type is chosen at TSSetUp, before the
     * blocks' PC exists (PCSetUp_BJacobi creates it), so its type is read here, the
     * option's value and no more (the blocks read it themselves) */
    char      sub[64] = "";
    PetscBool set;
    PetscCall(PetscOptionsString("-sub_pc_type", "Preconditioner of block Jacobi's blocks (PETSc's option; drape stores the matrix as AIJ for lu, ilu or asm)", "TSSetUp_DrapeBE", sub, sub, sizeof sub, &set));
    be->sub_factor = PETSC_FALSE;
    if (set) PetscCall(PetscStrInList(sub, "lu,ilu,asm", ',', &be->sub_factor));
  }
  PetscOptionsHeadEnd();
  PetscCall(DrapeCheckInt(PetscObjectComm((PetscObject) ts), "-drape_pc_lag", be->pc_lag, 1, 1000000));
  if (mg_its_set) PetscCall(DrapeCheckReal(PetscObjectComm((PetscObject) ts), "-drape_mg_its", 1, &be->mg_its, 0, 1e6, "iterations"));
  PetscCall(DrapeCheckInt(PetscObjectComm((PetscObject) ts), "-drape_contact_its", be->contact_its, 1, 1000));
  PetscCall(DrapeCheckInt(PetscObjectComm((PetscObject) ts), "-drape_start_history", be->start_k, 1, BE_START_MAX));
  PetscCall(DrapeCheckReal(PetscObjectComm((PetscObject) ts), "-drape_solve_error", 1, &be->solve_error, 0, 1, ""));
  PetscCall(DrapeCheckReal(PetscObjectComm((PetscObject) ts), "-drape_energy_rise", 1, &be->rise_cut, 0, 1e-2, ""));
  PetscCall(DrapeCheckInt(PetscObjectComm((PetscObject) ts), "-drape_pc_overlap", be->pc_overlap, 0, 100));
  {
    /* bending friction: the single linearisation decides at the free motion's end
     * which triples slide, and a triple that turns back within the step is pushed on
     * by the full friction moment: energy put in (a denim Cusick drape at stick
     * stiffness 20 B kept 5e-4 J of kinetic energy at 6 s). Newton minimises the
     * step's incremental potential, the friction's included: the drape comes to rest
     * (BENCHMARKS.md, "Bending hysteresis"). The default, set before TSSetFromOptions
     * reads -snes_type into the SNES (after this function). */
    Cloth     cloth;
    ClothInfo info;
    PetscCall(TSDrapeBEGetCloth(ts, &cloth));
    if (cloth) PetscCall(ClothGetInfo(cloth, &info));
    if (cloth && (info.hysteresis[0] > 0 || info.hysteresis[1] > 0)) {
      SNES snes;
      PetscCall(TSGetSNES(ts, &snes));
      PetscCall(SNESSetType(snes, SNESNEWTONLS));
    }
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode TSView_DrapeBE(TS ts, PetscViewer viewer)
{
  TS_DrapeBE *be = (TS_DrapeBE *) ts->data;
  PetscBool   isascii;

  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject) viewer, PETSCVIEWERASCII, &isascii));
  if (isascii) {
    PetscCall(PetscViewerASCIIPrintf(viewer, "  drape backward Euler: (M - h dF/dv - h^2 dF/dx) dv = h F, velocity form\n"));
    PetscCall(PetscViewerASCIIPrintf(viewer, "  %" PetscInt_FMT " solves, %" PetscInt_FMT " rejected steps\n", be->nsolves, be->nrejected));
    if (be->contact) PetscCall(ContactSolveView(be->contact, viewer));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode TSCreate_DrapeBE(TS ts)
{
  TS_DrapeBE *be;
  SNES        snes;
  KSP         ksp;
  PC          pc;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&be));
  ts->data                = (void *) be;
  ts->ops->setup          = TSSetUp_DrapeBE;
  ts->ops->step           = TSStep_DrapeBE;
  ts->ops->reset          = TSReset_DrapeBE;
  ts->ops->destroy        = TSDestroy_DrapeBE;
  ts->ops->view           = TSView_DrapeBE;
  ts->ops->setfromoptions = TSSetFromOptions_DrapeBE;
  ts->ops->evaluatewlte   = TSEvaluateWLTE_DrapeBE;
  be->pc_lag              = 5;
  be->mg_its              = -1; /* drape's choice: BE_MG_ITS, or BE_MG_ITS_LARGE on a large lattice */
  be->pc_overlap          = 2;
  be->pc_switched         = -1;
  be->lits_fresh          = -1;
  be->fill_step           = -1;
  be->rise_cut            = 1e-3;
  be->keep                = PETSC_TRUE;
  be->solve_error         = BE_SOLVE_ERROR;
  be->start_k             = BE_START_HISTORY;
  be->keep_backoff        = 1;
  be->hybrid_backoff      = 0;
  be->contact_its         = 2; /* a third solve cost 30 % more CG iterations on the stiff drop and changed the rest strain on the sphere scene by under 0.02 % (polyester 0.25 against 0.27 %, denim 3.62 % both) */
  ts->usessnes            = PETSC_TRUE;
  ts->default_adapt_type  = TSADAPTDRAPE; /* fixed steps, cut after a failed solve and grown back (adapt.c) */
  ts->max_snes_failures   = -1;           /* a failed solve is retried at a smaller step */
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSDrapeBESetContact_C", TSDrapeBESetContact_DrapeBE));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSDrapeBESetSelfContact_C", TSDrapeBESetSelfContact_DrapeBE));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSDrapeBESetStiffness_C", TSDrapeBESetStiffness_DrapeBE));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSDrapeBEGetContactImpulse_C", TSDrapeBEGetContactImpulse_DrapeBE));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSDrapeBEGetStatistics_C", TSDrapeBEGetStatistics_DrapeBE));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSDrapeBEGetStepHistory_C", TSDrapeBEGetStepHistory_DrapeBE));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSDrapeBEGetFillStep_C", TSDrapeBEGetFillStep_DrapeBE));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSDrapeBEStateChanged_C", TSDrapeBEStateChanged_DrapeBE));
  PetscCall(PetscObjectComposeFunction((PetscObject) ts, "TSDrapeBEGetMatrixKept_C", TSDrapeBEGetMatrixKept_DrapeBE));
  /* drape's defaults; -snes_type, -ksp_type, -pc_type ... override them */
  PetscCall(TSGetSNES(ts, &snes));
  PetscCall(SNESSetType(snes, SNESKSPONLY));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPSetType(ksp, KSPCG));
  PetscCall(KSPSetTolerances(ksp, 1e-4, 1e-50, PETSC_DEFAULT, 1000)); /* BENCHMARKS.md: tighter changes no error */
  /* the absolute tolerances as drape leaves them: TSSetUp_DrapeBE sets its own
   * (from the weight) unless the options changed these, or the norm type from
   * KSP_NORM_DEFAULT */
  PetscCall(KSPGetTolerances(ksp, NULL, &be->ksp_atol, NULL, NULL));
  PetscCall(SNESGetTolerances(snes, &be->snes_atol, NULL, NULL, NULL, NULL));
  /* CG starts from the last step's solution, scaled (BEStartFromLastSolution): the
   * velocity change varies slowly from step to step, and the test stays
   * |r| < rtol |b| (BENCHMARKS.md: the same error, fewer iterations) */
  PetscCall(KSPSetInitialGuessNonzero(ksp, PETSC_TRUE));
  PetscCall(KSPSetPreSolve(ksp, BEStartFromLastSolution, be));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PCSetType(pc, PCDRAPE)); /* drape chooses at TSSetUp (BEChoosePreconditioner), unless -pc_type chose */
  PetscFunctionReturn(0);
}

PetscErrorCode DrapeTSRegister(void)
{
  PetscFunctionBeginUser;
  PetscCall(TSRegister(TSDRAPEBE, TSCreate_DrapeBE));
  PetscCall(PCRegister(PCDRAPE, PCCreate_Drape));
  PetscCall(DrapeTSAdaptRegister());
  PetscCall(PCBlockICCRegister());
  PetscCall(PCLatticeMGRegister());
  PetscFunctionReturn(0);
}
