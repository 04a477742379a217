"""Soak: a long flight of the companion against the simulated vehicle, sped up, with memory, CPU,
queues and loop rate sampled throughout.

    python benchmarks/bench_soak.py                 # 2 h of simulated time at 4x (about 30 min)
    python benchmarks/bench_soak.py --hours 0.1     # a quick look

The mission repeats a cycle for ``--hours``: the 4 m square at 2 m/s, then a 45 s hold, in 3 m/s
wind with turbulence. The vehicle and the companion run as separate processes over UDP, as in a
flight; the vehicle waits for a companion stalled by the host (``--wait-for-setpoints``, counted).
Sampled every 5 s of wall time from /proc (Linux): each process's resident memory and
CPU; every 10 s of vehicle time by the companion itself (its health.csv): receive-queue depth,
the longest wait of a datagram in that queue, the oldest telemetry a control tick used,
telemetry and setpoint rates, late ticks, the vehicle's achieved speed-up. Reported: memory at
the start and end and its trend over the second half [MiB per simulated hour], CPU, the largest
queue depth, the setpoint rate's mean, spread and trend [Hz per hour], tracking error per cycle
(first and last hour), and a figure. Results and the machine: docs/faults.md.
"""

from __future__ import annotations

import argparse
import math
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from companion.vehicle_process import VehicleProcess  # noqa: E402
from companion.flight.health import rss_mb  # noqa: E402

CYCLE_S = 75.0
"""one square (about 30 s with its corner holds) and a 45 s hold"""
TICK = os.sysconf("SC_CLK_TCK")


def soak_mission(hours: float) -> str:
    cycles = max(1, math.ceil(hours * 3600 / CYCLE_S) + 1)  # one more: a cycle is ~75 s, not exactly
    steps = ['[[steps]]\naction = "takeoff"\naltitude_m = 1.5\n', '[[steps]]\naction = "offboard"\n']
    for i in range(cycles):
        steps.append(f'[[steps]]\nname = "square {i}"\naction = "goto"\n'
                     'waypoints = [[4.0, 0.0, -1.5], [4.0, 4.0, -1.5], [0.0, 4.0, -1.5], [0.0, 0.0, -1.5]]\n'
                     'speed_m_s = 2.0\ntolerance_m = 0.3\nhold_s = 1.0\ntimeout_s = 40.0\n')
        steps.append(f'[[steps]]\nname = "hold {i}"\naction = "hold"\nduration_s = 45.0\n')
    steps.append('[[steps]]\naction = "land"\n')
    return (f'name = "soak"\ndescription = "{cycles} cycles of square + hold"\n\n[controller]\nposition = "ism_do"\n'
            'rate_hz = 100\n\n[trajectory]\nmax_speed_m_s = 2.0\nmax_accel_m_s2 = 4.0\nmax_jerk_m_s3 = 20.0\n'
            'bandwidth_rad_s = 2.0\n\n' + "\n".join(steps))


def cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def trend_per_hour(t_s: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope over the second half, per simulated hour."""
    half = t_s >= t_s[0] + 0.5 * (t_s[-1] - t_s[0])
    if half.sum() < 3:
        return float("nan")
    return float(np.polyfit(t_s[half] / 3600.0, y[half], 1)[0])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=2.0, help="simulated hours")
    ap.add_argument("--speedup", type=float, default=4.0)
    ap.add_argument("--figure", default=str(ROOT / "docs/figures/soak.png"))
    ap.add_argument("--json", help="also write the figures as JSON here")
    ap.add_argument("--wait-for-setpoints", type=float, default=0.05, metavar="SECONDS",
                    help="the vehicle waits for a companion this far behind (sitl --help; 0: never)")
    args = ap.parse_args()

    work = Path(tempfile.mkdtemp(prefix="soak-"))
    mission = work / "soak.toml"
    mission.write_text(soak_mission(args.hours))
    vehicle = VehicleProcess("--flavour", "paper", "--param", "SIM_WIND_N=3", "--param", "SIM_TURB_SIGMA=0.6",
                             "--wait-for-setpoints", str(args.wait_for_setpoints), speedup=args.speedup)
    comp = subprocess.Popen([sys.executable, "-m", "companion", "fly", str(mission), "--connect",
                             f"udp://{vehicle.url}", "--out", str(work), "--no-plots", "--quiet", "--output",
                             "attitude_rates"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    samples: list[tuple[float, float, float, float, float]] = []  # wall, rss companion, rss vehicle, cpu c, cpu v
    wall0 = time.monotonic()
    try:
        while comp.poll() is None:
            samples.append((time.monotonic() - wall0, rss_mb(comp.pid), rss_mb(vehicle.pid), cpu_s(comp.pid),
                            cpu_s(vehicle.pid)))
            time.sleep(5.0)
        out = comp.communicate()[0]
    finally:
        if comp.poll() is None:
            comp.kill()
        report = vehicle.stop(timeout_s=30)
    wall = time.monotonic() - wall0
    if comp.returncode != 0:
        print(out)
        print(json.dumps(report))
        return 1
    flight = next(p for p in work.iterdir() if p.is_dir())
    with open(flight / "health.csv") as f:
        rows = list(csv.DictReader(f))
    h = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    seg = json.loads((flight / "segments.json").read_text())
    squares = [(s["t_start"], s["rms_error_m"]) for s in seg["segments"] if s["name"].startswith("square")]

    s = np.array(samples)
    t_sim = np.interp(s[:, 0], h["wall_s"], h["t_s"])  # wall sample times on the vehicle clock
    cpu_c = np.diff(s[:, 3]) / np.diff(s[:, 0]) * 100
    cpu_v = np.diff(s[:, 4]) / np.diff(s[:, 0]) * 100
    flying = h["setpoints_per_s"] > 0
    rate = h["setpoints_per_s"][flying][1:-1]
    t_rate = h["t_s"][flying][1:-1]
    sq_t, sq_rms = np.array([q[0] for q in squares]), np.array([q[1] for q in squares])
    first, last = sq_rms[sq_t < sq_t[0] + 3600], sq_rms[sq_t >= sq_t[-1] - 3600]
    warm = int(np.argmax(t_sim >= min(300.0, 0.1 * t_sim[-1])))  # "at start": once both have warmed up
    res = {
        "simulated_h": float(h["t_s"][-1] / 3600), "wall_min": wall / 60,
        "speedup": float(np.median(h["vehicle_speedup"])),
        "rss_companion_mb": [float(s[warm, 1]), float(s[-1, 1])],
        "rss_vehicle_mb": [float(s[warm, 2]), float(s[-1, 2])],
        "rss_trend_companion_mb_per_h": trend_per_hour(t_sim, s[:, 1]),
        "rss_trend_vehicle_mb_per_h": trend_per_hour(t_sim, s[:, 2]),
        "cpu_companion_pct": float(np.median(cpu_c)), "cpu_vehicle_pct": float(np.median(cpu_v)),
        "rx_queue_max": int(h["rx_queue"].max()),
        "rx_lag_max_ms": float(h["rx_lag_max_ms"].max()),
        "telemetry_age_max_ms": float(h["telemetry_age_max_ms"].max()),
        "telemetry_age_p99_of_rows_ms": float(np.percentile(h["telemetry_age_max_ms"], 99)),
        "vehicle_skipped_ms": report["stats"].get("skipped_ms", 0),
        "setpoint_hz": [float(rate.mean()), float(rate.min()), float(rate.max())],
        "setpoint_trend_hz_per_h": trend_per_hour(t_rate, rate),
        "late_ticks": int(h["late_ticks"][-1]), "vehicle_overruns": report["stats"].get("overruns", 0),
        "vehicle_waits": report["stats"].get("setpoint_waits", 0), "vehicle_waited_ms": report["stats"].get(
            "waited_ms", 0), "vehicle_longest_wait_ms": report.get("longest_wait_ms", 0.0),
        "setpoint_age_ms": report.get("setpoint_age_ms", {}),
        "square_rms_m_first_hour": float(np.median(first)), "square_rms_m_last_hour": float(np.median(last)),
        "squares": len(squares),
    }
    print(f"soak: {res['simulated_h']:.2f} h simulated in {res['wall_min']:.1f} min ({res['speedup']:.2f}x)")
    print(f"{'':<34}{'companion':>12}{'vehicle':>12}")
    print(f"{'resident memory at start [MiB]':<34}{res['rss_companion_mb'][0]:>12.1f}{res['rss_vehicle_mb'][0]:>12.1f}")
    print(f"{'resident memory at end [MiB]':<34}{res['rss_companion_mb'][1]:>12.1f}{res['rss_vehicle_mb'][1]:>12.1f}")
    print(f"{'trend, 2nd half [MiB / sim h]':<34}{res['rss_trend_companion_mb_per_h']:>12.2f}"
          f"{res['rss_trend_vehicle_mb_per_h']:>12.2f}")
    print(f"{'CPU, median [% of a core]':<34}{res['cpu_companion_pct']:>12.0f}{res['cpu_vehicle_pct']:>12.0f}")
    print(f"receive queue depth, max: {res['rx_queue_max']} datagrams (of 2000); longest wait in it "
          f"{res['rx_lag_max_ms']:.1f} ms (wall)")
    print(f"oldest telemetry a tick used: {res['telemetry_age_max_ms']:.0f} ms of vehicle time (99th percentile of "
          f"10 s rows: {res['telemetry_age_p99_of_rows_ms']:.0f} ms); vehicle paused {res['vehicle_skipped_ms']} ms "
          f"after host stalls")
    print(f"setpoint rate per vehicle second: mean {rate.mean():.2f} Hz, min {rate.min():.1f}, max {rate.max():.1f}; "
          f"trend {res['setpoint_trend_hz_per_h']:+.3f} Hz/h; late ticks {res['late_ticks']}; "
          f"vehicle overruns {res['vehicle_overruns']}")
    print(f"the vehicle waited for the companion {res['vehicle_waits']} times, {res['vehicle_waited_ms'] / 1e3:.1f} s "
          f"of wall time in all, longest {res['vehicle_longest_wait_ms']:.0f} ms")
    age = res["setpoint_age_ms"]
    if age:
        print(f"loop latency (telemetry stamp to setpoint at the vehicle) [vehicle ms]: last {age['n']}: p50 "
              f"{age['p50']:.0f}, p99 {age['p99']:.0f}, max {age['max']:.0f}; largest in the flight "
              f"{age['max_since_start']:.0f}")
    print(f"square RMS error, median: first hour {1000 * res['square_rms_m_first_hour']:.1f} mm, "
          f"last hour {1000 * res['square_rms_m_last_hour']:.1f} mm ({len(squares)} squares)")
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=1))
    draw(args.figure, t_sim, s, cpu_c, cpu_v, h, sq_t, sq_rms)
    print(f"figure: {args.figure}")
    return 0


def draw(path: str, t_sim, s, cpu_c, cpu_v, h, sq_t, sq_rms) -> None:  # type: ignore[no-untyped-def]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 1, figsize=(9, 9), sharex=True)
    hours = t_sim / 3600
    ax[0].plot(hours, s[:, 1], label="companion")
    ax[0].plot(hours, s[:, 2], label="vehicle (sitl)")
    ax[0].set_ylabel("resident memory [MiB]")
    ax[0].set_ylim(0, 1.3 * max(s[:, 1].max(), s[:, 2].max()))
    ax[0].legend(loc="lower right")
    ax[1].plot(hours[1:], cpu_c, label="companion")
    ax[1].plot(hours[1:], cpu_v, label="vehicle")
    ax[1].set_ylabel("CPU [% of a core]")
    ax[1].legend(loc="lower right")
    ax[2].plot(h["t_s"] / 3600, h["setpoints_per_s"], label="setpoints [Hz of vehicle time]")
    ax[2].plot(h["t_s"] / 3600, h["rx_queue"], label="receive queue [datagrams]")
    ax[2].plot(h["t_s"] / 3600, h["telemetry_age_max_ms"], label="oldest telemetry used [vehicle ms]")
    ax[2].set_ylabel("rate / depth / age")
    ax[2].legend(loc="center right")
    ax[3].plot(sq_t / 3600, 1000 * sq_rms, ".")
    ax[3].set_ylabel("square RMS error [mm]")
    ax[3].set_xlabel("simulated time [h]")
    ax[0].set_title("Soak: companion + simulated vehicle, square + hold cycles in 3 m/s wind")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    raise SystemExit(main())
