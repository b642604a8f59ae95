"""Run the C unit tests (tests/unit/*.c, built by `make all` into $DRAPE_BUILD/tests)."""

import os
import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BUILD = ROOT / os.environ.get("DRAPE_BUILD", "build")


def run_unit(name, *args, timeout=300):
    exe = BUILD / "tests" / name
    if not exe.is_file():
        pytest.fail(f"{exe} not found; build it with `make all` (DRAPE_BUILD={BUILD})")
    proc = subprocess.run([str(exe), *args], cwd=ROOT, capture_output=True, text=True, timeout=timeout)
    output = f"$ {exe} {' '.join(args)}\n--- stdout ---\n{proc.stdout}\n--- stderr ---\n{proc.stderr}"
    return proc, output


def test_kernels():
    proc, output = run_unit("test_kernels")
    assert proc.returncode == 0, f"test_kernels exited with code {proc.returncode}\n{output}"
    assert re.search(r"^\d+ passed, 0 failed$", proc.stdout, re.MULTILINE), f"no 'N passed, 0 failed' line\n{output}"
