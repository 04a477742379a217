"""Autopilot rules without sockets: the firmware logic the MAVLink server exposes."""

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.setpoints import ATTITUDE_IGNORED
from companion.mavlink.modes import px4_custom_mode
from companion.control import quaternion as quat
from sitl.autopilot import world
from sitl.autopilot.logic import Autopilot, AutopilotParams, LandedState, MavResult, Mode
from sitl.plant.scenario import Scenario
from sitl.plant.vehicle import SimVehicle

NAN = math.nan


def make(**params):
    v = SimVehicle(Scenario(name="unit"), "ism_do", 1, (0.0, 0.0, 0.0), 0.0, hovering=False)
    ap = Autopilot(v, AutopilotParams(**params))
    run(ap, 1.2)
    return ap


def run(ap, seconds):
    for _ in range(int(round(seconds / ap.dt))):
        world.step(ap)


def airborne(ap):
    assert ap.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,)).result == MavResult.ACCEPTED
    assert ap.command(mavlink.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, NAN, NAN, NAN)).result == MavResult.ACCEPTED
    run(ap, 4.0)
    assert ap.mode == Mode.HOLD and not ap.landed


def stream(ap, seconds, q=None, thrust=None, sender=255, type_mask=0, rates=(0.0, 0.0, 0.0)):
    q = q or quat.from_yaw(0.0)
    thrust = thrust if thrust is not None else 0.63 * 9.81 / ap.vehicle.scenario.vehicle.thrust_max_n
    for _ in range(int(seconds / 0.02)):
        assert ap.attitude_target(sender, type_mask, q, rates, thrust) is None
        run(ap, 0.02)


@pytest.mark.parametrize("flavour, result, mode", [("px4", MavResult.ACCEPTED, Mode.OFFBOARD),
                                                    ("ardupilot", MavResult.DENIED, Mode.MANUAL)])
def test_px4_takes_offboard_while_disarmed_as_the_mode_to_arm_into(flavour, result, mode):
    """PX4 v1.16 accepts OFFBOARD on the ground, disarmed and without a stream (the mode the user
    chose); arming then needs the stream. ArduCopter has no OFFBOARD."""
    ap = make(flavour=flavour)
    assert ap.set_mode(Mode.OFFBOARD).result == result and ap.mode == mode
    if flavour == "px4":
        assert ap.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,)).result != MavResult.ACCEPTED
        stream(ap, 0.5)
        assert ap.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,)).result == MavResult.ACCEPTED


def test_takeoff_reaches_the_takeoff_altitude_and_holds_it():
    ap = make()
    airborne(ap)
    run(ap, 3.0)
    assert ap.vehicle.state.pos_ned_m[2] == pytest.approx(-2.5, abs=0.05)
    assert ap.landed_state == LandedState.IN_AIR


def test_only_the_system_that_took_offboard_control_may_steer():
    ap = make()
    airborne(ap)
    stream(ap, 1.0, sender=200)
    assert ap.set_mode(Mode.OFFBOARD, sender=200).result == MavResult.ACCEPTED
    before = ap.offboard_attitude
    reason = ap.attitude_target(77, 0, quat.from_euler(0.5, 0.0, 0.0), (0.0, 0.0, 0.0), 0.9)
    assert reason == "setpoint from a system without offboard control"
    assert ap.offboard_attitude == before
    assert ap.set_mode(Mode.OFFBOARD, sender=77).result == MavResult.DENIED



def test_another_systems_stream_neither_enables_offboard_nor_becomes_the_owners_setpoint():
    """Before offboard anyone may stream; a 60 deg, full-thrust setpoint from system 77 arriving last
    must not be what the vehicle flies when system 200 takes control."""
    ap = make()
    airborne(ap)
    stream(ap, 1.0, sender=77)
    assert ap.set_mode(Mode.OFFBOARD, sender=200).result == MavResult.TEMPORARILY_REJECTED  # 200 has not streamed
    stream(ap, 1.0, sender=200)
    rogue = quat.from_euler(math.radians(60), 0.0, 0.0)
    assert ap.attitude_target(77, 0, rogue, (0.0, 0.0, 0.0), 1.0) is None  # the newest, before offboard
    assert ap.set_mode(Mode.OFFBOARD, sender=200).result == MavResult.ACCEPTED
    assert quat.angle_between(ap.offboard_attitude.q_d, rogue) > math.radians(55)
    run(ap, 0.02)  # 20 ms with no setpoint from 200: level, at hover thrust
    roll = quat.to_euler(ap.vehicle.state.q)[0]
    assert abs(roll) < math.radians(2) and ap.vehicle.state.vel_ned_m_s[2] == pytest.approx(0.0, abs=0.05)

def test_rates_only_setpoint_turns_the_vehicle_at_the_commanded_rate():
    """type_mask bit 7: the attitude is ignored, body rates are flown, as an attitude reference
    integrated from them. A 1 rad/s yaw rate for 1 s turns the reference by exactly 1 rad; the
    12 rad/s loop has caught up with it within ~0.1 s, so the vehicle has turned 1 +- 0.05 rad."""
    ap = make()
    airborne(ap)
    stream(ap, 1.0)
    assert ap.set_mode(Mode.OFFBOARD).result == MavResult.ACCEPTED
    yaw0 = quat.to_euler(ap.vehicle.state.q)[2]
    stream(ap, 1.0, type_mask=ATTITUDE_IGNORED, rates=(0.0, 0.0, 1.0))
    turned = quat.to_euler(ap.vehicle.state.q)[2] - yaw0
    assert abs(turned - 1.0) < 0.05


def test_px4_flavour_flies_only_the_yaw_rate_beside_an_attitude_and_the_paper_flavour_all_rates():
    ap = make()
    ap.attitude_target(255, 0, quat.IDENTITY, (0.5, 0.5, 0.2), 0.3)
    assert ap.offboard_attitude.omega_d_rad_s == (0.0, 0.0, 0.2)
    assert ap.rejected["attitude and body rates together"] == 1  # what PX4 publishes as a second setpoint
    ap.attitude_target(255, 3, quat.IDENTITY, (0.5, 0.5, 0.2), 0.3)  # roll, pitch ignored: deliberate
    assert ap.rejected["attitude and body rates together"] == 1
    ap2 = make(paper_inner_loop=True)
    ap2.attitude_target(255, 0, quat.IDENTITY, (0.5, 0.5, 0.2), 0.3)
    assert ap2.offboard_attitude.omega_d_rad_s == (0.5, 0.5, 0.2)


def test_return_to_launch_flies_home_and_lands():
    ap = make()
    airborne(ap)
    ap.target = (3.0, -2.0, -2.5)  # move away in hold
    run(ap, 6.0)
    assert math.hypot(*ap.vehicle.state.pos_ned_m[:2]) > 3.0
    assert ap.set_mode(Mode.RTL).result == MavResult.ACCEPTED
    run(ap, 20.0)
    assert not ap.armed
    assert math.hypot(*ap.vehicle.state.pos_ned_m[:2]) < 0.1


# --- ArduPilot flavour -----------------------------------------------------------------------


AS_THE_COMPANION_SETS_IT = {"rate_ff_enabled": False, "angle_boost": False}
"""ATC_RATE_FF_ENAB 0 and ATC_ANGLE_BOOST 0: what companion.flight.prepare sets before it flies"""


def guided_airborne(**params):
    ap = make(flavour="ardupilot", position_after_s=0.0, **params)
    assert ap.command(mavlink.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, 0, 0, 1.5)).result == MavResult.DENIED  # not armed
    ap.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,))
    assert ap.command(mavlink.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, 0, 0, 1.5)).result == MavResult.DENIED  # not GUIDED
    assert ap.set_mode(Mode.GUIDED).result == MavResult.ACCEPTED
    assert ap.command(mavlink.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, 0, 0,
                                                    1.5)).result == MavResult.ACCEPTED  # relative height
    run(ap, 4.0)
    assert ap.mode == Mode.GUIDED and ap.vehicle.state.pos_ned_m[2] == pytest.approx(-1.5, abs=0.05)
    return ap


def test_ardupilot_modes_are_copter_numbers():
    from sitl.autopilot.logic import custom_mode, mode_from_command

    assert custom_mode(Mode.GUIDED, "ardupilot") == 4 and custom_mode(Mode.LAND, "ardupilot") == 9
    assert custom_mode(Mode.TAKEOFF, "ardupilot") == 4  # take-off runs inside GUIDED
    assert mode_from_command("ardupilot", 20, 0) == Mode.GUIDED  # GUIDED_NOGPS
    assert mode_from_command("ardupilot", 6, 0) == Mode.RTL
    assert custom_mode(Mode.OFFBOARD, "px4") == px4_custom_mode("OFFBOARD")
    assert make(flavour="ardupilot").set_mode(Mode.OFFBOARD).result == MavResult.DENIED


def test_ardupilot_thrust_is_a_climb_rate_unless_guid_options_makes_it_throttle():
    """0.5 holds altitude whatever the mass; with GUID_OPTIONS bit 3 the same 0.5 is throttle,
    9.3 N against 6.18 N of weight, so the vehicle climbs."""
    for throttle, climbs in ((False, False), (True, True)):
        ap = guided_airborne(guided_thrust_is_throttle=throttle, **AS_THE_COMPANION_SETS_IT)
        z0 = ap.vehicle.state.pos_ned_m[2]
        stream(ap, 2.0, thrust=0.5)
        dz = ap.vehicle.state.pos_ned_m[2] - z0
        assert (dz < -1.0) if climbs else abs(dz) < 0.15, (throttle, dz)


def test_ardupilot_flies_targets_past_angle_max_and_levels_after_guid_timeout():
    """ArduCopter (seen on its SITL): GUIDED does not limit an attitude target to ANGLE_MAX; once the
    targets stop it flies the last one for GUID_TIMEOUT, then levels out at zero climb rate without
    holding position (it drifts on)."""
    ap = guided_airborne(guided_thrust_is_throttle=True, angle_max_deg=30.0, guided_timeout_s=1.0,
                         **AS_THE_COMPANION_SETS_IT)
    hover = 0.63 * 9.81 / ap.vehicle.scenario.vehicle.thrust_max_n
    stream(ap, 0.6, q=quat.from_euler(math.radians(40.0), 0.0, 0.0), thrust=hover / math.cos(math.radians(40)))
    assert math.degrees(quat.tilt_angle(ap.setpoint.q_d)) == pytest.approx(40.0, abs=0.1)
    run(ap, 1.2)  # targets stop: after GUID_TIMEOUT it levels, still in GUIDED
    levelled = ap.vehicle.state.pos_ned_m
    run(ap, 3.0)
    assert ap.mode == Mode.GUIDED and ap.armed
    assert math.degrees(quat.tilt_angle(ap.vehicle.state.q)) < 3.0
    drift = math.dist(levelled[:2], ap.vehicle.state.pos_ned_m[:2])
    assert drift > 1.0 and math.hypot(*ap.vehicle.state.vel_ned_m_s[:2]) > 0.2  # not holding position
    assert abs(ap.vehicle.state.vel_ned_m_s[2]) < 0.2  # climb rate zero


def test_ardupilot_keeps_turning_the_last_target_by_its_rates_until_guid_timeout():
    ap = guided_airborne(guided_thrust_is_throttle=True, guided_timeout_s=1.0, **AS_THE_COMPANION_SETS_IT)
    hover = 0.63 * 9.81 / ap.vehicle.scenario.vehicle.thrust_max_n
    stream(ap, 0.2, q=quat.IDENTITY, thrust=hover, rates=(0.0, 0.3, 0.0))  # 0.3 rad/s of pitch sent along
    run(ap, 0.8)  # silent, still within GUID_TIMEOUT: the target went on pitching
    assert math.degrees(quat.tilt_angle(ap.setpoint.q_d)) > 10.0


def test_ardupilot_shapes_attitude_targets_unless_rate_ff_is_off():
    """ATC_RATE_FF_ENAB 1 (ArduPilot's default): a 20 deg step in the target is approached as a
    critically damped second order of time constant ATC_INPUT_TC, 0.15 s: after 0.16 s the attitude
    flown is near 20 (1 - (1 + x) e^-x) deg, x = 0.16 / 0.15 (5.8 deg), after 1 s at the target.
    ATC_RATE_FF_ENAB 0: the target is flown as sent."""
    step = quat.from_euler(math.radians(20.0), 0.0, 0.0)
    for shaped in (True, False):
        ap = guided_airborne(guided_thrust_is_throttle=True, rate_ff_enabled=shaped, angle_boost=False)
        hover = 0.63 * 9.81 / ap.vehicle.scenario.vehicle.thrust_max_n
        stream(ap, 0.16, q=step, thrust=hover)  # 8 targets, 20 ms apart
        tilt = math.degrees(quat.tilt_angle(ap.setpoint.q_d))
        if shaped:
            x = 0.16 / 0.15
            assert tilt == pytest.approx(20.0 * (1.0 - (1.0 + x) * math.exp(-x)), abs=1.0)
            stream(ap, 0.84, q=step, thrust=hover)
            assert math.degrees(quat.tilt_angle(ap.setpoint.q_d)) == pytest.approx(20.0, abs=0.5)
        else:
            assert tilt == pytest.approx(20.0, abs=0.01)


def test_ardupilot_boosts_throttle_by_the_tilt_unless_angle_boost_is_off():
    """ATC_ANGLE_BOOST 1: a throttle of u at a 30 deg lean becomes u / cos 30 deg (15 % more);
    with 0 it is flown as sent."""
    tilt = quat.from_euler(math.radians(30.0), 0.0, 0.0)
    for boost in (True, False):
        ap = guided_airborne(guided_thrust_is_throttle=True, rate_ff_enabled=False, angle_boost=boost)
        m = ap.vehicle.scenario.vehicle
        u = 0.63 * 9.81 / math.cos(math.radians(30.0)) / m.thrust_max_n
        stream(ap, 0.5, q=tilt, thrust=u)
        lean = float(quat.tilt_angle(ap.vehicle.estimator.q))
        expected = u * m.thrust_max_n / (math.cos(lean) if boost else 1.0)
        assert ap.setpoint.thrust_n == pytest.approx(expected, rel=1e-3)  # the tilt of one step earlier
        assert (ap.setpoint.thrust_n / (u * m.thrust_max_n) > 1.1) is boost


def test_ardupilot_reports_a_stale_hover_throttle_that_it_learns_in_flight():
    """MOT_THST_HOVER: 5 % below the true hover throttle at boot (ArduCopter SITL reports its saved
    0.35 and learns about 0.367), e^-1 of that error left after 10 s airborne; PX4's MPC_THR_HOVER is the model's."""
    from sitl.autopilot.logic import HOVER_STALE

    ap = guided_airborne(guided_thrust_is_throttle=True, **AS_THE_COMPANION_SETS_IT)
    m = ap.vehicle.scenario.vehicle
    true = m.weight_n / m.thrust_max_n
    flown = ap.airborne_s
    assert 0.5 < flown < 4.0
    expected = true * (1 + (HOVER_STALE - 1) * math.exp(-flown / 10.0))
    assert ap.reported_hover_throttle() == pytest.approx(expected, rel=1e-9)
    assert make(flavour="ardupilot").reported_hover_throttle() == pytest.approx(0.95 * true, rel=1e-9)
    run(ap, 10.0)
    assert ap.reported_hover_throttle() / true - 1 == pytest.approx(-0.05 * math.exp(-(flown + 10.0) / 10.0), rel=1e-3)
    assert make(flavour="px4").reported_hover_throttle() == true


def test_boot_time_offsets_every_stamp_and_the_stamps_a_companion_sends_back_unwrap_across_the_wrap():
    """``sitl --boot-time``: 10 ms before time_boot_ms wraps, then 20 ms later. The stamps sent carry
    the offset (time_boot_ms wrapped, time_usec not); a setpoint stamped before the wrap and read
    after it is 20 ms old, not 49.7 days in the future."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    from companion.mavlink.boot_time import BOOT_MS_MODULUS
    from sitl.autopilot.telemetry import GeoOrigin, Telemetry

    ap = make()
    offset_ms = BOOT_MS_MODULUS - 10 - round(ap.t * 1000)
    tel = Telemetry(ap, mavlink.MAVLink(None), GeoOrigin(), mavlink.MAV_AUTOPILOT_PX4, offset_ms)
    before, t_before = tel.time_boot_ms, ap.t
    assert before == BOOT_MS_MODULUS - 10 and tel.time_usec == (BOOT_MS_MODULUS - 10) * 1000
    run(ap, 0.02)
    assert tel.time_boot_ms == 10 and tel.time_usec == (BOOT_MS_MODULUS + 10) * 1000
    assert math.isclose(ap.t - tel.sim_time_of(before), 0.02, abs_tol=1e-9)
    assert math.isclose(tel.sim_time_of(before), t_before, abs_tol=1e-9)
    assert math.isclose(tel.sim_time_of(tel.time_boot_ms), ap.t, abs_tol=1e-9)
