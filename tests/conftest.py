"""Shared helpers for drape's test suite: run the program (scripts/drape_run.py, whose
Result has the run's report) and read its HDF5 output (scripts/drape_h5.py).

Every successful run is made with -malloc_dump -options_left and is checked for
leaks and unused options, so each test also guards those; one-rank runs (and the
multi-rank runs that ask for it) add -malloc_debug, PETSc's check of the whole heap
at every allocation. On several ranks that check costs 4-7x the run (measured on a
25^2 drapebe run: 0.6 -> 2.7 s on 2 ranks, 1.0 -> 6.8 s on 4, oversubscribed):
PETSc's communication allocates at every exchange, and each allocation walks the
heap. tests/test_integration.py's 1/2/4-rank runs keep it on every rank count."""
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
import drape_h5  # noqa: E402
import drape_run  # noqa: E402
from drape_run import mpiexec  # noqa: E402,F401  (for the tests that launch drape themselves)

# The tests that launch drape, its unit tests or mpiexec through subprocess.run
# themselves get drape_run's retry of a start Open MPI could not make, as the runs
# through drape_run.run do.
if not hasattr(subprocess.run, "__wrapped__"):
    subprocess.run = drape_run.run_again_if_not_started(subprocess.run)

BUILD = ROOT / os.environ.get("DRAPE_BUILD", "build")
DRAPE = BUILD / "drape"
LEAK = re.compile(r"^\[\s*\d+\]\s*\d+ bytes", re.M)

# How closely the explicit schemes agree across partitions (rank counts, DMDA or
# METIS): to round-off, not bitwise, on an arbitrary x86-64 machine. PETSc's VecAXPY
# (the symplectic update) goes through the BLAS, and OpenBLAS's AVX2 kernels
# (Haswell, Zen) use fused multiply-adds for the first n & -16 entries of a vector and
# separate ones for the rest, so the last bit of a particle's update depends on where
# it sits in its rank's array. Measured with OPENBLAS_CORETYPE=Haswell or Zen:
# 3.4e-14 m on a 0.3 m cloth (SkylakeX, Sandybridge, Nehalem, Prescott kernels:
# bitwise). A ghost-exchange or partition bug shows at 1e-6 m or more. The same run
# on the same ranks (a restart on as many ranks) is bitwise: the same lengths take
# the same kernels.
ROUNDOFF = 1e-10  # m


def printed(res, pattern, cast=float):
    """First group of `pattern` in a run's stdout: a number only the prose gives."""
    m = re.search(pattern, res.stdout)
    assert m, f"{pattern!r} not in output:\n{res.stdout}"
    return cast(m.group(1))


def run(args, np_=1, check=True, checks=True, timeout=600, malloc_debug=None):
    """Run drape with `args` (a list or a string) on np_ ranks; returns its drape_run.Result.
    malloc_debug: check the heap at every allocation (default: on one rank only)."""
    if isinstance(args, str):
        args = args.split()
    if malloc_debug is None:
        malloc_debug = np_ == 1
    extra = (["-malloc_debug"] if malloc_debug else []) + ["-malloc_dump", "-options_left"] if check and checks else []
    res = drape_run.run(DRAPE, list(args) + extra, np_, timeout)
    if check:
        assert res.returncode == 0, f"{res.cmd} failed:\n{res.stdout}\n{res.stderr}"
        if checks:
            assert "There are no unused options." in res.stdout, f"unused options:\n{res.stdout}"
            assert not LEAK.search(res.stdout + res.stderr), f"memory leak:\n{res.stdout}{res.stderr}"
    return res


def refused(args, what):
    """drape refuses `args` on a small sheet with one sentence containing `what`: a
    non-zero exit, no PETSc error stack."""
    res = run(args + " -da_grid_x 8 -da_grid_y 8 -ts_max_steps 1", check=False)
    msg = res.stdout + res.stderr
    assert res.returncode != 0 and what in msg and "PETSC ERROR" not in msg, msg


def wait_for_frames(path, n, timeout=60):
    """Wait until the HDF5 file a running drape writes holds n complete frames."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        time.sleep(0.3)
        try:
            if drape_h5.load(path).nframes >= n:
                return
        except (OSError, KeyError, ValueError):  # not yet a drape file, or a frame being written
            pass
    raise AssertionError(f"{path} did not reach {n} frames in {timeout} s")


def rest_shape(tmp, n, options):
    """Final positions of the cloth of `options` on an n x n lattice, run (damping
    5 1/s, at most 8 s) until drape stops it at rest."""
    out = tmp / f"rest{n}.h5"
    res = run(f"{options} -da_grid_x {n} -da_grid_y {n} -cloth_damping 5 -ts_max_time 8 -drape_rest_tol 1e-6 -output_interval 1 "
              f"-output_file {out}", checks=False)
    assert res.report["at_rest"], res.stdout
    return drape_h5.load(out).positions[-1]


@pytest.fixture
def tmp(tmp_path):
    return tmp_path


def pytest_configure(config):
    if not DRAPE.exists():
        raise pytest.UsageError(f"{DRAPE} is missing: build with 'make all' (or run 'make test')")
