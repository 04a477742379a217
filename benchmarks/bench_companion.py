"""The companion's setpoint stream: achieved rate and period jitter at 100 and 250 Hz, CPU use.

    python benchmarks/bench_companion.py

The simulated vehicle runs at real time (1x) in its own process; the companion flies
missions/hold.toml (20 s of offboard hold) in another. From the companion's flight summary: the
number of setpoints sent while engaged over the engaged (vehicle) time, and the distribution of
the wall-clock spacing between consecutive setpoints; from the OS: the companion process's CPU
time over its wall time. Results and the machine: docs/companion.md.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from companion.vehicle_process import VehicleProcess  # noqa: E402
from companion.plots import load_timeseries  # noqa: E402


def fly(rate_hz: float, backend: str) -> dict:
    vehicle = VehicleProcess("--flavour", "paper", speedup=1.0)
    out = Path(tempfile.mkdtemp())
    try:
        r = subprocess.run([sys.executable, "-m", "companion", "fly", str(ROOT / "missions/hold.toml"),
                            "--connect", f"udp://{vehicle.url}", "--rate", str(rate_hz), "--backend", backend,
                            "--output", "attitude_rates",
                            "--out", str(out), "--no-plots", "--quiet"], capture_output=True, text=True, timeout=180)
    finally:
        vehicle.stop()
    if r.returncode != 0:
        raise RuntimeError(r.stdout + r.stderr)
    flight = next(p for p in out.iterdir() if p.is_dir())
    meta = json.loads((flight / "segments.json").read_text())
    d = load_timeseries(flight)
    engaged = d["streaming"] > 0
    t = d["t"][engaged]
    hold = next(s for s in meta["segments"] if s["name"] == "hold")
    in_hold = (t >= hold["t_start"]) & (t < hold["t_end"])
    achieved = in_hold.sum() / (hold["t_end"] - hold["t_start"])
    timing = meta["setpoint_timing"]
    return {"rate": rate_hz, "backend": backend, "achieved_hz": achieved, "sent": meta["setpoints_sent"],
            "median_period_ms": timing.get("median_period_ms"), "p99_jitter_ms": timing.get("p99_abs_jitter_ms"),
            "cpu_companion_pct": 100 * meta["cpu_s"] / meta["wall_s"]}


def main() -> int:
    print(f"{'backend':>10} {'rate':>5} {'achieved [Hz]':>14} {'% of rate':>10} {'median period [ms]':>19} "
          f"{'p99 |jitter| [ms]':>18} {'companion CPU [% of a core]':>28}")
    for backend in ("pymavlink", "mavsdk"):
        for rate in (100.0, 250.0):
            r = fly(rate, backend)
            print(f"{backend:>10} {rate:>5.0f} {r['achieved_hz']:>14.1f} {100 * r['achieved_hz'] / rate:>10.1f} "
                  f"{r['median_period_ms']:>19.2f} {r['p99_jitter_ms']:>18.2f} {r['cpu_companion_pct']:>28.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
