/* Private layout of the Cloth object, shared by src/cloth/ only. */
#pragma once

#include <cloth.h>
#include <partition.h>
#include "kernels.h"

/* Elements as local particle indices (owned + ghost), each with its coefficient.
 * `own` marks elements whose energy this rank counts (exactly one rank each);
 * forces are computed by every rank that owns one of the element's particles.
 * The shear list holds the lattice cells, each as its four corners in a row with
 * vertices (i,j), (i+1,j), (i,j+1), (i+1,j+1) and one class: the force loop reads
 * it cell by cell. */
#define CLOTH_ELEMENT_CLASSES 64
typedef struct {
  PetscInt       n;
  PetscInt      *p;   /* 2 (stretch) or 3 (angle: a, b, vertex c) per element */
  unsigned char *cls; /* coefficient class of each element                    */
  unsigned char *own;
  /* the few distinct (coefficient, rest length) pairs of a lattice (boundary rows
   * carry half): a byte per element instead of two doubles, a third of the memory
   * the force loop streams */
  PetscInt  nclass;
  PetscReal coef_tab[CLOTH_ELEMENT_CLASSES]; /* k, or kappa                    */
  PetscReal rest_tab[CLOTH_ELEMENT_CLASSES]; /* rest length (stretch), else 0 */
  /* bending triples whose rigidity depends on curvature (-cloth_bend_table): each
   * class's law (n = 0: linear); has_law: some class has one */
  PetscBool     has_law;
  KernelBendLaw law_tab[CLOTH_ELEMENT_CLASSES];
} ClothElements;

static inline PetscReal            ElemCoef(const ClothElements *el, PetscInt e) { return el->coef_tab[el->cls[e]]; }
static inline PetscReal            ElemRest(const ClothElements *el, PetscInt e) { return el->rest_tab[el->cls[e]]; }
static inline const KernelBendLaw *ElemLaw(const ClothElements *el, PetscInt e) { return el->has_law ? &el->law_tab[el->cls[e]] : NULL; }

/* Bending friction (-cloth_bend_hysteresis; KernelFriction): one element per warp
 * and weft triple, its five particles a, b, vertex c (as in the bending list) and
 * the crossing thread's neighbours of c, a0 and a1 (c itself for one of them at the
 * cloth's edge), with the triple's direction (0 warp, 1 weft), area and plastic
 * curvature kp: the state of the slider, the same on every rank that holds the
 * element (each updates it from the same positions after every step). */
typedef struct {
  PetscInt       n;
  PetscInt      *p; /* 5 per element */
  unsigned char *own, *dir;
  PetscReal     *area, *kp;
} ClothFrictionList;

/* Default stick stiffness of the bending friction over the bending rigidity
 * (-cloth_bend_hysteresis_stiffness; BENCHMARKS.md "Bending hysteresis"). */
#define CLOTH_HYSTERESIS_STIFFNESS 10.0

/* Plane waves of the initial sheet's out-of-plane imperfection (-cloth_imperfection):
 * w(a, b) = A sqrt(2/M) sum_m cos(k (a, b).d_m + phi_m), k = 2 pi / wavelength,
 * directions d_m stratified over [0, pi), so that the mean of w^2 over the plane is
 * exactly A^2. A function of the material point, not of the lattice: the same
 * specimen on every lattice and every partition. */
#define CLOTH_IMPERFECTION_MODES 32

typedef enum {
  CLOTH_HORIZONTAL,
  CLOTH_VERTICAL
} ClothOrientation;

typedef enum {
  CLOTH_PIN_NONE,
  CLOTH_PIN_CORNERS,
  CLOTH_PIN_EDGE_CORNERS,
  CLOTH_PIN_EDGE,
  CLOTH_PIN_LIST
} ClothPinType;

typedef enum {
  CLOTH_MODEL_DRAPE,
  CLOTH_MODEL_PAPER
} ClothModel;

typedef enum {
  CLOTH_SQUARE,
  CLOTH_CIRCLE,
  CLOTH_POLYGON
} ClothShape;

/* The lattice patch of the explicit force kernel (lattice.c). */
typedef struct _n_ClothLattice ClothLattice;

struct _p_Cloth {
  MPI_Comm comm;
  /* options */
  PetscReal        size[2], density, damping, gravity[3], origin[3];
  PetscReal        stretch[2], shear, bend[3];     /* bend: warp, weft, and the bias (a 45 deg strip) */
  ClothModel       model;                          /* drape (with the bias term) or paper            */
  PetscBool        bias_default;                   /* the bias rigidity is the default (Bw + Bf)/2, not given: fitted to the lattice */
  PetscReal        bend_coef[3];                   /* per-area rigidities of the warp and weft triples and the diagonal pair (ClothBendCoefficients) */
  char             fabric[256];                    /* named fabric the material came from, or "" */
  PetscInt         bend_nb;                        /* samples of the fabric's bending table (0: none)            */
  PetscReal        bend_dk;                        /* their curvature step (1/m)                                 */
  PetscReal        bend_b[3][KERNEL_BEND_LAW_MAX]; /* warp, weft, bias: rigidity relative to the first sample */
  PetscBool        bend_table;                     /* -cloth_bend_table: the triples' rigidity follows the table */
  PetscReal        hysteresis[2];                  /* -cloth_bend_hysteresis: KES 2HB of the warp and weft, N m/m (0: none) */
  PetscReal        hyst_stiffness;                 /* the friction's stick stiffness K over the direction's B              */
  KernelFriction   friction[2];                    /* warp and weft triples' law (area 1)                                  */
  ClothOrientation orientation;
  PetscReal        tilt; /* degrees about the warp direction, from the orientation's plane */
  ClothPinType     pin;
  ClothShape       shape;
  char             outline[PETSC_MAX_PATH_LEN]; /* polygon file (-cloth_outline)  */
  PetscInt         nring, *ring_start;          /* rings: outer boundary, holes     */
  PetscReal       *ring_xy;                     /* vertices, 2 each, all rings      */
  /* the activity of the lattice around the rank's particles (ClothIsActive computes
   * it elsewhere): columns act_i0 .. act_i0 + act_w - 1, rows act_j0 .. */
  PetscInt       act_i0, act_j0, act_w, act_h;
  unsigned char *act;
  char           partition[64];                /* -cloth_partition: dmda, metis, ptscotch, ... */
  PetscInt (*work)(void *, const PetscReal *); /* particle work at its initial position */
  void     *work_ctx;
  PetscInt *pin_list, npin_list; /* (i, j) pairs */
  PetscBool exact_hessian;       /* keep indefinite Hessians (tests only)  */
  PetscBool setup;

  PetscReal imperfection[2];                         /* -cloth_imperfection: rms amplitude, wavelength (m; 0: flat) */
  PetscInt  imperfection_seed;                       /* -cloth_imperfection_seed                                                   */
  PetscReal imperf_dir[CLOTH_IMPERFECTION_MODES][2]; /* the field's plane waves: unit directions ...                               */
  PetscReal imperf_phase[CLOTH_IMPERFECTION_MODES];  /* ... and phases                                                             */

  /* lattice */
  DM da;
  /* Xg: global, wraps caller arrays; Yl: local (owned + ghost) force; Xl: local
   * positions, only with ghosts (ClothScatterPositions); Zl: ClothSetUpImplicit */
  Vec        Xg, Xl, Yl, Zl;
  VecScatter ghost;                      /* global -> local (without ghosts: a copy); ClothSetUpGhosts */
  PetscBool  any_ghost;                  /* some rank has ghosts                               */
  VecScatter to_dmda;                    /* Cloth order -> DMDA order (NULL: the same)         */
  PetscInt  *natural;                    /* local -> natural lattice index j Mx + i            */
  PetscInt   rstart;                     /* global block number of the first owned particle    */
  PetscInt   ncut, owned_min, owned_max; /* partition quality                      */
  PetscInt   held_min, held_max;         /* particles a rank owns, the inactive too */
  PetscReal  active_total;
  PetscInt   Mx, My;
  PetscReal  spacing[2];
  PetscInt   nowned, nlocal;
  /* index maps; where two are equal they are one array (ClothDestroy frees it once):
   * owned_local is 0, 1, ... and is natural or global where those are too; global is
   * natural on one rank; row_map is col_map without ghosts */
  PetscInt     *owned_local;       /* local index of each owned particle       */
  PetscInt     *row_map, *col_map; /* local -> global block index, or -1 (pinned; row_map: ghosts); ClothSetUpImplicit */
  PetscInt     *global;            /* local -> global block index              */
  PetscReal    *mass;              /* owned particles                          */
  PetscBool    *pinned;            /* owned particles                          */
  PetscBool    *pinned_local;      /* owned + ghost; inactive particles too; ClothSetUpImplicit */
  PetscBool    *active;            /* owned: inside the cloth outline          */
  ClothElements stretch_el, shear_el, bend_el;
  PetscInt      nstretch, nshear, nbend, npinned; /* global counts            */
  PetscReal     total_mass;

  ClothFrictionList friction_el; /* bending friction; n = 0 without -cloth_bend_hysteresis */
  /* contact constraints of the implicit solve (ClothSetConstraints), local particles */
  ClothConstraint *ctype;
  PetscReal       *cnormal;     /* 3 each */
  PetscReal       *cblock;      /* owned: added to a sliding particle's diagonal block, 9 each */
  PetscBool        constrained; /* any local particle constrained */
  PetscReal       *hdiag;       /* diagonal blocks of the Hessian at the last assembly (owned, 9 each) */
  /* row-buffer assembly of the implicit matrix (forces.c): per owned block row its
   * sorted global block columns and a 3 x 3ncols row-major value buffer; per element
   * block pair the position of its (0,0) entry, or -1; rb_coo: the buffer goes to
   * rb_mat by MatSetValuesCOO (in buffer order), else by MatSetValuesBlocked rows */
  Mat        rb_mat;
  PetscBool  rb_coo, rb_csr, rb_sym;  /* rb_csr: copied into AIJ's arrays (RowBufferToAIJ) */
  PetscBool  rb_alias;                /* rb_val is the one-rank matrix's value array while it is assembled (else NULL) */
  PetscBool  rb_block;                /* blocks whole, by columns (RowBufferStrides); else scalar rows */
  PetscBool  rb_built_block;          /* rb_block when the buffer's positions were made (RowBufferGrow keeps them only so) */
  PetscInt   rb_split;                /* several ranks, (S)BAIJ: 1 if the diagonal block's pattern is the buffer's owned columns (RowBufferSplitCheck), 0 if not, -1 unknown */
  PetscInt  *rb_lo, *rb_cut, rb_ncut; /* rb_split: per row its first owned column's position; the rows with blocks outside the diagonal block */
  PetscInt  *rb_done;                 /* rb_split: per tile the assembly step that completes it */
  PetscInt  *rb_start, *rb_ncols, *rb_colstart, *rb_cols, *rb_map, *rb_diag;
  PetscReal *rb_val;
  /* rb_split: no buffer of the owned columns. rb_val is the diagonal block's value
   * array while it is assembled (its row k from rb_vstart[k]); the blocks of a cut row
   * outside it are in rb_gval from rb_gstart[k] (below the owned range, then above).
   * A position pos (rb_map, rb_diag, ex_map) is in rb_val if pos < rb_nva, else
   * pos - rb_nva in rb_gval (RowBufferAt); rb_nva = PETSC_MAX_INT otherwise. */
  PetscInt  *rb_vstart, *rb_gstart, rb_nva;
  PetscReal *rb_gval;
  /* the order of the sums (RowBufferSchedule, forces.c): rb_ntile tiles of rb_tile
   * owned rows; per kind, the first element of each chunk (rb_ntile + 1 each) and the
   * steps its chunks lag behind the tiles */
  PetscInt rb_ntile, rb_tile, *rb_chunk, rb_lag[4];
  /* blocks besides the elements' (ClothSetExtraBlocks): owned row, global block
   * column, 9 values, position in rb_val (-1: not held) */
  PetscInt   ex_n, ex_m, *ex_row, *ex_col, *ex_map;
  PetscInt   px_n, *px_row, *px_col; /* the extra blocks the row buffer's pattern holds (PatternMerge) */
  PetscReal *ex_val;

  ClothLattice *lattice; /* the explicit force kernel's patch (lattice.c); NULL: the element lists' loops */
};

/* forces.c */
static inline KernelFriction FrictionOf(Cloth c, const ClothFrictionList *fl, PetscInt e)
{
  KernelFriction f = c->friction[fl->dir[e]];
  f.area           = fl->area[e];
  return f;
}
/* The element lists of the Hessian by kind: 0 stretch edges (2 particles), 1 shear
 * corners (3), 2 bending triples (3), 3 bending friction (5). */
#define CLOTH_KINDS 4
static inline PetscInt KindSize(PetscInt kind) { return kind == 0 ? 2 : (kind == 3 ? 5 : 3); }

static inline const ClothElements *KindList(Cloth c, PetscInt kind) { return kind == 0 ? &c->stretch_el : (kind == 1 ? &c->shear_el : &c->bend_el); }

static inline PetscInt KindCount(Cloth c, PetscInt kind) { return kind == 3 ? c->friction_el.n : KindList(c, kind)->n; }

static inline const PetscInt *KindParticles(Cloth c, PetscInt kind, PetscInt e) { return kind == 3 ? c->friction_el.p + 5 * e : KindList(c, kind)->p + KindSize(kind) * e; }

/* The Gauss-Newton Hessian of friction element e (out of line: the loops over the
 * other kinds stay as small as they were). */
static __attribute__((noinline)) void FrictionHessian(Cloth c, PetscInt e, const PetscInt *p, const PetscReal *xl, PetscReal *H)
{
  const KernelFriction f = FrictionOf(c, &c->friction_el, e);
  KernelFrictionEnergy(&f, c->friction_el.kp[e], xl + 3 * p[0], xl + 3 * p[1], xl + 3 * p[2], xl + 3 * p[3], xl + 3 * p[4], NULL, H);
}

/* Hessian of element e of list `kind`; H is (3n x 3n) row-major, n = KindSize(kind).
 * The bending friction gives its Gauss-Newton part, projected or not. */
static inline void ElementHessian(Cloth c, PetscBool project, PetscInt kind, PetscInt e, const PetscReal *xl, PetscReal *H)
{
  const PetscInt *p = KindParticles(c, kind, e);

  if (kind == 3)
    FrictionHessian(c, e, p, xl, H);
  else {
    const ClothElements *el = KindList(c, kind);
    if (kind == 0)
      KernelStretch(xl + 3 * p[0], xl + 3 * p[1], ElemCoef(el, e), ElemRest(el, e), NULL, H, project);
    else
      KernelAngle(kind == 1 ? KERNEL_SHEAR : KERNEL_BEND, xl + 3 * p[0], xl + 3 * p[1], xl + 3 * p[2], ElemCoef(el, e), ElemLaw(el, e), NULL, H, project);
  }
}

/* forces.c: J += a M + b H(x) element by element, each element's whole matrix
 * through MatSetValuesBlocked (both halves): the reference the tests compare
 * ClothAssembleMatrix with (tests/unit/test_assembly.c). Collective. */
PETSC_INTERN PetscErrorCode ClothAssembleMatrixElementwise(Cloth, const PetscScalar *x, PetscReal a, PetscReal b, Mat J);

/* The local (owned + ghost) work vector Yl of the element lists' force loop and the
 * Hessian product, made at its first use (the lattice kernel needs none). Not
 * collective. */
PETSC_INTERN PetscErrorCode ClothGetLocalWork(Cloth, Vec *);
/* The ghost scatter and the local copy of the positions, at their first use
 * (ClothScatterPositions, ClothSetUpImplicit). Collective. */
PETSC_INTERN PetscErrorCode ClothSetUpGhosts(Cloth);
PETSC_INTERN PetscErrorCode ClothScatterPositions(Cloth, const PetscScalar *, const PetscScalar **);
PETSC_INTERN PetscErrorCode ClothEndScatter(Cloth, const PetscScalar **);

/* lattice.c: the explicit force kernel on the lattice patch, from the owned positions
 * x (it gathers the ghosts'): the internal force f, or the acceleration a = M^-1 F +
 * g - c v (0 on pinned particles), of the owned particles; or the symplectic update
 * in place (ClothKickDrift). Collective (the ghosts). */
PETSC_INTERN PetscErrorCode ClothLatticeSetUp(Cloth);
PETSC_INTERN PetscErrorCode ClothLatticeDestroy(Cloth);
PETSC_INTERN PetscErrorCode ClothLatticeComputeForce(Cloth, const PetscScalar *x, PetscScalar *f);
PETSC_INTERN PetscErrorCode ClothLatticeComputeAcceleration(Cloth, const PetscScalar *x, const PetscScalar *v, PetscScalar *a);
PETSC_INTERN PetscErrorCode ClothLatticeKickDrift(Cloth, PetscScalar *x, PetscScalar *v, PetscReal kick, PetscReal drift);
PETSC_INTERN PetscErrorCode ClothLatticeEnergies(Cloth, const PetscScalar *x, PetscReal energy[3], PetscReal *strain);
/* The ghosts' positions alone (3 each, local particle nowned + g at xg + 3 g), from
 * their owners, where the lattice kernel is set up (c->lattice): what a loop over the
 * element lists needs without the whole local copy of ClothScatterPositions.
 * Collective. */
PETSC_INTERN PetscErrorCode ClothLatticeGetGhosts(Cloth, const PetscScalar *x, const PetscScalar **xg);
PETSC_INTERN PetscErrorCode ClothLatticeRestoreGhosts(Cloth, const PetscScalar **xg);

/* fabrics.c: the measured fabrics of -cloth_fabric */
PETSC_INTERN PetscErrorCode ClothSetFabric(Cloth, const char *);
PETSC_INTERN PetscErrorCode ClothFabricList(char *, size_t);
