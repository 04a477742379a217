"""The firmware's airframe is the plant's: each motor output drives the rotor whose position and
spin the firmware's mixer was told (PX4's CA_ROTOR*, ArduPilot's frame type), for both layouts.
A motor order or a sign that disagreed would flip the vehicle on its first take-off."""

from __future__ import annotations

import math

import pytest

from companion.control.allocation import wrench_from_rotor_speeds_sq
from companion.control.params import VehicleParams
from sitl.firmware.airframe import ardupilot_parameters, px4_parameters, rotor_geometry
from sitl.firmware.motors import FIRMWARE_TO_PLANT, rotor_commands, thrust_model_factor
from sitl.plant.scenario import Scenario


@pytest.mark.parametrize("layout", ["x", "plus"])
def test_each_motor_output_acts_where_the_firmware_believes_it_is(layout: str) -> None:
    v = VehicleParams(layout=layout)
    for motor, (x, y, ccw) in enumerate(rotor_geometry(v)):
        w_sq = [0.0, 0.0, 0.0, 0.0]
        w_sq[FIRMWARE_TO_PLANT[motor]] = 1e5
        (tx, ty, tz), thrust = wrench_from_rotor_speeds_sq(tuple(w_sq), v)  # type: ignore[arg-type]
        # thrust along -z_B at (x, y): moment (-y T, x T); a counter-clockwise rotor yaws the body clockwise (+z)
        assert tx == pytest.approx(-y * thrust, abs=1e-12)
        assert ty == pytest.approx(x * thrust, abs=1e-12)
        assert (tz > 0) == ccw


def test_px4_and_ardupilot_number_the_quad_x_as_their_documentation_draws_it() -> None:
    """1 front-right (ccw), 2 back-left (ccw), 3 front-left (cw), 4 back-right (cw)."""
    geometry = rotor_geometry(VehicleParams(layout="x"))
    quadrants = [(math.copysign(1, x), math.copysign(1, y), ccw) for x, y, ccw in geometry]
    assert quadrants == [(1, 1, True), (-1, -1, True), (1, -1, False), (-1, 1, False)]
    plus = rotor_geometry(VehicleParams(layout="plus"))  # 1 right, 2 left, 3 front, 4 back
    assert [(round(x, 6), round(y, 6)) for x, y, _ in plus] == [(0, 0.17), (0, -0.17), (0.17, 0), (-0.17, 0)]


def test_px4_is_told_the_plants_geometry_hover_thrust_and_thrust_curve() -> None:
    sc = Scenario(name="t", vehicle=VehicleParams(layout="x"))
    p = px4_parameters(sc)
    v = sc.vehicle
    assert p["CA_ROTOR_COUNT"] == 4
    for i, (x, y, ccw) in enumerate(rotor_geometry(v)):
        assert (p[f"CA_ROTOR{i}_PX"], p[f"CA_ROTOR{i}_PY"]) == (pytest.approx(x, abs=1e-4), pytest.approx(y, abs=1e-4))
        assert p[f"CA_ROTOR{i}_KM"] == pytest.approx((1 if ccw else -1) * v.k_torque_nm_s2 / v.k_thrust_n_s2, abs=1e-4)
    assert p["MPC_THR_HOVER"] == pytest.approx(v.weight_n / v.thrust_max_n, abs=1e-3)
    assert p["EKF2_EV_DELAY"] == pytest.approx(sc.sensors.mocap_delay_s * 1e3)
    a = ardupilot_parameters(sc)
    assert (a["FRAME_CLASS"], a["FRAME_TYPE"]) == (1, 1)
    assert ardupilot_parameters(Scenario(name="t"))["FRAME_TYPE"] == 0


def test_the_thrust_the_firmware_models_is_the_plants() -> None:
    """Both autopilots model thrust as f u^2 + (1 - f) u of full thrust (f: THR_MDL_FAC,
    MOT_THST_EXPO): the plant's rotors give exactly that above idle, quantised by the 8-bit grid
    (0.6 % of full thrust near hover)."""
    v = VehicleParams()
    f = thrust_model_factor(v)
    for u in (0.2, 0.4, 0.577, 0.8, 1.0):
        (w, *_), = [rotor_commands((u,) * 4, v, 256)]
        thrust = 4 * v.k_thrust_n_s2 * w * w / v.thrust_max_n
        assert thrust == pytest.approx(f * u * u + (1 - f) * u, abs=0.006), u


def test_stopped_disarmed_and_garbage_outputs_stop_the_motors() -> None:
    v = VehicleParams()
    assert rotor_commands((0.5, 0.5, 0.5, 0.5), v, 256, armed=False) == (0.0, 0.0, 0.0, 0.0)
    assert rotor_commands((0.01,) * 4, v, 256) == (pytest.approx(v.rotor_speed_min_rad_s),) * 4  # idle at least
    cmd = rotor_commands((0.0, -1.0, math.nan, 2.0), v, 256)
    # firmware motors 1-3 stopped (plant rotors 4, 2, 1), motor 4 (plant rotor 3) saturates at full speed
    assert cmd == (0.0, 0.0, pytest.approx(v.rotor_speed_max_rad_s), 0.0)
