"""scripts/work_precision.py --quick: every scheme has rows, the first-order schemes'
errors fall with the step, the work-precision PNGs are drawn, the fastest-scheme
table is written and the reference check (two RK4 references) is recorded."""
import csv
import subprocess
import sys
import warnings

import numpy as np
import pytest

from conftest import ROOT

SCRIPT = ROOT / "scripts" / "work_precision.py"
SCHEMES = ["explicit Euler", "symplectic Euler", "backward Euler", "RK2", "RK4", "RK5DP adaptive"]
FIRST_ORDER = ["explicit Euler", "symplectic Euler", "backward Euler"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("wp")
    proc = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--out", str(out)], capture_output=True, text=True,
                          timeout=120, cwd=ROOT)
    assert proc.returncode == 0, f"work_precision.py --quick failed:\n{proc.stdout}\n{proc.stderr}"
    with open(out / "work_precision.csv") as f:
        rows = list(csv.DictReader(f))
    return out, rows, proc.stdout


def test_rows_for_every_scheme(study):
    _, rows, _ = study
    assert set(rows[0]) == {"scene", "scheme", "dt", "tol", "steps", "wall_s", "err_rms", "err_max", "status"}
    for scene in ("hang", "swing"):
        for scheme in SCHEMES:
            mine = [r for r in rows if r["scene"] == scene and r["scheme"] == scheme]
            assert len(mine) == 2, f"{scene}/{scheme}: expected 2 rows (2 sizes in --quick), got {mine}"
            for r in mine:
                assert r["status"] == "ok", r
                assert float(r["wall_s"]) >= 0 and int(r["steps"]) > 0
                assert 0 < float(r["err_rms"]) <= float(r["err_max"]) < 0.1, r
            assert all(r["tol" if scheme == "RK5DP adaptive" else "dt"] for r in mine)
    rest = {r["scheme"] for r in rows if r["scene"] == "rest" and r["status"] == "ok"}
    assert {"symplectic Euler", "backward Euler"} <= rest


def test_first_order_errors_fall_with_the_step(study):
    _, rows, _ = study
    for scene in ("hang", "swing"):
        for scheme in FIRST_ORDER:
            mine = sorted((float(r["dt"]), float(r["err_max"]), float(r["err_rms"])) for r in rows
                          if r["scene"] == scene and r["scheme"] == scheme)
            (dt1, max1, rms1), (dt2, max2, rms2) = mine
            assert dt1 < dt2
            assert max1 < max2 and rms1 < rms2, f"{scene}/{scheme}: error did not fall with the step: {mine}"
            # first order: a step ten times smaller gives an error about ten times smaller
            order = np.log(max2 / max1) / np.log(dt2 / dt1)
            assert 0.7 < order < 1.3, f"{scene}/{scheme}: observed order {order:.2f}: {mine}"


def test_reference_check_recorded(study):
    _, rows, stdout = study
    for scene in ("hang", "swing", "rest"):
        ref = [r for r in rows if r["scene"] == scene and r["status"] == "ref_check"]
        assert len(ref) == 1, f"{scene}: no reference-check row"
        diff = float(ref[0]["err_max"])
        smallest = min(float(r["err_max"]) for r in rows if r["scene"] == scene and r["status"] == "ok")
        assert diff * 10 <= smallest, f"{scene}: reference difference {diff} not far below the smallest error {smallest}"
        assert f"{scene}: references dt_ref=" in stdout


def test_png_not_blank(study):
    out, _, _ = study
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import matplotlib.image
    for scene in ("hang", "swing", "rest"):
        png = out / f"wp_{scene}.png"
        assert png.exists() and png.stat().st_size > 5000, png
        img = matplotlib.image.imread(png)[..., :3]
        assert img.std() > 0.05, f"{png} looks blank"
        # coloured lines are drawn (not only black axes on white)
        assert (np.ptp(img, axis=-1) > 0.3).sum() > 500, f"{png} has no scheme lines"


def test_fastest_table(study):
    out, _, stdout = study
    md = (out / "fastest.md").read_text()
    assert "| scene | target err_max | fastest scheme |" in md
    for scene in ("hang", "swing", "rest"):
        for t in ("1e-02", "1e-03", "1e-04"):
            assert f"| {scene} | {t} |" in md
    assert "Reference check" in md and md.splitlines()[2] in stdout
