/* The preconditioner type "blockicc" (src/integrate/pcblockicc.c): incomplete
 * Cholesky without fill, IC(0) (with -pc_blockicc_levels 1, its level-1 fill too:
 * IC(1)), of an SBAIJ matrix of block size 3 (on many ranks,
 * of each rank's diagonal block: block Jacobi), in
 * 3 x 3 blocks, that stays positive definite. PETSc's ICC(0) of the same matrix
 * (PCICC on SBAIJ) inverts each pivot block as it comes: where the dropped fill
 * leaves a pivot block indefinite, its preconditioner is indefinite and CG stops
 * (KSP_DIVERGED_INDEFINITE_PC). Here such a factorisation is made again with the
 * dropped fill compensated on the diagonal (Ajiz and Jennings), positive definite
 * by construction; where no pivot fails, the factor is IC(0)'s.
 *
 * Options: -pc_blockicc_type auto (the default: compensated only when IC(0)
 * fails), plain or compensated; -pc_blockicc_pivot_tol (1e-8);
 * -pc_blockicc_precision single (the default: the factor stored in float, the
 * arithmetic in double; double where a rounded pivot block would not be positive
 * definite) or double; -pc_blockicc_levels 0 (the default, IC(0)) or 1 (IC(1): the
 * fill of two of the matrix's blocks kept too). */
#pragma once

#include <petscpc.h>

#define PCBLOCKICC "blockicc"

/* Register the type with PCRegister() (again: no harm). Not collective. */
PETSC_EXTERN PetscErrorCode PCBlockICCRegister(void);
/* Whether the last factorisation compensated the dropped fill on any rank
 * (PETSC_FALSE on a PC of another type). Collective on PC. */
PETSC_EXTERN PetscErrorCode PCBlockICCGetCompensated(PC, PetscBool *);
/* The factor's fill: 0, the matrix's pattern (IC(0), the default); 1, also the
 * blocks that two of the matrix's blocks fill (IC(1): fewer CG iterations, a larger
 * factor). On a PC of another type, nothing. The next set-up makes the factor anew.
 * Not collective. */
PETSC_EXTERN PetscErrorCode PCBlockICCSetLevels(PC, PetscInt);
/* The fill (-1 on a PC of another type). Not collective. */
PETSC_EXTERN PetscErrorCode PCBlockICCGetLevels(PC, PetscInt *);
/* x = M^-1 x in place, M the factor (PCApply without a second vector). Not
 * collective. */
PETSC_EXTERN PetscErrorCode PCBlockICCApplyInPlace(PC, Vec x);
