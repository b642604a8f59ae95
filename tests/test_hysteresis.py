"""Bending hysteresis (-cloth_bend_hysteresis): the friction between a bent fabric's
yarns as an elastic-perfectly plastic element per thread triple (src/cloth/kernels.h,
KernelFriction; its kernel is Taylor-tested in tests/unit/test_kernels.c). Here: the
strip it bends rests on the heavy cantilever of its law, the plastic state is the same
on any number of ranks, and bad values are refused."""
import hashlib
import signal
import subprocess
import sys

import numpy as np
import pytest

from conftest import DRAPE, ROOT, ROUNDOFF, refused, run, wait_for_frames

sys.path.insert(0, str(ROOT / "scripts"))
import cantilever  # noqa: E402
import drape_h5  # noqa: E402
import elastica  # noqa: E402

CIRCLE = ("-da_grid_x 25 -da_grid_y 25 -cloth_shape circle -cloth_size 0.3 -cloth_center 0,0,0.0025 "
          "-solid_type cylinder -solid_radius 0.09 -solid_height 0.3 -solid_translate 0,0,-0.15 "
          "-ts_max_time 0.1 -output_interval 0.02 -cloth_bend_hysteresis 5e-4 -drape_json")


def test_law_elastica_known_answers():
    """elastica.solve_law: with the elastic law it is the elastica (solve, to 1e-9); with
    Grosberg's law at a stick stiffness of 1e6 B it is solve_frictional (1e-5); the
    regularised law (stick K = r B) bends the strip more than the rigid-plastic one and
    less than the elastica, and converges to the rigid-plastic one as r grows (the
    error falls about as 1/r)."""
    for lam in (2.0, 8.0, 30.0):
        a, b = elastica.solve(lam), elastica.solve_law(lam, lambda m: m)
        assert abs(a.drop - b.drop) < 1e-9 and abs(a.reach - b.reach) < 1e-9, (lam, a.drop, b.drop)
    for eta in (0.5, 1.0, 2.0):
        f = elastica.solve_frictional(8.0, eta)
        g = elastica.solve_law(8.0, elastica.grosberg_law(eta, 1e6))
        assert abs(f.drop - g.drop) < 1e-5 and abs(f.reach - g.reach) < 1e-5, (eta, f.drop, g.drop)
        drops = [elastica.solve_law(8.0, elastica.grosberg_law(eta, r)).drop - f.drop for r in (5.0, 20.0, 80.0)]
        assert all(d > 0 for d in drops) and elastica.solve(8.0).drop > f.drop + drops[0], drops
        assert 2.5 < drops[0] / drops[1] < 5.5 and 2.5 < drops[1] / drops[2] < 5.5, drops
    with pytest.raises(ValueError):
        elastica.grosberg_law(-1.0)


@pytest.mark.parametrize("angle", [0, 90])
def test_cantilever_with_bending_friction_rests_on_its_law(angle):
    """A denim strip (paper's model: thread triples only) at lambda = 8 with the friction
    moment HB = B / L (eta = 1) and stick stiffness 20 B, released flat and overdamped
    (damping 10 x its first frequency, so it does not swing back and unload): its tip
    rests within 5 % of the heavy cantilever of Grosberg's regularised law on first
    loading, and 30 % higher than the elastica without friction; the error falls with
    the spacing."""
    err = {}
    for n in (5, 10):
        r = cantilever.run_case(angle, n, lam=8.0, fabric=("-cloth_fabric", "denim", "-cloth_model", "paper"), eta=1.0, stick=20.0, damping=10.0, drape=DRAPE)
        assert r["at_rest"], r
        assert abs(r["drop_err"]) < 0.05 and abs(r["reach_err"]) < 0.05, r
        assert r["drop"] < 0.75 * elastica.solve(8.0).drop * r["L"], r
        err[n] = max(abs(r["drop_err"]), abs(r["reach_err"]))
    assert err[10] < 0.5 * err[5], err  # measured: 2.5 % -> 0.5 % (warp), 0.2 % (weft); 0.1 % at 20 rows


def test_plastic_state_is_the_same_on_any_rank_count(tmp):
    """The slider's curvature is a state of each triple, updated after every step by
    every rank holding the triple from the same positions: symplectic Euler's frames
    are the same on 1, 2 and 3 ranks (METIS) to the BLAS's rounding (conftest.ROUNDOFF),
    backward Euler's within solver round-off; the friction acted (hundreds of triples slid and kept a plastic
    curvature; the frames differ from the run without it by centimetres)."""
    for scheme, tol in (("-ts_type basicsymplectic -ts_dt 2e-4", ROUNDOFF), ("-ts_type drapebe -ts_dt 2e-3 -ksp_rtol 1e-12", 1e-9)):
        ref = tmp / "ref.h5"
        res = run(f"{CIRCLE} {scheme} -output_file {ref}")
        assert res.report["hysteresis_plastic_triples"] > 100, res.report
        a = drape_h5.load(ref)
        for np_ in (2, 3):
            out = tmp / f"n{np_}.h5"
            res = run(f"{CIRCLE} {scheme} -cloth_partition metis -output_file {out}", np_=np_)
            assert np.abs(a.positions - drape_h5.load(out).positions).max() <= tol, (scheme, np_)
    run(f"{CIRCLE} -ts_type basicsymplectic -ts_dt 2e-4 -cloth_bend_hysteresis 0 -output_file {tmp / 'none.h5'}")
    assert np.abs(a.positions - drape_h5.load(tmp / "none.h5").positions).max() > 5e-3


def test_bending_friction_defaults_to_newton_and_the_options_override_it():
    """drapebe's SNES is newtonls with bending friction, ksponly without: a default set
    on the SNES before the options, so that -snes_type still chooses."""
    base = "-da_grid_x 8 -da_grid_y 8 -cloth_pin edge_corners -ts_type drapebe -ts_dt 2e-3 -ts_max_steps 2"
    assert run(f"{base} -cloth_bend_hysteresis 5e-4").report["snes_type"] == "newtonls"
    assert run(f"{base} -cloth_bend_hysteresis 5e-4 -snes_type ksponly").report["snes_type"] == "ksponly"
    assert run(base).report["snes_type"] == "ksponly"


def test_newton_with_friction_takes_its_steps_without_a_failed_solve():
    """Denim's Cusick drape with the median friction (BENCHMARKS.md, "Bending
    hysteresis"), 31^2, its first 40 steps of 1 ms: Newton's default line search (cp,
    for a residual that is the gradient of the step's potential and an SPD matrix that
    is not its Jacobian) takes every step at once, and block IC stays. Backtracking on
    |R| (bt, PETSc's default, chosen here by -snes_linesearch_type) fails near
    convergence: steps retried at a quarter. Those failures, after linear solves that
    converged, are not the preconditioner's, and block IC stays (they were taken for
    its, and it gave way to the multigrids)."""
    base = ("-options_file runs/cusick.opts -cloth_fabric denim -cloth_bend_hysteresis 2.363e-3,1.565e-3 "
            "-da_grid_x 31 -da_grid_y 31 -ts_max_steps 40 -output_interval 0")
    rep = run(base).report
    assert rep["steps"] == 40 and rep["steps_retried"] == 0 and rep["pc_switched_step"] == -1, rep
    rep = run(f"{base} -snes_linesearch_type bt").report
    assert rep["steps_retried"] > 0 and rep["pc_switched_step"] == -1, rep


@pytest.mark.parametrize("args, what", [("-cloth_bend_hysteresis -1e-3", "-cloth_bend_hysteresis"),
                                        ("-cloth_bend_hysteresis nan", "-cloth_bend_hysteresis"),
                                        ("-cloth_bend_hysteresis 1e-3,1e-3,1e-3", "one value (warp = weft) or two"),
                                        ("-cloth_bend_hysteresis 1e-3 -cloth_model paper -cloth_bend 0,1e-5", "needs a warp bending rigidity"),
                                        ("-cloth_bend_hysteresis 1e-3 -cloth_bend_hysteresis_stiffness 0", "-cloth_bend_hysteresis_stiffness")])
def test_bad_hysteresis_is_refused(args, what):
    refused(args, what)


def test_restart_of_a_run_with_hysteresis_is_refused(tmp):
    """The frames do not hold the plastic curvature: a restart would forget it, so it is
    refused in one sentence and the file is left as it was."""
    out = tmp / "h.h5"
    run(f"-da_grid_x 8 -da_grid_y 8 -cloth_bend_hysteresis 1e-4 -ts_max_steps 3 -output_interval 1e-3 -output_file {out}")
    before = hashlib.sha256(out.read_bytes()).hexdigest()
    res = run(f"-restart {out} -ts_max_time 1", check=False)
    msg = res.stdout + res.stderr
    assert res.returncode != 0 and "-restart cannot continue a run with -cloth_bend_hysteresis" in msg and "PETSC ERROR" not in msg, msg
    assert hashlib.sha256(out.read_bytes()).hexdigest() == before


def test_sigterm_of_a_run_with_hysteresis_does_not_promise_a_restart(tmp):
    """Stopped by SIGTERM, a run with bending friction keeps its frames but says that
    -restart cannot continue it, and exits 1, not 75: a batch script that requeues on
    75 (runs/cluster/drape.slurm) would start a job that can only fail."""
    out = tmp / "h.h5"
    proc = subprocess.Popen([str(DRAPE), "-da_grid_x", "16", "-da_grid_y", "16", "-cloth_bend_hysteresis", "1e-4", "-ts_type", "basicsymplectic",
                             "-ts_dt", "1e-4", "-ts_max_time", "100", "-output_steps", "50", "-drape_progress", "0", "-output_file", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_frames(out, 3)
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 1, stdout + stderr
    assert "Stopped by SIGTERM" in stdout and "-restart cannot continue a run with -cloth_bend_hysteresis" in stdout, stdout
    assert "continue with -restart" not in stdout and "PETSC ERROR" not in stdout + stderr
    assert drape_h5.load(out).nframes >= 3
