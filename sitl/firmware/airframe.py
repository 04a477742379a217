"""The firmware's airframe, configured to match the plant: parameter sets for PX4 and ArduCopter.

What depends on the scenario is derived here — the rotor geometry and motor order of the layout,
the hover thrust, the thrust curve of the motor interface (:func:`.motors.thrust_model_factor`),
the tracking system's delay; what does not is read from ``airframes/px4.toml`` and
``airframes/ardupilot.toml`` (``[common]`` and the table of the position source).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from companion.control.params import VehicleParams
from sitl.plant.scenario import Scenario

from .motors import FIRMWARE_TO_PLANT, thrust_model_factor

__all__ = ["px4_parameters", "ardupilot_parameters", "rotor_geometry", "AIRFRAMES"]

AIRFRAMES = Path(__file__).parent / "airframes"

PLUS_POSITIONS = ((1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (0.0, 1.0))
"""the plant's rotors 1-4 on the "+" (front, left, back, right), in arm lengths (FRD x, y)"""
SPINS_CCW = (False, True, False, True)
"""the plant's rotors 2 and 4 turn counter-clockwise seen from above"""


def rotor_geometry(vehicle: VehicleParams) -> list[tuple[float, float, bool]]:
    """``(x_m, y_m, ccw)`` of each firmware motor 1-4 (FRD), for the vehicle's layout."""
    c, s, arm = vehicle.layout_cos, vehicle.layout_sin, vehicle.arm_length_m
    out = []
    for rotor in FIRMWARE_TO_PLANT:
        x, y = PLUS_POSITIONS[rotor]
        out.append((arm * (c * x - s * y), arm * (s * x + c * y), SPINS_CCW[rotor]))
    return out


def _table(name: str, source: str) -> dict[str, float]:
    data = tomllib.loads((AIRFRAMES / f"{name}.toml").read_text())
    return {**data["common"], **data[source]}


def hover_thrust(vehicle: VehicleParams) -> float:
    """Collective thrust to hover, normalised by full thrust."""
    return vehicle.weight_n / vehicle.thrust_max_n


def px4_parameters(scenario: Scenario) -> dict[str, float]:
    v = scenario.vehicle
    params = _table("px4", scenario.nav_sensors.position_source)
    params |= {"CA_AIRFRAME": 0, "CA_ROTOR_COUNT": 4, "MPC_THR_HOVER": round(hover_thrust(v), 3),
               "THR_MDL_FAC": round(thrust_model_factor(v), 3)}
    km = v.k_torque_nm_s2 / v.k_thrust_n_s2
    for i, (x, y, ccw) in enumerate(rotor_geometry(v)):
        params |= {f"CA_ROTOR{i}_PX": round(x, 4), f"CA_ROTOR{i}_PY": round(y, 4),
                   f"CA_ROTOR{i}_KM": round(km if ccw else -km, 4)}
        params[f"PWM_MAIN_FUNC{i + 1}"] = 101 + i
    if scenario.nav_sensors.position_source == "mocap":
        params["EKF2_EV_DELAY"] = round(scenario.sensors.mocap_delay_s * 1e3, 1)
    return params


def ardupilot_parameters(scenario: Scenario) -> dict[str, float]:
    v = scenario.vehicle
    params = _table("ardupilot", scenario.nav_sensors.position_source)
    params |= {"FRAME_CLASS": 1, "FRAME_TYPE": 1 if v.layout == "x" else 0,
               "MOT_THST_HOVER": round(hover_thrust(v), 3), "MOT_THST_EXPO": round(thrust_model_factor(v), 3)}
    if scenario.nav_sensors.position_source == "mocap":
        params["VISO_DELAY_MS"] = round(scenario.sensors.mocap_delay_s * 1e3)
    return params
