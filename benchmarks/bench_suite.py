"""The main test suite (everything but the real autopilots) with different numbers of workers,
one after the other on the same commit: wall time, CPU time and the share of the cores kept busy.

    python benchmarks/bench_suite.py                 # -n 2 and -n 4
    python benchmarks/bench_suite.py --workers 2 3 4 6

Each run is ``pytest -q -n N -m "not firmware"`` in a process of its own; its CPU is the children's
rusage (the workers and every vehicle, relay and companion they start). Results and the machine:
docs/benchmarks.md ("The test suite").
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(workers: int) -> dict[str, float | str]:
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    w0 = time.monotonic()
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", str(workers), "-m", "not firmware",
                          "-p", "no:cacheprovider"], cwd=ROOT, capture_output=True, text=True)
    wall = time.monotonic() - w0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    last = out.stdout.strip().splitlines()[-1] if out.stdout.strip() else out.stderr.strip()[-200:]
    m = re.search(r"(\d+) passed", last)
    return {"workers": workers, "wall_s": wall, "cpu_s": cpu, "busy": cpu / wall / (os.cpu_count() or 1),
            "passed": int(m.group(1)) if m else 0, "result": last, "rc": out.returncode}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--workers", type=int, nargs="+", default=[2, 4])
    args = ap.parse_args()
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    print(f"# bench_suite  {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}  commit {head.stdout.strip()}  "
          f"nproc {os.cpu_count()}  load {' '.join(f'{x:.2f}' for x in os.getloadavg())}\n")
    print(f"{'workers':>8} {'wall s':>8} {'CPU s':>8} {'cores busy':>11} {'passed':>7}  result")
    for n in args.workers:
        r = run(n)
        print(f"{r['workers']:>8} {r['wall_s']:8.0f} {r['cpu_s']:8.0f} {100 * r['busy']:10.0f}% {r['passed']:>7}  "
              f"{r['result']}", flush=True)
    print(f"(load at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())})")


if __name__ == "__main__":
    main()
