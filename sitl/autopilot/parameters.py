"""The simulated vehicle's parameters: controller gains, firmware behaviour, simulation settings.

Served over the MAVLink parameter protocol (all REAL32), so QGroundControl, MAVProxy or a
script can read them and change them in flight: wind, turbulence, an external force or torque,
a mass error or a weak motor take effect at the next plant step. Names follow PX4 where PX4
has the parameter (COM_OF_LOSS_T, MIS_TAKEOFF_ALT, ...); SIM_* are the simulation's own.

One declarative table (:data:`PX4_ROWS`, :data:`ARDUPILOT_ROWS`, :data:`COMMON_ROWS`): each row
names the field it sets (of the autopilot's :class:`~sitl.autopilot.logic.AutopilotParams`, of the
live :class:`~sitl.plant.scenario.Scenario`, or of the vehicle), its range and its unit. The ranges are
what flies: any value in range, alone or with any others in range, leaves the hovering vehicle
upright (``tests/sitl/test_parameters.py`` sets them all, edges included, in flight), except the
rows marked as deliberate faults (a dead motor, a failed sensor), which end in a defined failsafe.
A value outside its range, a non-integer for an integer parameter, or a write to a read-only one
is refused (the old value is echoed, as PX4 does) with a reason. The table in docs/sitl.md is
:func:`markdown_table`'s output (a test keeps them equal).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable, Iterator

from .logic import Autopilot, Severity

__all__ = ["Row", "Param", "ParamTable", "build_parameters", "markdown_table", "PX4_ROWS", "ARDUPILOT_ROWS",
           "COMMON_ROWS", "ATTITUDE_KINDS"]

ATTITUDE_KINDS = ("pd", "pd_do", "ism_do")


@dataclass(frozen=True)
class Row:
    """One parameter: where its value lives, its range and unit.

    ``field`` is a dotted path with a root: ``autopilot.<AutopilotParams field>``,
    ``scenario.<path>`` (attitude and position gains, wind, model error, motor efficiency of the
    live scenario), ``vehicle.<attribute>`` (the run-time force and torque), ``controller`` (the
    attitude controller's kind), ``fault.<window>`` (a fault injected from now for the value's
    seconds) or ``derived.<name>`` (read-only). A vector field takes ``components``: the
    multiplier of the value for each component, None to leave it.
    """

    name: str
    field: str
    minimum: float
    maximum: float
    unit: str
    description: str
    components: tuple[float | None, ...] | None = None
    integer: bool = False
    read_only: bool = False
    fault: bool = False
    """a deliberate fault: the vehicle may not fly on, but must end in a defined failsafe"""
    scale: float = 1.0
    """wire value x scale = field value (ArduPilot's centidegrees)"""


V = (1.0, None, None)
E = (None, 1.0, None)
D = (None, None, 1.0)
XYZ = (1.0, 1.0, 1.0)

PX4_ROWS: tuple[Row, ...] = (
    Row("COM_OF_LOSS_T", "autopilot.offboard_loss_timeout_s", 0.1, 60.0, "s", "offboard loss timeout"),
    Row("COM_FAIL_ACT_T", "autopilot.failsafe_hold_s", 0.0, 60.0, "s", "hold before landing after offboard loss"),
    Row("MIS_TAKEOFF_ALT", "autopilot.takeoff_alt_m", 0.5, 100.0, "m", "take-off height above home"),
    Row("MPC_TKO_SPEED", "autopilot.takeoff_speed_m_s", 0.2, 3.0, "m/s", "take-off climb speed"),
    Row("MPC_LAND_SPEED", "autopilot.land_speed_m_s", 0.2, 3.0, "m/s", "landing descent speed"),
    Row("COM_DISARM_PRFLT", "autopilot.disarm_preflight_s", 0.0, 120.0, "s", "disarm if no take-off within"),
    Row("COM_DISARM_LAND", "autopilot.disarm_land_s", 0.0, 60.0, "s", "disarm after touch-down"),
    Row("MPC_THR_HOVER", "derived.hover_thrust", 0.0, 1.0, "", "hover thrust, normalised (m g / T_max)",
        read_only=True),
    Row("SIM_THRUST_MAX", "scenario.vehicle.thrust_max_n", 0.0, 1e3, "N", "thrust at normalised 1.0",
        read_only=True),
)

ARDUPILOT_ROWS: tuple[Row, ...] = (
    Row("GUID_OPTIONS", "autopilot.guided_options", 0.0, 1023.0, "",
        "bitmask; bit 3 (8): SET_ATTITUDE_TARGET thrust is throttle, else a climb rate", integer=True),
    Row("GUID_TIMEOUT", "autopilot.guided_timeout_s", 0.1, 5.0, "s", "attitude targets older than this are not flown"),
    Row("ATC_ANGLE_MAX", "autopilot.angle_max_deg", 10.0, 80.0, "deg", "maximum lean angle of ArduPilot's own "
        "modes (not of GUIDED attitude targets)"),
    Row("ATC_RATE_FF_ENAB", "autopilot.rate_ff_enabled", 0.0, 1.0, "", "1: attitude targets are shaped by "
        "ATC_INPUT_TC; 0: flown as sent", integer=True),
    Row("ATC_INPUT_TC", "autopilot.input_tc_s", 0.0, 1.0, "s", "time constant of that shaping"),
    Row("ATC_ANGLE_BOOST", "autopilot.angle_boost", 0.0, 1.0, "", "1: throttle divided by the cosine of the "
        "tilt", integer=True),
    Row("MOT_THST_HOVER", "derived.hover_thrust", 0.0, 1.0, "", "hover throttle, normalised: 7 % high at boot, "
        "learnt in flight (10 s time constant)", read_only=True),
)

COMMON_ROWS: tuple[Row, ...] = (
    Row("ATT_CTRL", "controller", 0.0, 2.0, "", "attitude controller: 0 PD, 1 PD+DO, 2 ISM+DO", integer=True),
    Row("ATT_W_C", "scenario.attitude.omega_c_rad_s", 6.0, 20.0, "rad/s", "attitude omega_c"),
    Row("ATT_GAMMA", "scenario.attitude.observer_gain_rad_s", 1.0, 40.0, "rad/s", "torque observer Gamma_a",
        components=XYZ),
    Row("ATT_K_S", "scenario.attitude.sliding_gain_rad_s", 0.0, 20.0, "rad/s", "ISM sliding gain", components=XYZ),
    Row("ATT_EPS", "scenario.attitude.boundary_layer_rad_s", 0.1, 2.0, "rad/s", "ISM boundary layer",
        components=XYZ),
    Row("POS_W_C", "scenario.position.omega_c_rad_s", 0.3, 2.5, "rad/s", "hold position omega_c", components=XYZ),
    Row("POS_GAMMA_XY", "scenario.position.observer_gain_rad_s", 0.3, 12.0, "rad/s",
        "hold force observer, horizontal", components=(1.0, 1.0, None)),
    Row("POS_GAMMA_Z", "scenario.position.observer_gain_rad_s", 0.3, 12.0, "rad/s", "hold force observer, vertical",
        components=D),
    Row("SIM_WIND_N", "scenario.wind.mean_ned_m_s", -6.0, 6.0, "m/s", "mean wind (air velocity) north",
        components=V),
    Row("SIM_WIND_E", "scenario.wind.mean_ned_m_s", -6.0, 6.0, "m/s", "mean wind east", components=E),
    Row("SIM_WIND_D", "scenario.wind.mean_ned_m_s", -3.0, 3.0, "m/s", "mean wind down", components=D),
    Row("SIM_TURB_SIGMA", "scenario.wind.turbulence.sigma_m_s", 0.0, 1.5, "m/s",
        "turbulence intensity, 0 = off (u, v; w gets 2/3)", components=(1.0, 1.0, 2.0 / 3.0)),
    Row("SIM_TURB_ALT", "scenario.wind.turbulence.altitude_m", 0.3, 300.0, "m", "altitude for the Dryden scales"),
    Row("SIM_FORCE_X", "vehicle.extra_force_ned_n", -6.0, 6.0, "N", "external force north", components=V),
    Row("SIM_FORCE_Y", "vehicle.extra_force_ned_n", -6.0, 6.0, "N", "external force east", components=E),
    Row("SIM_FORCE_Z", "vehicle.extra_force_ned_n", -2.0, 6.0, "N", "external force down", components=D),
    Row("SIM_TORQUE_X", "vehicle.extra_torque_nm", -0.15, 0.15, "N m", "external torque, body x", components=V),
    Row("SIM_TORQUE_Y", "vehicle.extra_torque_nm", -0.15, 0.15, "N m", "external torque, body y", components=E),
    Row("SIM_TORQUE_Z", "vehicle.extra_torque_nm", -0.04, 0.04, "N m", "external torque, body z", components=D),
    Row("SIM_MASS_FAC", "scenario.model_error.mass_factor", 0.75, 1.6, "", "plant mass / model mass"),
    Row("SIM_INERTIA_FAC", "scenario.model_error.inertia_factor", 0.5, 2.0, "", "plant inertia / model inertia"),
    *(Row(f"SIM_MOT{i + 1}_EFF", "scenario.airframe.motor_efficiency", 0.0, 1.5, "",
          f"motor {i + 1} thrust efficiency (a deliberate fault away from 1)",
          components=tuple(1.0 if j == i else None for j in range(4)), fault=True) for i in range(4)),
    Row("SIM_MOCAP_DROP", "fault.mocap_dropout", 0.0, 3600.0, "s", "tracking dropout from now, for", fault=True),
    Row("SIM_IMU_FREEZE", "fault.imu_frozen", 0.0, 3600.0, "s", "IMU frozen from now, for", fault=True),
    Row("SIM_IMU_NAN", "fault.imu_nan", 0.0, 3600.0, "s", "IMU reads NaN from now, for", fault=True),
    Row("SIM_STATE_NAN", "fault.state_nan", 0.0, 1.0, "",
        "1: the plant's state turns NaN (tests the numerical-fault failsafe)", integer=True,
        fault=True),
    Row("SIM_SEED", "derived.seed", 0.0, 2.0**32 - 1, "", "random seed of this vehicle", read_only=True),
)


@dataclass
class Param:
    name: str
    value: float
    minimum: float
    maximum: float
    description: str
    apply: Callable[[float], None] | None = None
    """None: read-only"""
    unit: str = ""
    integer: bool = False
    fault: bool = False


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

    def __iter__(self) -> Iterator[Param]:
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
        for edge in (p.minimum, p.maximum):  # an edge sent as REAL32 is that edge, not a refusal
            if abs(value - edge) <= 1e-6 * max(1.0, abs(edge)):
                value = edge
        if not p.minimum <= value <= p.maximum:
            return f"{name}: {value:g} outside [{p.minimum:g}, {p.maximum:g}]"
        if p.integer and value != int(value):
            return f"{name}: {value:g} is not an integer"
        try:
            p.apply(value)
        except ValueError as exc:
            return f"{name}: {exc}"
        p.value = value
        return None


def _get_path(obj: Any, path: list[str]) -> Any:
    for part in path:
        obj = getattr(obj, part)
    return obj


def _replace_path(obj: Any, path: list[str], value: Any) -> Any:
    """A copy of frozen dataclass ``obj`` with the field at ``path`` replaced."""
    if not path:
        return value
    head = path[0]
    return dataclasses.replace(obj, **{head: _replace_path(getattr(obj, head), path[1:], value)})


def _put(old: Any, components: tuple[float | None, ...] | None, x: float) -> Any:
    """``x`` into a scalar, or into a vector's components by their multipliers."""
    if components is None:
        return x
    return tuple(o if k is None else k * x for o, k in zip(old, components))


def _take(value: Any, components: tuple[float | None, ...] | None) -> float:
    """The parameter's value read back from a scalar or a vector field."""
    if components is None:
        return float(value)
    i, k = next((i, k) for i, k in enumerate(components) if k is not None)
    return float(value[i]) / k if k else 0.0


class _Binding:
    """Reads and writes the fields of the rows on one live autopilot and vehicle."""

    def __init__(self, ap: Autopilot) -> None:
        self.ap = ap
        self.v = ap.vehicle

    def get(self, row: Row) -> float:
        root, *path = row.field.split(".")
        ap, v = self.ap, self.v
        if root == "autopilot":
            if path == ["guided_options"]:
                return 8.0 if ap.params.guided_thrust_is_throttle else 0.0
            return float(getattr(ap.params, path[0])) / row.scale
        if root == "scenario":
            if path == ["vehicle", "thrust_max_n"]:
                return float(v.scenario.vehicle.thrust_max_n)
            if path == ["wind", "turbulence", "sigma_m_s"]:
                return float(max(v.scenario.wind.turbulence.sigma_m_s))
            return _take(_get_path(v.scenario, path), row.components)
        if root == "vehicle":
            return _take(getattr(v, path[0]), row.components)
        if root == "controller":
            return float(ATTITUDE_KINDS.index(v.onboard.controller.kind))
        if root == "fault":
            return 0.0
        if path == ["seed"]:
            return float(v.seeds if isinstance(v.seeds, int) else v.seeds[0])
        return ap.reported_hover_throttle()

    def setter(self, row: Row) -> Callable[[float], None] | None:
        if row.read_only:
            return None
        root, *path = row.field.split(".")
        return getattr(self, f"_set_{root}")(row, path)

    def _set_autopilot(self, row: Row, path: list[str]) -> Callable[[float], None]:
        ap = self.ap
        if path == ["guided_options"]:
            def guided(x: float) -> None:
                ap.params = dataclasses.replace(ap.params, guided_thrust_is_throttle=bool(int(x) & 8))
            return guided

        flag = isinstance(getattr(ap.params, path[0]), bool)

        def apply(x: float) -> None:
            ap.params = dataclasses.replace(ap.params, **{path[0]: bool(x) if flag else x * row.scale})
        return apply

    def _set_scenario(self, row: Row, path: list[str]) -> Callable[[float], None]:
        v = self.v
        after = {"attitude": self._attitude, "position": self._position, "wind": self._wind,
                 "model_error": self._model_error, "airframe": self._airframe}[path[0]]

        def apply(x: float) -> None:
            v.scenario = _replace_path(v.scenario, path, _put(_get_path(v.scenario, path), row.components, x))
            after()
        return apply

    def _attitude(self) -> None:
        self.v.set_attitude_gains(self.v.scenario)

    def _position(self) -> None:
        from companion.control.outer_loop import PositionLoop

        sc, ap = self.v.scenario, self.ap
        ap.position_loop = PositionLoop.create(ap.params.hold_controller, sc.vehicle, sc.position, sc.reference)

    def _wind(self) -> None:
        v = self.v
        turb = v.scenario.wind.turbulence
        on = max(turb.sigma_m_s) > 0.0 or turb.w20_m_s > 0.0
        if on != turb.enabled:
            v.scenario = _replace_path(v.scenario, ["wind", "turbulence", "enabled"], on)
        v.set_wind(v.scenario.wind)

    def _model_error(self) -> None:
        self.v.set_plant_vehicle(self.v.scenario.plant_vehicle)

    def _airframe(self) -> None:
        v = self.v
        v.plant.airframe = v.scenario.airframe
        v.plant.__post_init__()

    def _set_vehicle(self, row: Row, path: list[str]) -> Callable[[float], None]:
        v = self.v

        def apply(x: float) -> None:
            setattr(v, path[0], _put(getattr(v, path[0]), row.components, x))
        return apply

    def _set_controller(self, row: Row, path: list[str]) -> Callable[[float], None]:
        v = self.v

        def apply(x: float) -> None:
            v.set_attitude_controller(ATTITUDE_KINDS[int(x)])
        return apply

    def _set_fault(self, row: Row, path: list[str]) -> Callable[[float], None]:
        """Setting the parameter starts the fault now, for that many seconds (0 ends it)."""
        ap, v, window = self.ap, self.v, path[0]

        def apply(x: float) -> None:
            assert v.faults is not None
            if window == "state_nan":
                if x:
                    ap.say(Severity.WARNING, "Fault injected: NaN plant state")
                    s = v.plant.state
                    v.plant.state = s._replace(vel_ned_m_s=(math.nan, s.vel_ned_m_s[1], s.vel_ned_m_s[2]))
                return
            setattr(v.faults, window, (v.t, v.t + x) if x > 0 else (math.inf, math.inf))
            if x > 0:
                ap.say(Severity.WARNING, f"Fault injected: {window} for {x:g} s")
        return apply


def rows_for(ap: Autopilot) -> tuple[Row, ...]:
    return (ARDUPILOT_ROWS if ap.ardupilot else PX4_ROWS) + COMMON_ROWS


def build_parameters(ap: Autopilot) -> ParamTable:
    """The parameter table bound to one autopilot and its vehicle."""
    binding = _Binding(ap)
    params = []
    for row in rows_for(ap):
        params.append(Param(row.name, binding.get(row), row.minimum, row.maximum, row.description,
                            binding.setter(row), row.unit, row.integer, row.fault))
    return ParamTable(params)


def out_of_range(table: ParamTable) -> list[str]:
    """Parameters whose value (from a scenario, say) is outside their range: what it would take
    a PARAM_SET to do, refused."""
    return [f"{p.name} = {p.value:g} outside [{p.minimum:g}, {p.maximum:g}]" for p in table
            if p.apply is not None and not p.fault and not p.minimum <= p.value <= p.maximum]


def markdown_table(ap: Autopilot, rows: tuple[Row, ...] | None = None) -> str:
    """``rows`` (all of ``ap``'s) as docs/sitl.md shows them, defaults from ``ap``'s scenario."""
    lines = ["| name | default | range | unit | meaning |", "|---|---|---|---|---|"]
    table = build_parameters(ap)
    for row in rows if rows is not None else rows_for(ap):
        p = table.get(row.name)
        assert p is not None
        rng = "read-only" if row.read_only else f"{_num(row.minimum)} .. {_num(row.maximum)}"
        meaning = row.description + (" (integer)" if row.integer and row.name != "ATT_CTRL" else "")
        if row.fault:
            meaning += " — fault"
        lines.append(f"| `{row.name}` | {_num(p.value)} | {rng} | {row.unit} | {meaning} |")
    return "\n".join(lines)


def _num(x: float) -> str:
    return f"{x:.4g}" if abs(x) < 1e6 else f"{x:.6g}"
