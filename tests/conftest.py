"""Shared helpers for drape's test suite: run the program, read its HDF5 output.

Every successful run is made with -malloc_debug -malloc_dump -options_left and is
checked for leaks and unused options, so each test also guards those."""
import os
import re
import subprocess
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
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


def mpiexec(np_):
    cmd = ["mpiexec"]
    if os.geteuid() == 0:
        cmd.append("--allow-run-as-root")
    return cmd + ["--oversubscribe", "-np", str(np_)]


class Result:
    def __init__(self, proc):
        self.returncode = proc.returncode
        self.stdout = proc.stdout
        self.stderr = proc.stderr

    def value(self, pattern, cast=float):
        """First group of `pattern` in stdout."""
        m = re.search(pattern, self.stdout)
        assert m, f"{pattern!r} not in output:\n{self.stdout}"
        return cast(m.group(1))


def run(args, np_=1, check=True, checks=True, timeout=600):
    """Run drape with `args` (a list or a string) on np_ ranks."""
    if isinstance(args, str):
        args = args.split()
    extra = ["-drape_progress", "0"]
    if check and checks:
        extra += ["-malloc_debug", "-malloc_dump", "-options_left"]
    cmd = (mpiexec(np_) if np_ > 1 else []) + [str(DRAPE)] + list(args) + extra
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    res = Result(proc)
    if check:
        assert proc.returncode == 0, f"{' '.join(cmd)} failed:\n{proc.stdout}\n{proc.stderr}"
        if checks:
            assert "There are no unused options." in proc.stdout, f"unused options:\n{proc.stdout}"
            assert not LEAK.search(proc.stdout + proc.stderr), f"memory leak:\n{proc.stdout}{proc.stderr}"
    return res


def wait_for_frames(path, n, timeout=60):
    """Wait until the HDF5 file a running drape writes holds n complete frames."""
    deadline = time.time() + timeout
    while time.time() < deadline:
        time.sleep(0.3)
        try:
            with h5py.File(path, "r", locking=False) as f:
                if f["time"].shape[0] >= n:
                    return
        except (OSError, KeyError):
            pass
    raise AssertionError(f"{path} did not reach {n} frames in {timeout} s")


class Frames:
    """The complete frames of a drape HDF5 file."""

    def __init__(self, path):
        with h5py.File(path, "r") as f:
            n = f["time"].shape[0]
            self.time = f["time"][:n].ravel()
            self.step = f["step"][:n].ravel()
            self.x = f["position"][:n]
            self.v = f["velocity"][:n]
            self.energy = {k[7:]: f[k][:n].ravel() for k in f if k.startswith("energy_")}
            self.contact_force = f["contact_force"][:n].reshape(n, 3)
            self.attrs = dict(f.attrs)

    @property
    def total_energy(self):
        return sum(self.energy.values())


def rest_shape(tmp, n, options):
    """Final positions of the cloth of `options` on an n x n lattice, run (damping
    5 1/s, at most 8 s) until drape stops it at rest."""
    out = tmp / f"rest{n}.h5"
    res = run(f"{options} -da_grid_x {n} -da_grid_y {n} -cloth_damping 5 -ts_max_time 8 -drape_rest_tol 1e-6 -output_interval 1 "
              f"-output_file {out}", checks=False)
    assert "At rest" in res.stdout
    return Frames(out).x[-1]


@pytest.fixture
def tmp(tmp_path):
    return tmp_path


def pytest_configure(config):
    if not DRAPE.exists():
        raise pytest.UsageError(f"{DRAPE} is missing: build with 'make all' (or run 'make test')")
