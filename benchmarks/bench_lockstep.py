"""The bundled MAVLink vehicle in lockstep: how fast it flies a mission, and where its time goes.

    python benchmarks/bench_lockstep.py                 # 3 flights of missions/waypoints.toml
    python benchmarks/bench_lockstep.py --profile 25    # and cProfile the vehicle (top 25 by own time)

The companion (this process) flies the mission against ``sitl --flavour paper --lockstep`` (the
world advances 10 ms per setpoint) with the speed-up capped at 1000, so only the two processes
limit it. Per flight: simulated seconds over wall seconds (what a user sees), and each process's
CPU seconds per simulated second. The vehicle's *capacity* is the inverse of its CPU per
simulated second: how fast it would fly behind a companion that costs nothing, on another core
[issue 15: the bundled MAVLink vehicle >= 50x sustained in lockstep].

Results and the machine: docs/benchmarks.md ("The MAVLink vehicle in lockstep").
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import pstats
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from companion.flight import Flight, FlightOptions, run_flight  # noqa: E402
from companion.mission import load_mission  # noqa: E402
from companion.vehicle_process import VehicleProcess  # noqa: E402

MISSION = ROOT / "missions" / "waypoints.toml"


def _cpu(who: int) -> float:
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


def fly_once(out: Path, profile: Path | None) -> dict[str, float]:
    prefix = ("-m", "cProfile", "-o", str(profile)) if profile else ()
    vehicle = VehicleProcess("--flavour", "paper", "--lockstep", speedup=1000.0, interpreter_args=prefix)
    child0, self0, w0 = _cpu(resource.RUSAGE_CHILDREN), _cpu(resource.RUSAGE_SELF), time.monotonic()
    try:
        opts = FlightOptions(connect=f"udp://{vehicle.url}", controller="ism_do", out_dir=out,
                             output="attitude_rates", mission_file=MISSION)
        with open(os.devnull, "w") as quiet, contextlib.redirect_stdout(quiet):  # the flight's own report
            code = asyncio.run(run_flight(Flight(load_mission(MISSION), opts), plots=False))
        wall = time.monotonic() - w0
        self_cpu = _cpu(resource.RUSAGE_SELF) - self0
    finally:
        report = vehicle.stop()
    vehicle_cpu = _cpu(resource.RUSAGE_CHILDREN) - child0
    sim = float(report["t"])
    if code != 0:
        raise SystemExit(f"the flight ended with exit {code}")
    return {"sim_s": sim, "wall_s": wall, "speedup": sim / wall, "vehicle_cpu_per_sim_s": vehicle_cpu / sim,
            "companion_cpu_per_sim_s": self_cpu / sim, "capacity": sim / vehicle_cpu}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--profile", type=int, default=0, metavar="N", help="profile one more flight's vehicle, top N")
    args = ap.parse_args()
    print(f"# bench_lockstep  {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}  nproc {os.cpu_count()}  "
          f"load {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"# {MISSION.name} against sitl --flavour paper --lockstep, speed-up cap 1000\n")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.runs):
            rows.append(fly_once(Path(tmp) / f"run{i}", None))
        print(f"{'run':>4} {'sim s':>7} {'wall s':>7} {'x real time':>12} {'vehicle CPU/sim s':>18} "
              f"{'companion CPU/sim s':>20} {'vehicle capacity':>17}")
        for i, r in enumerate(rows):
            print(f"{i + 1:>4} {r['sim_s']:7.1f} {r['wall_s']:7.2f} {r['speedup']:12.1f} "
                  f"{r['vehicle_cpu_per_sim_s']:18.4f} {r['companion_cpu_per_sim_s']:20.4f} {r['capacity']:16.1f}x")
        med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
        print(f"median: {med['speedup']:.1f}x real time; vehicle capacity {med['capacity']:.1f}x; "
              f"companion {med['companion_cpu_per_sim_s']:.4f} CPU s per simulated s "
              f"(capacity {1 / med['companion_cpu_per_sim_s']:.1f}x)")
        if args.profile:
            prof = Path(tmp) / "vehicle.prof"
            r = fly_once(Path(tmp) / "profiled", prof)
            print(f"\n## the vehicle under cProfile ({r['sim_s']:.1f} s simulated, {r['speedup']:.1f}x with the "
                  f"profiler's overhead), top {args.profile} by own time")
            pstats.Stats(str(prof)).sort_stats("tottime").print_stats(args.profile)
    print(f"(load at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())})")


if __name__ == "__main__":
    main()
