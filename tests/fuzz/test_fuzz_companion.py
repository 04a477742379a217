"""Fuzzing the companion's MAVLink input path (``PymavlinkLink._parse``, what the reader task
runs on each datagram): telemetry, heartbeats, ACKs, parameters and texts with any values, from
the vehicle and from strangers, damaged or not.

After any sequence: nothing was raised or caught, the state the controller reads is a valid
sample (finite, a unit quaternion, within physical limits) or the initial one, the vehicle clock's
rate stays within its bounds, and every table is bounded."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.modes import px4_custom_mode
from companion.link.pymavlink_link import MAX_PARAMS, PymavlinkLink
from companion.link.state import MAX_POSITION_M, MAX_RATE_RAD_S, MAX_SPECIFIC_FORCE_M_S2, MAX_SPEED_M_S

from .strategies import FUZZ, datagram
from .watchdog import no_hang

CORPUS = Path(__file__).parent / "corpus" / "companion"

TELEMETRY = tuple(getattr(mavlink, f"MAVLink_{n}_message") for n in (
    "heartbeat", "attitude_quaternion", "local_position_ned", "highres_imu", "extended_sys_state", "sys_status",
    "statustext", "command_ack", "param_value", "attitude", "timesync", "ping"))


def locked_link() -> PymavlinkLink:
    """A link that has locked on to a PX4 vehicle (system 1) by its heartbeat."""
    link = PymavlinkLink("udp://127.0.0.1:14540")
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    link._parse(mav.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                                     mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_SAFETY_ARMED,
                                     px4_custom_mode("OFFBOARD"), mavlink.MAV_STATE_ACTIVE).pack(mav), 0.0,
                link.address)
    assert link.state.sysid == 1
    return link


def feed(link: PymavlinkLink, datagrams: list[bytes]) -> None:
    with no_hang(seconds=20):
        for i, data in enumerate(datagrams):
            link._parse(data, 0.001 * i, link.address)  # from the vehicle's address


def check(link: PymavlinkLink) -> None:
    st_ = link.state
    assert link.stats["handler_errors"] == 0, dict(link.stats)
    assert abs(math.sqrt(sum(c * c for c in st_.q)) - 1.0) < 1e-6, st_.q
    assert all(math.isfinite(c) and abs(c) <= MAX_POSITION_M for c in st_.pos_ned_m)
    assert all(math.isfinite(c) and abs(c) <= MAX_SPEED_M_S for c in st_.vel_ned_m_s)
    assert all(math.isfinite(c) and abs(c) <= MAX_RATE_RAD_S for c in st_.omega_rad_s)
    sf = st_.specific_force_body_m_s2
    assert sf is None or all(math.isfinite(c) and abs(c) <= MAX_SPECIFIC_FORCE_M_S2 for c in sf)
    assert 0.01 < link.clock.rate < 1000.0
    assert len(st_.statustexts) <= 100 and len(st_.params) <= MAX_PARAMS
    assert link._queue.qsize() == 0


@FUZZ
@given(st.lists(datagram(TELEMETRY, srcs=(1, 1, 1, 2)), min_size=1, max_size=30))
def test_no_telemetry_sequence_breaks_the_companions_state(datagrams: list[bytes]) -> None:
    link = locked_link()
    feed(link, datagrams)
    check(link)


@FUZZ
@given(st.lists(st.binary(min_size=1, max_size=16), min_size=1, max_size=50))
def test_invented_parameter_names_are_bounded(names: list[bytes]) -> None:
    link = locked_link()
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    for i, name in enumerate(names):
        link._parse(mav.param_value_encode(name, float(i), mavlink.MAV_PARAM_TYPE_REAL32, 65535, i).pack(mav), 0.0,
                    link.address)
    check(link)


@pytest.mark.parametrize("path", sorted(CORPUS.glob("*.bin")), ids=lambda p: p.stem)
def test_regression_corpus(path: Path) -> None:
    """Inputs that once broke something (or nearly did): one datagram per line of hex."""
    link = locked_link()
    feed(link, [bytes.fromhex(line) for line in path.read_text().split() if line])
    check(link)
