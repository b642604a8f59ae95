"""The start-up stability estimate (src/integrate/stability.c): Omega_max by Lanczos
from the lattice's sign patterns, on the whole lattice (small ones) or on two
windows (larger ones), against known answers and the slow reference."""
import math

import pytest

from conftest import run


def omega(args, np_=1):
    return run(f"{args} -ts_max_steps 0 -drape_progress 0", np_=np_).report["omega_max"]


@pytest.mark.parametrize("n", [32, 128])
def test_stretch_lattice_top_mode(n):
    """A stretch-only square lattice at rest, unpinned: the top mode alternates along
    the warp (x) with every row alike (half masses and half stiffness on the boundary
    rows keep it exact), Omega_max^2 = 4 k/m = 4 Y/(rho h^2). 32^2: the whole lattice
    (within 0.05 %: Lanczos stops once a step gains less than 1e-4 in Omega^2);
    128^2: the windows, a principal submatrix, a little below (within 0.3 %)."""
    Y, rho = 500.0, 0.15
    h = 1.0 / (n - 1)
    exact = 2 * math.sqrt(Y / rho) / h
    om = omega(f"-da_grid_x {n} -da_grid_y {n} -cloth_pin none -cloth_shear 0 -cloth_bend 0 -cloth_stretch {Y} -cloth_density {rho}")
    assert om <= exact * (1 + 1e-9), (om, exact)
    assert om >= exact * (1 - (5e-4 if n == 32 else 3e-3)), (om, exact)


@pytest.mark.parametrize("extra", ["", "-cloth_fabric denim -cloth_size 1,0.7", "-cloth_tilt 30 -cloth_imperfection 0.01"])
def test_estimate_matches_converged_reference(extra):
    """On a 24^2 sheet (whole lattice), the default estimate is within 0.2 % of 300
    Lanczos steps on the elements' full matrices (-drape_stability_reference: fully
    converged; it also checks the directional Hessian product against the matrices)
    and not above it."""
    base = f"-da_grid_x 24 -da_grid_y 24 -cloth_pin edge_corners {extra}"
    ref = omega(f"{base} -drape_stability_reference -drape_stability_its 300")
    om = omega(base)
    assert ref * (1 - 2e-3) <= om <= ref * (1 + 1e-9), (om, ref)




@pytest.mark.parametrize("n", [40, 160])
def test_same_on_one_and_two_ranks(n):
    """The estimate does not depend on the partition (to round-off): 40^2 (whole
    lattice) and 160^2 (windows) on 1 and 2 ranks, DMDA and METIS."""
    base = f"-da_grid_x {n} -da_grid_y {n} -cloth_pin edge_corners -cloth_fabric denim"
    one = omega(base)
    for np_, part in [(2, "dmda"), (2, "metis")]:
        other = omega(f"{base} -cloth_partition {part}", np_=np_)
        assert abs(other / one - 1) < 1e-10, (n, np_, part, one, other)
