"""Run drape: its command line (one rank directly, more through mpiexec) and its
report, for the scripts and the test suite.

Usage::

    import drape_run
    r = drape_run.run("build/drape", ["-options_file", "runs/hang.opts", "-ts_max_steps", "5"])
    r.report["symplectic_limit"]   # the run's report (-drape_json), or None
    r.status()                     # "ok", "diverged", the reason of a failed solve, or "failed"

Every run is made with -drape_json -drape_progress 0: drape ends a completed run
with one JSON line of its start-up numbers and summary (the attributes of its HDF5
file's root), which is the report. A run that ends with an error has no report,
only one sentence on stderr ("drape: error: ..."), read here and nowhere else.
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DIVERGED = re.compile(r"diverged at step (\d+)")
SOLVE_FAILED = re.compile(r"failed: SNES (\S+), KSP (\S+) after \d+ linear iterations")


def fail(prog, msg):
    sys.exit(f"{prog}: error: {msg}")


def mpiexec(np_):
    """The MPI launcher's command for np_ ranks (--allow-run-as-root only for root)."""
    return ["mpiexec"] + (["--allow-run-as-root"] if os.geteuid() == 0 else []) + ["--oversubscribe", "-np", str(np_)]


def parse_report(stdout):
    """The JSON object of drape's -drape_json line (the last line starting with "{"), or None."""
    for line in reversed(stdout.splitlines()):
        if line.startswith("{"):
            return json.loads(line)
    return None


class Result:
    """One drape run: command, exit code, output, peak RSS (bytes, of the largest
    rank) and report (a dict, None when the run did not complete).

    The peak RSS is the report's memory_peak_rank_max (each rank's own VmHWM) when the
    run completed; else os.wait4's ru_maxrss, which on Linux is at least the RSS of
    the process the launch was forked from (a test runner's worker, say)."""

    def __init__(self, cmd, returncode, stdout, stderr, maxrss):
        self.cmd, self.returncode, self.stdout, self.stderr = " ".join(cmd), returncode, stdout, stderr
        self.report = parse_report(stdout)
        peak = (self.report or {}).get("memory_peak_rank_max")
        self.maxrss = peak if peak is not None and peak > 0 else maxrss

    def summary(self):
        """(steps, simulated time, wall s of the time loop, CG iterations per step: 0 for
        the explicit schemes), or None."""
        r = self.report
        return None if r is None else (r["steps"], r["t"], r["wall"], r["cg_per_step"])

    def limits(self):
        """The symplectic and explicit Euler limits estimated at start-up, NaN for explicit
        Euler when it is unstable at every step (no damping); None without an estimate."""
        r = self.report
        if r is None or "symplectic_limit" not in r:
            return None
        return {"symplectic": r["symplectic_limit"], "explicit": r["euler_limit"] or float("nan")}

    def error(self):
        """drape's error sentence (the one stderr line starting "drape: error:"), or None."""
        lines = [line for line in self.stderr.splitlines() if line.startswith("drape: error:")]
        return lines[0] if len(lines) == 1 else None

    def diverged_at(self):
        """The step at which drape's divergence check stopped the run, or None."""
        m = DIVERGED.search(self.error() or "")
        return int(m.group(1)) if m else None

    def status(self):
        """'ok', 'diverged' (drape's own divergence check), the KSP reason of a failed
        solve (the SNES reason if KSP converged), or 'failed'."""
        if self.returncode == 0:
            return "ok"
        m = SOLVE_FAILED.search(self.error() or "")
        if m:
            return m.group(2) if m.group(2).startswith("DIVERGED") else m.group(1)
        return "diverged" if self.diverged_at() is not None else "failed"

    def tail(self, n=1500):
        return f"  {self.cmd}\n{self.stdout[-n:]}{self.stderr[-n:]}"


# Open MPI's own start failing before drape runs: a one-process run forks a daemon
# (orted) in MPI_Init, and on a loaded machine that fork has been seen to fail, once in
# a test suite's 1500 starts ("ompi_rte_init failed", "Unable to start a daemon on the
# local node"). Such a start is made again, up to LAUNCH_TRIES times.
LAUNCH_FAILED = "Unable to start a daemon on the local node"
LAUNCH_TRIES = 3


def run(exe, args, np_=1, timeout=None):
    """Run drape `exe` with `args` on np_ ranks (from the repository's root); a run
    longer than `timeout` s is killed. Returns a Result (its peak RSS: drape's own, or os.wait4's).
    A start that Open MPI could not make (LAUNCH_FAILED, nothing printed by drape) is
    made again."""
    return run_again_if_not_started(_run_once)(exe, args, np_, timeout)


def launch_failed(returncode, stdout, stderr):
    """Did Open MPI fail to start the program: a failure with LAUNCH_FAILED on stderr
    and no word from drape on stdout (str or bytes, None if not captured)?"""
    def text(s):
        return s.decode(errors="replace") if isinstance(s, bytes) else (s or "")
    return returncode != 0 and LAUNCH_FAILED in text(stderr) and "drape" not in text(stdout)


def run_again_if_not_started(run_):
    """`run_` (subprocess.run, or anything returning an object with returncode, stdout
    and stderr) made again, up to LAUNCH_TRIES times, when Open MPI could not start the
    program: run() takes it, and so do the tests that launch drape, its unit tests or
    mpiexec themselves (tests/conftest.py installs it on subprocess.run). A run whose
    output is not captured is never made again."""
    def wrapped(*args, **kwargs):
        for attempt in range(1, LAUNCH_TRIES + 1):
            try:
                res = run_(*args, **kwargs)
            except subprocess.CalledProcessError as e:
                if attempt < LAUNCH_TRIES and launch_failed(e.returncode, e.stdout, e.stderr):
                    continue
                raise
            if attempt == LAUNCH_TRIES or not launch_failed(res.returncode, res.stdout, res.stderr):
                return res
    wrapped.__wrapped__ = run_
    return wrapped


def _run_once(exe, args, np_, timeout):
    cmd = (mpiexec(np_) if np_ > 1 else []) + [str(exe)] + [str(a) for a in args] + ["-drape_progress", "0", "-drape_json"]
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        p = subprocess.Popen(cmd, stdout=out, stderr=err, text=True, cwd=ROOT)
        deadline = None if timeout is None else time.time() + timeout
        while True:
            pid, status, ru = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            if deadline is not None and time.time() > deadline:
                p.kill()
                pid, status, ru = os.wait4(p.pid, 0)
                break
            time.sleep(0.01)
        p.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        return Result(cmd, p.returncode, out.read(), err.read(), ru.ru_maxrss * 1024)


class Drape:
    """drape as a script runs it: <build>/drape on np_ ranks; a missing executable, or
    a run the script cannot do without failing, stops the script with one sentence."""

    def __init__(self, prog, build, np_=1):
        self.prog, self.np = prog, np_
        b = Path(build)
        self.exe = (b if b.is_absolute() else ROOT / b) / "drape"
        if not self.exe.exists():
            fail(prog, f"drape is not built ({self.exe} is missing): run 'make all' first")
        if np_ > 1 and not shutil.which("mpiexec"):
            fail(prog, "--np needs mpiexec on the PATH")

    def run(self, args, timeout=1800):
        """Run drape with `args`; returns a Result."""
        try:
            return run(self.exe, args, self.np, timeout)
        except OSError as e:
            fail(self.prog, f"cannot run {self.exe}: {e}")

    def must(self, args, what):
        """Run drape; stop the script with one sentence if the run fails."""
        r = self.run(args)
        if r.returncode or r.report is None:
            fail(self.prog, f"{what} failed unexpectedly (exit {r.returncode}):\n{r.tail()}")
        return r

    def limits(self, base):
        """The stability limits drape estimates at start-up for `base` (Result.limits)."""
        r = self.run(list(base) + ["-ts_max_steps", "0"])
        lim = r.limits()
        if r.returncode or lim is None:
            fail(self.prog, f"drape did not report its stability limits (exit {r.returncode}):\n{r.tail()}")
        return lim
