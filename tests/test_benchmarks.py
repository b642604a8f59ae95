"""The benchmark scripts paper_tables.py, scaling.py, solver_study.py, rtol_accuracy.py, implicit_study.py and bench_assembly.py in --quick mode:
their CSV columns and contents, and the claims they rest on (a dense implicit matrix
gives the AIJ frames, the Blender shortcut is less accurate than drape's default,
bytes per particle are plausible); plus -drape_mat_type dense on 1 and 2 ranks."""
import csv
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, run

import drape_h5

SCRIPTS = ROOT / "scripts"


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def quick(name, out):
    proc = subprocess.run([sys.executable, str(SCRIPTS / name), "--quick", "--out", str(out)], capture_output=True, text=True,
                          timeout=120, cwd=ROOT)
    assert proc.returncode == 0, f"{name} --quick failed:\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


def png_ok(path):
    assert path.is_file() and path.stat().st_size > 5000, path


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper_tables")
    return out, quick("paper_tables.py", out)


@pytest.fixture(scope="module")
def scaling(tmp_path_factory):
    out = tmp_path_factory.mktemp("scaling")
    return out, quick("scaling.py", out)


@pytest.fixture(scope="module")
def solver(tmp_path_factory):
    out = tmp_path_factory.mktemp("solver_study")
    return out, quick("solver_study.py", out)


def test_table1_dense_matches_aij(tables):
    out, _ = tables
    t1 = rows(out / "table1.csv")
    assert len(t1) == 2
    for col in ("particles", "dense_s", "csr_s", "drape_s", "dense_projected", "dense_vs_csr_max_diff", "csr_its_per_step", "paper_dense_s"):
        assert col in t1[0]
    for r in t1:
        assert float(r["dense_s"]) > 0 and float(r["csr_s"]) > 0 and float(r["drape_s"]) > 0
        # same matrix, same PC (none), same CG: the same positions to solver tolerance
        assert float(r["dense_vs_csr_max_diff"]) < 1e-7, r
    assert any(int(r["dense_projected"]) for r in t1)  # the projection path is exercised
    png_ok(out / "table1.png")


def test_table2_protocol(tables):
    out, stdout = tables
    t2 = rows(out / "table2.csv")
    assert [int(r["N"]) for r in t2] == [12, 16]
    for r in t2:
        h = float(r["explicit_critical_dt"])
        assert 0.5 < h / float(r["printed_symplectic_limit"]) < 3, r
        assert float(r["implicit10_dt"]) == pytest.approx(10 * h, rel=1e-3)
        assert float(r["explicit_s"]) >= 0 and float(r["implicit10_s"]) >= 0
        assert int(r["explicit_steps"]) > int(r["implicit10_steps"])
    md = (out / "tables.md").read_text()
    assert "## Table 1" in md and "## Table 2" in md and "Who wins" in md
    assert "paper dense" in md and "paper explicit" in md
    png_ok(out / "table2.png")


def test_scaling_columns_and_memory(scaling):
    out, _ = scaling
    sc = rows(out / "scaling.csv")
    for col in ("scheme", "N", "particles", "dt", "steps", "s_per_step", "s_per_simulated_s", "peak_rss_bytes", "bytes_per_particle"):
        assert col in sc[0]
    got = {(r["scheme"], int(r["N"])) for r in sc}
    assert got == {(s, n) for s in ("symplectic", "explicit", "beuler") for n in (16, 32)} | {("symplectic", 48), ("explicit", 48)}
    for r in sc:
        assert float(r["s_per_step"]) > 0 and float(r["s_per_simulated_s"]) > 0
        assert int(r["peak_rss_bytes"]) > 10 * 2**20
    mem = {r["scheme"]: r for r in rows(out / "memory.csv")}
    for s in ("symplectic", "explicit", "beuler"):
        bpp = float(mem[s]["bytes_per_particle"])
        # at least the state (6 doubles) and at most a few dense 3x3 blocks per neighbour
        assert 48 < bpp < 2e4, (s, bpp)
        assert int(mem[s]["max_lattice_side"]) > 1000
    # the implicit scheme stores a matrix and its ILU factor
    assert float(mem["beuler"]["bytes_per_particle"]) > float(mem["symplectic"]["bytes_per_particle"])
    png_ok(out / "scaling.png")
    assert "bytes/particle" in (out / "scaling.md").read_text()


def test_solver_pcs(solver):
    out, _ = solver
    pcs = rows(out / "pcs.csv")
    for n in (16, 24):
        mine = {r["pc"]: r for r in pcs if int(r["N"]) == n}
        assert set(mine) == {"none", "jacobi", "bjacobi", "icc", "gamg", "hypre"}
        for r in mine.values():
            assert r["status"] == "ok" or r["status"].startswith("DIVERGED"), r
            if r["status"] == "ok":
                assert float(r["cg_its_per_step"]) > 0 and float(r["s_per_step"]) > 0
        assert mine["bjacobi"]["status"] == "ok"
        # a preconditioner cuts CG iterations
        assert float(mine["bjacobi"]["cg_its_per_step"]) < float(mine["none"]["cg_its_per_step"])
    png_ok(out / "pcs.png")


def test_blender_shortcut_less_accurate(solver):
    out, _ = solver
    sc = rows(out / "shortcut.csv")
    blender = sc[0]
    assert blender["config"] == "Blender shortcut" and "-ksp_converged_maxits" in blender["options"]
    default = next(r for r in sc if r["rtol"] and float(r["rtol"]) == 1e-6)
    loose = next(r for r in sc if r["rtol"] and float(r["rtol"]) == 1e-2)
    assert float(blender["err_max"]) > float(default["err_max"]) > 0
    assert float(loose["err_max"]) > float(default["err_max"])
    for r in sc:
        assert 0 < float(r["err_rms"]) <= float(r["err_max"]) < 0.1, r
    flags = {r["flags"]: r["status"] for r in rows(out / "flags.csv")}
    assert flags["no flag, -ts_max_reject 0"] == "DIVERGED_ITS" and flags["-ksp_converged_maxits"] == "ok", flags
    assert flags["no flag"].startswith("ok,") and flags["no flag"].endswith("steps retried"), flags
    assert "equal accuracy" in (out / "solver_study.md").read_text()


@pytest.mark.parametrize("np_", [1, 2])
def test_dense_matrix_gives_aij_frames(tmp, np_):
    """-drape_mat_type dense (seqdense / mpidense, assembled by MatSetValuesBlocked) against AIJ,
    same PC: the same frames to solver tolerance, no leak, no unused option."""
    common = "-da_grid_x 10 -da_grid_y 9 -cloth_pin edge_corners -ts_type drapebe -ts_dt 5e-3 -ts_max_steps 8 -pc_type jacobi -ksp_rtol 1e-10"
    a = run(f"{common} -output_file {tmp / 'aij.h5'}", np_)
    d = run(f"{common} -drape_mat_type dense -output_file {tmp / 'dense.h5'}", np_)
    assert "dense matrix" in d.stdout and "aij matrix" in a.stdout
    fa, fd = drape_h5.load(tmp / "aij.h5"), drape_h5.load(tmp / "dense.h5")
    assert np.array_equal(fa.time, fd.time)
    assert np.max(np.abs(fa.positions - fd.positions)) < 1e-9


@pytest.mark.parametrize("script", ["paper_tables.py", "scaling.py", "solver_study.py", "implicit_study.py"])
def test_missing_build_is_one_sentence(tmp, script):
    proc = subprocess.run([sys.executable, str(SCRIPTS / script), "--quick", "--out", str(tmp), "--build", str(tmp / "nobuild")],
                          capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode != 0
    msg = proc.stderr.strip()
    assert msg.count("\n") == 0 and "drape is not built" in msg and "make all" in msg, msg


def test_rtol_accuracy_quick(tmp_path):
    """rtol_accuracy.py: every tolerance's error against the true motion is reported,
    for CG started from the last step's solution and from zero; a tight solve
    (rtol 1e-6) lands within 1 % of the exact linearised step from either start, and
    the warm start needs no more CG iterations than the cold one."""
    quick("rtol_accuracy.py", tmp_path)
    r = rows(tmp_path / "rtol_accuracy.csv")
    assert [(x["rtol"], x["cg_start"]) for x in r] == [("1e-12", "zero")] + [(t, s) for t in ("0.01", "0.001", "0.0001", "1e-06") for s in ("last step", "zero")]
    err = {(x["rtol"], x["cg_start"]): float(x["err_max"]) for x in r}
    its = {(x["rtol"], x["cg_start"]): float(x["cg_its_per_step"]) for x in r}
    assert all(0 < e < 0.5 for e in err.values())
    exact = err[("1e-12", "zero")]
    assert all(abs(err[("1e-06", s)] - exact) <= 0.01 * exact for s in ("last step", "zero"))
    assert all(its[(t, "last step")] <= its[(t, "zero")] for t in ("0.01", "0.001", "0.0001", "1e-06"))
    assert "vs rtol 1e-12" in (tmp_path / "rtol_accuracy.md").read_text()


def test_implicit_study_quick(tmp_path):
    """implicit_study.py --quick: every table is written; on the stiff hang smoothed
    aggregation (ML) needs far fewer CG iterations than block Jacobi/ICC(0); every run
    that completed rests below 3 % edge strain; contact costs are positive ratios."""
    quick("implicit_study.py", tmp_path)
    stiff = rows(tmp_path / "stiff.csv")
    hang = {r["solver"]: r for r in stiff if r["scene"] == "hang" and r["scheme"].startswith("drapebe")}
    assert set(hang) == {"bjacobi", "ml", "gamg", "default"}
    assert hang["ml"]["status"] == hang["bjacobi"]["status"] == "completed" and hang["ml"]["pc"] == "ml"
    assert float(hang["ml"]["cg_per_step"]) < 0.5 * float(hang["bjacobi"]["cg_per_step"])
    drop = [r for r in stiff if r["scene"] == "drop"]
    assert all(r["status"] == "completed" for r in drop if r["solver"] != "gamg"), drop
    done = [r for r in stiff + rows(tmp_path / "fabrics.csv") if r["status"] == "completed"]
    assert all(float(r["strain_percent"]) < 3 for r in done), done
    contact = rows(tmp_path / "contact.csv")
    assert len(contact) == 2 and all(float(r["ratio"]) > 0 for r in contact)
    strip = {r["solver"]: r for r in rows(tmp_path / "strip.csv")}
    assert strip["default"]["status"] == "completed"
    assert "Stiff cloth" in (tmp_path / "implicit_study.md").read_text()


def test_bench_assembly_quick_measures_every_way_into_every_matrix(tmp_path):
    """bench_assembly.py --quick: a positive assembly time for AIJ and SBAIJ by COO and
    by rows, MatSetValuesCOO's share only where COO was used and below the whole."""
    quick("bench_assembly.py", tmp_path)
    got = {(r["mat"], r["assembly"]): r for r in rows(tmp_path / "bench_assembly.csv")}
    assert set(got) == {("aij", "coo"), ("aij", "rows"), ("sbaij", "rows"), ("sbaij", "coo")}
    for (mat, mode), r in got.items():
        t, h = float(r["ms_per_assembly"]), float(r["ms_handoff"])
        assert t > 0, r
        assert (0 < h < t) if mode == "coo" else np.isnan(h), r
