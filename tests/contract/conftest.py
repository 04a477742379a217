"""One contract, two implementations: each assertion runs against the bundled vehicle's flavour and
against the real firmware (skipped, with the reason, where no build is found). Where the bundled
vehicle differs from the firmware, the bundled vehicle is what changes."""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.setpoints import ROLL_PITCH_RATES_IGNORED
from companion.vehicle_process import VehicleProcess
from helpers.processes import ROOT, child_env
from helpers.firmware import ArduCopterSitl, Px4Sih, find_arducopter, find_px4

SPEED = 4.0


@dataclass
class Target:
    name: str
    url: str
    """pymavlink connection string"""
    sysid: int = 1
    speed: float = SPEED

    def connect(self, source_system: int = 250) -> mavutil.mavfile:
        m = mavutil.mavlink_connection(self.url, source_system=source_system, source_component=190)
        m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                             mavlink.MAV_STATE_UNINIT)
        return m


@pytest.fixture(params=["bundled", "firmware"])
def px4(request) -> Iterator[Target]:
    if request.param == "bundled":
        v = VehicleProcess("--flavour", "px4", speedup=SPEED, env=child_env(), cwd=ROOT)
        yield Target("bundled px4", f"udpout:{v.url}")
        v.stop()
        return
    build, why = find_px4()
    if build is None:
        pytest.skip(why)
    with Px4Sih(build, speed=SPEED) as p:
        yield Target("PX4 v1.16 SIH", f"udpin:127.0.0.1:{p.api_port}", sysid=p.sysid)


@pytest.fixture(params=["bundled", "firmware"])
def copter(request) -> Iterator[Target]:
    if request.param == "bundled":
        # the tests stream at 50 Hz of wall time: a stalled test process stops the simulated clock
        # (up to 1 s of wall time) rather than leave the vehicle flying its last target
        v = VehicleProcess("--flavour", "ardupilot", "--wait-for-setpoints", "0.5", speedup=SPEED, env=child_env(),
                           cwd=ROOT)
        yield Target("bundled ardupilot", f"udpout:{v.url}")
        v.stop()
        return
    binary, why = find_arducopter()
    if binary is None:
        pytest.skip(why)
    with ArduCopterSitl(binary, speedup=SPEED) as a:
        yield Target("ArduCopter SITL", f"tcp:127.0.0.1:{a.tcp_port}")


def wait(m: mavutil.mavfile, kind: str, cond=lambda msg: True, timeout: float = 10.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        msg = m.recv_match(type=kind, blocking=True, timeout=0.2)
        if msg is not None and cond(msg):
            return msg
    raise AssertionError(f"no {kind} within {timeout} s")


def drain(m: mavutil.mavfile) -> dict:
    """Read everything waiting; the newest message of each kind (a client that streams setpoints
    reads nothing meanwhile, and the first message of a kind it reads after is an old one)."""
    newest: dict = {}
    while (msg := m.recv_match(blocking=False)) is not None:
        if msg.get_srcComponent() == 1:
            newest[msg.get_type()] = msg
    return newest


def latest(m: mavutil.mavfile, kind: str, timeout: float = 5.0):
    """The newest message of ``kind`` now (waits for one if none is waiting)."""
    found = drain(m).get(kind)
    return found if found is not None else wait(m, kind, timeout=timeout)


def stream_until(m: mavutil.mavfile, sysid: int, q, thrust: float, done, timeout: float,
                 type_mask: int = ROLL_PITCH_RATES_IGNORED) -> bool:
    """SET_ATTITUDE_TARGET at 50 Hz of wall time, every message read between two handed to ``done``,
    until it returns True (then True) or for ``timeout`` seconds (then False)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        m.mav.set_attitude_target_send(0, sysid, 1, type_mask, list(q), 0, 0, 0, thrust)
        stop = time.monotonic() + 0.02
        while (msg := m.recv_match(blocking=True, timeout=max(stop - time.monotonic(), 0.001))) is not None:
            if done(msg):
                return True
            if time.monotonic() >= stop:
                break
    return False


def stream(m: mavutil.mavfile, sysid: int, seconds: float, q, thrust: float,
           type_mask: int = ROLL_PITCH_RATES_IGNORED) -> None:
    """SET_ATTITUDE_TARGET at 50 Hz of wall time for ``seconds``, reading (and dropping) what arrives."""
    stream_until(m, sysid, q, thrust, lambda msg: False, seconds, type_mask)
