"""Run the C unit tests (tests/unit/*.c, built by `make all` into $DRAPE_BUILD/tests)."""

import re
import subprocess

import pytest

from conftest import BUILD, ROOT, mpiexec


def run_unit(name, *args, timeout=300):
    exe = BUILD / "tests" / name
    if not exe.is_file():
        pytest.fail(f"{exe} not found; build it with `make all` (DRAPE_BUILD={BUILD})")
    proc = subprocess.run([str(exe), *args], cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    output = f"$ {exe} {' '.join(args)}\n--- stdout ---\n{proc.stdout}\n--- stderr ---\n{proc.stderr}"
    return proc, output


def run_unit_ranks(name, np_, args, npassed):
    """A C unit test on np_ ranks with leak checking; asserts its closing line."""
    cmd = [str(BUILD / "tests" / name)] + args + ["-malloc_debug", "-malloc_dump"]
    if np_ > 1:
        cmd = mpiexec(np_) + cmd
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert re.search(rf"^{npassed} passed, 0 failed$", proc.stdout, re.MULTILINE), proc.stdout
    assert " bytes " not in proc.stdout + proc.stderr, "memory leak"


def test_kernels():
    proc, output = run_unit("test_kernels")
    assert proc.returncode == 0, f"test_kernels exited with code {proc.returncode}\n{output}"
    assert re.search(r"^\d+ passed, 0 failed$", proc.stdout, re.MULTILINE), f"no 'N passed, 0 failed' line\n{output}"


@pytest.mark.parametrize("np_", [1, 2])
def test_cloth_rigid_motion_and_force_balance(np_):
    """A rigidly moved cloth at rest feels no internal force; forces rotate with the
    cloth and have no resultant or torque; a sheet rolled into cylinders at 0, 90 and
    45 degrees to the warp stores the energy of its strip rigidities Bw, Bf, Bb:
    drape's model within 1e-3 on a square and on a circle cut from it (every line's
    free end counted), the paper's ((Bw + Bf)/4 at 45 degrees) within 3 %; with
    -cloth_bend_table, denim rolled to 25 1/m stores the integral of its measured
    moment to 1e-6 (1 and 2 ranks, no leaks)."""
    run_unit_ranks("test_cloth", np_, ["-da_grid_x", "9", "-da_grid_y", "7", "-cloth_pin", "edge_corners"], 14)

@pytest.mark.parametrize("np_", [1, 2, 3])
@pytest.mark.parametrize("opts", ["", "-cloth_hessian exact -cloth_bend_hysteresis 0.01,0.01", "-cloth_model paper -cloth_partition metis"])
def test_assembled_matrix_matches_elementwise_reference(np_, opts):
    """The implicit matrix of ClothAssembleMatrix (blocks formed alone from each
    element's h or H6, summed tile by tile) against each element's whole matrix
    added block by block, at randomly distorted positions on a 25 x 23 lattice (3
    tiles on one rank), without and with sliding and fixed particles: AIJ (csr, coo,
    rows) and BAIJ equal to the bit, and the diagonal blocks of H too; SBAIJ (rows,
    coo) within 1e-13 (its lower half is its upper's transpose). Projected and exact
    Hessians, the bending friction, the paper's model, a METIS partition; 1, 2
    and 3 ranks, no leaks. A sum in another order, a constraint left out or the kinds'
    order broken by the tiles fails it. On several ranks (S)BAIJ's rows are summed in
    the diagonal block's own array, and a cut row's other blocks (below and above the
    rank's columns: a middle rank of 3) are handed to PETSc. Extra blocks (self-
    contact's pairs) outside the pattern: a new matrix grown from the last one's
    buffer (their union kept) and one made anew (the union reset), each against the
    reference with its extra blocks; a block the grown pattern left out fails it."""
    run_unit_ranks("test_assembly", np_, ["-da_grid_x", "25", "-da_grid_y", "23", "-cloth_pin", "edge_corners"] + opts.split(), 30)


@pytest.mark.parametrize("np_", [1, 2])
def test_cusick_analysis_known_silhouettes(np_):
    """Drape coefficient and folds on constructed silhouettes: a square and a 7-lobed
    star (exact areas, 4 and 7 maxima), the flat specimen (DC = 1), one hanging
    straight down the pedestal (DC = 0), a shrunk specimen (exact DC), an 8-lobed
    drape (8 folds)."""
    run_unit_ranks("test_cusick", np_, ["-cloth_shape", "circle", "-cloth_size", "0.3", "-da_grid_x", "41", "-da_grid_y", "41"], 6)


def test_cusick_analysis_same_on_any_ranks_and_partition():
    """Each rank rasterises its own cells and the rasters are OR-ed: the 8-lobed
    drape's DC (printed to 17 digits) and folds are the same to the bit on 1, 2 and 3
    ranks, DMDA blocks and METIS parts (a cell's corners on different ranks, a rank's
    cells not a block)."""
    seen = {}
    for np_ in (1, 2, 3):
        for part in ("dmda", "metis"):
            cmd = [str(BUILD / "tests" / "test_cusick"), "-cloth_shape", "circle", "-cloth_size", "0.3", "-da_grid_x", "41", "-da_grid_y", "41", "-cloth_partition", part]
            if np_ > 1:
                cmd = mpiexec(np_) + cmd
            proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
            assert proc.returncode == 0, proc.stdout + proc.stderr
            m = re.search(r"^8-lobed drape: DC = (\S+), (\d+) folds$", proc.stdout, re.MULTILINE)
            assert m, proc.stdout
            seen[(np_, part)] = (m.group(1), int(m.group(2)))
    assert len(set(seen.values())) == 1, seen
    dc, folds = seen[(1, "dmda")]
    assert folds == 8 and 0.2 < float(dc) < 0.9, seen


def test_self_contact_narrow_phase():
    """Closest points (point-triangle, segment-segment) against brute force, cubic
    roots, collision times with known answers (a point falling through a triangle, a
    triangle rising through a point, a rotating triangle, crossing edges, in-plane
    entry) and 2000 random sweeps: every crossing a dense sampling sees is found, no
    later than it (no leaks); and the near list's distances in lanes (the machine's
    instruction set) equal to the bit to the scalar ones, degenerate cases too."""
    run_unit_ranks("test_selfcontact", 1, [], 5)


def test_self_contact_broad_phases():
    """CGAL's box intersection and the spatial hash return exactly the pairs (and their
    order) of a brute-force test of every pair of boxes, on two flat layers, crumpled
    layers, a tangle and a sheet with long sweeps (the hash's cells grow), and agree
    with each other on a folded 121^2 lattice (no leaks)."""
    run_unit_ranks("test_broadphase", 1, [], 2)


def test_block_icc_preconditioner():
    """Block IC(0) (PCBLOCKICC, drapebe's default preconditioner): exact on a block
    chain (no fill to drop), the same as PETSc's ICC(0) to round-off where that is
    positive definite, and, on a bending matrix where PETSc's ICC(0) stops CG as an
    indefinite preconditioner, compensated: symmetric, positive definite, and CG
    converges; stored in single precision within float's rounding, and in double where
    a rounded pivot block would be indefinite; with level-1 fill exact on a ladder,
    where IC(0) is not (no leaks)."""
    run_unit_ranks("test_blockicc", 1, [], 5)


@pytest.mark.parametrize("np_", [1, 3])
def test_sbaij_product_is_petscs_to_the_bit(np_):
    """drape's product for SBAIJ of block size 3 (drapebe's matrix on one rank, each
    rank's diagonal block on many): on a lattice's pattern, with 300 far blocks, with
    a row missing its diagonal block and an empty row, A x equals PETSc's MatMult to
    the bit (the same sums in the same order); an AIJ matrix keeps PETSc's product
    (1 and 3 ranks, no leaks)."""
    run_unit_ranks("test_sbaijmult", np_, [], 4)


def test_lattice_multigrid_preconditioner():
    """The lattice multigrid (PCLATTICEMG): its V(1,1), W and hybrid cycles symmetric to
    round-off (the coarse levels hold one triangle; the sweeps backward are the
    transposes of those forward) and positive definite, with sliding, fixed and pinned
    rows and either smoother, on odd and even lattices; CG iterations that do not grow
    from 33^2 to 129^2 where block IC(0)'s nearly triple; the hybrid cycle with the
    Gauss-Seidel smoother refused; block IC in place as out of place (no leaks)."""
    run_unit_ranks("test_latticemg", 1, [], 4)
