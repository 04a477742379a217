"""Offline simulator throughput: simulated seconds per wall-clock second, one vehicle and batches.

The full loop per 1 kHz step: plant (rotor lag, drag, rigid body), IMU and 60 Hz tracking
system, onboard attitude estimate, ISM+DO attitude controller, mixer with quantisation, and the
ISM+DO position loop at 100 Hz with reference generation (32)-(34); E3's turbulent wind.

    python benchmarks/bench_simulation.py [--seconds 10] [--repeat 5]

Prints a table (best and median of the repeats: this machine's timing is noisy, so the best
run is the one least disturbed). Results and the machine they came from: docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time

from sitl.plant.scenario import load_scenario
from sitl.lab.simulation import Simulation


def time_run(n: int, seconds: float) -> float:
    sc = load_scenario("E3_wind").with_changes(duration_s=seconds)
    seeds = 1 if n == 1 else list(range(1, n + 1))
    sim = Simulation(sc, "ism_do", "ism_do", seeds)
    t0 = time.perf_counter()
    sim.run()
    return time.perf_counter() - t0


def _timed_batch(args: tuple[int, float, int]) -> float:
    n, seconds, first_seed = args
    sc = load_scenario("E3_wind").with_changes(duration_s=seconds)
    sim = Simulation(sc, "ism_do", "ism_do", list(range(first_seed, first_seed + n)))
    t0 = time.perf_counter()
    sim.run()
    return time.perf_counter() - t0


def parallel(n: int, seconds: float, processes: int) -> float:
    """Vehicle-steps per second with ``processes`` batches of ``n`` vehicles stepped at once."""
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(processes) as pool:
        t0 = time.perf_counter()
        list(pool.map(_timed_batch, [(n, seconds, 100_000 * i) for i in range(processes)]))
        wall = time.perf_counter() - t0
    return processes * n * seconds * 1000 / wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per run")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--batches", type=int, nargs="*", default=[1, 100, 1000, 4000])
    args = ap.parse_args()
    print(f"python {platform.python_version()} on {platform.machine()}, {os.cpu_count()} cores, "
          f"{platform.processor() or platform.platform()}")
    print(f"{'vehicles':>9} {'sim s':>6} {'best wall s':>12} {'median wall s':>14} "
          f"{'x real time (best)':>19} {'x real time (median)':>21} {'vehicle-steps/s (best)':>23}")
    for n in args.batches:
        secs = args.seconds if n <= 100 else max(1.0, args.seconds / 10)
        reps = args.repeat if n <= 1000 else max(1, args.repeat // 2)
        walls = [time_run(n, secs) for _ in range(reps)]
        best, med = min(walls), statistics.median(walls)
        steps = secs * 1000 * n
        print(f"{n:>9} {secs:>6.1f} {best:>12.3f} {med:>14.3f} {secs / best:>19.1f} {secs / med:>21.1f} "
              f"{steps / best:>23,.0f}")
        sys.stdout.flush()
    cores = os.cpu_count() or 1
    rate = parallel(4000, 2.0, cores)
    print(f"{cores} processes x 4000 vehicles, 2 s simulated each: {rate:,.0f} vehicle-steps/s "
          f"(one vehicle alone: see the first row)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
