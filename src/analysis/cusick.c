/* The Cusick drape test: silhouette area, drape coefficient, number of folds. */
#include <analysis.h>
#include <petscdmda.h>

PetscErrorCode CusickSilhouette(PetscInt ntri, const PetscReal *xy, const PetscReal c[2], PetscReal extent, PetscInt npixels, PetscReal *area, PetscInt nbins, PetscReal *radius)
{
  const PetscReal px = 2 * extent / npixels, x0 = c[0] - extent, y0 = c[1] - extent;
  unsigned char  *cover;
  PetscInt        count = 0;

  PetscFunctionBeginUser;
  PetscCall(PetscCalloc1(npixels * npixels, &cover));
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

/* Projected triangles of the active cells of the natural-order positions X. */
static PetscErrorCode ActiveTriangles(Cloth cloth, PetscInt Mx, PetscInt My, const PetscScalar *X, PetscInt *ntri, PetscReal **xy)
{
  PetscInt n = 0;

  PetscFunctionBeginUser;
  PetscCall(PetscMalloc1(12 * (Mx - 1) * (My - 1) + 1, xy));
  for (PetscInt j = 0; j + 1 < My; j++) {
    for (PetscInt i = 0; i + 1 < Mx; i++) {
      const PetscInt q[4] = {j * Mx + i, j * Mx + i + 1, (j + 1) * Mx + i + 1, (j + 1) * Mx + i};
      if (!(ClothIsActive(cloth, i, j) && ClothIsActive(cloth, i + 1, j) && ClothIsActive(cloth, i + 1, j + 1) && ClothIsActive(cloth, i, j + 1))) continue;
      for (PetscInt t = 0; t < 2; t++) {
        const PetscInt v[3] = {q[0], q[1 + t], q[2 + t]};
        for (PetscInt k = 0; k < 3; k++) {
          (*xy)[6 * n + 2 * k]     = X[3 * v[k]];
          (*xy)[6 * n + 2 * k + 1] = X[3 * v[k] + 1];
        }
        n++;
      }
    }
  }
  *ntri = n;
  PetscFunctionReturn(0);
}

PetscErrorCode CusickAnalyse(Cloth cloth, const PetscScalar *x, const PetscScalar *x0, PetscReal pedestal_radius, const PetscReal c[2], PetscReal *dc, PetscInt *folds)
{
  DM          da;
  Vec         G, N, Z;
  VecScatter  scatter;
  ClothInfo   info;
  PetscMPIInt rank;
  PetscReal   result[2] = {0, 0};

  PetscFunctionBeginUser;
  PetscCall(ClothGetDM(cloth, &da));
  PetscCall(ClothGetInfo(cloth, &info));
  PetscCallMPI(MPI_Comm_rank(PetscObjectComm((PetscObject) da), &rank));
  PetscCall(DMCreateGlobalVector(da, &G));
  PetscCall(DMDACreateNaturalVector(da, &N));
  PetscCall(VecScatterCreateToZero(N, &scatter, &Z));
  for (PetscInt pass = 0; pass < 2; pass++) {
    PetscCall(ClothToDMDA(cloth, pass ? x : x0, G));
    PetscCall(DMDAGlobalToNaturalBegin(da, G, INSERT_VALUES, N));
    PetscCall(DMDAGlobalToNaturalEnd(da, G, INSERT_VALUES, N));
    PetscCall(VecScatterBegin(scatter, N, Z, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterEnd(scatter, N, Z, INSERT_VALUES, SCATTER_FORWARD));
    if (!rank) {
      const PetscScalar *X;
      PetscReal         *xy, area = 0, radius[720], extent = 0.6 * PetscSqrtReal(PetscSqr(info.size[0]) + PetscSqr(info.size[1]));
      PetscInt           ntri;
      PetscCall(VecGetArrayRead(Z, &X));
      PetscCall(ActiveTriangles(cloth, info.Mx, info.My, X, &ntri, &xy));
      PetscCall(VecRestoreArrayRead(Z, &X));
      PetscCall(CusickSilhouette(ntri, xy, c, extent, 1200, &area, 720, radius));
      PetscCall(PetscFree(xy));
      if (!pass)
        result[0] = area; /* the flat specimen */
      else {
        PetscReal disc = PETSC_PI * pedestal_radius * pedestal_radius;
        PetscInt  nf   = 0;
        result[0]      = (area - disc) / (result[0] - disc);
        /* a fold must stand out of the lattice's own staircase outline and be a
         * tenth of the overhang deep */
        PetscCall(CusickCountFolds(720, radius, PetscMax(0.1 * (0.5 * PetscMin(info.size[0], info.size[1]) - pedestal_radius), 1.5 * PetscMax(info.spacing[0], info.spacing[1])), &nf));
        result[1] = nf;
      }
    }
  }
  PetscCallMPI(MPI_Bcast(result, 2, MPIU_REAL, 0, PetscObjectComm((PetscObject) da)));
  *dc    = result[0];
  *folds = (PetscInt) result[1];
  PetscCall(VecScatterDestroy(&scatter));
  PetscCall(VecDestroy(&Z));
  PetscCall(VecDestroy(&N));
  PetscCall(VecDestroy(&G));
  PetscFunctionReturn(0);
}
