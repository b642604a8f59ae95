"""Checkpoint and restart: continued runs match uninterrupted ones, SIGTERM writes a
checkpoint and exits cleanly, bad restart files are refused with one sentence."""
import signal
import subprocess

import h5py
import numpy as np
import pytest

from conftest import DRAPE, ROOT, ROUNDOFF, run, wait_for_frames

import drape_h5
import drape_run

SCENE = "-da_grid_x 12 -da_grid_y 10 -cloth_pin edge_corners -output_interval 0.01"


@pytest.mark.parametrize("scheme,tol,np_restart", [
    ("-ts_type basicsymplectic -ts_dt 2e-4", 0.0, 1),
    ("-ts_type basicsymplectic -ts_dt 2e-4", ROUNDOFF, 2),
    ("-ts_type drapebe -ts_dt 2e-3 -ksp_rtol 1e-12", 1e-10, 2),
])
def test_restart_matches_uninterrupted_run(tmp, scheme, tol, np_restart):
    """Stop at t = 0.05, restart (possibly on another number of ranks) to 0.1: the
    file then holds the frames of the uninterrupted run (symplectic: bitwise on as
    many ranks, round-off on others; backward Euler: solver tolerance)."""
    full, part = tmp / "full.h5", tmp / "part.h5"
    run(f"{SCENE} {scheme} -ts_max_time 0.1 -output_file {full}")
    run(f"{SCENE} {scheme} -ts_max_time 0.05 -output_file {part}")
    res = run(f"-restart {part} -ts_max_time 0.1", np_=np_restart)
    a, b = drape_h5.load(full), drape_h5.load(part)
    assert len(a.time) == len(b.time) == 11
    assert np.allclose(a.time, b.time, rtol=0, atol=1e-12)
    assert np.array_equal(a.step, b.step)
    assert np.abs(a.positions - b.positions).max() <= tol and np.abs(a.velocities - b.velocities).max() <= tol * 100
    assert (tmp / "part.xmf").read_text().count("<Time Value=") == 11
    # the report counts the steps of the restarted run; "step" goes on from the file's
    assert res.report["step"] == b.step[-1] and res.report["steps"] == b.step[-1] - b.step[5]
    assert res.report["t"] == b.time[-1] and res.report["ranks"] == np_restart


def test_sigterm_writes_a_checkpoint_and_restart_continues(tmp):
    out, full = tmp / "sig.h5", tmp / "full.h5"
    args = "-da_grid_x 40 -da_grid_y 40 -cloth_pin edge_corners -ts_type basicsymplectic -ts_dt 1e-4 -output_steps 200"
    proc = subprocess.Popen([str(DRAPE)] + args.split() + ["-ts_max_time", "100", "-drape_progress", "0", "-drape_json", "-output_file", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_frames(out, 3)
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 75, stdout + stderr
    assert "Stopped by SIGTERM" in stdout and f"-restart {out}" in stdout
    stopped = drape_h5.load(out)
    stop_step = int(stopped.step[-1])
    report = drape_run.parse_report(stdout)  # a run stopped by SIGTERM completes its report
    assert report["stopped_by"] == "SIGTERM" and report["step"] == stop_step and report["t"] == stopped.time[-1]
    assert stopped.attrs["stopped_by"] == "SIGTERM" and stopped.attrs["step"] == stop_step
    t_end = stopped.time[-1] + 0.05
    # continue to t_end; an uninterrupted run to t_end has the same scheduled frames
    run(f"-restart {out} -ts_max_time {t_end}")
    run(f"{args} -ts_max_time {t_end} -output_file {full}")
    a, b = drape_h5.load(full), drape_h5.load(out)
    sched = [k for k, s in enumerate(b.step) if s % 200 == 0]
    assert stop_step % 200 != 0 or len(sched) == len(b.step)
    assert np.array_equal(b.positions[sched], a.positions[: len(sched)]) and np.array_equal(b.step[sched], a.step[: len(sched)])
    assert np.array_equal(b.positions[-1], a.positions[-1])


@pytest.mark.parametrize("kind,message", [("missing", "does not exist"), ("text", "not an HDF5 file"),
                                          ("foreign", "not written by drape"), ("empty", "holds no complete frame")])
def test_bad_restart_file_is_refused(tmp, kind, message):
    path = tmp / f"{kind}.h5"
    if kind == "text":
        path.write_text("not hdf5\n")
    elif kind == "foreign":
        with h5py.File(path, "w") as f:
            f["x"] = [1.0, 2.0]
    elif kind == "empty":
        with h5py.File(path, "w") as f:
            f.attrs["drape_version"], f.attrs["options"] = "0", "-da_grid_x 4"
            for name in ("time", "step"):
                f.create_dataset(name, shape=(0, 1))
            for name in ("position", "velocity"):
                f.create_dataset(name, shape=(0, 4, 4, 3))
    res = subprocess.run([str(DRAPE), "-restart", str(path)], capture_output=True, text=True, cwd=tmp)
    lines = [l for l in res.stderr.splitlines() if l.strip()]
    assert res.returncode != 0 and len(lines) == 1 and message in lines[0], res.stderr


def test_file_cut_at_random_bytes_is_refused_or_read_to_a_whole_frame(tmp):
    src = tmp / "src.h5"
    run(f"{SCENE} -ts_type basicsymplectic -ts_dt 2e-4 -ts_max_time 0.05 -output_file {src}")
    data = src.read_bytes()
    rng = np.random.default_rng(2026)
    for cut in sorted(rng.integers(1, len(data), size=6)):
        path = tmp / f"cut{cut}.h5"
        path.write_bytes(data[:cut])
        res = subprocess.run([str(DRAPE), "-restart", str(path), "-ts_max_time", "0.06", "-drape_progress", "0"],
                             capture_output=True, text=True, cwd=tmp)
        if res.returncode:
            lines = [l for l in res.stderr.splitlines() if l.strip()]
            assert len(lines) == 1 and "Cannot restart from" in lines[0], res.stderr
        else:
            assert "Summary:" in res.stdout


def test_restart_writes_the_file_it_continues_unless_told(tmp):
    """The frames go on in the file restarted from (the output's default), not in the
    file its stored options name (a copy's name the original, which must stay as it
    is); -output_file names another."""
    part, copy, other = tmp / "part.h5", tmp / "copy.h5", tmp / "other.h5"
    run(f"{SCENE} -ts_type basicsymplectic -ts_dt 2e-4 -ts_max_time 0.02 -output_file {part}")
    copy.write_bytes(part.read_bytes())
    before = part.read_bytes()
    run(f"-restart {copy} -ts_max_time 0.04")
    assert part.read_bytes() == before
    assert len(drape_h5.load(copy).time) == 5 and len(drape_h5.load(part).time) == 3
    run(f"-restart {part} -ts_max_time 0.03 -output_file {other}")
    assert part.read_bytes() == before and drape_h5.load(other).time[0] > 0.02 - 1e-12
