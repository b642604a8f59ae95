"""The explicit force kernel on the lattice (src/cloth/lattice.c, -cloth_force_kernel
lattice, the default) against the element lists' loops (-cloth_force_kernel elements):
the same elements, so the same motion to round-off, on every outline, model and
partition; and on any partition the same motion as on one rank."""
import numpy as np
import pytest

import drape_h5
from conftest import run

# a sheet that is not flat (the imperfection), swinging from two pins: every kind of
# element strained, bent and sheared within 0.05 s
BASE = ("-cloth_pin edge_corners -cloth_imperfection 2e-3,0.1 -ts_type basicsymplectic -ts_dt 1e-4 -ts_max_time 0.05 "
        "-output_interval 0.01 -drape_stability_its 0")

CASES = {
    "square": "-da_grid_x 21 -da_grid_y 21",
    "paper": "-da_grid_x 21 -da_grid_y 21 -cloth_model paper",
    "oblong": "-da_grid_x 25 -da_grid_y 14 -cloth_size 1,0.6 -cloth_bend 5e-6,5e-6,6e-6",
    "circle": "-da_grid_x 25 -da_grid_y 25 -cloth_shape circle -cloth_pin none -cloth_orientation vertical",
    "fabric": "-da_grid_x 21 -da_grid_y 21 -cloth_fabric denim",
}


def frames(tmp, name, args, np_=1):
    out = tmp / f"{name}.h5"
    run(f"{BASE} {args} -output_file {out}", np_=np_)
    return drape_h5.load(out)


@pytest.mark.parametrize("case", sorted(CASES))
def test_lattice_kernel_moves_the_cloth_as_the_element_lists(tmp, case):
    """Positions, velocities, energies and the largest strain of every frame agree
    with the element lists' to round-off (the sums are taken in another order)."""
    ref = frames(tmp, "elements", f"{CASES[case]} -cloth_force_kernel elements")
    lat = frames(tmp, "lattice", CASES[case])
    assert len(ref.time) == 6 and np.array_equal(ref.time, lat.time)
    scale = np.abs(ref.positions).max()
    moved = np.abs(ref.positions[-1] - ref.positions[0]).max()
    assert moved > 1e-3, "the test scene must move"
    assert np.abs(lat.positions - ref.positions).max() <= 1e-12 * scale
    assert np.abs(lat.velocities - ref.velocities).max() <= 1e-9 * np.abs(ref.velocities).max()
    # the energies and the largest strain, from the lattice's patch (ClothLatticeEnergies)
    for name in ("stretch", "shear", "bend"):
        e, r = lat.energies[name], ref.energies[name]
        assert np.abs(e - r).max() <= 1e-9 * np.abs(r).max() + 1e-300, name
    assert np.abs(lat.strain_max - ref.strain_max).max() <= 1e-9 * np.abs(ref.strain_max).max()


@pytest.mark.parametrize("np_,partition", [(2, "dmda"), (3, "metis"), (4, "dmda"), (3, "ptscotch")])
def test_lattice_kernel_on_any_partition(tmp, np_, partition):
    """A patch per rank (a DMDA block, or the bounding box of a METIS part with empty
    slots): the same frames as on one rank, for the circle (cut cells, classes of
    every kind) and the square."""
    for case in ("circle", "square"):
        one = frames(tmp, f"{case}1", CASES[case])
        many = frames(tmp, f"{case}{np_}", f"{CASES[case]} -cloth_partition {partition}", np_=np_)
        assert np.abs(many.positions - one.positions).max() <= 1e-12 * np.abs(one.positions).max(), case
        for name in ("stretch", "shear", "bend"):  # each element counted once, on the rank owning its centre
            assert np.abs(many.energies[name] - one.energies[name]).max() <= 1e-9 * np.abs(one.energies[name]).max(), (case, name)
