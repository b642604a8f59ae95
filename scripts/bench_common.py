"""Helpers shared by the benchmark scripts paper_tables.py, scaling.py and solver_study.py.

Run drape (one rank directly, more through mpiexec), read its start-up limits and
its summary line, measure the child's peak resident memory, describe the machine,
and stop with one clear sentence when drape is missing or a run fails.
"""
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SUMMARY = re.compile(r"Summary: (\d+) steps to t = (\S+) s in (\S+) s wall, (\S+) particle-steps/s(?:, ([0-9.]+) CG iterations per step)?")
LIMIT = {k: re.compile(rf"{k} Euler: stable for h < (\S+) s") for k in ("symplectic", "explicit")}
KSP_FAILURE = re.compile(r"failed: SNES (\S+), KSP (\S+) after (\d+) linear iterations")


def fail(prog, msg):
    sys.exit(f"{prog}: error: {msg}")


def machine():
    model = "unknown CPU"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        for line in open("/proc/meminfo"):
            if line.startswith("MemTotal"):
                mem = f", {int(line.split()[1]) / 2**20:.0f} GB"
                break
    except OSError:
        pass
    return f"{model}, {os.cpu_count()} cores{mem}, {platform.system()} {platform.release()}"


class Result:
    """One drape run: return code, output, peak RSS (bytes, the drape process on one rank)."""

    def __init__(self, cmd, rc, stdout, stderr, maxrss):
        self.cmd, self.returncode, self.stdout, self.stderr, self.maxrss = " ".join(cmd), rc, stdout, stderr, maxrss

    def summary(self):
        """(steps, simulated time, wall s of the time loop, CG its/step or None), or None."""
        m = SUMMARY.search(self.stdout)
        if not m:
            return None
        return int(m.group(1)), float(m.group(2)), float(m.group(3)), float(m.group(5)) if m.group(5) else None

    def status(self):
        """'ok', 'diverged' (drape's own divergence check), the KSP reason of a failed solve, or 'failed'."""
        if self.returncode == 0:
            return "ok"
        text = self.stdout + self.stderr
        m = KSP_FAILURE.search(text)
        if m:
            return m.group(2) if m.group(2).startswith("DIVERGED") else m.group(1)
        if "diverged" in text:
            return "diverged"
        return "failed"

    def tail(self, n=1500):
        return f"  {self.cmd}\n{self.stdout[-n:]}{self.stderr[-n:]}"


class Drape:
    def __init__(self, prog, build, np_=1):
        self.prog, self.np = prog, np_
        b = Path(build)
        self.exe = (b if b.is_absolute() else ROOT / b) / "drape"
        if not self.exe.exists():
            fail(prog, f"drape is not built ({self.exe} is missing): run 'make all' first")

    def launcher(self):
        if self.np <= 1:
            return []
        mpi = shutil.which("mpiexec")
        if not mpi:
            fail(self.prog, "--np needs mpiexec on the PATH")
        return [mpi] + (["--allow-run-as-root"] if os.geteuid() == 0 else []) + ["--oversubscribe", "-np", str(self.np)]

    def run(self, args, timeout=1800):
        """Run drape with `args`; returns a Result with the child's peak RSS (os.wait4)."""
        cmd = self.launcher() + [str(self.exe)] + [str(a) for a in args] + ["-drape_progress", "0"]
        with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
            try:
                p = subprocess.Popen(cmd, stdout=out, stderr=err, text=True, cwd=ROOT)
            except OSError as e:
                fail(self.prog, f"cannot run {self.exe}: {e}")
            deadline = time.time() + timeout
            while True:
                pid, status, ru = os.wait4(p.pid, os.WNOHANG)
                if pid:
                    break
                if time.time() > deadline:
                    p.kill()
                    pid, status, ru = os.wait4(p.pid, 0)
                    break
                time.sleep(0.02)
            p.returncode = os.waitstatus_to_exitcode(status)
            out.seek(0)
            err.seek(0)
            return Result(cmd, p.returncode, out.read(), err.read(), ru.ru_maxrss * 1024)

    def must(self, args, what):
        """Run drape; stop the script with one sentence if the run fails."""
        r = self.run(args)
        if r.returncode or r.summary() is None:
            fail(self.prog, f"{what} failed unexpectedly (exit {r.returncode}):\n{r.tail()}")
        return r

    def limits(self, base):
        """The symplectic and explicit Euler limits drape prints at start-up; NaN for explicit
        Euler when drape says it is unstable at every step (no damping)."""
        r = self.run(list(base) + ["-ts_max_steps", "0"])
        m = {k: LIMIT[k].search(r.stdout) for k in LIMIT}
        if not m["explicit"] and "explicit Euler: unstable at every step" in r.stdout:
            m["explicit"] = None
        elif not m["explicit"]:
            m["symplectic"] = None
        if r.returncode or not m["symplectic"]:
            fail(self.prog, f"cannot read the stability limits drape prints at start-up:\n{r.tail()}")
        return {k: float(v.group(1)) if v else float("nan") for k, v in m.items()}


def median(xs):
    return statistics.median(xs) if xs else float("nan")


def positions(h5, frame=-1):
    """Positions [My, Mx, 3] of a complete frame of a drape HDF5 file."""
    import h5py
    with h5py.File(h5, "r") as f:
        n = f["time"].shape[0]
        return f["position"][frame if frame >= 0 else n + frame], float(f["time"][frame if frame >= 0 else n + frame][0])


def md_table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def write_csv(path, rows, fields=None):
    import csv
    fields = fields or list(rows[0])
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
