"""The compiled kernel against today's object-based loop, side by side in one run.

    python benchmarks/bench_kernel.py            # everything (~3 min on two cores)
    python benchmarks/bench_kernel.py --quick    # shorter flights, fewer repeats

Figures (issue 15's targets in brackets), all on the E3_wind scenario (3 m/s turbulent wind,
ISM+DO/ISM+DO, every noise on):

- one vehicle: real-time factor of ``Simulation.run`` (objects) and ``simulate_compiled`` [>= 500x];
- batches: vehicle-steps per second of the objects' array path, of ``fly_batch`` (vehicles in
  lanes, W per instruction) and of ``fly_one_by_one`` (the layout before lanes), on both cores (a
  share of the vehicles per Python thread, the GIL released) and on one thread, with CPU seconds,
  each beside ONE compiled vehicle on one core measured in the same run [>= 8 M/s on both cores;
  issue 24: 4000 vehicles on both cores >= 4x one vehicle on one core];
- bytes per vehicle: the resident memory a 4000-vehicle batch (no log) adds to a process that
  has already flown, over 4000, each engine in a fresh process [<= 16 KB];
- compile: a whole process that flies one vehicle for 10 ms, with an empty kernel cache (cold) and
  then with the cache it left (cached) [<= 20 s, <= 1 s], and where the cold compile goes (numba's
  compile events, own time per function);
- the companion's 250 Hz position loop: ``PositionLoop.update`` interpreted against the same
  ``position_loop_step`` compiled and called from Python, per call (median and 99th percentile).

Results and the machine: docs/benchmarks.md ("Compiled kernel").
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from companion.control.position import DoConst  # noqa: E402
from sitl.lab.simulation import Simulation, simulate_compiled  # noqa: E402
from sitl.plant import kernel as K  # noqa: E402
from sitl.plant.scenario import load_scenario  # noqa: E402

SCENARIO = "E3_wind"


def best_median(fn, repeat: int) -> tuple[float, float]:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times)


def one_vehicle(duration_s: float, repeat: int) -> None:
    sc = load_scenario(SCENARIO)
    simulate_compiled(sc, "ism_do", "ism_do", 1, 0.01)  # load the cached kernel
    print(f"\n## one vehicle, {SCENARIO}, {duration_s:g} s simulated, best / median of {repeat}")
    print(f"{'engine':>10} {'best s':>8} {'median s':>9} {'x real time (best)':>19} {'(median)':>9}")
    for name, fn in (("objects", lambda: Simulation(sc, "ism_do", "ism_do", 1).run(duration_s)),
                     ("compiled", lambda: simulate_compiled(sc, "ism_do", "ism_do", 1, duration_s))):
        b, m = best_median(fn, repeat)
        print(f"{name:>10} {b:>8.3f} {m:>9.3f} {duration_s / b:>19.0f} {duration_s / m:>9.0f}")


def _batch_rows(n: int) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    sc = load_scenario(SCENARIO)
    consts = [K.flight_const(sc, "ism_do", "ism_do", s) for s in range(1, n + 1)]
    codec = K.flight_codec(K.position_family(consts[0]))
    return np.array([codec.pack(c) for c in consts]), codec.arrays(consts[0])


def compiled_batch(n: int, duration_s: float, threads: int | None = None,
                   layout: str = "lanes") -> tuple[float, float]:
    """(wall s, CPU s) of ``n`` vehicles for ``duration_s``, no log: ``fly_batch`` (``layout``
    "lanes", what a batch flies on) or ``fly_one_by_one`` (the layout before lanes)."""
    rows, arrays = _batch_rows(n)
    steps = int(duration_s * 1000)
    logs, final = np.empty((n, 0, len(K.LOG_COLUMNS))), np.empty((n, 3))
    fly = K.fly_batch if layout == "lanes" else K.fly_one_by_one
    fly(DoConst, rows[:8], *arrays, 1, logs[:8], final[:8])  # load (or compile) the kernel
    c0, t0 = time.process_time(), time.perf_counter()
    fly(DoConst, rows, *arrays, steps, logs, final, threads)
    return time.perf_counter() - t0, time.process_time() - c0


def one_core_one_vehicle(duration_s: float, repeat: int) -> float:
    """Vehicle-steps per second of ONE compiled vehicle on one core (the best of ``repeat``)."""
    wall = min(compiled_batch(1, duration_s, 1, "one by one")[0] for _ in range(repeat))
    return duration_s * 1000 / wall


def objects_batch(n: int, duration_s: float) -> tuple[float, float]:
    sc = load_scenario(SCENARIO)
    sim = Simulation(sc, "ism_do", "ism_do", list(range(1, n + 1)))
    c0, t0 = time.process_time(), time.perf_counter()
    sim.run(duration_s)
    return time.perf_counter() - t0, time.process_time() - c0


def batches(quick: bool) -> None:
    """Every batch beside ONE compiled vehicle on one core, measured in the same run: the lanes
    (``fly_batch``) and the vehicles one by one (``fly_one_by_one``, the layout before them)."""
    scale = 3 if quick else 1
    one = one_core_one_vehicle(10.0 / scale, 3)
    print(f"\n## batches, {SCENARIO}, vehicle-steps/s (Python threads, the GIL released; {K.cores()} cores; "
          f"lanes of {K.lanes.W} vehicles)")
    print(f"one compiled vehicle on one core: {one / 1e6:.2f} M steps/s (best of 3, {10 / scale:g} s simulated); "
          f"'x one' = a row's M steps/s over it")
    print(f"{'engine':>29} {'vehicles':>8} {'sim s':>6} {'wall s':>7} {'CPU s':>7} {'M steps/s':>10} "
          f"{'M steps/CPU-s':>14} {'x one':>6}")
    runs: list[tuple[str, int, float, int | None, str]] = [("objects (arrays)", 1000, 1.0 / scale, None, "")]
    for n, d in ((2, 10.0), (100, 5.0), (1000, 2.0), (4000, 1.0)):
        for layout in ("one by one", "lanes"):
            if layout == "lanes" and n < K.lanes.W:
                continue
            runs.append((f"compiled {layout}, 1 thread", n, d / scale, 1, layout))
            runs.append((f"compiled {layout}, all", n, d / scale, None, layout))
    ratios = {}
    for name, n, d, threads, layout in runs:
        wall, cpu = objects_batch(n, d) if not layout else compiled_batch(n, d, threads, layout)
        steps = n * d * 1000
        ratios[name, n] = steps / wall / one
        print(f"{name:>29} {n:>8} {d:>6.2f} {wall:>7.2f} {cpu:>7.2f} {steps / wall / 1e6:>10.2f} "
              f"{steps / cpu / 1e6:>14.2f} {steps / wall / one:>6.2f}")
    print(f"4000 vehicles on all cores: lanes {ratios['compiled lanes, all', 4000]:.2f}x one vehicle on one core "
          f"(issue 24: >= 4x), one by one {ratios['compiled one by one, all', 4000]:.2f}x")


MEMORY = """
import os, sys
import numpy as np
sys.path.insert(0, {root!r})
from sitl.plant.scenario import load_scenario
from sitl.plant import kernel as K
from sitl.lab.simulation import Simulation

def rss():
    return int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

sc = load_scenario("E3_wind")
n, engine = int(sys.argv[1]), sys.argv[2]
Simulation(sc, "ism_do", "ism_do", [1, 2]).run(0.01)  # imports and first-use allocations
c1 = K.flight_const(sc, "ism_do", "ism_do", 1)
codec = K.flight_codec(K.position_family(c1))
K.fly_batch(K.position_family(c1), np.array([codec.pack(c1)]), *codec.arrays(c1), 10, np.empty((1, 0, 53)),
            np.empty((1, 3)))
before = rss()
if engine == "compiled":
    rows = np.array([codec.pack(K.flight_const(sc, "ism_do", "ism_do", s)) for s in range(1, n + 1)])
    logs, final = np.empty((n, 0, len(K.LOG_COLUMNS))), np.empty((n, 3))
    K.fly_batch(K.position_family(c1), rows, *codec.arrays(c1), 200, logs, final)
else:
    sim = Simulation(sc, "ism_do", "ism_do", list(range(1, n + 1)))
    for _ in range(200):
        sim.vehicle.step(sim.setpoint)
print(rss() - before)
"""


def rss_growth(n: int, engine: str) -> int:
    code = MEMORY.format(root=str(ROOT))
    out = subprocess.run([sys.executable, "-c", code, str(n), engine], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1])


def memory() -> None:
    print("\n## bytes per vehicle: resident memory a 4000-vehicle batch adds (200 steps, no log) / 4000")
    for engine in ("objects", "compiled"):
        grow = rss_growth(4000, engine)
        print(f"{engine:>10}: {grow / 4000:>9,.0f} B per vehicle ({grow / 2**20:.1f} MB for 4000)")
    print(f"  compiled, by construction: {K.flight_codec(DoConst).size * 8} B of constants per vehicle "
          f"(a flight_codec row of PD+DO, ISM+DO or INDI) "
          f"+ 24 B of result; the state (164 numbers, 1312 B) lives on its thread's stack")


START = """
import sys, time
t0 = time.perf_counter()
sys.path.insert(0, {root!r})
from sitl.lab.simulation import simulate_compiled
from sitl.plant.scenario import load_scenario
simulate_compiled(load_scenario("E3_wind"), "ism_do", "ism_do", {seeds}, 0.01)
print(time.perf_counter() - t0)
"""


def _start(cache: str, seeds: str = "1") -> tuple[float, float]:
    """(whole-process wall s, in-process s from first import to the flight's end)"""
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", START.format(root=str(ROOT), seeds=seeds)], env=env,
                         capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, float(out.stdout.split()[-1])


def compile_times(repeat: int) -> None:
    for what, seeds in (("one vehicle", "1"), ("a batch of 8 vehicles (lanes: both kernels)", "list(range(1, 9))")):
        print(f"\n## start: a process that flies {what} for 10 ms (whole process / import to flight's end)")
        with tempfile.TemporaryDirectory() as cache:
            cold = _start(cache, seeds)
            cached = [_start(cache, seeds) for _ in range(repeat)]
        print(f"  cold (empty cache): {cold[0]:.2f} s / {cold[1]:.2f} s")
        for w, i in cached:
            print(f"  cached:             {w:.2f} s / {i:.2f} s")


COMPILE_EVENTS = """
import collections, sys, tempfile, os
os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp()
sys.path.insert(0, {root!r})
from numba.core import event
rec = event.RecordingListener()
event.register("numba:compile", rec)
from sitl.lab.simulation import simulate_compiled
from sitl.plant.scenario import load_scenario
simulate_compiled(load_scenario("E3_wind"), "ism_do", "ism_do", 1, 0.01)
own, stack = collections.Counter(), []
for ts, e in rec.buffer:
    name = getattr(getattr(e.data.get("dispatcher"), "py_func", None), "__qualname__", "?")
    if e.is_start:
        stack.append([name, ts, 0.0])
    else:
        n, t0, inner = stack.pop()
        own[n] += ts - t0 - inner
        if stack:
            stack[-1][2] += ts - t0
print(f"  {{sum(own.values()):.1f}} s in {{len(own)}} functions; the most expensive, own time (callees excluded):")
for n, d in own.most_common(8):
    print(f"  {{d:6.2f}} s  {{n}}")
"""


def compile_events() -> None:
    """Where a cold compile goes: numba's compile events per function, in a fresh process."""
    print("\n## cold compile by function (numba:compile events, empty cache)")
    out = subprocess.run([sys.executable, "-c", COMPILE_EVENTS.format(root=str(ROOT))], capture_output=True,
                         text=True, check=True)
    print(out.stdout.rstrip())


def companion_loop(calls: int) -> None:
    """PositionLoop.update (the companion's call at 250 Hz) against position_loop_step compiled."""
    from companion.control.jit import kernel
    from companion.control.outer_loop import PositionLoop, PositionMeasurement, position_loop_step
    from companion.control.params import VehicleParams
    from companion.control.trajectory import PositionReference

    dt = 1.0 / 250.0
    v = VehicleParams()
    meas = PositionMeasurement((0.01, -0.02, -1.0), (0.1, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, -9.81))
    ref = PositionReference((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0)
    loop = PositionLoop.create("ism_do", v)
    compiled = kernel(position_loop_step)
    c = loop.const(dt)
    st = loop.state
    compiled(c, st, meas.pos_ned_m, meas.vel_ned_m_s, meas.q, meas.specific_force_ned_m_s2, True, ref)

    def interpreted_call() -> None:
        loop.update(meas, ref, dt)

    def compiled_call() -> None:
        nonlocal st
        st, _ = compiled(c, st, meas.pos_ned_m, meas.vel_ned_m_s, meas.q, meas.specific_force_ned_m_s2, True, ref)

    print(f"\n## the companion's position loop (ISM+DO, 250 Hz), {calls} calls each, wall time per call")
    for name, fn in (("interpreted (PositionLoop.update)", interpreted_call),
                     ("compiled, called from Python", compiled_call)):
        per = []
        for _ in range(calls):
            t0 = time.perf_counter_ns()
            fn()
            per.append(time.perf_counter_ns() - t0)
        per.sort()
        med, p99 = per[len(per) // 2] / 1e3, per[int(0.99 * len(per))] / 1e3
        print(f"{name:>34}: median {med:7.1f} us, p99 {p99:7.1f} us, {100 * med * 1e-6 * 250:.2f} % of a core "
              f"at 250 Hz")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--only", choices=("one", "batches", "memory", "start", "compile", "companion"))
    args = ap.parse_args()
    print(f"# bench_kernel  {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}  nproc {os.cpu_count()}  "
          f"load {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    parts = {
        "one": lambda: one_vehicle(10.0 if args.quick else 45.0, 2 if args.quick else 3),
        "batches": lambda: batches(args.quick),
        "memory": memory,
        "start": lambda: compile_times(2 if args.quick else 3),
        "compile": compile_events,
        "companion": lambda: companion_loop(2000 if args.quick else 20000),
    }
    for name, part in parts.items():
        if args.only in (None, name):
            part()
    print(f"\n(load at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
