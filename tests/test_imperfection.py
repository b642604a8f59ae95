"""A specimen that is not quite flat (-cloth_imperfection A[,wavelength],
-cloth_imperfection_seed N): a smooth random out-of-plane displacement of the initial
sheet, a sum of plane waves in material coordinates (src/cloth/cloth.c,
ClothImperfection). What it must be: the same specimen on every lattice, rank count
and partition (a function of the material point, drawn from the seed by a portable
generator); of the rms amplitude asked for; different for another seed; along the
sheet's normal; and bad values are refused. The runs stop after one short step: only
the initial frame (frame 0) is read."""
import numpy as np
import pytest

from conftest import refused, run

import drape_h5

SHEET = "-cloth_size 1 -cloth_center 0,0,1 -ts_dt 1e-4 -ts_max_steps 1 -output_interval 1"


def initial(tmp, name, args, np_=1):
    out = tmp / f"{name}.h5"
    run(f"{SHEET} {args} -output_file {out}", np_=np_)
    return drape_h5.load(out).positions[0]  # [j][i][xyz]


def test_the_same_specimen_on_every_lattice_and_rank_count(tmp):
    """The 41^2 lattice's particles are every second one of the 81^2 lattice's on the
    same 1 m sheet: their imperfection agrees to round-off (a lattice-dependent field,
    white noise per particle say, would differ by the amplitude). On 1 and 3 ranks
    (METIS) the initial frame is bitwise the same: each particle's position is the same
    arithmetic on the same numbers, whichever rank owns it."""
    imp = "-cloth_imperfection 1e-3,0.1 -cloth_imperfection_seed 7"
    coarse = initial(tmp, "c", f"-da_grid_x 41 -da_grid_y 41 {imp}")
    fine = initial(tmp, "f", f"-da_grid_x 81 -da_grid_y 81 {imp}")
    w = coarse[..., 2] - 1
    assert np.abs(w).max() > 1e-3  # it is there
    assert np.abs(w - (fine[::2, ::2, 2] - 1)).max() < 1e-15
    assert np.abs(coarse[..., :2] - fine[::2, ::2, :2]).max() < 1e-15  # out of plane only
    three = initial(tmp, "n3", f"-da_grid_x 41 -da_grid_y 41 {imp} -cloth_partition metis", np_=3)
    assert np.array_equal(coarse, three)


def test_rms_amplitude_and_seeds(tmp):
    """Over the infinite plane the field's mean square is exactly A^2 (its 32 plane
    waves have distinct directions); over a sheet 50 wavelengths across, sampled 8
    times a wavelength, the rms is within 5 % of A: that sheet's sampling spread, from
    200 random draws of the field in numpy, is 0.5 % median, 2.3 % at the 95th and
    3.6 % at most. The mean is near 0. Another seed is another specimen (correlation
    under 0.2); the same seed the same one, bitwise."""
    a = 2e-4
    imp = f"-da_grid_x 401 -da_grid_y 401 -ts_type euler -cloth_imperfection {a},0.02"
    w1 = initial(tmp, "s1", f"{imp} -cloth_imperfection_seed 1")[..., 2] - 1
    w2 = initial(tmp, "s2", f"{imp} -cloth_imperfection_seed 2")[..., 2] - 1
    assert abs(np.sqrt(np.mean(w1**2)) / a - 1) < 0.05, np.sqrt(np.mean(w1**2))
    assert abs(np.sqrt(np.mean(w2**2)) / a - 1) < 0.05, np.sqrt(np.mean(w2**2))
    assert abs(w1.mean()) < 0.05 * a
    assert abs(np.corrcoef(w1.ravel(), w2.ravel())[0, 1]) < 0.2
    again = initial(tmp, "s1b", f"{imp} -cloth_imperfection_seed 1")[..., 2] - 1
    assert np.array_equal(w1, again)


def test_the_displacement_is_along_the_sheets_normal(tmp):
    """A vertical sheet (warp x, weft z) is displaced along its normal, warp x weft =
    -y, by the same field as the horizontal one along +z."""
    imp = "-da_grid_x 21 -da_grid_y 21 -cloth_imperfection 1e-3 -gravity 0,0,0"
    h = initial(tmp, "h", imp)
    v = initial(tmp, "v", f"{imp} -cloth_orientation vertical")
    assert np.abs(h[..., 2] - 1).max() > 1e-3
    assert np.abs((v[..., 1] - 0) + (h[..., 2] - 1)).max() < 1e-15
    assert np.abs(v[..., 0] - h[..., 0]).max() < 1e-15 and np.abs((v[..., 2] - 1) - h[..., 1]).max() < 1e-15


@pytest.mark.parametrize("args, what", [("-cloth_imperfection -1e-3", "-cloth_imperfection (its amplitude) must be zero or positive"),
                                        ("-cloth_imperfection nan", "-cloth_imperfection (its amplitude)"),
                                        ("-cloth_imperfection 1e-3,inf", "-cloth_imperfection (its wavelength)"),
                                        ("-cloth_imperfection 1e-3,0.01,2", "one value (amplitude) or two"),
                                        ("-cloth_imperfection 0.02,0.1", "more than 5% of its wavelength"),
                                        ("-cloth_imperfection 1e-3 -cloth_imperfection_seed -1", "-cloth_imperfection_seed must be zero or positive")])
def test_bad_imperfection_is_refused(args, what):
    refused(args, what)
