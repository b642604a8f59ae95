/* drape's product for the implicit matrix in symmetric storage
 * (src/integrate/sbaijmult.c): PETSc's MatMult for SBAIJ of block size 3, the same
 * sums in the same order (the same bits), with each row's sums in registers and the
 * next row prefetched into the caches. */
#pragma once

#include <petscmat.h>

/* J's product (MATOP_MULT) becomes drape's when J is SeqSBAIJ of block size 3, or
 * its diagonal block's when J is MPISBAIJ (whose product takes that block's); any
 * other matrix is left as it is. Set again after J is preallocated anew, which
 * gives it PETSc's. Not collective. */
PETSC_EXTERN PetscErrorCode DrapeMatUseSBAIJProduct(Mat);
/* Does J take drape's product (as DrapeMatUseSBAIJProduct set it, and no
 * preallocation since gave it PETSc's)? Not collective. */
PETSC_EXTERN PetscErrorCode DrapeMatHasSBAIJProduct(Mat, PetscBool *);
