"""Helpers shared by the benchmark scripts (bench_core.py, paper_tables.py,
scaling.py, solver_study.py, rtol_accuracy.py, implicit_study.py): describe the
machine, take medians, write Markdown tables and CSV files. They run drape through
drape_run.py and read its frames through drape_h5.py.
"""
import os
import platform
import statistics


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


def median(xs):
    return statistics.median(xs) if xs else float("nan")


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
