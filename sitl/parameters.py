"""The simulated vehicle's parameters: controller gains, firmware behaviour, simulation settings.

Served over the MAVLink parameter protocol (all REAL32), so QGroundControl, MAVProxy or a
script can read them and change them in flight: wind, turbulence, an external force or torque,
a mass error or a weak motor take effect at the next plant step. Names follow PX4 where PX4
has the parameter (COM_OF_LOSS_T, MIS_TAKEOFF_ALT, ...); SIM_* are the simulation's own.
A value outside its range, or a write to a read-only parameter, is refused (the old value is
echoed, as PX4 does) with a reason.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable

from .autopilot import Autopilot, Severity
from .wind import TurbulenceParams, WindParams

__all__ = ["Param", "ParamTable", "build_parameters"]

ATTITUDE_KINDS = ("pd", "pd_do", "ism_do")


@dataclass
class Param:
    name: str
    value: float
    minimum: float
    maximum: float
    description: str
    apply: Callable[[float], None] | None = None
    """None: read-only"""


class ParamTable:
    """Ordered parameters (the index is the PARAM_VALUE index)."""

    def __init__(self, params: list[Param]) -> None:
        self._params = params
        self._by_name = {p.name: i for i, p in enumerate(params)}
        for p in params:
            if len(p.name) > 16:
                raise ValueError(f"parameter name {p.name!r} is longer than MAVLink's 16 characters")

    def __len__(self) -> int:
        return len(self._params)

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(self._params)

    def index(self, name: str) -> int | None:
        return self._by_name.get(name)

    def at(self, index: int) -> Param | None:
        return self._params[index] if 0 <= index < len(self._params) else None

    def get(self, name: str) -> Param | None:
        i = self._by_name.get(name)
        return None if i is None else self._params[i]

    def set(self, name: str, value: float) -> str | None:
        """Apply a new value; returns why it was refused, or None."""
        p = self.get(name)
        if p is None:
            return f"unknown parameter {name!r}"
        if p.apply is None:
            return f"{name} is read-only"
        if not math.isfinite(value):
            return f"{name}: value is not finite"
        if not p.minimum <= value <= p.maximum:
            return f"{name}: {value:g} outside [{p.minimum:g}, {p.maximum:g}]"
        try:
            p.apply(value)
        except ValueError as exc:
            return f"{name}: {exc}"
        p.value = value
        return None


def build_parameters(ap: Autopilot) -> ParamTable:
    """The parameter table bound to one autopilot and its vehicle."""
    v = ap.vehicle
    sc = v.scenario

    def ap_param(field: str) -> Callable[[float], None]:
        def apply(x: float) -> None:
            ap.params = dataclasses.replace(ap.params, **{field: x})
        return apply

    def att_gain(field: str, vector: bool) -> Callable[[float], None]:
        def apply(x: float) -> None:
            gains = dataclasses.replace(v.scenario.attitude, **{field: (x, x, x) if vector else x})
            v.set_attitude_gains(dataclasses.replace(v.scenario, attitude=gains))
        return apply

    def att_kind(x: float) -> None:
        if x != int(x):
            raise ValueError("ATT_CTRL must be 0, 1 or 2")
        v.set_attitude_controller(ATTITUDE_KINDS[int(x)])

    def pos_gain(field: str, axes: tuple[int, ...]) -> Callable[[float], None]:
        def apply(x: float) -> None:
            g = ap.position_loop.controller.gains
            old = list(getattr(g, field))
            for i in axes:
                old[i] = x
            gains = dataclasses.replace(g, **{field: tuple(old)})
            from companion.control.outer_loop import PositionLoop

            ap.position_loop = PositionLoop.create(ap.params.hold_controller, sc.vehicle, gains, sc.reference)
        return apply

    wind = {"mean": list(sc.wind.mean_ned_m_s), "sigma": max(sc.wind.turbulence.sigma_m_s),
            "alt": sc.wind.turbulence.altitude_m}

    def set_wind() -> None:
        s = wind["sigma"]
        turb = TurbulenceParams(enabled=s > 0.0, altitude_m=wind["alt"], sigma_m_s=(s, s, 2.0 * s / 3.0))  # type: ignore[arg-type]
        v.set_wind(WindParams(tuple(wind["mean"]), turb))  # type: ignore[arg-type]

    def wind_axis(i: int) -> Callable[[float], None]:
        def apply(x: float) -> None:
            wind["mean"][i] = x  # type: ignore[index]
            set_wind()
        return apply

    def wind_value(key: str) -> Callable[[float], None]:
        def apply(x: float) -> None:
            wind[key] = x
            set_wind()
        return apply

    def force_axis(i: int) -> Callable[[float], None]:
        def apply(x: float) -> None:
            f = list(v.extra_force_ned_n)
            f[i] = x
            v.extra_force_ned_n = tuple(f)  # type: ignore[assignment]
        return apply

    def torque_axis(i: int) -> Callable[[float], None]:
        def apply(x: float) -> None:
            t = list(v.extra_torque_nm)
            t[i] = x
            v.extra_torque_nm = tuple(t)  # type: ignore[assignment]
        return apply

    factors = {"mass": sc.model_error.mass_factor, "inertia": sc.model_error.inertia_factor}

    def model_factor(key: str) -> Callable[[float], None]:
        def apply(x: float) -> None:
            factors[key] = x
            v.set_plant_vehicle(sc.vehicle.scaled(factors["mass"], factors["inertia"]))
        return apply

    def motor(i: int) -> Callable[[float], None]:
        def apply(x: float) -> None:
            eff = list(v.plant.airframe.motor_efficiency)
            eff[i] = x
            v.plant.airframe = dataclasses.replace(v.plant.airframe, motor_efficiency=tuple(eff))  # type: ignore[arg-type]
            v.plant.__post_init__()
        return apply

    def fault(window: str) -> Callable[[float], None]:
        """Setting the parameter starts the fault now, for that many seconds (0 ends it)."""
        def apply(x: float) -> None:
            assert v.faults is not None
            setattr(v.faults, window, (v.t, v.t + x) if x > 0 else (math.inf, math.inf))
            if x > 0:
                ap.say(Severity.WARNING, f"Fault injected: {window} for {x:g} s")
        return apply

    a, g, pg = ap.params, sc.attitude, sc.position
    hover = sc.vehicle.weight_n / sc.vehicle.thrust_max_n
    params = [
        Param("COM_OF_LOSS_T", a.offboard_loss_timeout_s, 0.1, 60.0, "offboard loss timeout [s]",
              ap_param("offboard_loss_timeout_s")),
        Param("COM_FAIL_ACT_T", a.failsafe_hold_s, 0.0, 60.0, "hold before landing after offboard loss [s]",
              ap_param("failsafe_hold_s")),
        Param("MIS_TAKEOFF_ALT", a.takeoff_alt_m, 0.5, 100.0, "take-off height above home [m]",
              ap_param("takeoff_alt_m")),
        Param("MPC_TKO_SPEED", a.takeoff_speed_m_s, 0.2, 5.0, "take-off climb speed [m/s]",
              ap_param("takeoff_speed_m_s")),
        Param("MPC_LAND_SPEED", a.land_speed_m_s, 0.2, 3.0, "landing descent speed [m/s]",
              ap_param("land_speed_m_s")),
        Param("COM_DISARM_PRFLT", a.disarm_preflight_s, 0.0, 120.0, "disarm if no take-off within [s]",
              ap_param("disarm_preflight_s")),
        Param("COM_DISARM_LAND", a.disarm_land_s, 0.0, 60.0, "disarm after touch-down [s]",
              ap_param("disarm_land_s")),
        Param("MPC_THR_HOVER", hover, 0.0, 1.0, "hover thrust, normalised (m g / T_max)"),
        Param("SIM_THRUST_MAX", sc.vehicle.thrust_max_n, 0.0, 1e3, "thrust at normalised 1.0 [N]"),
    ]
    if ap.ardupilot:
        params = _ardupilot_params(ap, hover)
    params += [
        Param("ATT_CTRL", float(ATTITUDE_KINDS.index(v.onboard.controller.kind)), 0.0, 2.0,
              "attitude controller: 0 PD, 1 PD+DO, 2 ISM+DO", att_kind),
        Param("ATT_W_C", g.omega_c_rad_s, 1.0, 60.0, "attitude omega_c [rad/s]", att_gain("omega_c_rad_s", False)),
        Param("ATT_GAMMA", g.observer_gain_rad_s[0], 0.1, 100.0, "torque observer Gamma_a [rad/s]",
              att_gain("observer_gain_rad_s", True)),
        Param("ATT_K_S", g.sliding_gain_rad_s[0], 0.0, 100.0, "ISM sliding gain [rad/s]",
              att_gain("sliding_gain_rad_s", True)),
        Param("ATT_EPS", g.boundary_layer_rad_s[0], 0.01, 10.0, "ISM boundary layer [rad/s]",
              att_gain("boundary_layer_rad_s", True)),
        Param("POS_W_C", pg.omega_c_rad_s[0], 0.2, 5.0, "hold position omega_c [rad/s]",
              pos_gain("omega_c_rad_s", (0, 1, 2))),
        Param("POS_GAMMA_XY", pg.observer_gain_rad_s[0], 0.1, 30.0, "hold force observer, horizontal [rad/s]",
              pos_gain("observer_gain_rad_s", (0, 1))),
        Param("POS_GAMMA_Z", pg.observer_gain_rad_s[2], 0.1, 30.0, "hold force observer, vertical [rad/s]",
              pos_gain("observer_gain_rad_s", (2,))),
        Param("SIM_WIND_N", wind["mean"][0], -20.0, 20.0, "mean wind north [m/s]", wind_axis(0)),  # type: ignore[index]
        Param("SIM_WIND_E", wind["mean"][1], -20.0, 20.0, "mean wind east [m/s]", wind_axis(1)),  # type: ignore[index]
        Param("SIM_WIND_D", wind["mean"][2], -5.0, 5.0, "mean wind down [m/s]", wind_axis(2)),  # type: ignore[index]
        Param("SIM_TURB_SIGMA", float(wind["sigma"]), 0.0, 5.0, "turbulence intensity, 0 = off [m/s]",  # type: ignore[arg-type]
              wind_value("sigma")),
        Param("SIM_TURB_ALT", float(wind["alt"]), 0.3, 300.0, "altitude for the Dryden scales [m]",  # type: ignore[arg-type]
              wind_value("alt")),
        Param("SIM_FORCE_X", 0.0, -50.0, 50.0, "external force north [N]", force_axis(0)),
        Param("SIM_FORCE_Y", 0.0, -50.0, 50.0, "external force east [N]", force_axis(1)),
        Param("SIM_FORCE_Z", 0.0, -50.0, 50.0, "external force down [N]", force_axis(2)),
        Param("SIM_TORQUE_X", 0.0, -1.0, 1.0, "external torque, body x [N m]", torque_axis(0)),
        Param("SIM_TORQUE_Y", 0.0, -1.0, 1.0, "external torque, body y [N m]", torque_axis(1)),
        Param("SIM_TORQUE_Z", 0.0, -1.0, 1.0, "external torque, body z [N m]", torque_axis(2)),
        Param("SIM_MASS_FAC", factors["mass"], 0.5, 2.0, "plant mass / model mass", model_factor("mass")),
        Param("SIM_INERTIA_FAC", factors["inertia"], 0.5, 2.0, "plant inertia / model inertia",
              model_factor("inertia")),
        *[Param(f"SIM_MOT{i + 1}_EFF", sc.airframe.motor_efficiency[i], 0.0, 1.5,
                f"motor {i + 1} thrust efficiency", motor(i)) for i in range(4)],
        Param("SIM_MOCAP_DROP", 0.0, 0.0, 3600.0, "tracking dropout from now, for [s]", fault("mocap_dropout")),
        Param("SIM_IMU_FREEZE", 0.0, 0.0, 3600.0, "IMU frozen from now, for [s]", fault("imu_frozen")),
        Param("SIM_IMU_NAN", 0.0, 0.0, 3600.0, "IMU reads NaN from now, for [s]", fault("imu_nan")),
        Param("SIM_SEED", float(v.seeds if isinstance(v.seeds, int) else v.seeds[0]), 0.0, 2**24,
              "random seed of this vehicle"),
    ]
    return ParamTable(params)


def _ardupilot_params(ap: Autopilot, hover: float) -> list[Param]:
    """ArduCopter's names for what the companion needs (MAVLINK.md)."""

    def ap_param(field: str, scale: float = 1.0) -> Callable[[float], None]:
        def apply(x: float) -> None:
            ap.params = dataclasses.replace(ap.params, **{field: x * scale})
        return apply

    def guid_options(x: float) -> None:
        if x != int(x) or x < 0:
            raise ValueError("GUID_OPTIONS is a bitmask (a non-negative integer)")
        ap.params = dataclasses.replace(ap.params, guided_thrust_is_throttle=bool(int(x) & 8))

    a = ap.params
    return [
        Param("GUID_OPTIONS", 8.0 if a.guided_thrust_is_throttle else 0.0, 0.0, 1023.0,
              "bit 3 (8): SET_ATTITUDE_TARGET thrust is throttle, else a climb rate", guid_options),
        Param("GUID_TIMEOUT", a.guided_timeout_s, 0.1, 5.0, "attitude targets older than this are not flown [s]",
              ap_param("guided_timeout_s")),
        Param("ANGLE_MAX", a.angle_max_deg * 100.0, 1000.0, 8000.0, "maximum lean angle [cdeg]",
              ap_param("angle_max_deg", 0.01)),
        Param("MOT_THST_HOVER", hover, 0.0, 1.0, "hover throttle, normalised"),
    ]
