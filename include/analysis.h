/* Analysis of drape results: the Cusick drape test (BS 5058 / ISO 9073-9 style).
 *
 * The draped specimen is projected on the horizontal plane (its silhouette, the
 * union of the projected lattice cells, rasterised), then
 *   DC = (A_shadow - A_disc) / (A_specimen - A_disc)
 * with A_disc the pedestal's area and A_specimen the flat specimen's silhouette
 * (so a flat specimen gives exactly 1, one hanging straight down the pedestal's
 * edge 0). Folds (nodes) are the prominent maxima of the silhouette's radius
 * against angle. */
#pragma once

#include <cloth.h>
#include <solid.h>
#include <report.h>

/* Rasterise ntri triangles (xy: 6 reals each) on a square grid of half-width
 * `extent` around (cx, cy) with `npixels` per side; return the covered area and,
 * for nbins equal angle bins around (cx, cy), the largest radius covered (0 if none).
 * Not collective. */
PETSC_EXTERN PetscErrorCode CusickSilhouette(PetscInt ntri, const PetscReal *xy, const PetscReal c[2], PetscReal extent, PetscInt npixels, PetscReal *area, PetscInt nbins, PetscReal *radius);
/* Number of folds: prominent maxima of the radius profile (circular). Not collective. */
PETSC_EXTERN PetscErrorCode CusickCountFolds(PetscInt nbins, const PetscReal *radius, PetscReal prominence, PetscInt *folds);
/* Drape coefficient and folds of the cloth at x (owned order), against the flat
 * reference x0, for a pedestal of radius r centred at c. Each rank rasterises the
 * cells of its DMDA block, the rasters (1200 x 1200 pixels, whatever the lattice) are
 * OR-ed onto rank 0: no rank holds the whole lattice, and the result is the same to
 * the bit on any ranks and partition. Collective. */
PETSC_EXTERN PetscErrorCode CusickAnalyse(Cloth, const PetscScalar *x, const PetscScalar *x0, PetscReal pedestal_radius, const PetscReal c[2], PetscReal *dc, PetscInt *folds);

/* The analysis as a part of a run: its options (-cusick_pedestal_radius,
 * -cusick_center), the flat specimen it compares with, and its numbers at the end.
 * Create: not collective. SetFromOptions: collective (a -cusick_center without a
 * pedestal radius is refused). Enabled: not collective. */
typedef struct _p_Cusick   *Cusick;
PETSC_EXTERN PetscErrorCode CusickCreate(MPI_Comm, Cusick *);
PETSC_EXTERN PetscErrorCode CusickSetFromOptions(Cusick);
PETSC_EXTERN PetscErrorCode CusickEnabled(Cusick, PetscBool *);
/* Check that the pedestal lies under the flat specimen at x (owned order) and that
 * a solid holds it up, and keep x as the flat reference. Collective. */
PETSC_EXTERN PetscErrorCode CusickSetUp(Cusick, Cloth, Solid, const PetscScalar *x);
/* Analyse the cloth at x: the drape coefficient and folds on viewer (NULL: not
 * printed; with a warning unless the cloth came to rest) and in the report
 * (drape_coefficient, drape_folds). Collective. */
PETSC_EXTERN PetscErrorCode CusickView(Cusick, Cloth, const PetscScalar *x, PetscBool at_rest, Report, PetscViewer);
/* Not collective. */
PETSC_EXTERN PetscErrorCode CusickDestroy(Cusick *);
