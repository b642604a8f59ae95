/* The cloth: a lattice of particles at warp/weft crossings (paper sections 2-3).
 *
 * A Cloth owns the lattice, the material, the pins, the lumped masses, the
 * partition (DMDA blocks or a graph partition, -cloth_partition: which rank owns which
 * particle), the ghost exchange and the local element lists (stretch edges, shear
 * corners, bending triples) that the physics kernels loop over. Every array handed
 * out by the functions below is in "owned-particle order": 3 entries per particle
 * owned by this rank, in natural lattice order within the rank; a DMDA (dof 3)
 * remains for natural-order I/O (ClothToDMDA, ClothFromDMDA). */
#pragma once

#include <petscdm.h>
#include <petscmat.h>

typedef struct _p_Cloth *Cloth;

/* Internal energy split by kind, plus kinetic and gravitational energy. */
typedef struct {
  PetscReal kinetic, gravity, stretch, shear, bend;
  PetscReal strain_max;       /* largest stretch of any lattice edge, (l - L)/L          */
  PetscReal contact_depth;    /* deepest penetration corrected since the last frame, m */
  PetscInt  contact_count;    /* particles in contact after the last step            */
  PetscReal contact_force[3]; /* mean force of the solid on the cloth since the last frame, N */
} ClothEnergies;

/* Mechanical energy: kinetic + gravitational + elastic (stretch, shear, bending). */
static inline PetscReal ClothEnergyMechanical(const ClothEnergies *e) { return e->kinetic + e->gravity + e->stretch + e->shear + e->bend; }

/* Summary numbers a driver prints or writes next to the results. */
typedef struct {
  PetscInt    Mx, My;                     /* lattice size (warp x weft)           */
  PetscInt    nparticles, npinned;        /* global counts                        */
  PetscInt    nactive;                    /* particles inside the cloth's outline */
  PetscInt    owned_min, owned_max, ncut; /* active particles per rank, stretch edges cut by the partition */
  PetscInt    held_min, held_max;         /* particles per rank with the inactive ones */
  const char *partition;                  /* dmda, metis, ptscotch or parmetis    */
  PetscInt    nstretch, nshear, nbend;    /* global element counts                */
  PetscInt    nowned;                     /* particles owned by this rank         */
  PetscReal   mass;                       /* total mass, kg                       */
  PetscReal   density;                    /* areal density, kg/m^2                */
  PetscReal   damping;                    /* mass-proportional damping, 1/s       */
  PetscReal   gravity[3];                 /* m/s^2                                */
  PetscReal   size[2], spacing[2];        /* cloth size and lattice spacing, m    */
  PetscReal   stretch[2], shear, bend[3]; /* continuum rigidities (see docs/model.md); bend: warp, weft, bias */
  const char *model;                      /* drape or paper                       */
  PetscBool   bend_table;                 /* rigidity varies with curvature (-cloth_bend_table) */
  PetscReal   hysteresis[2];              /* bending hysteresis 2HB warp, weft (N m/m; 0: none)  */
  PetscReal   hyst_stiffness;             /* its stick stiffness over the bending rigidity       */
  PetscReal   imperfection[2];            /* initial out-of-plane imperfection: rms amplitude, wavelength (m; 0: flat) */
  PetscInt    imperfection_seed;          /* its field's seed                                    */
} ClothInfo;

/* Create (not collective: nothing is communicated yet), read the -cloth_* and
 * -da_grid_* options and the outline file, set up (partition, layout, element
 * lists), view, destroy: Collective. */
PETSC_EXTERN PetscErrorCode ClothCreate(MPI_Comm, Cloth *);
PETSC_EXTERN PetscErrorCode ClothSetFromOptions(Cloth);
PETSC_EXTERN PetscErrorCode ClothSetUp(Cloth);
/* What the Hessian and the implicit matrix need besides the explicit force (a
 * third local work vector, the maps of local particles to matrix rows and columns,
 * the ghosts' pin flags), made once: call after ClothSetUp and before
 * ClothApplyHessian, ClothSetConstraints or ClothCreateMatrix. An explicit run
 * without the stability estimate never pays for them. Collective. */
PETSC_EXTERN PetscErrorCode ClothSetUpImplicit(Cloth);
PETSC_EXTERN PetscErrorCode ClothDestroy(Cloth *);
PETSC_EXTERN PetscErrorCode ClothView(Cloth, PetscViewer);
/* The lattice and material in numbers (global counts are set up collectively by
 * ClothSetUp). Not collective. */
PETSC_EXTERN PetscErrorCode ClothGetInfo(Cloth, ClothInfo *);
/* The lattice DMDA (dof 3), for I/O: VecView/VecLoad of its global vectors are in
 * natural lattice order; fill them with ClothToDMDA. Not collective. */
PETSC_EXTERN PetscErrorCode ClothGetDM(Cloth, DM *);
/* Natural lattice index (j Mx + i) of each owned particle. Not collective. */
PETSC_EXTERN PetscErrorCode ClothGetNatural(Cloth, const PetscInt **);
/* A vector in owned-particle order (3 entries per particle, block size 3). Collective. */
PETSC_EXTERN PetscErrorCode ClothCreateVector(Cloth, Vec *);
/* Owned-order array <-> DMDA global vector (whose VecView/VecLoad are in natural
 * order): a copy for -cloth_partition dmda, a scatter for a graph partition. Collective. */
PETSC_EXTERN PetscErrorCode ClothToDMDA(Cloth, const PetscScalar *x, Vec Xda);
PETSC_EXTERN PetscErrorCode ClothFromDMDA(Cloth, Vec Xda, PetscScalar *x);
/* Lumped particle masses and pin flags, owned-particle order (1 entry each). Not
 * collective. */
PETSC_EXTERN PetscErrorCode ClothGetMasses(Cloth, const PetscReal **, const PetscBool **);

/* Is lattice particle (i, j) part of the cloth? (-cloth_shape circle cuts the
 * lattice to a disc; the particles outside it stay where they are, take part in
 * no interaction and count in no sum.) */
PETSC_EXTERN PetscBool ClothIsActive(Cloth, PetscInt i, PetscInt j);
/* Owned-order active flags. ClothIsActive and ClothGetActive: not collective. */
PETSC_EXTERN PetscErrorCode ClothGetActive(Cloth, const PetscBool **);

/* Work of a particle, from its initial position, for a graph partition to
 * balance (e.g. contact candidates count more); call before ClothSetUp. Not
 * collective. */
PETSC_EXTERN PetscErrorCode ClothSetPartitionWeight(Cloth, PetscInt (*work)(void *, const PetscReal x[3]), void *ctx);

/* Initial state: the flat sheet at rest given by the options. Not collective. */
PETSC_EXTERN PetscErrorCode ClothSetInitialState(Cloth, PetscScalar *x, PetscScalar *v);
/* Acceleration a = F(x, v)/m with internal, gravity and damping forces; 0 at pins.
 * Collective (ghost exchange), as are the four below. */
PETSC_EXTERN PetscErrorCode ClothComputeAcceleration(Cloth, const PetscScalar *x, const PetscScalar *v, PetscScalar *a);
/* One symplectic update in place, v += kick a(x, v), then x += drift v, in one pass
 * over the cloth; *done = PETSC_FALSE (nothing changed) where the force loop cannot
 * fuse it (the element lists' loop: -cloth_force_kernel elements, bending laws or
 * friction): then compute a and update apart. Collective. */
PETSC_EXTERN PetscErrorCode ClothKickDrift(Cloth, PetscScalar *x, PetscScalar *v, PetscReal kick, PetscReal drift, PetscBool *done);
/* Internal force only (no gravity, no damping, pins not zeroed). */
PETSC_EXTERN PetscErrorCode ClothComputeInternalForce(Cloth, const PetscScalar *x, PetscScalar *f);
/* After a step that ended at x (owned-particle order): the bending friction's
 * return mapping (-cloth_bend_hysteresis; nothing without it). Collective. */
PETSC_EXTERN PetscErrorCode ClothUpdatePlasticState(Cloth, const PetscScalar *x);
/* Triples whose bending friction holds a plastic curvature (kp != 0; global count).
 * Collective. */
PETSC_EXTERN PetscErrorCode ClothGetPlasticCount(Cloth, PetscInt *n);
/* Energies of the state (x, v), summed over all ranks; the bending friction's
 * (the energy its springs store) is in bend. */
PETSC_EXTERN PetscErrorCode ClothComputeEnergies(Cloth, const PetscScalar *x, const PetscScalar *v, ClothEnergies *);
/* y = H(x) z with H the exact Hessian of the internal energy (of the bending
 * friction, its Gauss-Newton part: the stick springs); pinned rows and columns
 * removed. Matrix-free, from each element's directional derivatives: used for the
 * stability estimate. ClothApplyHessianElementwise: the same product through each
 * element's full matrix (several times slower; the reference of the tests). */
PETSC_EXTERN PetscErrorCode ClothApplyHessian(Cloth, const PetscScalar *x, const PetscScalar *z, PetscScalar *y);
PETSC_EXTERN PetscErrorCode ClothApplyHessianElementwise(Cloth, const PetscScalar *x, const PetscScalar *z, PetscScalar *y);
/* The Hessian restricted to lattice rectangles (rect: i0, i1, j0, j1 each, inclusive):
 * every element that touches a particle inside, gathered with its particles to every
 * rank in an order independent of the partition (Collective); then, on each rank
 * alone, y = H z with z and y zero at the particles outside the rectangles or pinned
 * (a principal submatrix of ClothApplyHessian's operator). */
typedef struct _p_ClothWindow *ClothWindow;
PETSC_EXTERN PetscErrorCode    ClothWindowCreate(Cloth, const PetscScalar *x, PetscInt nrect, const PetscInt rect[], ClothWindow *);
PETSC_EXTERN PetscErrorCode    ClothWindowGetParticles(ClothWindow, PetscInt *n, const PetscInt **natural, const PetscReal **mass, const PetscBool **free);
PETSC_EXTERN PetscErrorCode    ClothWindowApplyHessian(ClothWindow, const PetscScalar *z, PetscScalar *y);
PETSC_EXTERN PetscErrorCode    ClothWindowDestroy(ClothWindow *);
/* Natural index of the first particle of the stretch edge that tension stiffens most
 * (the largest k (1 + max(0, 1 - L/l))). Collective; the same on any partition. */
PETSC_EXTERN PetscErrorCode ClothStretchHotSpot(Cloth, const PetscScalar *x, PetscInt *natural);
/* A matrix of the given type (block size 3) preallocated for the pattern of a*M + b*H
 * (-drape_mat_type, -drape_mat_assembly: MatSetPreallocationCOO for AIJ, block rows
 * through MATPREALLOCATOR otherwise). Collective. */
PETSC_EXTERN PetscErrorCode ClothCreateMatrix(Cloth, MatType, Mat *);
/* J = a M + b H(x); pinned particles get m*I on the diagonal and nothing else.
 * Collective (ghost exchange, MatSetValuesCOO or MatAssembly). */
PETSC_EXTERN PetscErrorCode ClothAssembleMatrix(Cloth, const PetscScalar *x, PetscReal a, PetscReal b, Mat J);
/* The 3x3 diagonal blocks H_kk (owned particles, 9 each, row-major) of the Hessian
 * that the last ClothAssembleMatrix used, before any constraint filtered them;
 * NULL before the first assembly. */
PETSC_EXTERN PetscErrorCode ClothGetHessianDiagonal(Cloth, const PetscReal **);

/* Contact constraints of the implicit solve, one per owned particle: free, sliding
 * (only the motion along a surface of outward unit normal n is free) or fixed.
 * ClothAssembleMatrix then returns S J S + (I - S) D, with S the per-particle
 * projector onto the free directions (I, I - n n^T or 0) and D the mean diagonal of
 * the particle's unconstrained block of J (ClothGetConstraintScale), which stays
 * SPD and as well scaled as J; block (may be NULL; owned, 9 each, symmetric PSD in
 * the tangent plane) is added to a sliding particle's diagonal block (friction).
 * type == NULL removes every constraint. Collective (ghost particles learn their
 * owner's). */
typedef enum {
  CLOTH_FREE,
  CLOTH_SLIDE,
  CLOTH_FIXED
} ClothConstraint;
PETSC_EXTERN PetscErrorCode ClothSetConstraints(Cloth, const ClothConstraint type[], const PetscReal normal[], const PetscReal block[]);
/* Blocks of the implicit matrix besides the cloth's (self-contact in the solve):
 * n blocks (owned particle rows[e], global block column cols[e]; neither pinned),
 * 9 values each (row-major), added times b to J = a M + b H by the next
 * ClothAssembleMatrix (copied). *fits: PETSC_FALSE if a block is outside the
 * pattern of the matrix ClothCreateMatrix made last: make a new one, which holds
 * them. Not collective. */
PETSC_EXTERN PetscErrorCode ClothSetExtraBlocks(Cloth, PetscInt n, const PetscInt rows[], const PetscInt cols[], const PetscReal vals[], PetscBool *fits);
/* d of owned particle k for J = a M + b H at the last assembly (m before any). */
PETSC_EXTERN PetscErrorCode ClothGetConstraintScale(Cloth, PetscReal a, PetscReal b, PetscInt k, PetscReal *d);
