/* The preconditioner type "latticemg" (src/integrate/pclatticemg.c): geometric
 * multigrid on the cloth's lattice for drapebe's SBAIJ matrix (block size 3), on
 * one rank. Each coarser level keeps every other lattice node of the one below
 * (bilinear interpolation of each displacement component, filtered by the contact
 * constraints: a constrained direction takes no coarse correction); its operator is
 * the Galerkin product P^T A P, formed block by block on the lattice's stencil (5 x 5
 * blocks a node: the stretch, shear and bending couplings reach two nodes, and so do
 * their coarse products; its upper triangle stored, 13 blocks a node, in single
 * precision). Smoothing: block IC(0) on the finest level (PCBLOCKICC,
 * options prefix -mg_fine_), symmetric block Gauss-Seidel on the coarser ones, a
 * dense LDL^T factorisation on the coarsest (at most 64 nodes). A (1,1) cycle,
 * a W-cycle below the first coarse level (-pc_latticemg_gamma), symmetric, so CG
 * takes it; positive definite where 2 M - A is, M the finest
 * level's smoother. Where it is not (block IC(0) of a stiff step can miss A by more
 * than a factor 2 in some direction: CG stops with an indefinite preconditioner),
 * the hybrid cycle M^-1 + (I - M^-1 A) Q (I - A M^-1), Q the coarse correction, is
 * positive definite for any positive definite M, at the same cost and somewhat
 * more iterations (PCLatticeMGSetHybrid; drapebe takes it at such a failure).
 *
 * Options: -pc_latticemg_levels (the most levels; 0, the default: down to the
 * coarsest), -pc_latticemg_coarse_nodes (64), -pc_latticemg_coarse_lag (4),
 * -pc_latticemg_smoother (blockicc or sgs), -pc_latticemg_hybrid, -pc_latticemg_gamma
 * (2). */
#pragma once

#include <petscpc.h>
#include <cloth.h>

#define PCLATTICEMG "latticemg"

/* Register the type with PCRegister() (again: no harm). Not collective. */
PETSC_EXTERN PetscErrorCode PCLatticeMGRegister(void);
/* The lattice (Mx x My nodes) and, for each of the matrix's n block rows, its node
 * (j Mx + i) and whether it is pinned (its row decoupled: no coarse correction).
 * node and pinned are copied. On a PC of another type, nothing. Not collective. */
PETSC_EXTERN PetscErrorCode PCLatticeMGSetLattice(PC, PetscInt Mx, PetscInt My, PetscInt n, const PetscInt node[], const PetscBool pinned[]);
/* The contact constraints of the rows (ClothSetConstraints: free, sliding along the
 * surface of outward normal n, fixed; type NULL: none): the types copied, the
 * normals referenced (3 a row, needed where a row slides; the array must stay valid
 * while the PC is used, as ContactSolve's does); the next set-up filters the
 * interpolation with them. On a PC of another type, nothing. Not collective. */
PETSC_EXTERN PetscErrorCode PCLatticeMGSetConstraints(PC, const ClothConstraint type[], const PetscReal normal[]);
/* The hybrid cycle instead of V(1,1) (or back); on a PC of another type, nothing.
 * Not collective. */
PETSC_EXTERN PetscErrorCode PCLatticeMGSetHybrid(PC, PetscBool);
/* Whether it takes the hybrid cycle (PETSC_FALSE on a PC of another type). Not
 * collective. */
PETSC_EXTERN PetscErrorCode PCLatticeMGGetHybrid(PC, PetscBool *);
/* Whether it may take the hybrid cycle: with the block IC smoother, not with
 * Gauss-Seidel (-pc_latticemg_smoother sgs: not symmetric, the cycle refused at its
 * set-up); PETSC_FALSE on a PC of another type. Not collective. */
PETSC_EXTERN PetscErrorCode PCLatticeMGHybridAllowed(PC, PetscBool *);
