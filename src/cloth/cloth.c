/* The cloth lattice: options, DMDA layout, masses, pins and element lists. */
#include "clothimpl.h"
#include <petscdmda.h>

static const char *const orientation_names[] = {"horizontal", "vertical", "ClothOrientation", "CLOTH_", NULL};
static const char *const shape_names[]       = {"square", "circle", "ClothShape", "CLOTH_", NULL};
static const char *const pin_names[]         = {"none", "corners", "edge_corners", "edge", "list", "ClothPinType", "CLOTH_PIN_", NULL};

PetscErrorCode ClothCreate(MPI_Comm comm, Cloth *cloth)
{
  Cloth c;

  PetscFunctionBeginUser;
  PetscCall(PetscNew(&c));
  c->comm        = comm;
  c->size[0]     = 1.0;
  c->size[1]     = 1.0;
  c->density     = 0.15;  /* kg/m^2: a light cotton (poplin, lawn) is 0.1-0.2     */
  c->damping     = 0.2;   /* 1/s: light air drag on a 1 m cloth                     */
  c->stretch[0]  = 500.0; /* N/m: tensile rigidity per unit width at small strain   */
  c->stretch[1]  = 500.0;
  c->shear       = 30.0; /* N/m per rad: KES G ~ 0.5 gf/(cm deg)                  */
  c->bend[0]     = 5e-6; /* N m: KES B ~ 0.05 gf cm^2/cm                           */
  c->bend[1]     = 5e-6;
  c->gravity[2]  = -9.81;
  c->origin[2]   = 1.0;
  c->orientation = CLOTH_HORIZONTAL;
  c->pin         = CLOTH_PIN_NONE;
  c->Mx          = 32;
  c->My          = 32;
  *cloth         = c;
  PetscFunctionReturn(0);
}

/* Read a 1- or 2-entry option: one value means warp = weft. */
static PetscErrorCode OptionsWarpWeft(PetscOptionItems *PetscOptionsObject, const char *name, const char *text, PetscReal value[2])
{
  PetscInt  n = 2;
  PetscBool set;
  char      deflt[64];

  PetscFunctionBeginUser;
  PetscCall(PetscSNPrintf(deflt, sizeof deflt, "%g,%g", (double) value[0], (double) value[1]));
  PetscCall(PetscOptionsRealArray(name, text, deflt, value, &n, &set));
  if (set && n == 1) value[1] = value[0];
  PetscCheck(!set || n > 0, PETSC_COMM_WORLD, PETSC_ERR_USER_INPUT, "Option %s needs one value (warp = weft) or two (warp,weft)", name);
  PetscFunctionReturn(0);
}

PetscErrorCode ClothSetFromOptions(Cloth c)
{
  PetscInt          n, npin = 0, ipin = (PetscInt) c->pin, iorient = (PetscInt) c->orientation, hess = 0;
  PetscBool         set;
  const char *const hessian_names[] = {"projected", "exact", "ClothHessian", "", NULL};

  PetscFunctionBeginUser;
  PetscOptionsBegin(c->comm, NULL, "Cloth: lattice, material, pins and initial state", "Cloth");
  PetscCall(PetscOptionsInt("-da_grid_x", "Particles along the warp (lattice columns)", "ClothSetFromOptions", c->Mx, &c->Mx, NULL));
  PetscCall(PetscOptionsInt("-da_grid_y", "Particles along the weft (lattice rows)", "ClothSetFromOptions", c->My, &c->My, NULL));
  n = 2;
  PetscCall(PetscOptionsRealArray("-cloth_size", "Cloth size along warp,weft (m)", "ClothSetFromOptions", c->size, &n, &set));
  if (set && n == 1) c->size[1] = c->size[0];
  PetscCall(PetscOptionsReal("-cloth_density", "Areal density (kg/m^2)", "ClothSetFromOptions", c->density, &c->density, NULL));
  PetscCall(PetscOptionsReal("-cloth_damping", "Mass-proportional damping c, force -c m v (1/s)", "ClothSetFromOptions", c->damping, &c->damping, NULL));
  PetscCall(OptionsWarpWeft(PetscOptionsObject, "-cloth_stretch", "Tensile rigidity warp[,weft] (N/m); 0 removes the stretch energy", c->stretch));
  PetscCall(PetscOptionsReal("-cloth_shear", "In-plane shear rigidity (N/m per rad^2); 0 removes the shear energy", "ClothSetFromOptions", c->shear, &c->shear, NULL));
  PetscCall(OptionsWarpWeft(PetscOptionsObject, "-cloth_bend", "Bending rigidity warp[,weft] (N m); 0 removes the bending energy", c->bend));
  n = 3;
  PetscCall(PetscOptionsRealArray("-gravity", "Gravity vector gx,gy,gz (m/s^2)", "ClothSetFromOptions", c->gravity, &n, &set));
  PetscCheck(!set || n == 3, c->comm, PETSC_ERR_USER_INPUT, "Option -gravity needs three components gx,gy,gz; got %" PetscInt_FMT, n);
  n = 3;
  PetscCall(PetscOptionsRealArray("-cloth_center", "Centre of the initial flat sheet x,y,z (m)", "ClothSetFromOptions", c->origin, &n, &set));
  PetscCheck(!set || n == 3, c->comm, PETSC_ERR_USER_INPUT, "Option -cloth_center needs three components x,y,z; got %" PetscInt_FMT, n);
  PetscCall(PetscOptionsEList("-cloth_orientation", "Initial sheet: horizontal (warp x, weft y) or vertical (warp x, weft z)", "ClothSetFromOptions", orientation_names, 2, orientation_names[iorient], &iorient, NULL));
  {
    PetscInt ishape = (PetscInt) c->shape;
    PetscCall(PetscOptionsEList("-cloth_shape", "Cloth outline: square (the whole lattice) or circle (the disc inscribed in -cloth_size, e.g. a Cusick specimen)", "ClothSetFromOptions", shape_names, 2, shape_names[ishape], &ishape, NULL));
    c->shape = (ClothShape) ishape;
  }
  PetscCall(PetscOptionsEList("-cloth_pin", "Pinned particles: none, corners (all 4), edge_corners (two corners of the last weft row), edge (the last weft row), list", "ClothSetFromOptions", pin_names, 5, pin_names[ipin], &ipin, NULL));
  npin = 2 * 1024;
  PetscCall(PetscMalloc1(npin, &c->pin_list));
  PetscCall(PetscOptionsIntArray("-cloth_pin_list", "Pinned lattice indices i0,j0,i1,j1,... (with -cloth_pin list)", "ClothSetFromOptions", c->pin_list, &npin, &set));
  c->npin_list = set ? npin / 2 : 0;
  PetscCall(PetscOptionsEList("-cloth_hessian", "Hessian in the implicit matrix: projected (SPD, default) or exact (may be indefinite)", "ClothSetFromOptions", hessian_names, 2, hessian_names[0], &hess, NULL));
  PetscOptionsEnd();
  c->pin           = (ClothPinType) ipin;
  c->orientation   = (ClothOrientation) iorient;
  c->exact_hessian = hess == 1 ? PETSC_TRUE : PETSC_FALSE;

  PetscCheck(c->Mx >= 2 && c->My >= 2, c->comm, PETSC_ERR_USER_INPUT, "The lattice must have at least 2 x 2 particles; got -da_grid_x %" PetscInt_FMT " -da_grid_y %" PetscInt_FMT, c->Mx, c->My);
  PetscCheck(c->size[0] > 0 && c->size[1] > 0, c->comm, PETSC_ERR_USER_INPUT, "-cloth_size must be positive (metres); got %g,%g", (double) c->size[0], (double) c->size[1]);
  PetscCheck(c->density > 0, c->comm, PETSC_ERR_USER_INPUT, "-cloth_density must be positive (kg/m^2); got %g", (double) c->density);
  PetscCheck(c->damping >= 0, c->comm, PETSC_ERR_USER_INPUT, "-cloth_damping must be zero or positive (1/s); got %g", (double) c->damping);
  PetscCheck(c->stretch[0] >= 0 && c->stretch[1] >= 0 && c->shear >= 0 && c->bend[0] >= 0 && c->bend[1] >= 0, c->comm, PETSC_ERR_USER_INPUT, "Material rigidities (-cloth_stretch, -cloth_shear, -cloth_bend) must be zero or positive");
  PetscCheck(c->pin != CLOTH_PIN_LIST || c->npin_list > 0, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin list needs -cloth_pin_list i0,j0,i1,j1,...");
  PetscCheck(c->npin_list == 0 || c->pin == CLOTH_PIN_LIST, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin_list is used only with -cloth_pin list");
  PetscCheck(npin % 2 == 0, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin_list needs pairs i,j; got %" PetscInt_FMT " numbers", npin);
  for (PetscInt p = 0; p < c->npin_list; p++) {
    PetscInt i = c->pin_list[2 * p], j = c->pin_list[2 * p + 1];
    PetscCheck(i >= 0 && i < c->Mx && j >= 0 && j < c->My, c->comm, PETSC_ERR_USER_INPUT, "-cloth_pin_list entry (%" PetscInt_FMT ",%" PetscInt_FMT ") is outside the %" PetscInt_FMT " x %" PetscInt_FMT " lattice (indices start at 0)", i, j, c->Mx,
               c->My);
  }
  PetscFunctionReturn(0);
}

PetscBool ClothIsActive(Cloth c, PetscInt i, PetscInt j)
{
  PetscReal a, b, r;

  if (c->shape == CLOTH_SQUARE) return PETSC_TRUE;
  a = (i - 0.5 * (c->Mx - 1)) / (0.5 * (c->Mx - 1));
  b = (j - 0.5 * (c->My - 1)) / (0.5 * (c->My - 1));
  r = a * a + b * b;
  return (PetscBool) (r <= 1 + 1e-12);
}

PetscErrorCode ClothGetActive(Cloth c, const PetscBool **active)
{
  PetscFunctionBeginUser;
  *active = c->active;
  PetscFunctionReturn(0);
}

static PetscBool IsPinned(Cloth c, PetscInt i, PetscInt j)
{
  PetscBool last_row = (PetscBool) (j == c->My - 1), end_col = (PetscBool) (i == 0 || i == c->Mx - 1);

  switch (c->pin) {
  case CLOTH_PIN_NONE:
    return PETSC_FALSE;
  case CLOTH_PIN_CORNERS:
    return (PetscBool) (end_col && (j == 0 || last_row));
  case CLOTH_PIN_EDGE_CORNERS:
    return (PetscBool) (end_col && last_row);
  case CLOTH_PIN_EDGE:
    return last_row;
  case CLOTH_PIN_LIST:
    for (PetscInt p = 0; p < c->npin_list; p++)
      if (c->pin_list[2 * p] == i && c->pin_list[2 * p + 1] == j) return PETSC_TRUE;
  }
  return PETSC_FALSE;
}

/* Share of the lattice spacing that a boundary row/column carries (1/2). */
static inline PetscReal EdgeWeight(PetscInt i, PetscInt M) { return (i == 0 || i == M - 1) ? 0.5 : 1.0; }

static PetscErrorCode ElementsAllocate(ClothElements *el, PetscInt n, PetscInt nper, PetscBool rest)
{
  PetscFunctionBeginUser;
  el->n = 0;
  PetscCall(PetscMalloc3(nper * n + 1, &el->p, n + 1, &el->coef, n + 1, &el->own));
  el->rest = NULL;
  if (rest) PetscCall(PetscMalloc1(n + 1, &el->rest));
  PetscFunctionReturn(0);
}

static PetscErrorCode ElementsDestroy(ClothElements *el)
{
  PetscFunctionBeginUser;
  PetscCall(PetscFree3(el->p, el->coef, el->own));
  PetscCall(PetscFree(el->rest));
  PetscFunctionReturn(0);
}

/* Build the element lists over the ghosted block: every element with at least one
 * owned particle (so owned particles receive all their forces without a reverse
 * scatter), its energy counted by the owner of its first or vertex particle. */
static PetscErrorCode ClothBuildElements(Cloth c)
{
  const PetscReal dx = c->spacing[0], dy = c->spacing[1];
  PetscInt        gxs = c->gxs, gys = c->gys, gxe = c->gxs + c->gxm, gye = c->gys + c->gym, nl = c->nlocal;
  ClothElements  *st = &c->stretch_el, *sh = &c->shear_el, *be = &c->bend_el;

#define LOCAL(i, j) (((j) -gys) * c->gxm + ((i) -gxs))
#define OWNED(i, j) ((i) >= c->xs && (i) < c->xs + c->xm && (j) >= c->ys && (j) < c->ys + c->ym)
#define ACT(i, j)   ClothIsActive(c, i, j)
  PetscFunctionBeginUser;
  PetscCall(ElementsAllocate(st, 2 * nl, 2, PETSC_TRUE));
  PetscCall(ElementsAllocate(sh, 4 * nl, 3, PETSC_FALSE));
  PetscCall(ElementsAllocate(be, 2 * nl, 3, PETSC_FALSE));
  for (PetscInt j = gys; j < gye; j++) {
    for (PetscInt i = gxs; i < gxe; i++) {
      /* stretch along the warp (i) and the weft (j) */
      if (c->stretch[0] > 0 && i + 1 < gxe && (OWNED(i, j) || OWNED(i + 1, j)) && ACT(i, j) && ACT(i + 1, j)) {
        PetscInt e       = st->n++;
        st->p[2 * e]     = LOCAL(i, j);
        st->p[2 * e + 1] = LOCAL(i + 1, j);
        st->coef[e]      = c->stretch[0] * dy * EdgeWeight(j, c->My) / dx;
        st->rest[e]      = dx;
        st->own[e]       = (unsigned char) OWNED(i, j);
      }
      if (c->stretch[1] > 0 && j + 1 < gye && (OWNED(i, j) || OWNED(i, j + 1)) && ACT(i, j) && ACT(i, j + 1)) {
        PetscInt e       = st->n++;
        st->p[2 * e]     = LOCAL(i, j);
        st->p[2 * e + 1] = LOCAL(i, j + 1);
        st->coef[e]      = c->stretch[1] * dx * EdgeWeight(i, c->Mx) / dy;
        st->rest[e]      = dy;
        st->own[e]       = (unsigned char) OWNED(i, j);
      }
      /* shear: the four corners of cell (i, j) as (a: warp end, b: weft end, c: vertex) */
      if (c->shear > 0 && i + 1 < gxe && j + 1 < gye && (OWNED(i, j) || OWNED(i + 1, j) || OWNED(i, j + 1) || OWNED(i + 1, j + 1)) && ACT(i, j) && ACT(i + 1, j) && ACT(i, j + 1) && ACT(i + 1, j + 1)) {
        const PetscInt corner[4][3] = {
          {LOCAL(i + 1, j), LOCAL(i, j + 1), LOCAL(i, j)}, {LOCAL(i, j), LOCAL(i + 1, j + 1), LOCAL(i + 1, j)}, {LOCAL(i + 1, j + 1), LOCAL(i, j), LOCAL(i, j + 1)}, {LOCAL(i, j + 1), LOCAL(i + 1, j), LOCAL(i + 1, j + 1)}};
        for (PetscInt k = 0; k < 4; k++) {
          PetscInt e = sh->n++;
          for (PetscInt q = 0; q < 3; q++) sh->p[3 * e + q] = corner[k][q];
          sh->coef[e] = c->shear / 8;
          sh->own[e]  = (unsigned char) OWNED(i, j);
        }
      }
      /* bending: triples along the warp and the weft centred on (i, j) */
      if (c->bend[0] > 0 && i - 1 >= gxs && i + 1 < gxe && (OWNED(i - 1, j) || OWNED(i, j) || OWNED(i + 1, j)) && ACT(i - 1, j) && ACT(i, j) && ACT(i + 1, j)) {
        PetscInt e       = be->n++;
        be->p[3 * e]     = LOCAL(i - 1, j);
        be->p[3 * e + 1] = LOCAL(i + 1, j);
        be->p[3 * e + 2] = LOCAL(i, j);
        be->coef[e]      = c->bend[0] * dy * EdgeWeight(j, c->My) / dx;
        be->own[e]       = (unsigned char) OWNED(i, j);
      }
      if (c->bend[1] > 0 && j - 1 >= gys && j + 1 < gye && (OWNED(i, j - 1) || OWNED(i, j) || OWNED(i, j + 1)) && ACT(i, j - 1) && ACT(i, j) && ACT(i, j + 1)) {
        PetscInt e       = be->n++;
        be->p[3 * e]     = LOCAL(i, j - 1);
        be->p[3 * e + 1] = LOCAL(i, j + 1);
        be->p[3 * e + 2] = LOCAL(i, j);
        be->coef[e]      = c->bend[1] * dx * EdgeWeight(i, c->Mx) / dy;
        be->own[e]       = (unsigned char) OWNED(i, j);
      }
    }
  }
#undef LOCAL
#undef OWNED
#undef ACT
  PetscFunctionReturn(0);
}

static PetscInt CountOwned(const ClothElements *el, PetscInt per)
{
  PetscInt n = 0;
  for (PetscInt e = 0; e < el->n; e++) n += el->own[e];
  return n / per;
}

PetscErrorCode ClothSetUp(Cloth c)
{
  const PetscInt        *gidx;
  ISLocalToGlobalMapping ltog;
  PetscInt               k, counts[4], sums[4];
  PetscReal              mass;

  PetscFunctionBeginUser;
  if (c->setup) PetscFunctionReturn(0);
  PetscCall(DMDACreate2d(c->comm, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DMDA_STENCIL_BOX, c->Mx, c->My, PETSC_DECIDE, PETSC_DECIDE, 3, 2, NULL, NULL, &c->da));
  PetscCall(DMSetFromOptions(c->da));
  PetscCall(DMSetUp(c->da));
  PetscCall(DMDASetFieldName(c->da, 0, "x"));
  PetscCall(DMDASetFieldName(c->da, 1, "y"));
  PetscCall(DMDASetFieldName(c->da, 2, "z"));
  PetscCall(DMDAGetInfo(c->da, NULL, &c->Mx, &c->My, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
  PetscCall(DMDAGetCorners(c->da, &c->xs, &c->ys, NULL, &c->xm, &c->ym, NULL));
  PetscCall(DMDAGetGhostCorners(c->da, &c->gxs, &c->gys, NULL, &c->gxm, &c->gym, NULL));
  c->spacing[0] = c->size[0] / (c->Mx - 1);
  c->spacing[1] = c->size[1] / (c->My - 1);
  c->nowned     = c->xm * c->ym;
  c->nlocal     = c->gxm * c->gym;
  PetscCall(DMCreateGlobalVector(c->da, &c->Xg));
  PetscCall(DMCreateLocalVector(c->da, &c->Xl));
  PetscCall(VecDuplicate(c->Xl, &c->Yl));
  PetscCall(VecReplaceArray(c->Xg, NULL)); /* the global vector only ever wraps caller arrays */

  PetscCall(DMGetLocalToGlobalMapping(c->da, &ltog));
  PetscCall(ISLocalToGlobalMappingGetBlockIndices(ltog, &gidx));
  PetscCall(PetscMalloc4(c->nowned, &c->owned_local, c->nowned, &c->mass, c->nowned, &c->pinned, c->nowned, &c->active));
  PetscCall(PetscMalloc4(c->nlocal, &c->row_map, c->nlocal, &c->col_map, c->nlocal, &c->pinned_local, c->nlocal, &c->global));
  for (PetscInt j = c->gys; j < c->gys + c->gym; j++) {
    for (PetscInt i = c->gxs; i < c->gxs + c->gxm; i++) {
      PetscInt  l        = (j - c->gys) * c->gxm + (i - c->gxs);
      PetscBool owned    = (PetscBool) (i >= c->xs && i < c->xs + c->xm && j >= c->ys && j < c->ys + c->ym);
      c->pinned_local[l] = (PetscBool) (IsPinned(c, i, j) || !ClothIsActive(c, i, j));
      c->global[l]       = gidx[l];
      c->col_map[l]      = c->pinned_local[l] ? -1 : gidx[l];
      c->row_map[l]      = owned ? c->col_map[l] : -1;
    }
  }
  PetscCall(ISLocalToGlobalMappingRestoreBlockIndices(ltog, &gidx));
  k    = 0;
  mass = 0;
  for (PetscInt j = c->ys; j < c->ys + c->ym; j++) {
    for (PetscInt i = c->xs; i < c->xs + c->xm; i++, k++) {
      PetscInt l        = (j - c->gys) * c->gxm + (i - c->gxs);
      c->owned_local[k] = l;
      c->mass[k]        = c->density * c->spacing[0] * c->spacing[1] * EdgeWeight(i, c->Mx) * EdgeWeight(j, c->My);
      c->pinned[k]      = c->pinned_local[l];
      c->active[k]      = ClothIsActive(c, i, j);
      if (c->active[k]) mass += c->mass[k];
    }
  }
  PetscCall(ClothBuildElements(c));
  counts[0] = CountOwned(&c->stretch_el, 1);
  counts[1] = CountOwned(&c->shear_el, 4);
  counts[2] = CountOwned(&c->bend_el, 1);
  counts[3] = 0;
  for (k = 0; k < c->nowned; k++) counts[3] += c->pinned[k] && c->active[k];
  PetscCall(MPIU_Allreduce(counts, sums, 4, MPIU_INT, MPI_SUM, c->comm));
  PetscCall(MPIU_Allreduce(&mass, &c->total_mass, 1, MPIU_REAL, MPI_SUM, c->comm));
  c->nstretch = sums[0];
  c->nshear   = sums[1];
  c->nbend    = sums[2];
  c->npinned  = sums[3];
  c->setup    = PETSC_TRUE;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothDestroy(Cloth *cloth)
{
  Cloth c = *cloth;

  PetscFunctionBeginUser;
  if (!c) PetscFunctionReturn(0);
  PetscCall(PetscFree(c->pin_list));
  if (c->setup) {
    PetscCall(ElementsDestroy(&c->stretch_el));
    PetscCall(ElementsDestroy(&c->shear_el));
    PetscCall(ElementsDestroy(&c->bend_el));
    PetscCall(PetscFree4(c->owned_local, c->mass, c->pinned, c->active));
    PetscCall(PetscFree4(c->row_map, c->col_map, c->pinned_local, c->global));
    PetscCall(PetscFree4(c->ctype, c->ctype_owned, c->cnormal, c->cnormal_owned));
    PetscCall(PetscFree(c->map));
    PetscCall(PetscFree(c->map_diag));
  }
  PetscCall(VecDestroy(&c->Xg));
  PetscCall(VecDestroy(&c->Xl));
  PetscCall(VecDestroy(&c->Yl));
  PetscCall(DMDestroy(&c->da));
  PetscCall(PetscFree(*cloth));
  PetscFunctionReturn(0);
}

PetscErrorCode ClothGetInfo(Cloth c, ClothInfo *info)
{
  PetscFunctionBeginUser;
  info->Mx         = c->Mx;
  info->My         = c->My;
  info->nparticles = c->Mx * c->My;
  info->npinned    = c->npinned;
  info->nstretch   = c->nstretch;
  info->nshear     = c->nshear;
  info->nbend      = c->nbend;
  info->nowned     = c->nowned;
  info->mass       = c->total_mass;
  info->damping    = c->damping;
  info->shear      = c->shear;
  for (PetscInt d = 0; d < 3; d++) info->gravity[d] = c->gravity[d];
  for (PetscInt d = 0; d < 2; d++) {
    info->size[d]    = c->size[d];
    info->spacing[d] = c->spacing[d];
    info->stretch[d] = c->stretch[d];
    info->bend[d]    = c->bend[d];
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ClothGetDM(Cloth c, DM *da)
{
  PetscFunctionBeginUser;
  *da = c->da;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothGetMasses(Cloth c, const PetscReal **mass, const PetscBool **pinned)
{
  PetscFunctionBeginUser;
  if (mass) *mass = c->mass;
  if (pinned) *pinned = c->pinned;
  PetscFunctionReturn(0);
}

PetscErrorCode ClothSetInitialState(Cloth c, PetscScalar *x, PetscScalar *v)
{
  PetscInt k = 0;

  PetscFunctionBeginUser;
  for (PetscInt j = c->ys; j < c->ys + c->ym; j++) {
    for (PetscInt i = c->xs; i < c->xs + c->xm; i++, k++) {
      PetscReal a = i * c->spacing[0] - 0.5 * c->size[0], b = j * c->spacing[1] - 0.5 * c->size[1];
      x[3 * k]     = c->origin[0] + a;
      x[3 * k + 1] = c->origin[1] + (c->orientation == CLOTH_HORIZONTAL ? b : 0);
      x[3 * k + 2] = c->origin[2] + (c->orientation == CLOTH_HORIZONTAL ? 0 : b);
      for (PetscInt d = 0; d < 3; d++) v[3 * k + d] = 0;
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ClothView(Cloth c, PetscViewer viewer)
{
  PetscFunctionBeginUser;
  PetscCall(PetscViewerASCIIPrintf(viewer, "Cloth: %" PetscInt_FMT " x %" PetscInt_FMT " particles (%g x %g m, spacing %g x %g m), %" PetscInt_FMT " pinned, mass %g kg\n", c->Mx, c->My, (double) c->size[0], (double) c->size[1],
                                   (double) c->spacing[0], (double) c->spacing[1], c->npinned, (double) c->total_mass));
  PetscCall(PetscViewerASCIIPrintf(viewer, "  interactions: %" PetscInt_FMT " stretch edges, %" PetscInt_FMT " shear cells, %" PetscInt_FMT " bending triples\n", c->nstretch, c->nshear, c->nbend));
  PetscCall(PetscViewerASCIIPrintf(viewer, "  material: stretch %g,%g N/m, shear %g N/m, bend %g,%g N m, density %g kg/m^2, damping %g 1/s\n", (double) c->stretch[0], (double) c->stretch[1], (double) c->shear, (double) c->bend[0],
                                   (double) c->bend[1], (double) c->density, (double) c->damping));
  PetscCall(PetscViewerASCIIPrintf(viewer, "  gravity (%g, %g, %g) m/s^2, Hessian %s\n", (double) c->gravity[0], (double) c->gravity[1], (double) c->gravity[2], c->exact_hessian ? "exact" : "SPD-projected"));
  PetscFunctionReturn(0);
}
