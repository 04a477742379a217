"""The output policy sits before the guard: the guard judges the setpoint as it goes on the wire,
and the wire carries the stamp of the telemetry the setpoint was computed from."""

import asyncio
import math
import socket

import pytest
from pymavlink import mavutil

from companion.control.params import PositionGains, ReferenceParams, TrajectoryParams, VehicleParams
from companion.flight.guard import SetpointGuard
from companion.flight.offboard import OffboardController
from companion.flight.output import Output
from companion.flight.thrust_scale import ThrustScaleEstimator
from companion.link.pymavlink_link import PymavlinkLink
from companion.link.state import VehicleState

PERIOD = 0.01
DEFAULT_GUARD = SetpointGuard()


def controller(output: Output, guard: SetpointGuard = DEFAULT_GUARD) -> OffboardController:
    return OffboardController("ism_do", VehicleParams(), PositionGains(), ReferenceParams(), TrajectoryParams(),
                              ThrustScaleEstimator(18.5, adapt=False), guard, output=output, period_s=PERIOD)


def tilted_state(t: float) -> VehicleState:
    """A vehicle 0.3 rad off level and 1 m from its target: the law asks for large roll and pitch rates."""
    st = VehicleState()
    st.set_position((1.0, -1.0, -2.0), (0.5, 0.0, 0.0), t, 0.0)
    s = math.sin(0.15)
    st.set_attitude((math.cos(0.15), s, 0.0, 0.0), (0.0, 0.0, 0.0), t, 0.0)
    return st


def first_tick(output: Output, guard: SetpointGuard = DEFAULT_GUARD):
    c = controller(output, guard)
    st = tilted_state(10.0)
    c.start(st)
    c.set_target((0.0, 0.0, -2.0))
    tick = None
    for k in range(1, 30):
        st.t_pos = st.t_att = 10.0 + PERIOD * k
        tick, _ = c.update(st, st.t_pos)
    return tick


@pytest.mark.parametrize("autopilot, zeroed", [("px4", (0, 1)), ("ardupilot", (0, 1, 2))])
def test_in_attitude_mode_the_ignored_rates_go_out_as_zero_and_the_guard_sees_that(autopilot, zeroed):
    tick = first_tick(Output("attitude", autopilot))
    law = tick.attitude.omega_d_rad_s
    assert max(abs(law[0]), abs(law[1])) > 0.05  # the law did ask for roll/pitch rates
    for i in range(3):
        assert tick.setpoint.body_rates_rad_s[i] == (0.0 if i in zeroed else pytest.approx(float(law[i])))
    assert tick.rejected is None


def test_rates_over_the_guard_are_clipped_before_it_judges_them():
    """A guard at 1 deg/s: the wire rates are clipped to it in norm (direction kept), so the setpoint
    the guard judges is the one sent, and passes."""
    guard = SetpointGuard(max_rate_rad_s=math.radians(1.0))
    tick = first_tick(Output("attitude_rates", "px4"), guard)
    sent = tick.setpoint.body_rates_rad_s
    law = tuple(float(w) for w in tick.attitude.omega_d_rad_s)
    assert math.hypot(*sent) == pytest.approx(guard.max_rate_rad_s, rel=1e-9)
    assert math.hypot(*law) > 2 * guard.max_rate_rad_s
    k = math.hypot(*sent) / math.hypot(*law)
    assert sent == pytest.approx(tuple(k * w for w in law), rel=1e-9)
    assert tick.rejected is None


@pytest.mark.parametrize("kind", ["attitude", "position"])
def test_a_setpoint_carries_the_stamp_it_was_computed_from_not_the_newest(kind):
    """The link knows telemetry up to 12.345 s, the setpoint was computed from 12.3 s: time_boot_ms
    says 12300 (a lockstep vehicle runs one period past it), on a real UDP socket."""
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(5.0)

    async def main():
        link = PymavlinkLink(f"udp://127.0.0.1:{rx.getsockname()[1]}")
        await link.open()
        try:
            link.state.sysid, link.state.compid = 1, 1  # as after the autopilot's heartbeat
            link.state.set_attitude((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 12.345, 0.0)  # newest telemetry
            if kind == "attitude":
                link.send_attitude_target((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.5, 0, stamp_s=12.3)
            else:
                link.send_position_target((0.0, 0.0, -1.0), (0.0,) * 3, (0.0,) * 3, 0.0, stamp_s=12.3)
            for _ in range(5):  # heartbeats may come first
                for m in mav.parse_buffer(rx.recv(512)) or []:
                    if m.get_type() == wanted:
                        return m
            raise AssertionError(f"no {wanted}")
        finally:
            await link.close()

    mav = mavutil.mavlink.MAVLink(None)
    wanted = "SET_ATTITUDE_TARGET" if kind == "attitude" else "SET_POSITION_TARGET_LOCAL_NED"
    assert asyncio.run(main()).time_boot_ms == 12300
