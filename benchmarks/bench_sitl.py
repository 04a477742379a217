"""Simulated vehicle on the wire: sustained speed-up with telemetry, setpoint-to-telemetry
round trip, and loop lateness at real time.

    python benchmarks/bench_sitl.py

1. Speed-up: the vehicle runs in its own process at a requested speed-up while a pymavlink
   client receives every telemetry stream at its default rate; the achieved speed-up is simulated
   time (from the messages' own timestamps) over wall time, for 5 s of wall time.
2. Round trip at 1x: armed on the ground in OFFBOARD, ATTITUDE_TARGET streamed at 1 kHz; the
   client alternates the thrust of SET_ATTITUDE_TARGET and times, on its own wall clock, the first
   ATTITUDE_TARGET that carries the new value (UDP out, parse, apply at the next 1 ms step,
   encode, UDP back).
3. Loop lateness at 1x: how late the vehicle's loop starts each due step (from its exit report).
Results and the machine: docs/sitl.md.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from companion.mavlink.modes import PX4_MODES  # noqa: E402
from tests.helpers.processes import Client, SitlProcess  # noqa: E402


def achieved_speedup(requested: float, wall_s: float = 5.0) -> tuple[float, dict]:
    s = SitlProcess(speedup=requested)
    c = Client(s.url)
    c.wait("HEARTBEAT")
    first = c.wait("ATTITUDE_QUATERNION")
    w0 = time.monotonic()
    last, n = first, 0
    while time.monotonic() - w0 < wall_s:
        m = c.recv(0.05)
        if m is not None:
            n += 1
            if m.get_type() == "ATTITUDE_QUATERNION":
                last = m
    wall = time.monotonic() - w0
    c.close()
    report = s.stop()
    return (last.time_boot_ms - first.time_boot_ms) / 1000.0 / wall, {"msgs_per_wall_s": n / wall, **report}


def round_trip(samples: int = 200) -> list[float]:
    s = SitlProcess("--param", "COM_DISARM_PRFLT=120", speedup=1.0)
    c = Client(s.url)
    c.wait("SYS_STATUS", lambda m: m.onboard_control_sensors_health & mavlink.MAV_SYS_STATUS_PREARM_CHECK)
    every_ms = 1000
    assert c.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_ATTITUDE_TARGET, every_ms) == 0
    assert c.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
    q = (1.0, 0.0, 0.0, 0.0)
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        c.attitude_target(q, thrust=0.10)
        c.recv(0.01)
    c.m.mav.command_long_send(1, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                              *PX4_MODES["OFFBOARD"], 0, 0, 0, 0)
    for _ in range(50):
        c.attitude_target(q, thrust=0.10)
        c.recv(0.01)
    out = []
    for i in range(samples):
        thrust = 0.12 if i % 2 == 0 else 0.10
        t0 = time.monotonic()
        c.attitude_target(q, thrust=thrust)
        while True:
            m = c.recv(0.5)
            if m is None:
                break
            if m.get_type() == "ATTITUDE_TARGET" and abs(m.thrust - thrust) < 1e-4:
                out.append(time.monotonic() - t0)
                break
        time.sleep(0.005)
    c.close()
    s.stop()
    return out


def main() -> int:
    print("1. sustained speed-up, all telemetry streams at their default rates, one client")
    print(f"{'requested':>10} {'achieved':>9} {'msgs/s received':>16} {'overruns':>9}")
    for req in (1, 5, 10, 15, 20, 30):
        got, rep = achieved_speedup(req)
        print(f"{req:>10} {got:>9.1f} {rep['msgs_per_wall_s']:>16.0f} {rep['stats'].get('overruns', 0):>9}")
    print("\n2. setpoint -> first telemetry reflecting it, 1x, loopback")
    rt = [x * 1000 for x in round_trip()]
    q = statistics.quantiles(rt, n=100)
    print(f"   n={len(rt)}  median {statistics.median(rt):.2f} ms  p90 {q[89]:.2f} ms  p99 {q[98]:.2f} ms  "
          f"max {max(rt):.2f} ms")
    print("\n3. loop lateness at 1x over 20 s (how late each due 1 kHz step started)")
    s = SitlProcess("--duration", "20", speedup=1.0)
    c = Client(s.url)
    end = time.monotonic() + 21
    while time.monotonic() < end and s.alive():
        c.recv(0.1)
    rep = s.stop()
    print(f"   {rep['loop_lateness_ms']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
