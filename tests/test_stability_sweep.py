"""scripts/stability_sweep.py --quick: the bisection finds the printed symplectic limit,
no run ends in a silent NaN, every divergence is drape's own message."""
import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "stability_sweep.py"
SWEEPS = ("stretch", "density", "damping", "lattice")


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("stability")
    proc = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert proc.returncode == 0, f"stability_sweep failed:\n{proc.stdout}\n{proc.stderr}"
    return out


def test_outputs_exist(quick):
    for name in SWEEPS:
        assert (quick / f"sweep_{name}.csv").is_file()
        assert (quick / f"sweep_{name}.png").stat().st_size > 0
        assert len([r for r in rows(quick / f"sweep_{name}.csv") if r["scheme"] == "symplectic"]) == 2
    for name in ("backward_euler.csv", "summary.md", "summary.json", "runs.csv"):
        assert (quick / name).is_file()


def test_symplectic_limit_matches_printed(quick):
    for name in SWEEPS:
        for r in rows(quick / f"sweep_{name}.csv"):
            if r["scheme"] != "symplectic":
                continue
            ratio = float(r["measured"]) / float(r["printed"])
            assert 0.8 <= ratio <= 1.25, f"{name}={r['value']}: measured/printed {ratio}"
            assert int(r["failed"]) == 0


def test_no_silent_nan_and_divergences_caught(quick):
    counts = json.loads((quick / "summary.json").read_text())
    assert counts["silent_nan"] == 0, counts["silent_nan_runs"]
    assert counts["unexpected_failures"] == [], counts["unexpected_failures"]
    assert counts["diverged_caught"] > 0  # the bisection must have seen unstable steps
    log = rows(quick / "runs.csv")
    assert len(log) == counts["runs"] - counts["solver_errors"]
    for r in log:
        if int(r["rc"]) != 0:
            assert r["status"] == "diverged" and r["stderr"].startswith("drape: error: The run diverged at step"), r
        else:
            assert r["status"] == "ok" and int(r["nonfinite"]) == 0, r


def test_limit_falls_with_stiffness(quick):
    sym = sorted((float(r["value"]), float(r["measured"])) for r in rows(quick / "sweep_stretch.csv")
                 if r["scheme"] == "symplectic")
    assert len(sym) >= 2
    assert all(b[1] < a[1] for a, b in zip(sym, sym[1:])), sym


def test_backward_euler_at_250_times_the_symplectic_limit_reaches_the_end(quick):
    """Both backward-Euler solvers take the stiff light fabric (1e4 N/m, 0.05 kg/m^2) at
    0.05 s, about 250 x the symplectic limit, to t = 1 s within the quick sweep's 2000
    steps; Newton only with a line search for its SPD matrix (drape's default, cp:
    backtracking on |R| cut the step again and again and stopped near t = 0.07 s).
    (At such a step both are far from the true motion, which they damp: 0.3-0.4 m RMS
    from a small-step reference at t = 1 s; BENCHMARKS.md, "Stability stress test".)"""
    (r,) = rows(quick / "backward_euler.csv")
    assert float(r["h"]) == 0.05 and float(r["h_over_sym_limit"]) > 200
    for s in ("ksponly", "newtonls"):
        assert r[f"{s}_status"] == "ok" and r[f"{s}_nonfinite"] == "False", r
        assert float(r[f"{s}_t_reached"]) == pytest.approx(1.0), r
