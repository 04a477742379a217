"""Batches on both cores two ways, side by side in one run: numba's ``parallel=True`` (a ``prange``
over the vehicles, workqueue layer: the loop until 2026-12-02) against ``fly_batch`` (the same
compiled loop, ``nogil``, a share of the vehicles per Python thread: the loop since).

    python benchmarks/bench_threads.py [--vehicles 400] [--seconds 2] [--pairs 3]

Prints vehicle-steps per wall second and per CPU second for each, pairs alternating. The prange
loop is compiled here, uncached (~25 s). Results: docs/benchmarks.md ("Threading layer, then
threads").
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicles", type=int, default=400)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--pairs", type=int, default=3)
    args = ap.parse_args()
    os.environ.setdefault("NUMBA_OPT", "1")
    import numba

    from companion.control.jit import register_with_numba
    from companion.control.position import DoConst
    from sitl.plant import kernel as K
    from sitl.plant.scenario import load_scenario

    numba.config.THREADING_LAYER = "workqueue"  # type: ignore[attr-defined]
    register_with_numba()
    fly_loop, unpack, position = K.fly_loop, K._unpack_flight, K._marker(DoConst)

    @numba.njit(parallel=True, error_model="numpy")  # type: ignore[misc]
    def fly_prange(rows, forces, torques, waypoints, steps, logs, final):  # type: ignore[no-untyped-def]
        for i in numba.prange(rows.shape[0]):
            st = fly_loop(unpack(position, rows[i], forces, torques, waypoints), steps, logs[i:i + 1])
            p = st.body.pos_ned_m
            final[i, 0] = p[0]
            final[i, 1] = p[1]
            final[i, 2] = p[2]

    n = args.vehicles
    sc = load_scenario("E3_wind")
    consts = [K.flight_const(sc, "ism_do", "ism_do", s) for s in range(1, n + 1)]
    codec = K.flight_codec(DoConst)
    rows, arrays = np.array([codec.pack(c) for c in consts]), codec.arrays(consts[0])
    logs, final = np.empty((n, 0, len(K.LOG_COLUMNS))), np.empty((n, 3))
    t0 = time.perf_counter()
    fly_prange(rows[:2], *arrays, 1, logs[:2], final[:2])
    print(f"prange loop compiled in {time.perf_counter() - t0:.1f} s")
    K.fly_batch(DoConst, rows[:2], *arrays, 1, logs[:2], final[:2])
    steps = int(args.seconds * 1000)
    print(f"{n} E3_wind vehicles x {args.seconds} s, {K.cores()} cores")
    print(f"{'loop':>8} {'wall s':>7} {'CPU s':>7} {'M steps/s':>10} {'M steps/CPU-s':>14}")
    for _ in range(args.pairs):
        for name, fn in (("prange", fly_prange), ("threads", K.fly_batch)):
            c0, w0 = time.process_time(), time.perf_counter()
            fn(*(() if fn is fly_prange else (DoConst,)), rows, *arrays, steps, logs, final)
            wall, cpu = time.perf_counter() - w0, time.process_time() - c0
            print(f"{name:>8} {wall:>7.2f} {cpu:>7.2f} {n * steps / wall / 1e6:>10.2f} {n * steps / cpu / 1e6:>14.2f}")


if __name__ == "__main__":
    main()
