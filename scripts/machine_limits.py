#!/usr/bin/env python3
"""The machine's limits for one core: memory bandwidth (STREAM triad) and peak
double-precision FMA rate, vector and scalar (scripts/machine_limits.c, compiled
here with the system's cc -O3 -march=native; no test times it).

    python3 scripts/machine_limits.py            # arrays of 2^25 doubles (268 MB each)
    python3 scripts/machine_limits.py --quick    # smoke run: small arrays, short loops

bench_core.py calls measure() and puts the figures in its generated table.
"""
import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

from drape_run import ROOT, fail

PROG = "machine_limits"
SOURCE = ROOT / "scripts" / "machine_limits.c"
FLAGS = ["-O3", "-march=native"]
FULL = (1 << 25, 10, 20_000_000)  # doubles per array (3 x 268 MB, 8 x the 32 MB L3), triads, FMA iterations
QUICK = (1 << 20, 2, 1_000_000)


def compile_(build, prog=PROG):
    """Compile machine_limits.c into <build>/machine_limits (when missing or older); its path."""
    cc = os.environ.get("MACHINE_CC", "cc")
    if not shutil.which(cc):
        fail(prog, f"the C compiler '{cc}' is not on the PATH (Debian: apt-get install gcc; or name one with MACHINE_CC=...)")
    b = Path(build)
    exe = (b if b.is_absolute() else ROOT / b) / "machine_limits"
    if not exe.exists() or exe.stat().st_mtime < SOURCE.stat().st_mtime:
        exe.parent.mkdir(parents=True, exist_ok=True)
        p = subprocess.run([cc] + FLAGS + ["-Wall", "-Wextra", "-o", str(exe), str(SOURCE), "-lm"], capture_output=True, text=True)
        if p.returncode:
            fail(prog, f"{cc} could not compile {SOURCE}: {p.stderr.strip()}")
    return exe


def measure(build, quick=False, prog=PROG):
    """{'triad_gb_per_s', 'peak_gflop_per_s', 'scalar_gflop_per_s', 'fma_lanes',
    'triad_array_mb', 'compiler'} of this machine, one core."""
    exe = compile_(build, prog)
    p = subprocess.run([str(exe)] + [str(v) for v in (QUICK if quick else FULL)], capture_output=True, text=True)
    if p.returncode:
        fail(prog, f"{exe} failed: {p.stderr.strip()}")
    out = {k: float(v) for k, v in (line.split() for line in p.stdout.splitlines())}
    out.pop("checksum", None)
    out["fma_lanes"] = int(out["fma_lanes"])
    out["compiler"] = f"{os.environ.get('MACHINE_CC', 'cc')} {' '.join(FLAGS)}"
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"), help="where the executable goes")
    p.add_argument("--quick", action="store_true", help="smoke run: 8 MB arrays, short FMA loops")
    a = p.parse_args()
    m = measure(a.build, a.quick)
    print(f"memory bandwidth (STREAM triad, one core, {m['triad_array_mb']:.0f} MB arrays): {m['triad_gb_per_s']:.1f} GB/s")
    print(f"peak FMA rate (one core, {m['fma_lanes']} doubles a vector): {m['peak_gflop_per_s']:.1f} GFLOP/s; scalar: {m['scalar_gflop_per_s']:.1f} GFLOP/s")


if __name__ == "__main__":
    sys.exit(main())
