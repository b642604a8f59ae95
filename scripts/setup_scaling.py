#!/usr/bin/env python3
"""Set-up on many ranks: peak memory per rank and set-up time (not a test).

A circular cloth (the Cusick specimen's disc inscribed in an N x N lattice, no
solid, no output) set up and not stepped (-ts_max_steps 0; -drape_stability_its 0
skips the start-up stability estimate, which is not part of the layout) on P ranks
of this machine (oversubscribed past its cores: times then are what one core
shared by several ranks gives, memory is what each rank holds), N in --sizes,
P in --ranks, each partition of --partitions (dmda, and the parallel partitioner
ptscotch; metis for comparison).

Per run:
  cloth_setup_s   the DrapeClothSetUp event of -log_view (ClothSetUp: DMDA,
                  partition, layout, element lists, lattice patch), slowest rank
  partition_s     its DrapePartition event (the partitioner alone), slowest rank
  setup_stage_s   the whole Setup stage (options, cloth, solid, integrator)
  wall_s          the launch to the exit, as the shell sees it
  setup_cpu_s, setup_cpu_rank_s
                  the report's setup_cpu and setup_cpu_rank_max: CPU seconds of the
                  set-up summed over ranks and the busiest rank's (oversubscribed
                  ranks share the cores, so the wall times above grow with the ranks
                  sharing a core; a rank's CPU time is its work, and Open MPI's
                  spinning waits)
  rank_max_mib, rank_min_mib, total_mib
                  -memory_view's maximum process memory (resident set) of the
                  largest and smallest rank, and of all ranks together
  hwm_mib         the kernel's peak resident set of the largest process of the job
                  (os.wait4 on the launcher: ru_maxrss is the largest of its
                  children's), a check of -memory_view's sampling
  fixed_mib       the same -memory_view maximum for a 16 x 16 lattice on as many
                  ranks: what a rank costs whatever the lattice (MPI, PETSc, HDF5)
  max_over_share  (rank_max - fixed) / ((total - P fixed) / P): 1 when every rank
                  holds its share of the lattice and no more

Output in --out (default out/setup_scaling): setup_scaling.csv, setup_scaling.md,
setup_scaling.png (per-rank memory and set-up time against the ranks).
--from-csv A.csv,B.csv makes the table and plot of earlier runs' rows instead
of measuring (the machine's load then is theirs).

    python3 scripts/setup_scaling.py --sizes 2048 --partitions dmda,ptscotch,metis   # 1-8 ranks: about 7 minutes here
    python3 scripts/setup_scaling.py --quick --out /tmp/ss           # smoke run, seconds
"""
import argparse
import csv
import os
import re
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import machine, md_table, write_csv  # noqa: E402
from drape_run import ROOT, Drape, fail  # noqa: E402

PROG = "setup_scaling"
MEMORY = re.compile(r"Maximum \(over computational time\) process memory:\s+total\s+(\S+)\s+max\s+(\S+)\s+min\s+(\S+)")


def event(stdout, name):
    """Max time (s) over ranks of -log_view's event `name`, or None."""
    m = re.search(rf"^{name}\s+\d+\s+\S+\s+(\S+)", stdout, re.M)
    return float(m.group(1)) if m else None


def stage(stdout, name):
    m = re.search(rf"^\s*\d+:\s+{name}:\s+(\S+)", stdout, re.M)
    return float(m.group(1)) if m else None


def args_for(n, part):
    return ["-da_grid_x", str(n), "-da_grid_y", str(n), "-cloth_shape", "circle", "-cloth_partition", part,
            "-ts_type", "basicsymplectic", "-ts_max_steps", "0", "-drape_stability_its", "0", "-memory_view", "-log_view"]


def measure(build, n, np_, part, timeout):
    drape = Drape(PROG, build, np_)
    t0 = time.time()
    r = drape.run(args_for(n, part), timeout=timeout)
    wall = time.time() - t0
    if r.returncode or r.report is None:
        fail(PROG, f"the {n} x {n} {part} run on {np_} ranks failed (exit {r.returncode}):\n{r.tail()}")
    m = MEMORY.search(r.stdout)
    if not m:
        fail(PROG, f"no -memory_view summary in the {n} x {n} {part} run on {np_} ranks:\n{r.tail()}")
    total, hi, lo = (float(x) for x in m.groups())
    return {"total": total, "max": hi, "min": lo, "hwm": r.maxrss, "wall": wall, "cloth": event(r.stdout, "DrapeClothSetUp"),
            "cpu": r.report.get("setup_cpu"), "cpu_rank": r.report.get("setup_cpu_rank_max"),
            "partition": event(r.stdout, "DrapePartition"), "stage": stage(r.stdout, "Setup"), "report": r.report}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="2048,4096", help="lattice sides N")
    p.add_argument("--ranks", default="1,2,4,8", help="rank counts P")
    p.add_argument("--partitions", default="dmda,ptscotch", help="-cloth_partition values")
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"), help="drape's build directory")
    p.add_argument("--timeout", type=float, default=1200, help="seconds per run")
    p.add_argument("--out", default=str(ROOT / "out" / "setup_scaling"))
    p.add_argument("--quick", action="store_true", help="smoke run: 64^2 on 1 and 2 ranks")
    p.add_argument("--from-csv", default="", help="comma-separated setup_scaling.csv files: table and plot of their rows, nothing run")
    a = p.parse_args()
    if a.quick:
        a.sizes, a.ranks = "64", "1,2"
    try:
        sizes = [int(s) for s in a.sizes.split(",") if s]
        ranks = [int(s) for s in a.ranks.split(",") if s]
    except ValueError:
        fail(PROG, "--sizes and --ranks take comma-separated integers")
    parts = [s for s in a.partitions.split(",") if s]
    if not sizes or not ranks or min(sizes) < 8 or min(ranks) < 1:
        fail(PROG, "--sizes needs lattice sides of at least 8 and --ranks rank counts of at least 1")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)

    rows = []
    if a.from_csv:
        for name in a.from_csv.split(","):
            try:
                with open(name, newline="") as f:
                    rows += list(csv.DictReader(f))
            except OSError as e:
                fail(PROG, f"cannot read {name}: {e}")
        rows.sort(key=lambda r: (int(r["N"]), r["partition"] != "dmda", r["partition"], int(r["ranks"])))
        ranks = []
    for np_ in ranks:
        fixed = {}
        for part in parts:
            fixed[part] = measure(a.build, 16, np_, part, a.timeout)["max"]
        for n in sizes:
            for part in parts:
                m = measure(a.build, n, np_, part, a.timeout)
                share = (m["total"] - np_ * fixed[part]) / np_
                row = {"N": n, "particles": n * n, "ranks": np_, "partition": part,
                       "cloth_setup_s": f"{m['cloth']:.3f}" if m["cloth"] is not None else "",
                       "partition_s": f"{m['partition']:.3f}" if m["partition"] is not None else "",
                       "setup_stage_s": f"{m['stage']:.3f}" if m["stage"] is not None else "", "wall_s": f"{m['wall']:.2f}",
                       "setup_cpu_s": f"{m['cpu']:.3f}" if m["cpu"] is not None else "",
                       "setup_cpu_rank_s": f"{m['cpu_rank']:.3f}" if m["cpu_rank"] is not None else "",
                       "rank_max_mib": f"{m['max'] / 2**20:.1f}", "rank_min_mib": f"{m['min'] / 2**20:.1f}",
                       "total_mib": f"{m['total'] / 2**20:.1f}", "hwm_mib": f"{m['hwm'] / 2**20:.1f}",
                       "fixed_mib": f"{fixed[part] / 2**20:.1f}",
                       "max_over_share": f"{(m['max'] - fixed[part]) / share:.3f}" if share > 0 else "",
                       "imbalance": f"{m['report']['owned_max'] * np_ / max(m['report']['active_particles'], 1):.3f}"}
                rows.append(row)
                print(f"  {n:5d}^2 {np_:2d} ranks {part:8s} cloth set-up {row['cloth_setup_s']:>8s} s (partition {row['partition_s'] or '-':>7s} s), "
                      f"Setup stage {row['setup_stage_s']:>8s} s, CPU {row['setup_cpu_rank_s']:>7s} s a rank ({row['setup_cpu_s']} s all), per rank {row['rank_min_mib']}-{row['rank_max_mib']} MiB "
                      f"(fixed {row['fixed_mib']}, max/share {row['max_over_share']}), HWM {row['hwm_mib']} MiB", flush=True)
    write_csv(out / "setup_scaling.csv", rows)
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT).stdout.strip()
    except OSError:
        commit = "unknown"
    hdr = ["N", "ranks", "partition", "ClothSetUp (s)", "partitioner (s)", "Setup stage (s)", "set-up CPU, busiest rank (s)", "set-up CPU, all ranks (s)",
           "per rank max (MiB)", "per rank min (MiB)", "all ranks (MiB)", "fixed (MiB)", "max / share", "imbalance"]
    md = [f"# Set-up on many ranks (drape {commit}, {machine()})", "",
          "Circular cloth in an N x N lattice, -ts_max_steps 0 -drape_stability_its 0; times the slowest rank's (-log_view, wall), CPU the report's "
          "setup_cpu_rank_max and setup_cpu, memory "
          "-memory_view's maximum resident set; fixed: the same on a 16 x 16 lattice; max / share = (max - fixed) / ((all - P fixed) / P).", "",
          md_table(hdr, [[r["N"], r["ranks"], r["partition"], r["cloth_setup_s"], r["partition_s"], r["setup_stage_s"], r.get("setup_cpu_rank_s", ""),
                          r.get("setup_cpu_s", ""), r["rank_max_mib"],
                          r["rank_min_mib"], r["total_mib"], r["fixed_mib"], r["max_over_share"], r["imbalance"]] for r in rows]), ""]
    text = "\n".join(md) + "\n"
    (out / "setup_scaling.md").write_text(text)
    print(text)
    if rows:
        plot(rows, out / "setup_scaling.png")


def plot(rows, path):
    """Per-rank peak memory (and the fixed cost plus the one-rank run's share, the
    ideal) and the busiest rank's set-up CPU time (and the one-rank run's over P),
    against the ranks, one line per N and partition."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.5))
    for key in sorted({(int(r["N"]), r["partition"]) for r in rows}):
        mine = sorted((r for r in rows if (int(r["N"]), r["partition"]) == key), key=lambda r: int(r["ranks"]))
        ranks = [int(r["ranks"]) for r in mine]
        line, = a1.loglog(ranks, [float(r["rank_max_mib"]) for r in mine], "o-", label=f"{key[0]}² {key[1]}")
        one = [r for r in mine if int(r["ranks"]) == 1]
        if key[1] == "dmda" and one:
            share = float(one[0]["rank_max_mib"]) - float(one[0]["fixed_mib"])
            a1.loglog(ranks, [float(r["fixed_mib"]) + share / int(r["ranks"]) for r in mine], ":", color=line.get_color(), label=f"{key[0]}²: fixed + share")
        cpu = [(int(r["ranks"]), float(r["setup_cpu_rank_s"])) for r in mine if r.get("setup_cpu_rank_s")]
        if cpu:
            a2.loglog([p for p, _ in cpu], [t for _, t in cpu], "o-", color=line.get_color(), label=f"{key[0]}² {key[1]}")
            if key[1] == "dmda" and cpu[0][0] == 1:
                a2.loglog([p for p, _ in cpu], [cpu[0][1] / p for p, _ in cpu], ":", color=line.get_color(), label=f"{key[0]}²: one rank's / P")
    a1.set_ylabel("peak memory of the largest rank (MiB)")
    a2.set_ylabel("set-up CPU time of the busiest rank (s)")
    for ax in (a1, a2):
        ax.set_xlabel("ranks (past 2 oversubscribed on 2 cores)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("drape: set-up of a disc in an N x N lattice on many ranks")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main()
