"""Partitions: DMDA blocks or METIS k-way give the same frames on 1-4 ranks, and
METIS balances an irregular (circular) cloth that DMDA blocks cannot."""
import numpy as np
import pytest

from conftest import Frames, run

CIRCLE = ("-da_grid_x 25 -da_grid_y 25 -cloth_shape circle -cloth_size 0.3 -cloth_center 0,0,0.0025 "
          "-solid_type cylinder -solid_radius 0.09 -solid_height 0.3 -solid_translate 0,0,-0.15 "
          "-ts_max_time 0.1 -output_interval 0.02")


@pytest.mark.parametrize("scheme,tol", [("-ts_type basicsymplectic -ts_dt 2e-4", 0.0),
                                        ("-ts_type beuler -ts_dt 2e-3 -ksp_rtol 1e-12", 1e-9)])
def test_same_frames_for_every_partition_and_rank_count(tmp, scheme, tol):
    ref = tmp / "ref.h5"
    run(f"{CIRCLE} {scheme} -output_file {ref}")
    a = Frames(ref)
    assert a.energy["kinetic"][-1] > 0
    for np_ in (2, 3, 4):
        for part in ("dmda", "metis"):
            out = tmp / f"{part}{np_}.h5"
            run(f"{CIRCLE} {scheme} -cloth_partition {part} -output_file {out}", np_=np_)
            b = Frames(out)
            assert np.abs(a.x - b.x).max() <= tol, (np_, part)


def quality(res):
    m = res.value(r"partition: \w+ on \d+ ranks, (\d+ to \d+) active", str).split(" to ")
    return int(m[0]), int(m[1]), res.value(r"imbalance ([0-9.]+)"), res.value(r"(\d+) of \d+ stretch edges cut", int)


def test_metis_balances_a_circular_cloth():
    """Every rank owns particles; METIS keeps the imbalance below 5 % on 3 ranks
    where DMDA's row blocks of a disc are over 20 % off, with a comparable cut."""
    base = "-da_grid_x 41 -da_grid_y 41 -cloth_shape circle -ts_max_steps 0"
    dmda = quality(run(f"{base} -cloth_partition dmda", np_=3))
    metis = quality(run(f"{base} -cloth_partition metis", np_=3))
    assert metis[0] > 0 and dmda[0] > 0
    assert metis[2] < 1.05 < 1.2 < dmda[2], (metis, dmda)
    assert metis[3] <= 1.5 * dmda[3]
