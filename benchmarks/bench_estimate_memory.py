"""``companion estimate`` on a long CSV: peak memory and time, by flight length.

    python benchmarks/bench_estimate_memory.py [--minutes 5 25] [--code DIR]

Writes a flight record as the lab writes it (``FlightLog.to_csv``: the 53 columns of LOG_COLUMNS,
``%.7g``, 100 Hz) of a hover with seeded noise, then runs ``companion estimate FILE --columns sitl
--mass 0.63`` in a fresh process per length and reads that process's peak resident memory
(``ru_maxrss``) after reading the log alone and after the whole command (estimate, CSV and plot
written). ``--code DIR`` runs another checkout's ``companion`` (e.g. an older commit exported with
``git archive``), for a before/after table. Results: docs/companion.md.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RATE_HZ = 100.0

CHILD = """
import json, resource, sys, time
from companion.cli import main
from companion.logs import read_log
import matplotlib, numpy
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t0 = time.perf_counter()
series = read_log(sys.argv[1], "sitl")
read_s = time.perf_counter() - t0
after_read = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
del series
t0 = time.perf_counter()
code = main(["estimate", sys.argv[1], "--columns", "sitl", "--mass", "0.63", "--out", sys.argv[2]])
total_s = time.perf_counter() - t0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"code": code, "base_mb": base / 1024, "read_mb": after_read / 1024, "peak_mb": peak / 1024,
                  "read_s": read_s, "total_s": total_s}))
"""


def write_record(path: Path, minutes: float, seed: int = 1) -> int:
    """A hover record with the lab's columns and number format; returns the rows."""
    sys.path.insert(0, str(ROOT))
    from sitl.plant.kernel import LOG_COLUMNS

    rng = np.random.default_rng(seed)
    n = int(minutes * 60 * RATE_HZ)
    with open(path, "w") as f:
        f.write(",".join(LOG_COLUMNS) + "\n")
        chunk = 10_000
        for start in range(0, n, chunk):
            k = min(chunk, n - start)
            data = rng.normal(0.0, 0.01, size=(k, len(LOG_COLUMNS)))
            col = {c: i for i, c in enumerate(LOG_COLUMNS)}
            data[:, col["t"]] = (start + np.arange(k)) / RATE_HZ
            data[:, col["z"]] += -1.5
            data[:, col["qw"]] += 1.0
            data[:, col["thrust_sp"]] += 0.63 * 9.81
            np.savetxt(f, data, delimiter=",", fmt="%.7g")
    return n


def run(code_dir: Path, log: Path) -> dict:
    out = Path(tempfile.mkdtemp())
    r = subprocess.run([sys.executable, "-c", CHILD, str(log), str(out)], cwd=code_dir, capture_output=True,
                       text=True, timeout=3600)
    if r.returncode != 0:
        raise RuntimeError(r.stdout + r.stderr)
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=float, nargs="+", default=[5.0, 25.0])
    ap.add_argument("--code", type=Path, default=ROOT, help="the checkout whose companion runs (default: this one)")
    args = ap.parse_args()
    print(f"code: {args.code}")
    print(f"{'minutes':>7} {'rows':>8} {'file [MB]':>9} {'imports [MB]':>12} {'after read [MB]':>15} "
          f"{'peak [MB]':>9} {'read [s]':>8} {'estimate [s]':>12}")
    with tempfile.TemporaryDirectory() as tmp:
        for minutes in args.minutes:
            log = Path(tmp) / f"hover_{minutes:g}min.csv"
            rows = write_record(log, minutes)
            r = run(args.code, log)
            assert r["code"] == 0, r
            print(f"{minutes:>7g} {rows:>8d} {log.stat().st_size / 1e6:>9.1f} {r['base_mb']:>12.0f} "
                  f"{r['read_mb']:>15.0f} {r['peak_mb']:>9.0f} {r['read_s']:>8.1f} {r['total_s']:>12.1f}",
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
