#!/usr/bin/env python3
"""Two builds of drape on the same scenes, run after one another (not a test).

A change meant to make drape faster is judged by CPU time, and on a shared machine a
run's CPU time moves by 5-15 % with what else runs: runs of the two builds made
hours apart compare the machine's states as much as the builds. Here each repeat
runs every scene with the baseline build and then with the new one, one run at a
time, and the ratios are of the medians. Every pair of runs must take the same
steps (the change is to be one of speed, not of results): a pair that does not is
reported as such. The frames are not compared (use scripts/drape_h5.py for that).

Scenes (--scenes, from SCENES below): the drapebe sphere drop at 64^2 with and
without self-contact (runs/sphere.opts, 1e-2 s to t = 1 s), the hang's race to
rest at 64^2 and 128^2 (scripts/rest_race.py's fastest drapebe settings), the
Cusick scene at 81^2 to t = 0.3 s, 30 steps of the hang at 256^2 and 10 at 512^2.

Output in --out (default out/compare_builds): compare_builds.csv (one row per run)
and compare_builds.md (the medians, their ratio new / baseline, the machine and the
commands).

    python3 scripts/compare_builds.py --baseline /tmp/old/build --repeat 3
    python3 scripts/compare_builds.py --baseline /tmp/old/build --scenes race128,hang256 --repeat 2
    python3 scripts/compare_builds.py --quick --out /tmp/cb     # smoke run: this build against itself
"""
import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import machine, md_table, median, write_csv  # noqa: E402
from drape_run import Drape, fail  # noqa: E402

PROG = "compare_builds.py"
SPHERE = "-options_file runs/sphere.opts -da_grid_x 64 -da_grid_y 64 -ts_dt 1e-2 -ts_max_time 1 -output_interval 0"
HANG = "-options_file runs/hang.opts -cloth_damping 5 -ts_max_time 60 -output_interval 1e6"
SCENES = {
    "sphere64_self": (SPHERE, "the sphere drop, drapebe 1e-2 s to 1 s, 64^2, self-contact"),
    "sphere64_noself": (SPHERE + " -contact_self 0", "the same without self-contact"),
    "race64": (HANG + " -da_grid_x 64 -da_grid_y 64 -ts_dt 7e-3 -drape_rest_tol 1e-9 -drape_settle_tol 1e-5 -ts_adapt_drape_settle_factor 10",
               "the hang to rest, 64^2, drapebe 7 ms settling up to 10 x, to 1e-9 J/kg"),
    "race128": (HANG + " -da_grid_x 128 -da_grid_y 128 -ts_dt 1e-2 -drape_rest_tol 2e-8 -drape_settle_tol 1e-4 -ts_adapt_drape_settle_factor 6 -drape_pc_lag 3",
                "the hang to rest, 128^2, drapebe 1e-2 s settling up to 6 x, the preconditioner every 3 steps, to 2e-8 J/kg"),
    "cusick81": ("-options_file runs/cusick.opts -cloth_fabric denim -da_grid_x 81 -da_grid_y 81 -ts_max_time 0.3 -output_interval 0",
                 "the Cusick scene, denim, 81^2, to t = 0.3 s"),
    "hang256": ("-options_file runs/hang.opts -da_grid_x 256 -da_grid_y 256 -ts_dt 1e-2 -ts_max_steps 30 -output_interval 0", "the hang, 256^2, 30 steps of 1e-2 s"),
    "hang512": ("-options_file runs/hang.opts -da_grid_x 512 -da_grid_y 512 -ts_dt 1e-2 -ts_max_steps 10 -output_interval 0", "the hang, 512^2, 10 steps of 1e-2 s"),
}
QUICK = {"sphere64_self": ["-da_grid_x", "16", "-da_grid_y", "16", "-ts_max_time", "0.1"], "race64": ["-da_grid_x", "16", "-da_grid_y", "16", "-ts_max_time", "1"]}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--baseline", help="the other build's directory (holding drape); --quick: this build")
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"), help="the new build's directory (default $DRAPE_BUILD or build)")
    p.add_argument("--scenes", default="sphere64_self,sphere64_noself,race64,race128", help="comma-separated subset of " + ",".join(SCENES))
    p.add_argument("--repeat", type=int, default=3, help="rounds (each: every scene, baseline then new)")
    p.add_argument("--out", default="out/compare_builds", help="output directory")
    p.add_argument("--quick", action="store_true", help="two small scenes, one round, this build against itself: a smoke run")
    a = p.parse_args()
    names = list(QUICK) if a.quick else a.scenes.split(",")
    unknown = [s for s in names if s not in SCENES]
    if unknown:
        fail(PROG, f"unknown scene {unknown[0]!r}: --scenes takes {', '.join(SCENES)}")
    if a.repeat < 1:
        fail(PROG, f"--repeat {a.repeat}: at least 1 round is needed")
    if not a.baseline and not a.quick:
        fail(PROG, "--baseline BUILD is needed: the directory of the build to compare with")
    repeat = 1 if a.quick else a.repeat
    builds = {"baseline": Drape(PROG, a.baseline or a.build), "new": Drape(PROG, a.build)}
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for r in range(repeat):
        for s in names:
            args = SCENES[s][0].split() + (QUICK[s] if a.quick else [])
            for tag, d in builds.items():
                res = d.run(args)
                if res.returncode or res.report is None:
                    fail(PROG, f"{s} with the {tag} build failed (exit {res.returncode}):\n{res.tail()}")
                j = res.report
                rows.append({"scene": s, "build": tag, "round": r, "cpu": j["cpu"], "wall": j["wall"], "steps": j["steps"],
                             "cg_per_step": j.get("cg_per_step", ""), "memory_peak": j.get("memory_peak", "")})
                print(f"{s:16s} {tag:8s} round {r}: {j['cpu']:8.2f} CPU s, {j['steps']} steps", flush=True)
    write_csv(out / "compare_builds.csv", rows)
    table = []
    for s in names:
        cpu = {t: median([x["cpu"] for x in rows if x["scene"] == s and x["build"] == t]) for t in builds}
        steps = {t: sorted({x["steps"] for x in rows if x["scene"] == s and x["build"] == t}) for t in builds}
        same = steps["baseline"] == steps["new"] and len(steps["new"]) == 1
        table.append([s, SCENES[s][1], ", ".join(map(str, steps["new"])) if same else f"DIFFER: {steps['baseline']} / {steps['new']}",
                      f"{cpu['baseline']:.2f}", f"{cpu['new']:.2f}", f"**{cpu['new'] / cpu['baseline']:.3f}**"])
    md = [f"# {PROG}", "", f"Machine: {machine()}. Baseline: {builds['baseline'].exe}; new: {builds['new'].exe}.",
          f"Medians of {repeat} round(s), CPU s of the time loop (drape's report); each round runs every scene with the baseline, then the new build.", "",
          md_table(["scene", "what", "steps", "baseline CPU s", "new CPU s", "new / baseline"], table), "",
          "    python3 scripts/compare_builds.py " + " ".join(sys.argv[1:])]
    (out / "compare_builds.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
