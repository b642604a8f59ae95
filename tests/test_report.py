"""The run's report: the JSON line of -drape_json (read by scripts/drape_run.py) and
the attributes of the HDF5 file's root (read by scripts/drape_h5.py) hold the same
entries, agree with the last frame, and say what the console prose says to its
printed precision (the prose is for people; these tests keep it honest)."""
import math

import pytest

from conftest import printed, run

import drape_h5

HANG = "-options_file runs/hang.opts -da_grid_x 16 -da_grid_y 12 -ts_max_steps 7 -output_interval 0.004"
CUSICK = "-options_file runs/cusick.opts -da_grid_x 31 -da_grid_y 31 -ts_max_time 0.04"


def same(report, attrs):
    """Every entry of the report is a root attribute of the file, with the same value
    (bools stored as 0/1, null as NaN or infinity)."""
    assert set(report) <= set(attrs), set(report) - set(attrs)
    for k, v in report.items():
        if v is None:
            assert not math.isfinite(attrs[k]), k
        else:
            assert attrs[k] == (int(v) if isinstance(v, bool) else v), (k, v, attrs[k])


def shown(value, fmt):
    """`value` as the prose prints it with C format `fmt`, as a number."""
    return float(format(value, fmt))


@pytest.fixture(scope="module")
def hang(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "hang.h5"
    res = run(f"{HANG} -output_file {out}")
    return res, drape_h5.load(out)


def test_json_line_is_the_file_attributes(hang):
    res, fr = hang
    rep = res.report
    same(rep, fr.attrs)
    assert "options" in fr.attrs and "description" not in fr.attrs and "lattice_Mx" not in fr.attrs
    assert (rep["ranks"], rep["lattice_mx"], rep["lattice_my"], rep["particles"], rep["pinned"]) == (1, 16, 12, 192, 2)
    assert (rep["active_particles"], rep["partition"], rep["owned_min"], rep["owned_max"], rep["stretch_edges_cut"]) == (192, "dmda", 192, 192, 0)
    assert (rep["ts_type"], rep["dt"], rep["t_max"], rep["snes_type"], rep["ksp_type"]) == ("drapebe", 2e-3, 4.0, "ksponly", "cg")
    assert rep["at_rest"] is False and rep["stopped_by"] == ""


def test_summary_is_the_last_frame(hang):
    """"steps" (of this run), "step" and "t" are those of the last frame; the strain is the frame's."""
    res, fr = hang
    rep = res.report
    assert rep["steps"] == rep["step"] == fr.step[-1] == 7
    assert rep["t"] == fr.time[-1]
    assert rep["strain_max"] == fr.strain_max[-1]
    assert (fr.shape, fr.attrs["mass"]) == ((12, 16), rep["mass"])
    assert rep["particle_steps_per_s"] == pytest.approx(rep["steps"] * rep["particles"] / rep["wall"])


def test_prose_says_the_report(hang):
    """The start-up lines and the summary line print the report's numbers (PETSc's %g
    prints 500 as "500.", hence the comparison as numbers)."""
    res, _ = hang
    rep = res.report

    def f(pattern, cast=float):
        return printed(res, pattern, cast)

    assert f(r"Cloth: (\d+) x", int) == rep["lattice_mx"] and f(r" x (\d+) particles", int) == rep["lattice_my"]
    assert f(r"(\d+) pinned", int) == rep["pinned"] and f(r"mass (\S+) kg") == shown(rep["mass"], "g")
    assert f(r"material: stretch (\S+),") == shown(rep["stretch_warp"], "g") and f(r"stretch \S+,(\S+) N/m") == shown(rep["stretch_weft"], "g")
    assert f(r"shear (\S+) N/m") == shown(rep["shear"], "g") and f(r"bend ([^,]+),") == shown(rep["bend_warp"], "g")
    assert f(r"bend [^,]+,([^,]+),") == shown(rep["bend_weft"], "g") and f(r"bend [^,]+,[^,]+,(\S+) N m") == shown(rep["bend_bias"], "g")
    assert f(r"model: (\w+)", str) == rep["model"] == "drape" and f(r"(\d+) bending triples", int) == rep["bending_triples"]
    assert f(r"density (\S+) kg") == shown(rep["density"], "g") and f(r"damping (\S+) 1/s") == shown(rep["damping"], "g")
    assert f(r"Omega_max = (\S+) rad/s", str) == format(rep["omega_max"], ".4e")
    assert f(r"symplectic Euler: stable for h < (\S+) s", str) == format(rep["symplectic_limit"], ".4e")
    assert f(r"explicit Euler: stable for h < (\S+) s", str) == format(rep["euler_limit"], ".4e")
    assert f(r"-ts_type (\w+), h = ", str) == rep["ts_type"] and f(r", h = (\S+) s") == shown(rep["dt"], "g")
    assert f(r"PC (\w+) on an assembled (\w+)", str) == rep["pc_type"] and f"assembled {rep['mat_type']} matrix" in res.stdout
    assert f"(block size 3, {rep['mat_product']}'s product)" in res.stdout and rep["mat_product"] == "drape"
    assert f(r"Summary: (\d+) steps", int) == rep["steps"] and f(r"steps to t = (\S+) s") == shown(rep["t"], "g")
    assert f(r"in (\S+) s wall") == shown(rep["wall"], ".3f") and f(r"wall, (\S+) particle-steps/s") == shown(rep["particle_steps_per_s"], ".4e")
    assert f(r"(\S+) CG iterations per step") == shown(rep["cg_per_step"], ".2f")
    assert f(r"largest edge strain (\S+) %") == shown(100 * rep["strain_max"], ".3g")
    assert rep["pc_switched_step"] == -1 and rep["pc_fill_step"] == -1 and rep["steps_rejected_error"] == 0  # ICC(0) throughout, fixed steps


def test_limits_without_damping_and_without_estimate():
    """No damping: explicit Euler is unstable at every step, euler_limit 0 (Result.limits:
    NaN). -drape_stability_its 0: no estimate, no limits. -ts_max_steps 0 still ends with
    the report, as the last line; explicit schemes have no solver entries."""
    base = "-da_grid_x 8 -da_grid_y 8 -cloth_pin edge_corners -ts_type basicsymplectic -ts_dt 1e-4 -ts_max_steps 0"
    res = run(f"{base} -cloth_damping 0", checks=False)
    assert "explicit Euler: unstable at every step" in res.stdout
    assert res.report["euler_limit"] == 0 and math.isnan(res.limits()["explicit"])
    assert res.limits()["symplectic"] == res.report["symplectic_limit"] > 0
    assert res.stdout.splitlines()[-1].startswith('{"drape_version": ')
    assert (res.report["steps"], res.report["step"], res.report["t"]) == (0, 0, 0)
    assert not {"snes_type", "ksp_type", "pc_type", "mat_type", "mat_product", "pc_switched_step", "pc_fill_step"} & set(res.report)
    assert res.report["cg_per_step"] == 0 and res.report["solves_per_step"] == 0
    res = run(f"{base} -drape_stability_its 0", checks=False)
    assert not {"omega_max", "symplectic_limit", "euler_limit"} & set(res.report) and res.limits() is None
    assert "Omega_max" not in res.stdout


def test_two_ranks_report_the_same_cloth(hang, tmp):
    one = hang[0].report
    out = tmp / "two.h5"
    two = run(f"{HANG} -output_file {out}", np_=2).report
    same(two, drape_h5.load(out).attrs)  # wall time included: the job's, max over ranks
    assert two["ranks"] == 2 and two["owned_min"] + two["owned_max"] == two["active_particles"] == 192
    assert two["partition"] == "dmda" and two["stretch_edges_cut"] > 0
    for k in ("lattice_mx", "lattice_my", "particles", "pinned", "steps", "step", "t", "ts_type", "ksp_type"):
        assert two[k] == one[k], k
    for k in ("mass", "omega_max", "symplectic_limit", "euler_limit"):
        assert two[k] == pytest.approx(one[k], rel=1e-9), k
    assert two["strain_max"] == pytest.approx(one["strain_max"], rel=1e-3)  # block Jacobi has a block per rank
    assert two["mat_type"] == "mpisbaij" and one["mat_type"] == "seqsbaij"
    assert two["mat_product"] == one["mat_product"] == "drape"  # each rank's diagonal block takes drape's


def test_cloth_without_interactions_reports_null_not_a_number_that_means_nothing():
    """Free particles (no stretch, shear or bending): Omega_max 0, so no symplectic limit
    (null, where PETSc's "infinity" would print 4.49e307) and no edge strain (null; the
    prose says there are no stretch edges); the HDF5 file holds infinity and NaN."""
    out_args = "-da_grid_x 6 -da_grid_y 6 -cloth_stretch 0 -cloth_shear 0 -cloth_bend 0 -ts_max_steps 3"
    res = run(out_args, checks=False)
    rep = res.report
    assert rep["omega_max"] == 0 and rep["symplectic_limit"] is None and rep["strain_max"] is None
    assert rep["euler_limit"] == pytest.approx(2 / rep["damping"])
    assert "; no stretch edges" in res.stdout and "largest edge strain" not in res.stdout


def test_cusick_drape_coefficient(tmp):
    """A Cusick run (stopped early: the numbers, not the drape, are tested) reports DC and
    folds as it prints them and as its file holds them."""
    out = tmp / "cusick.h5"
    res = run(f"{CUSICK} -output_file {out}")
    rep = res.report
    assert printed(res, r"drape coefficient DC = (\S+),", str) == format(rep["drape_coefficient"], ".4f")
    assert printed(res, r", (\d+) folds", int) == rep["drape_folds"]
    assert isinstance(rep["drape_folds"], int) and 0 < rep["drape_coefficient"] <= 1
    same(rep, drape_h5.load(out).attrs)
    assert "drape_coefficient" not in run(f"{HANG} -ts_max_steps 1", checks=False).report


def test_errors_have_no_report():
    """A refused run and a diverged one end with one sentence and no report; drape_run
    reads the sentence (status, the step of a divergence)."""
    res = run("-cloth_density 0 -ts_max_steps 1", check=False)
    assert res.report is None and res.status() == "failed" and "-cloth_density must be positive" in res.error()
    res = run("-da_grid_x 10 -da_grid_y 10 -cloth_pin edge_corners -ts_type basicsymplectic -ts_dt 2e-3 -ts_max_time 10", check=False)
    assert res.report is None and res.status() == "diverged"
    assert res.diverged_at() > 0 and f"The run diverged at step {res.diverged_at()} (" in res.error()


def test_setup_memory_per_particle():
    """The start-up report says what the set-up cost per particle (resident memory it
    added): an explicit run keeps the state (48 bytes), the masses and flags, the
    element lists (132 bytes) and the lattice kernel's classes (7 bytes), not PETSc's
    work copy of the state, an acceleration or force array, a third local vector or a
    ghost scatter on one rank (about 390 bytes a particle at d1f95c6; 236 at 1024^2
    now, 229 at 2048^2; issue 26's floor: 250 at 2048^2)."""
    res = run("-da_grid_x 1024 -da_grid_y 1024 -cloth_pin edge_corners -ts_type basicsymplectic -ts_dt 1e-6 -ts_max_steps 1 -drape_stability_its 0 -drape_json")
    assert 132 < res.report["setup_bytes_per_particle"] < 250


@pytest.mark.parametrize("np_", (1, 2))
def test_peak_memory_is_drapes_own(tmp, np_):
    """The peak memory the report gives (and the scripts and tests read) is drape's
    own: a small run launched by a process that holds 400 MB reports under 100 MB a
    rank. Linux's ru_maxrss of the launched process counts the RSS of the process it
    was forked from (at least the 400 MB here), so this would be false if drape
    reported it, or if the scripts read os.wait4's figure when the report has one."""
    ballast = b"\x01" * (400 << 20)  # written, so resident
    res = run(f"{HANG} -output_file {tmp / 'peak.h5'}", np_=np_)
    rep = res.report
    assert 5e6 < rep["memory_peak_rank_max"] < 100e6 and res.maxrss == rep["memory_peak_rank_max"]
    assert rep["memory_peak_rank_max"] <= rep["memory_peak"] <= np_ * rep["memory_peak_rank_max"]
    assert len(ballast) == 400 << 20
