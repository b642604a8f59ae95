/* The Cusick drape test: silhouette area, drape coefficient, number of folds. */
#include <analysis.h>
#include <drape.h>
#include <petscdmda.h>

struct _p_Cusick {
  MPI_Comm     comm;
  PetscReal    radius, center[2]; /* the pedestal; radius 0: no analysis */
  PetscBool    center_set;
  PetscScalar *x0; /* the flat specimen, owned order */
};

/* Mark the pixels whose centres lie in one of ntri triangles (xy: 6 reals each) in
 * cover (npixels x npixels, half-width extent around c); a pixel once covered stays
 * so, whichever triangle or rank covers it. */
static void SilhouetteCover(PetscInt ntri, const PetscReal *xy, const PetscReal c[2], PetscReal extent, PetscInt npixels, unsigned char *cover)
{
  const PetscReal px = 2 * extent / npixels, x0 = c[0] - extent, y0 = c[1] - extent;

  for (PetscInt t = 0; t < ntri; t++) {
    const PetscReal *p     = xy + 6 * t;
    PetscReal        lo[2] = {PetscMin(p[0], PetscMin(p[2], p[4])), PetscMin(p[1], PetscMin(p[3], p[5]))};
    PetscReal        hi[2] = {PetscMax(p[0], PetscMax(p[2], p[4])), PetscMax(p[1], PetscMax(p[3], p[5]))};
    PetscReal        det   = (p[2] - p[0]) * (p[5] - p[1]) - (p[4] - p[0]) * (p[3] - p[1]);
    PetscInt         i0 = PetscMax(0, (PetscInt) PetscFloorReal((lo[0] - x0) / px)), i1 = PetscMin(npixels - 1, (PetscInt) PetscFloorReal((hi[0] - x0) / px));
    PetscInt         j0 = PetscMax(0, (PetscInt) PetscFloorReal((lo[1] - y0) / px)), j1 = PetscMin(npixels - 1, (PetscInt) PetscFloorReal((hi[1] - y0) / px));
    if (det == 0) continue;
    for (PetscInt j = j0; j <= j1; j++) {
      for (PetscInt i = i0; i <= i1; i++) {
        /* pixel centre inside the triangle (barycentric coordinates) */
        PetscReal qx = x0 + (i + 0.5) * px, qy = y0 + (j + 0.5) * px;
        PetscReal l1 = ((p[2] - qx) * (p[5] - qy) - (p[4] - qx) * (p[3] - qy)) / det;
        PetscReal l2 = ((p[4] - qx) * (p[1] - qy) - (p[0] - qx) * (p[5] - qy)) / det;
        if (l1 >= 0 && l2 >= 0 && l1 + l2 <= 1) cover[j * npixels + i] = 1;
      }
    }
  }
}

/* The covered area and each angle bin's largest covered radius, from cover. */
static void SilhouetteMeasure(const unsigned char *cover, const PetscReal c[2], PetscReal extent, PetscInt npixels, PetscReal *area, PetscInt nbins, PetscReal *radius)
{
  const PetscReal px = 2 * extent / npixels, x0 = c[0] - extent, y0 = c[1] - extent;
  PetscInt        count = 0;

  for (PetscInt b = 0; b < nbins; b++) radius[b] = 0;
  for (PetscInt j = 0; j < npixels; j++) {
    for (PetscInt i = 0; i < npixels; i++) {
      PetscReal qx, qy, r, th;
      PetscInt  b;
      if (!cover[j * npixels + i]) continue;
      count++;
      qx        = x0 + (i + 0.5) * px - c[0];
      qy        = y0 + (j + 0.5) * px - c[1];
      r         = PetscSqrtReal(qx * qx + qy * qy);
      th        = PetscAtan2Real(qy, qx) + PETSC_PI;
      b         = PetscMin(nbins - 1, (PetscInt) (th / (2 * PETSC_PI) * nbins));
      radius[b] = PetscMax(radius[b], r);
    }
  }
  *area = count * px * px;
}

PetscErrorCode CusickSilhouette(PetscInt ntri, const PetscReal *xy, const PetscReal c[2], PetscReal extent, PetscInt npixels, PetscReal *area, PetscInt nbins, PetscReal *radius)
{
  unsigned char *cover;

  PetscFunctionBeginUser;
  PetscCall(PetscCalloc1(npixels * npixels, &cover));
  SilhouetteCover(ntri, xy, c, extent, npixels, cover);
  SilhouetteMeasure(cover, c, extent, npixels, area, nbins, radius);
  PetscCall(PetscFree(cover));
  PetscFunctionReturn(0);
}

PetscErrorCode CusickCountFolds(PetscInt nbins, const PetscReal *radius, PetscReal prominence, PetscInt *folds)
{
  PetscReal *r;
  PetscInt   w = PetscMax(1, nbins / 120), start = 0, n = 0;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc1(nbins, &r));
  /* circular moving average over 2w + 1 bins */
  for (PetscInt b = 0; b < nbins; b++) {
    PetscReal s = 0;
    for (PetscInt k = -w; k <= w; k++) s += radius[(b + k + nbins) % nbins];
    r[b] = s / (2 * w + 1);
  }
  /* walk around the circle from the global minimum; count a fold at each peak
   * that rises `prominence` above the last valley and falls as much after it */
  for (PetscInt b = 1; b < nbins; b++)
    if (r[b] < r[start]) start = b;
  {
    PetscReal valley = r[start], peak = r[start];
    PetscBool rising = PETSC_TRUE;
    for (PetscInt k = 1; k <= nbins; k++) {
      PetscReal v = r[(start + k) % nbins];
      if (rising) {
        if (v > peak)
          peak = v;
        else if (peak - v >= prominence && peak - valley >= prominence) {
          n++;
          rising = PETSC_FALSE;
          valley = v;
        }
      } else {
        if (v < valley)
          valley = v;
        else if (v - valley >= prominence) {
          rising = PETSC_TRUE;
          peak   = v;
        }
      }
    }
  }
  *folds = n;
  PetscCall(PetscFree(r));
  PetscFunctionReturn(0);
}

/* The raster of the silhouette: CUSICK_PIXELS x CUSICK_PIXELS pixels over a square
 * of 1.2 times the specimen's diagonal, CUSICK_BINS angle bins for the folds; its
 * size does not depend on the lattice. */
#define CUSICK_PIXELS 1200
#define CUSICK_BINS   720

/* Each rank rasterises the projected triangles of the active lattice cells whose
 * first corner (i, j) lies in its DMDA block (the other three corners are in the
 * block or in its ghost layer of one: a DMDA of the lattice's ownership with stencil
 * width 1), the ranks' rasters are OR-ed onto rank 0, which measures the area and
 * the radius profile. The union of the same triangles' pixels as the whole
 * lattice's on one rank: the same DC and folds, to the bit, on any ranks and
 * partition; each rank holds its block, its ghost layer and the raster (1.4 MB),
 * no array of the whole lattice. */
PetscErrorCode CusickAnalyse(Cloth cloth, const PetscScalar *x, const PetscScalar *x0, PetscReal pedestal_radius, const PetscReal c[2], PetscReal *dc, PetscInt *folds)
{
  DM              da, dag;
  Vec             G, L;
  ClothInfo       info;
  MPI_Comm        comm;
  PetscMPIInt     rank;
  PetscInt        m, n, xs, ys, xm, ym;
  const PetscInt *lx, *ly;
  PetscReal       result[2] = {0, 0}, *xy, extent;
  unsigned char  *cover, *all = NULL;

  PetscFunctionBeginUser;
  PetscCall(ClothGetDM(cloth, &da));
  PetscCall(ClothGetInfo(cloth, &info));
  comm = PetscObjectComm((PetscObject) da);
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  extent = 0.6 * PetscSqrtReal(PetscSqr(info.size[0]) + PetscSqr(info.size[1]));
  PetscCall(DMDAGetInfo(da, NULL, NULL, NULL, NULL, &m, &n, NULL, NULL, NULL, NULL, NULL, NULL, NULL));
  PetscCall(DMDAGetOwnershipRanges(da, &lx, &ly, NULL));
  PetscCall(DMDACreate2d(comm, DM_BOUNDARY_NONE, DM_BOUNDARY_NONE, DMDA_STENCIL_BOX, info.Mx, info.My, m, n, 3, 1, lx, ly, &dag));
  PetscCall(DMSetUp(dag));
  PetscCall(DMDAGetCorners(dag, &xs, &ys, NULL, &xm, &ym, NULL));
  PetscCall(DMGetGlobalVector(dag, &G));
  PetscCall(DMGetLocalVector(dag, &L));
  PetscCall(PetscMalloc1(12 * xm + 1, &xy));
  PetscCall(PetscMalloc1(CUSICK_PIXELS * CUSICK_PIXELS, &cover));
  if (!rank) PetscCall(PetscMalloc1(CUSICK_PIXELS * CUSICK_PIXELS, &all));
  for (PetscInt pass = 0; pass < 2; pass++) {
    const PetscScalar ***X;
    PetscCall(ClothToDMDA(cloth, pass ? x : x0, G)); /* the same layout as the Cloth's DMDA */
    PetscCall(DMGlobalToLocalBegin(dag, G, INSERT_VALUES, L));
    PetscCall(DMGlobalToLocalEnd(dag, G, INSERT_VALUES, L));
    PetscCall(DMDAVecGetArrayDOFRead(dag, L, &X));
    PetscCall(PetscArrayzero(cover, CUSICK_PIXELS * CUSICK_PIXELS));
    for (PetscInt j = ys; j < ys + ym && j + 1 < info.My; j++) { /* a row of cells at a time */
      PetscInt ntri = 0;
      for (PetscInt i = xs; i < xs + xm && i + 1 < info.Mx; i++) {
        const PetscInt q[4][2] = {{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}};
        if (!(ClothIsActive(cloth, i, j) && ClothIsActive(cloth, i + 1, j) && ClothIsActive(cloth, i + 1, j + 1) && ClothIsActive(cloth, i, j + 1))) continue;
        for (PetscInt t = 0; t < 2; t++) {
          const PetscInt v[3] = {0, 1 + t, 2 + t};
          for (PetscInt k = 0; k < 3; k++) {
            xy[6 * ntri + 2 * k]     = PetscRealPart(X[q[v[k]][1]][q[v[k]][0]][0]);
            xy[6 * ntri + 2 * k + 1] = PetscRealPart(X[q[v[k]][1]][q[v[k]][0]][1]);
          }
          ntri++;
        }
      }
      SilhouetteCover(ntri, xy, c, extent, CUSICK_PIXELS, cover);
    }
    PetscCall(DMDAVecRestoreArrayDOFRead(dag, L, &X));
    PetscCallMPI(MPI_Reduce(cover, all, CUSICK_PIXELS * CUSICK_PIXELS, MPI_UNSIGNED_CHAR, MPI_BOR, 0, comm));
    if (!rank) {
      PetscReal area, radius[CUSICK_BINS];
      SilhouetteMeasure(all, c, extent, CUSICK_PIXELS, &area, CUSICK_BINS, radius);
      if (!pass)
        result[0] = area; /* the flat specimen */
      else {
        PetscReal disc = PETSC_PI * pedestal_radius * pedestal_radius;
        PetscInt  nf   = 0;
        result[0]      = (area - disc) / (result[0] - disc);
        /* a fold must stand out of the lattice's own staircase outline and be a
         * tenth of the overhang deep */
        PetscCall(CusickCountFolds(CUSICK_BINS, radius, PetscMax(0.1 * (0.5 * PetscMin(info.size[0], info.size[1]) - pedestal_radius), 1.5 * PetscMax(info.spacing[0], info.spacing[1])), &nf));
        result[1] = nf;
      }
    }
  }
  PetscCallMPI(MPI_Bcast(result, 2, MPIU_REAL, 0, comm));
  *dc    = result[0];
  *folds = (PetscInt) result[1];
  PetscCall(PetscFree(all));
  PetscCall(PetscFree(cover));
  PetscCall(PetscFree(xy));
  PetscCall(DMRestoreLocalVector(dag, &L));
  PetscCall(DMRestoreGlobalVector(dag, &G));
  PetscCall(DMDestroy(&dag));
  PetscFunctionReturn(0);
}

PetscErrorCode CusickCreate(MPI_Comm comm, Cusick *cusick)
{
  PetscFunctionBeginUser;
  PetscCall(PetscNew(cusick));
  (*cusick)->comm = comm;
  PetscFunctionReturn(0);
}

PetscErrorCode CusickDestroy(Cusick *cusick)
{
  PetscFunctionBeginUser;
  if (!*cusick) PetscFunctionReturn(0);
  PetscCall(PetscFree((*cusick)->x0));
  PetscCall(PetscFree(*cusick));
  PetscFunctionReturn(0);
}

PetscErrorCode CusickSetFromOptions(Cusick c)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(c->comm, NULL, "Cusick drape test", "Cusick");
  PetscCall(PetscOptionsReal("-cusick_pedestal_radius", "Cusick drape test: pedestal radius (m); > 0 reports the drape coefficient and folds at the end", "CusickAnalyse", c->radius, &c->radius, NULL));
  {
    /* room for a third value: PETSc reads at most n and drops the rest without a word */
    PetscReal center[3] = {c->center[0], c->center[1], 0};
    PetscInt  n         = 3;
    PetscBool set;
    PetscCall(PetscOptionsRealArray("-cusick_center", "Cusick drape test: pedestal centre x,y (m)", "CusickAnalyse", center, &n, &set));
    PetscCheck(!set || n == 2, c->comm, PETSC_ERR_USER_INPUT, "-cusick_center needs two coordinates x,y; got %" PetscInt_FMT, n);
    c->center[0]  = center[0];
    c->center[1]  = center[1];
    c->center_set = set;
  }
  PetscOptionsEnd();
  PetscCall(DrapeCheckReal(c->comm, "-cusick_pedestal_radius", 1, &c->radius, 0, 1e3, "m (0: no analysis)"));
  {
    char got[32];
    PetscCheck(c->radius == 0 || c->radius >= 1e-3, c->comm, PETSC_ERR_USER_INPUT, "-cusick_pedestal_radius must be 0 (no analysis) or from 0.001 to 1000 m; got %s", DrapeFormatReal(c->radius, got, sizeof got));
  }
  PetscCall(DrapeCheckReal(c->comm, "-cusick_center", 2, c->center, -1e4, 1e4, "m"));
  PetscCheck(!c->center_set || c->radius > 0, c->comm, PETSC_ERR_USER_INPUT, "-cusick_center does not apply to this run: there is no Cusick analysis (add -cusick_pedestal_radius)");
  PetscFunctionReturn(0);
}

PetscErrorCode CusickEnabled(Cusick c, PetscBool *enabled)
{
  PetscFunctionBeginUser;
  *enabled = (PetscBool) (c->radius > 0);
  PetscFunctionReturn(0);
}

PetscErrorCode CusickSetUp(Cusick c, Cloth cloth, Solid solid, const PetscScalar *u)
{
  PetscReal        box[5] = {-PETSC_MAX_REAL, -PETSC_MAX_REAL, -PETSC_MAX_REAL, -PETSC_MAX_REAL, -PETSC_MAX_REAL}; /* -xmin, -ymin, xmax, ymax, -zmin of the flat specimen */
  const PetscBool *active;
  ClothInfo        info;

  PetscFunctionBeginUser;
  if (c->radius <= 0) PetscFunctionReturn(0);
  PetscCall(ClothGetInfo(cloth, &info));
  PetscCheck(2 * c->radius < PetscMin(info.size[0], info.size[1]), c->comm, PETSC_ERR_USER_INPUT, "-cusick_pedestal_radius %g m leaves no overhang on a %g x %g m specimen: the pedestal must be smaller than the specimen", (double) c->radius,
             (double) info.size[0], (double) info.size[1]);
  PetscCall(ClothGetActive(cloth, &active));
  for (PetscInt k = 0; k < info.nowned; k++)
    for (PetscInt d = 0; d < 2 && active[k]; d++) {
      box[d]     = PetscMax(box[d], -PetscRealPart(u[3 * k + d]));
      box[2 + d] = PetscMax(box[2 + d], PetscRealPart(u[3 * k + d]));
      if (!d) box[4] = PetscMax(box[4], -PetscRealPart(u[3 * k + 2]));
    }
  PetscCall(MPIU_Allreduce(MPI_IN_PLACE, box, 5, MPIU_REAL, MPIU_MAX, c->comm));
  PetscCheck(c->center[0] - c->radius > -box[0] && c->center[0] + c->radius < box[2] && c->center[1] - c->radius > -box[1] && c->center[1] + c->radius < box[3], c->comm, PETSC_ERR_USER_INPUT,
             "The Cusick pedestal (-cusick_center %g,%g, radius %g m) must lie under the flat specimen, which spans [%g, %g] x [%g, %g] m horizontally (the analysis needs a horizontal specimen)", (double) c->center[0], (double) c->center[1],
             (double) c->radius, (double) -box[0], (double) box[2], (double) -box[1], (double) box[3]);
  {
    /* the pedestal: a solid whose top is within a pedestal radius under the
     * specimen's centre (without one the cloth falls flat and DC = 1 means nothing) */
    PetscReal p[3] = {c->center[0], c->center[1], -box[4]}, distance = PETSC_MAX_REAL, normal[3];
    PetscBool empty;
    PetscCall(SolidIsEmpty(solid, &empty));
    if (!empty) PetscCall(SolidQuery(solid, p, &distance, normal));
    PetscCheck(distance <= c->radius, c->comm, PETSC_ERR_USER_INPUT,
               "-cusick_pedestal_radius %g: the Cusick analysis needs the pedestal, a solid just under the specimen's centre (%g, %g, %g) m (e.g. -solid_type cylinder -solid_radius %g, as in runs/cusick.opts), and %s", (double) c->radius,
               (double) p[0], (double) p[1], (double) p[2], (double) c->radius, empty ? "this run has no solid" : "the nearest solid is farther than the pedestal radius");
  }
  PetscCall(PetscFree(c->x0));
  PetscCall(PetscMalloc1(3 * info.nowned, &c->x0));
  PetscCall(PetscArraycpy(c->x0, u, 3 * info.nowned));
  PetscFunctionReturn(0);
}

PetscErrorCode CusickView(Cusick c, Cloth cloth, const PetscScalar *x, PetscBool at_rest, Report r, PetscViewer viewer)
{
  PetscReal dc;
  PetscInt  folds;

  PetscFunctionBeginUser;
  if (c->radius <= 0) PetscFunctionReturn(0);
  PetscCall(CusickAnalyse(cloth, x, c->x0, c->radius, c->center, &dc, &folds));
  PetscCall(ReportViewReal(r, viewer, "drape_coefficient", "Cusick drape test: drape coefficient DC = %.4f", dc));
  PetscCall(ReportViewInt(r, viewer, "drape_folds", ", %" PetscInt_FMT " folds", folds));
  if (viewer) PetscCall(PetscViewerASCIIPrintf(viewer, " (pedestal radius %g m)%s\n", (double) c->radius, at_rest ? "" : "; WARNING: the run ended before the cloth came to rest (set -drape_rest_tol and a longer -ts_max_time)"));
  PetscFunctionReturn(0);
}
