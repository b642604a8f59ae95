"""Post-processing scripts: drape_h5.load, render.py, animate.py, export_obj.py on
small real runs (a square cloth over a sphere, a circle Cusick specimen), and their
one-line errors on bad input."""
import os
import re
import shutil
import subprocess
import sys
import warnings

import h5py
import numpy as np
import pytest

import conftest
from conftest import ROOT

SCRIPTS = ROOT / "scripts"
with warnings.catch_warnings():  # matplotlib's import trips newer pyparsing's deprecations
    warnings.simplefilter("ignore", DeprecationWarning)
    import matplotlib.image
    from PIL import Image

    import animate
    import drape_h5
    import export_obj
    import render

SPHERE = "-options_file runs/sphere.opts -da_grid_x 11 -da_grid_y 11 -ts_max_time 0.1"
CIRCLE = ("-options_file runs/cusick.opts -cloth_shape circle -cloth_size 0.3 -da_grid_x 21 -da_grid_y 17 "
          "-ts_max_time 0.06")


def drape(args, out):
    conftest.run(f"{args} -output_file {out}", checks=False, timeout=120)
    return out


def script(name, *args, env=None):
    """Run scripts/<name> as a program."""
    return subprocess.run([sys.executable, str(SCRIPTS / name), *map(str, args)], capture_output=True, text=True,
                          timeout=120, cwd=ROOT, env=env)


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    return drape(SPHERE, tmp_path_factory.mktemp("sphere") / "s.h5")


@pytest.fixture(scope="module")
def circle(tmp_path_factory):
    return drape(CIRCLE, tmp_path_factory.mktemp("circle") / "c.h5")


def inside_circle(mx, my):
    """Count of lattice points inside the inscribed circle, straight from the formula."""
    count = 0
    for j in range(my):
        for i in range(mx):
            a = (i - (mx - 1) / 2) / ((mx - 1) / 2)
            b = (j - (my - 1) / 2) / ((my - 1) / 2)
            count += a * a + b * b <= 1 + 1e-12
    return count


def obj_counts(path):
    """(vertices [n, 3], faces [m, k] 1-based vertex numbers) of an OBJ file."""
    v, f = [], []
    for line in open(path):
        parts = line.split()
        if parts and parts[0] == "v":
            v.append([float(x) for x in parts[1:4]])
        elif parts and parts[0] == "f":
            f.append([int(x.split("/")[0]) for x in parts[1:]])
    return np.array(v), np.array(f)


# ---------------------------------------------------------------------------- reader


def test_load_square_run(sphere):
    run = drape_h5.load(sphere)
    with h5py.File(sphere, "r") as f:
        n = f["time"].shape[0]
        assert run.nframes == n > 2
        assert np.array_equal(run.positions, f["position"][:n])
        assert np.array_equal(run.solid_triangles.ravel(), f["solid_triangles"][:])
        assert np.array_equal(run.strain_max, f["strain_max"][:n, 0])
    assert run.frame_at(run.time[1], 1e-12) == 1 and run.frame_at(-1.0, 1e-12) is None
    assert run.attrs["lattice_mx"] == 11 and run.attrs["stopped_by"] == "" and run.attrs["at_rest"] in (0, 1)
    assert run.active.shape == (11, 11) and run.active.all()
    assert run.active_cells.sum() == 100
    assert run.floor == 0.0
    assert run.option("solid_type") == "sphere"
    assert run.option("cloth_center") == "0,0,0.6"
    assert set(run.contact) == {"depth", "count", "force"} and run.contact["force"].shape == (n, 3)


def test_circle_active_mask(circle):
    """drape writes the specimen's particles (/active): the inscribed disc less the
    spikes of the cut, the four points where the circle meets the lattice's axes (each
    a corner of no lattice cell inside the disc), as many as the report's
    active_particles; the reader's rebuild for files without /active agrees. The
    particles outside never move, every particle of the specimen does (none is
    pinned)."""
    run = drape_h5.load(circle)
    my, mx = run.shape
    assert (mx, my) == (21, 17)
    spikes = [(8, 0), (8, 20), (0, 10), (16, 10)]  # (j, i)
    assert not any(run.active[j, i] for j, i in spikes)
    assert run.active.sum() == run.attrs["active_particles"] == inside_circle(mx, my) - len(spikes)
    assert np.array_equal(run.active, drape_h5.active_mask(mx, my, "circle"))
    still = np.all(run.positions == run.positions[0], axis=(0, 3))
    assert still[~run.active].all()
    assert not still[run.active].any()
    assert run.option("cloth_shape") == "circle"


def test_parse_options():
    opts = drape_h5.parse_options("-solid_floor -0.45 -cloth_shape circle -gravity 0,0,-9.81 -flag -x 1")
    assert opts == {"solid_floor": "-0.45", "cloth_shape": "circle", "gravity": "0,0,-9.81", "flag": "", "x": "1"}


# ---------------------------------------------------------------------------- render.py


def test_render_png(sphere, tmp_path):
    out = tmp_path / "pic" / "s.png"
    res = script("render.py", sphere, "-o", out, "--frame", "-1", "--elev", "30", "--azim", "-50")
    assert res.returncode == 0, res.stderr
    assert "render: wrote" in res.stdout
    assert out.stat().st_size > 10_000
    img = matplotlib.image.imread(out)
    assert img.ndim == 3 and min(img.shape[:2]) > 200
    assert img[..., :3].var() > 1e-3, "blank picture"
    rgb = img[..., :3].reshape(-1, 3)
    assert (rgb.max(axis=1) - rgb.min(axis=1) > 0.3).mean() > 0.01, "no coloured cloth in the picture"


def test_render_circle_and_first_frame(circle, tmp_path):
    run = drape_h5.load(circle)
    out = tmp_path / "c.png"
    render.render(run, 0, str(out), dpi=60)
    img = matplotlib.image.imread(out)
    assert img[..., :3].var() > 1e-3


def test_cloth_facets_follow_the_mask(circle):
    run = drape_h5.load(circle)
    quads, tris, qn, tn = render.cloth_facets(run.positions[-1], run.active)
    assert len(quads) == run.active_cells.sum() and len(qn) == len(quads)
    assert len(tris) > 0 and np.isfinite(tn).all()  # the disc's edge, one triangle per 3-corner cell


def test_clip_box_keeps_area_inside():
    tri = np.array([[[0, 0, 0], [2, 0, 0], [0, 2, 0]]], float)
    for lo, hi, area in (([-1, -1, -1], [3, 3, 1], 2.0), ([-1, -1, -1], [1, 3, 1], 1.5), ([-1, -1, -1], [3, 1, 1], 1.5)):
        t = render.clip_box(tri, np.array(lo, float), np.array(hi, float))
        a = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum()
        assert a == pytest.approx(area)


# ---------------------------------------------------------------------------- animate.py


def test_animate_gif(sphere, tmp_path):
    out = tmp_path / "s.gif"
    n = drape_h5.load(sphere).nframes
    res = script("animate.py", sphere, "-o", out, "--every", "2", "--fps", "10", "--dpi", "40")
    assert res.returncode == 0, res.stderr
    expected = animate.frames_shown(n, 2)
    assert expected == list(range(0, n, 2)) + ([n - 1] if (n - 1) % 2 else [])
    assert animate.frames_shown(10, 3, count=5) == [0, 3, 4]
    with Image.open(out) as im:
        assert im.n_frames == len(expected)


def test_animate_mp4_needs_ffmpeg(sphere, tmp_path):
    out = tmp_path / "s.mp4"
    if shutil.which("ffmpeg"):
        res = script("animate.py", sphere, "-o", out, "--every", "3", "--dpi", "40")
        assert res.returncode == 0, res.stderr
        assert out.stat().st_size > 0
    res = script("animate.py", sphere, "-o", out, env={**os.environ, "PATH": ""})
    assert res.returncode == 2
    assert "ffmpeg" in res.stderr and "Traceback" not in res.stderr


# ---------------------------------------------------------------------------- export_obj.py


def test_export_obj_frame(sphere, tmp_path):
    run = drape_h5.load(sphere)
    k = run.nframes - 2
    res = script("export_obj.py", sphere, "-o", tmp_path, "--frame", k)
    assert res.returncode == 0, res.stderr
    v, f = obj_counts(tmp_path / f"cloth_{k:05d}.obj")
    assert len(v) == run.active.sum() == 121
    assert f.shape == (2 * 100, 3)
    assert f.min() == 1 and f.max() == len(v)
    assert np.allclose(v, run.positions[k].reshape(-1, 3), rtol=0, atol=1e-8)
    sv, sf = obj_counts(tmp_path / "solid.obj")
    assert len(sf) == len(run.solid_triangles)
    assert np.allclose(np.sort(sv[sf - 1].reshape(-1, 9), axis=0),
                       np.sort(run.solid_triangles.reshape(-1, 9), axis=0), atol=1e-8)
    assert (tmp_path / "floor.obj").exists()
    assert sorted(p.name for p in tmp_path.glob("cloth_*.obj")) == [f"cloth_{k:05d}.obj"]


def test_export_obj_all_circle(circle, tmp_path):
    run = drape_h5.load(circle)
    export_obj.main([str(circle), "-o", str(tmp_path), "--all", "--normals", "--uv"])
    files = sorted(tmp_path.glob("cloth_*.obj"))
    assert [p.name for p in files] == [f"cloth_{k:05d}.obj" for k in range(run.nframes)]
    ncells = int(run.active_cells.sum())
    assert 0 < ncells < 20 * 16
    for k, path in enumerate(files):
        v, f = obj_counts(path)
        assert len(v) == run.active.sum() == inside_circle(21, 17) - 4  # the disc less the four spikes of the cut
        assert len(f) == 2 * ncells
        assert np.allclose(v, run.positions[k][run.active], rtol=0, atol=1e-8)
    text = files[0].read_text()
    assert text.count("\nvn ") == text.count("\nvt ") == len(v)


def test_obj_triangles_face_up_for_a_flat_sheet(sphere):
    run = drape_h5.load(sphere)
    index, tri = export_obj.cloth_mesh(run.active)
    v = run.positions[0][run.active]
    n = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    assert (n[:, 2] > 0).all()


# ---------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("module,case", [pytest.param(m, c, id=f"{m.__name__}-{c}") for m in (render, animate, export_obj)
                                         for c in ("missing", "not_hdf5", "not_drape", "frame")
                                         if (m, c) != (animate, "frame")])  # animate.py has no --frame
def test_bad_input_one_line_error(module, case, sphere, tmp_path, capsys):
    args = []
    if case == "missing":
        path, want = tmp_path / "nope.h5", "no such file"
    elif case == "not_hdf5":
        path, want = tmp_path / "text.h5", "not an HDF5 file"
        path.write_text("hello\n")
    elif case == "not_drape":
        path, want = tmp_path / "other.h5", "not a drape output file"
        with h5py.File(path, "w") as f:
            f["time"] = np.zeros((1, 1))
    else:
        path, want, args = sphere, "out of range", ["--frame", "999"]
    out = ["-o", str(tmp_path / ("out" + {render: ".png", animate: ".gif", export_obj: ""}[module]))]
    with pytest.raises(SystemExit) as exc:
        module.main([str(path), *out, *args])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if "error:" in line]
    assert len(errors) == 1 and want in errors[0], err
    assert "Traceback" not in err


def test_bad_input_from_the_command_line(tmp_path):
    res = script("render.py", tmp_path / "missing.h5")
    assert res.returncode == 2
    assert res.stderr.strip().splitlines()[-1] == f"render.py: error: {tmp_path / 'missing.h5'}: no such file"


def test_setup_scaling_quick(tmp_path):
    """scripts/setup_scaling.py --quick: a 64^2 disc set up on 1 and 2 ranks with the
    DMDA's blocks and PT-Scotch; every row has its times (the set-up's CPU time too),
    memory per rank above the fixed cost, and a balanced partition."""
    import csv
    res = script("setup_scaling.py", "--quick", "--out", tmp_path)
    assert res.returncode == 0, res.stdout + res.stderr
    with open(tmp_path / "setup_scaling.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["ranks"], r["partition"]) for r in rows] == [("1", "dmda"), ("1", "ptscotch"), ("2", "dmda"), ("2", "ptscotch")]
    for r in rows:
        assert r["N"] == "64" and float(r["cloth_setup_s"]) > 0 and float(r["setup_stage_s"]) >= float(r["cloth_setup_s"])
        assert float(r["rank_max_mib"]) >= float(r["rank_min_mib"]) > float(r["fixed_mib"]) * 0.9 > 0
        assert float(r["imbalance"]) < 1.1
        # the set-up's CPU time: the busiest rank's is part of the sum, and all of it on one rank
        cpu, rank = float(r["setup_cpu_s"]), float(r["setup_cpu_rank_s"])
        assert 0 < rank <= cpu and (r["ranks"] != "1" or rank == cpu), r
    assert "| 64 | 2 | ptscotch |" in (tmp_path / "setup_scaling.md").read_text()


def test_cusick_lattices_quick(tmp_path):
    """scripts/cusick_lattices.py --quick: the flat specimen and specimen 1 on 21^2 and
    25^2; every run has a DC between 0 and 1 and its folds; the table has a row per
    lattice, the finest at distance 0 from itself, and the plot is written."""
    import csv
    res = script("cusick_lattices.py", "--quick", "--out", tmp_path)
    assert res.returncode == 0, res.stdout + res.stderr
    with open(tmp_path / "lattices.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted((r["grid"], r["specimen"]) for r in rows) == [("21", "1"), ("21", "flat"), ("25", "1"), ("25", "flat")]
    for r in rows:
        assert r["status"] == "ok" and 0 < float(r["drape_coefficient"]) < 1 and int(r["drape_folds"]) > 0, r
    md = (tmp_path / "lattices.md").read_text()
    assert md.count("\n| 2") == 2 and "| 25² | 12.50 |" in md
    assert re.search(r"\| 25² \|[^\n]*\| 0\.0000 \| yes \|", md), md
    assert (tmp_path / "lattices.png").stat().st_size > 1000


def test_rest_race_quick(tmp_path):
    """scripts/rest_race.py --quick on the vertical hang (16^2), whose rest is unique:
    the reference and its check (half the step) rest within 0.05 mm of each other;
    each scheme's runs come closer to the reference as the rest tolerance tightens
    (the softest modes creep), both schemes reach it within 1 mm, and the ratio of
    their fastest such runs is printed, with the median ratio of those two runs made
    again in two interleaved rounds, where they rest as before."""
    import csv
    res = script("rest_race.py", "--quick", "--scenes", "hangv64", "--repeat", "2", "--out", tmp_path)
    assert res.returncode == 0, res.stdout + res.stderr
    with open(tmp_path / "rest_race.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["scheme"] for r in rows[:2]] == ["symplectic", "symplectic"] and float(rows[1]["error_mm"]) < 0.05, rows[:2]
    runs = {}
    for r in rows[2:]:
        assert r["status"] == "ok", r
        if not r["round"]:
            runs.setdefault(r["run"], []).append(float(r["error_mm"]))
    # the repeats: the fastest run of each scheme within 1 mm, in turn, twice, at the same place
    repeats = [r for r in rows if r["round"]]
    assert [(r["round"], r["scheme"]) for r in repeats] == [("1", "symplectic"), ("1", "drapebe"), ("2", "symplectic"), ("2", "drapebe")], repeats
    for r in repeats:
        first = next(q for q in rows if q["run"] == r["run"] and q["rest_tol"] == r["rest_tol"] and not q["round"])
        assert r["error_mm"] == first["error_mm"] and r["steps"] == first["steps"], (r, first)
    ratios = [float(s["cpu"]) / float(b["cpu"]) for s, b in zip(repeats[::2], repeats[1::2])]
    assert re.search(rf"2 interleaved rounds of the two: .*median ratio {np.median(ratios):.2f}", res.stdout), (ratios, res.stdout)
    assert len(runs) == 4 and all(len(e) == 4 for e in runs.values()), runs  # 1e-6, 1e-7, 2e-8, 1e-8 J/kg
    for errors in runs.values():
        assert errors[-1] <= errors[0] + 1e-3, runs  # 1e-8 J/kg against 1e-6
    assert re.search(r"hangv64 \(16\^2; the reference and its check 0\.0\d mm apart\): fastest within 1 mm of the reference: symplectic Euler.*; drapebe.*; ratio \d", res.stdout), res.stdout
    assert "| hangv64 |" in (tmp_path / "rest_race.md").read_text()


def test_cusick_folds_counts_a_known_outline():
    """cusick_folds.count_folds, drape's walk of the outline, on r = R + A cos(k theta):
    k folds for every k from 3 to 16 where the bumps stand out of the prominence,
    none where they do not; and the raster's area of a disc is its area to a pixel's
    share of the rim."""
    import cusick_folds
    theta = (np.arange(720) + 0.5) / 720 * 2 * np.pi - np.pi
    for k in range(3, 17):
        assert cusick_folds.count_folds(0.12 + 0.01 * np.cos(k * theta + 0.3), 0.006) == k, k
        assert cusick_folds.count_folds(0.12 + 0.002 * np.cos(k * theta + 0.3), 0.006) == 0, k
    n = 60  # a disc of radius 0.1 as a fan of triangles about its centre
    phi = np.linspace(0, 2 * np.pi, n + 1)[:-1]
    xy = np.concatenate([[[0.0, 0.0]], 0.1 * np.stack([np.cos(phi), np.sin(phi)], axis=1)])
    tri = np.array([[0, 1 + i, 1 + (i + 1) % n] for i in range(n)])
    covered, radius = cusick_folds.silhouette(xy, tri, np.zeros(2), 0.2)
    polygon = 0.5 * n * 0.01 * np.sin(2 * np.pi / n)
    assert abs(covered - polygon) < 2 * np.pi * 0.1 * (0.4 / 1200), (covered, polygon)
    assert np.all(radius <= 0.1) and np.all(radius > 0.1 * np.cos(np.pi / n) - 0.4 / 1200)


def test_cusick_folds_matches_the_report(tmp_path):
    """scripts/cusick_folds.py on a Cusick run (denim, 41^2, to 0.6 s): its last frame's
    folds are the run's report's and its DC the report's to round-off (the same
    raster, the same walk); the first frame is the flat specimen (DC 1, no fold); the
    plot is written; a file without a Cusick pedestal, a missing file and labels that
    do not match the files are one-line errors."""
    import cusick_folds
    h5 = drape("-options_file runs/cusick.opts -cloth_fabric denim -da_grid_x 41 -da_grid_y 41 -ts_max_time 0.6 -output_interval 0.2",
               tmp_path / "c41.h5")
    rows = cusick_folds.history(h5)
    rep = drape_h5.load(h5, frames=False).attrs
    assert [r[0] for r in rows] == [0, 1, 2, 3] and rows[0][2:4] == (0, 1.0), rows
    assert rows[-1][2] == rep["drape_folds"] > 0 and abs(rows[-1][3] - rep["drape_coefficient"]) < 1e-12, (rows[-1], rep["drape_coefficient"])
    res = script("cusick_folds.py", h5, "--every", "2", "--plot", tmp_path / "f.png")
    assert res.returncode == 0 and f"DC {rep['drape_coefficient']:.4f}, {rep['drape_folds']} folds" in res.stdout, res.stdout + res.stderr
    assert (tmp_path / "f.png").stat().st_size > 1000
    res = script("cusick_folds.py", h5, h5, "--label", "one")
    assert res.returncode == 2 and "--label given 1 times for 2 files" in res.stderr, res.stderr
    for bad, why in ((tmp_path / "none.h5", "no such file"), (drape(SPHERE, tmp_path / "s.h5"), "has no Cusick pedestal")):
        res = script("cusick_folds.py", bad)
        assert res.returncode == 2 and why in res.stderr and res.stderr.count("\n") == 1, res.stderr


def test_a_failed_mpi_start_is_made_again_and_nothing_else(tmp_path):
    """drape_run.run makes a start again that Open MPI could not make (its message, no
    word from drape), and never a run that drape itself ended: a stand-in program
    whose first F starts fail so, then prints and exits with the given status. So does
    the tests' own subprocess.run (text or bytes, with check=True too), and never a
    run whose output it does not capture."""
    import drape_run
    starts = tmp_path / "starts"
    fake = tmp_path / "fake"
    fake.write_text(f"""#!/bin/sh
echo x >> {starts}
if [ "$(wc -l < {starts})" -le "$3" ]; then echo "--> Returned value {drape_run.LAUNCH_FAILED} (-127)" >&2; exit 1; fi
echo "drape $1"; exit $2
""")
    fake.chmod(0o755)

    def run(word, status, failed):
        starts.write_text("")
        res = drape_run.run(fake, [word, str(status), str(failed)])
        return res.returncode, "drape " + word in res.stdout, len(starts.read_text().split())

    assert run("ran", 0, 0) == (0, True, 1)
    assert run("ran", 0, 1) == (0, True, 2)
    assert run("failed", 1, 0) == (1, True, 1)  # drape's own failure is final
    assert run("failed", 1, 1) == (1, True, 2)
    assert run("never", 0, 9) == (1, False, drape_run.LAUNCH_TRIES)  # the last failure is returned

    # the same for the tests' own subprocess.run (conftest.py installs the wrapper)
    import subprocess
    assert hasattr(subprocess.run, "__wrapped__")

    def run_direct(word, status, failed, **kw):
        starts.write_text("")
        try:
            res = subprocess.run([str(fake), word, str(status), str(failed)], capture_output=True, **kw)
            out = res.stdout if isinstance(res.stdout, str) else res.stdout.decode()
            return res.returncode, "drape " + word in out, len(starts.read_text().split())
        except subprocess.CalledProcessError as e:
            return "raised", e.returncode, len(starts.read_text().split())

    assert run_direct("ran", 0, 1, text=True) == (0, True, 2)
    assert run_direct("ran", 0, 2) == (0, True, 3)  # bytes
    assert run_direct("failed", 3, 0, text=True) == (3, True, 1)
    assert run_direct("never", 0, 9, text=True) == (1, False, drape_run.LAUNCH_TRIES)
    assert run_direct("ran", 0, 1, text=True, check=True) == (0, True, 2)
    assert run_direct("never", 0, 9, text=True, check=True) == ("raised", 1, drape_run.LAUNCH_TRIES)
    starts.write_text("")
    assert subprocess.run([str(fake), "never", "0", "1"]).returncode == 1 and len(starts.read_text().split()) == 1  # not captured: not made again
