"""How large a lattice drape takes: the index limits PetscInt forces (3 unknowns per
particle; src/cloth/cloth.c, above ClothCheckLatticeSize, says why) and the memory
estimates, each refused with one sentence before anything of the lattice's size is
allocated."""
import re
import resource
import subprocess

from conftest import DRAPE, mpiexec
from test_hostile import drape, refused


def petscint_bits(tmp):
    res = drape(["-da_grid_x", "4", "-da_grid_y", "4", "-ts_max_steps", "0", "-drape_stability_its", "0", "-drape_progress", "0", "-log_view"], tmp)
    return 8 * int(re.search(r"sizeof\(PetscInt\) (\d)", res.stdout).group(1))


def test_index_limit_is_three_unknowns_per_particle(tmp):
    """With 32-bit indices the limit is 3 N <= 2^31 - 1: 26 754 x 26 754 (715 776 516
    particles) is within it and refused only by the memory estimate (286 GB on one
    rank), one more row and column is past it and refused for the indices. (Before,
    drape refused above 2^24 - 1 particles, 4095 x 4095, while the README said about
    26 700 x 26 700.) A 64-bit build refuses both for memory alone."""
    bits = petscint_bits(tmp)
    below = refused(drape(["-da_grid_x", "26754", "-da_grid_y", "26754"], tmp), "lattice needs at least")
    assert "GB per rank" in below, below
    above = refused(drape(["-da_grid_x", "26755", "-da_grid_y", "26755"], tmp), "")
    if bits == 32:
        assert "has more unknowns (3 per particle) than this PETSc build's 32-bit PetscInt indexes: at most 715827882 particles (e.g. 26754 x 26754)" in above, above
    else:
        assert "lattice needs at least" in above, above


def test_implicit_step_says_what_it_needs(tmp):
    """drapebe needs at least 2.3 kB per particle (the matrix and its block IC(0)
    preconditioner), the explicit schemes about 0.25 kB: under a 500 MB address-space
    limit a 520 x 520 lattice sets up and steps with symplectic Euler (with 32- and
    64-bit indices), and drapebe is refused before its matrix with the bytes per rank
    it needs."""
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (500 << 20, 500 << 20))
    base = ["-da_grid_x", "520", "-da_grid_y", "520", "-ts_max_steps", "1", "-drape_stability_its", "0", "-drape_progress", "0"]
    res = drape(base + ["-ts_type", "basicsymplectic", "-ts_dt", "1e-6"], tmp, preexec_fn=limit)
    assert res.returncode == 0, res.stdout + res.stderr
    error = refused(drape(base + ["-ts_type", "drapebe"], tmp, preexec_fn=limit), "The implicit step (drapebe) on a 520 x 520 lattice needs at least 0.6 GB per rank (2300 bytes per particle")
    assert "-ts_type basicsymplectic" in error, error


def test_serial_metis_graph_that_cannot_fit_is_refused(tmp):
    """Serial METIS builds the whole particle graph on rank 0 (about 140 bytes a
    particle above the rank's share). Under a 1000 MB address-space limit on 2 ranks a
    2000 x 2000 lattice fits the estimate with the DMDA's blocks (0.8 GB a rank: that
    check passes first) and not with -cloth_partition metis (0.56 GB more on rank
    0): refused before the graph, with its size and the partitioner to use instead.
    (No run of the DMDA's blocks under the limit: with 64-bit indices it may not fit
    the address space, which the estimate does not claim.)"""
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (1000 << 20, 1000 << 20))
    base = ["-da_grid_x", "2000", "-da_grid_y", "2000", "-ts_type", "basicsymplectic", "-ts_max_steps", "0", "-drape_stability_its", "0", "-drape_progress", "0"]

    def run2(part):
        return subprocess.run(mpiexec(2) + [str(DRAPE)] + base + ["-cloth_partition", part], capture_output=True, text=True, cwd=tmp, timeout=120, preexec_fn=limit)
    error = refused(run2("metis"), "-cloth_partition metis builds the whole particle graph of the 2000 x 2000 lattice on rank 0: about 0.6 GB (140 bytes a particle) on top of the rank's own 0.8 GB", ranks=2)
    assert "1.0 GB per process" in error and re.search(r"; use -cloth_partition (ptscotch|parmetis|dmda)", error) and "dmda" in error, error
