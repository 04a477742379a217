"""The bundled MAVLink vehicle in lockstep: how fast it flies a mission, and where its time goes.

    python benchmarks/bench_lockstep.py                 # 3 flights of missions/waypoints.toml
    python benchmarks/bench_lockstep.py --profile 25    # and cProfile the vehicle (top 25 by own time)
    python benchmarks/bench_lockstep.py --pieces        # and the companion's CPU per piece

The companion (this process) flies the mission against ``sitl --flavour paper --lockstep`` (the
world advances 10 ms per setpoint) with the speed-up capped at 1000, so only the two processes
limit it. Per flight: simulated seconds (the vehicle's time from its boot to the end of the
flight) over wall seconds (what a user sees), and each process's CPU seconds per simulated
second. The vehicle's *capacity* is the inverse of its CPU per simulated second: how fast it
would fly behind a companion that costs nothing, on another core [issue 15: the bundled MAVLink
vehicle >= 50x sustained in lockstep].

``--pieces`` flies each vehicle once more with its pieces timed in place (a ``--baseline`` by its
own copy of benchmarks/timed_vehicle.py), then once with the companion's pieces timed in place (CPU time of each call,
``time.process_time``): parse (datagrams to messages), state (messages into the vehicle state),
law (the control step: reference, position and attitude laws, guard), encode (setpoints and debug
values to frames), send (``sendto``), record (the flight's CSV row and .tlog); the rest is the
event loop, the waits and everything else, the whole process's CPU less the pieces.

Results and the machine: docs/benchmarks.md ("The MAVLink vehicle in lockstep").
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import pstats
import resource
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from companion.flight import Flight, FlightOptions, run_flight  # noqa: E402
from companion.mission import load_mission  # noqa: E402
from companion.vehicle_process import VehicleProcess  # noqa: E402
from timed_vehicle import Piece, put_back, time_in_place  # noqa: E402

MISSION = ROOT / "missions" / "waypoints.toml"


def _cpu(who: int) -> float:
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


def _proc_cpu(pid: int) -> float:
    """CPU seconds process ``pid`` has used so far (Linux: /proc/PID/stat, utime + stime)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


PIECES: dict[str, Piece] = {  # piece: (module, class or None, function) timed in place
    "parse": ("companion.link.pymavlink_link", None, "parse_datagram"),
    "state": ("companion.link.pymavlink_link", "PymavlinkLink", "_handle"),
    "law": ("companion.flight.offboard", "OffboardController", "step"),
    "encode": ("companion.link.pymavlink_link", "PymavlinkLink", "_send"),
    "send": ("companion.mavlink.udp", "UdpEndpoint", "_send_now"),
    "record": ("companion.flight.recorder", "FlightRecorder", "row"),
    "record ": ("companion.flight.recorder", "FlightRecorder", "traffic"),
}
"""``encode`` times all of ``_send``; the ``sendto`` and the .tlog inside it are taken out again"""


@contextlib.contextmanager
def timed_pieces() -> Iterator[dict[str, list[float]]]:
    """CPU seconds and calls of each piece while the block runs (the originals put back after)."""
    spent, undo = time_in_place(PIECES)
    try:
        yield spent
    finally:
        put_back(undo)


def pieces_table(r: dict[str, float], spent: dict[str, list[float]]) -> None:
    sim = r["sim_s"]
    per = {p.strip(): 0.0 for p in spent}
    calls = {p.strip(): 0 for p in spent}
    for p, (cpu, n) in spent.items():
        per[p.strip()] += cpu
        calls[p.strip()] += int(n)
    # encode's own time: _send less the sendto and the .tlog record it makes
    per["encode"] -= per["send"] + spent["record "][0]
    total = r["companion_cpu_per_sim_s"] * sim
    print(f"\n## the companion per piece ({sim:.1f} s simulated; CPU ms per simulated s; share of its CPU)")
    print(f"{'piece':>8} {'calls/sim s':>12} {'CPU ms/sim s':>13} {'us/call':>8} {'share':>6}")
    for p in per:
        print(f"{p:>8} {calls[p] / sim:12.0f} {1000 * per[p] / sim:13.2f} {1e6 * per[p] / max(calls[p], 1):8.1f} "
              f"{per[p] / total:6.0%}")
    rest = total - sum(per.values())
    print(f"{'rest':>8} {'':>12} {1000 * rest / sim:13.2f} {'':>8} {rest / total:6.0%}   (event loop, waits, the rest)")
    print(f"{'all':>8} {'':>12} {1000 * total / sim:13.2f}")


def fly_once(out: Path, engine: str, profile: Path | None = None, timed: Path | None = None,
             baseline: Path | None = None) -> dict[str, float]:
    """One flight of the mission; ``engine`` the vehicle's (``baseline``: a checkout of another commit
    flies its own vehicle, whatever engine it has); ``profile``/``timed``: the vehicle under cProfile,
    or with its pieces timed (benchmarks/timed_vehicle.py), writing to that file."""
    prefix: tuple[str, ...] = ("-m", "cProfile", "-o", str(profile)) if profile else ()
    if timed:  # a baseline's vehicle is timed by its own copy of the timers, on its own code
        prefix = (str((baseline or ROOT) / "benchmarks" / "timed_vehicle.py"), str(timed))
    # at the 1000x cap a companion's 10 ms between arming and its take-off are PX4's 10 s pre-flight
    # auto-disarm (a loaded host refused the take-off): 120 s here, the flight is what is measured
    args = ("--flavour", "paper", "--lockstep", "--param", "COM_DISARM_PRFLT=120") + (
        ("--engine", engine) if baseline is None else ())
    env = None if baseline is None else {**os.environ, "PYTHONPATH": str(baseline)}
    vehicle = VehicleProcess(*args, speedup=1000.0, interpreter_args=prefix, env=env, cwd=baseline)
    child0, self0, w0 = _cpu(resource.RUSAGE_CHILDREN), _cpu(resource.RUSAGE_SELF), time.monotonic()
    try:
        opts = FlightOptions(connect=f"udp://{vehicle.url}", controller="ism_do", out_dir=out,
                             output="attitude_rates", mission_file=MISSION)
        flight = Flight(load_mission(MISSION), opts)
        with open(os.devnull, "w") as quiet, contextlib.redirect_stdout(quiet):  # the flight's own report
            code, engaged = asyncio.run(_watched(flight, vehicle.pid, timed is not None))
        wall = time.monotonic() - w0
        self_cpu = _cpu(resource.RUSAGE_SELF) - self0
        flown_cpu, flown_sim = _proc_cpu(vehicle.pid) - engaged[0], flight.link.state.t - engaged[1]
    finally:
        vehicle.stop()
    vehicle_cpu = _cpu(resource.RUSAGE_CHILDREN) - child0
    sim = flight.link.state.t  # the vehicle's time when the flight ended (its clock starts at boot)
    if code != 0:
        raise SystemExit(f"the flight ended with exit {code}")
    return {"sim_s": sim, "wall_s": wall, "speedup": sim / wall, "vehicle_cpu_per_sim_s": vehicle_cpu / sim,
            "sustained_cpu_per_sim_s": flown_cpu / flown_sim, "capacity": flown_sim / flown_cpu,
            "companion_cpu_per_sim_s": self_cpu / sim}


async def _watched(flight: Flight, pid: int, mark: bool) -> tuple[int, tuple[float, float]]:
    """The flight's exit code, and the vehicle's CPU seconds and simulated time when the companion
    took control (offboard engaged: from there to the end, the vehicle flies the stream in lockstep).
    ``mark``: SIGUSR1 to the vehicle then and at the end (benchmarks/timed_vehicle.py)."""
    task = asyncio.create_task(run_flight(flight, plots=False))
    engaged = None
    while not task.done():
        if engaged is None and flight.engaged:
            engaged = (_proc_cpu(pid), flight.link.state.t)
            if mark:
                os.kill(pid, signal.SIGUSR1)
        await asyncio.sleep(0.02)
    if mark:
        os.kill(pid, signal.SIGUSR1)
    code = task.result()
    if engaged is None:
        raise SystemExit("the companion never took control")
    return code, engaged


def vehicle_pieces_table(label: str, path: Path) -> None:
    """The vehicle's pieces between the two marks: the companion taking control, the flight's end."""
    a, b = json.loads(path.read_text())["marks"][:2]
    sim, total = b["sim_s"] - a["sim_s"], b["cpu_s"] - a["cpu_s"]
    print(f"\n## the vehicle per piece, {label} ({sim:.1f} s simulated under the companion's control; CPU ms per "
          f"simulated s; share of its CPU)")
    print(f"{'piece':>10} {'calls/sim s':>12} {'CPU ms/sim s':>13} {'us/call':>8} {'share':>6}")
    spent = 0.0
    for p, (cpu_b, n_b) in b["pieces"].items():
        cpu, n = cpu_b - a["pieces"][p][0], n_b - a["pieces"][p][1]
        spent += cpu
        print(f"{p:>10} {n / sim:12.0f} {1000 * cpu / sim:13.2f} {1e6 * cpu / max(n, 1):8.1f} {cpu / total:6.0%}")
    rest = total - spent
    print(f"{'rest':>10} {'':>12} {1000 * rest / sim:13.2f} {'':>8} {rest / total:6.0%}   "
          f"(event loop, pacing, guard, the timers)")
    print(f"{'all':>10} {'':>12} {1000 * total / sim:13.2f}")


@contextlib.contextmanager
def checkout(rev: str | None) -> Iterator[Path | None]:
    """A worktree of ``rev`` (removed after), or None."""
    if rev is None:
        yield None
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "baseline"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(path), rev], check=True)
        try:
            yield path
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(path)], check=False)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3, help="flights per vehicle, interleaved")
    ap.add_argument("--engines", default="compiled,objects", help="the vehicle's engines to fly, side by side")
    ap.add_argument("--baseline", metavar="REV", help="also fly the vehicle of commit REV (a git worktree)")
    ap.add_argument("--profile", type=int, default=0, metavar="N", help="profile one more flight's vehicle, top N")
    ap.add_argument("--pieces", action="store_true", help="one more flight per vehicle with its pieces timed, "
                                                          "and one with the companion's")
    args = ap.parse_args()
    engines = [e for e in args.engines.split(",") if e]
    print(f"# bench_lockstep  {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}  nproc {os.cpu_count()}  "
          f"load {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"# {MISSION.name} against sitl --flavour paper --lockstep, speed-up cap 1000\n")
    with tempfile.TemporaryDirectory() as tmp, checkout(args.baseline) as base:
        vehicles: list[tuple[str, str, Path | None]] = [(f"engine {e}", e, None) for e in engines]
        if base is not None:
            vehicles.insert(0, (f"at {args.baseline}", "", base))
        rows: dict[str, list[dict[str, float]]] = {label: [] for label, _, _ in vehicles}
        for i in range(args.runs):
            for label, engine, b in vehicles:
                rows[label].append(fly_once(Path(tmp) / f"run{i}{engine}", engine, baseline=b))
        print(f"{'vehicle':>16} {'run':>4} {'sim s':>6} {'wall s':>7} {'x real time':>12} {'CPU/sim s':>10} "
              f"{'sustained':>10} {'capacity':>9} {'companion CPU/sim s':>20}")
        for label, rs in rows.items():
            for i, r in enumerate(rs):
                print(f"{label:>16} {i + 1:>4} {r['sim_s']:6.1f} {r['wall_s']:7.2f} {r['speedup']:12.1f} "
                      f"{r['vehicle_cpu_per_sim_s']:10.4f} {r['sustained_cpu_per_sim_s']:10.4f} "
                      f"{r['capacity']:8.1f}x {r['companion_cpu_per_sim_s']:20.4f}")
        print("\nmedians (CPU/sim s: the whole vehicle process, its boot and exit included; sustained: from the "
              "companion taking control to the flight's end; capacity: 1 / sustained)")
        for label, rs in rows.items():
            med = {k: statistics.median(r[k] for r in rs) for k in rs[0]}
            print(f"{label:>16}: {med['speedup']:.1f}x real time; vehicle {med['vehicle_cpu_per_sim_s']:.4f} CPU s "
                  f"per simulated s, sustained {med['sustained_cpu_per_sim_s']:.4f}, capacity {med['capacity']:.1f}x; "
                  f"companion {med['companion_cpu_per_sim_s']:.4f} (capacity "
                  f"{1 / med['companion_cpu_per_sim_s']:.1f}x)")
        if args.pieces:
            for label, engine, b in vehicles:
                if b is not None and not (b / "benchmarks" / "timed_vehicle.py").exists():
                    print(f"\n({label}: no benchmarks/timed_vehicle.py to time its pieces with)")
                    continue
                out = Path(tmp) / f"pieces-{engine or 'baseline'}.json"
                fly_once(Path(tmp) / f"pieces{engine or 'baseline'}", engine, timed=out, baseline=b)
                vehicle_pieces_table(label, out)
            with timed_pieces() as spent:
                r = fly_once(Path(tmp) / "pieces", engines[0])
            pieces_table(r, spent)
        if args.profile:
            prof = Path(tmp) / "vehicle.prof"
            r = fly_once(Path(tmp) / "profiled", engines[0], profile=prof)
            print(f"\n## the vehicle ({engines[0]}) under cProfile ({r['sim_s']:.1f} s simulated, {r['speedup']:.1f}x "
                  f"with the profiler's overhead), top {args.profile} by own time")
            pstats.Stats(str(prof)).sort_stats("tottime").print_stats(args.profile)
    print(f"(load at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())})")


if __name__ == "__main__":
    main()
