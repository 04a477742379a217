"""The plant's own parameters (SIM_*): wind, turbulence, external forces and torques, model
errors, motor efficiency, sensor faults — as a declarative table served over MAVLink's parameter
protocol.

Each :class:`Row` names the field it sets, its range and unit; :class:`PlantBinding` reads and
writes them on one live :class:`~sitl.plant.vehicle.SimVehicle`, so a change takes effect at the
next plant step. The bundled vehicle serves these rows beside its autopilot's
(:mod:`sitl.autopilot.parameters`); with a real autopilot's firmware flying the plant
(:mod:`sitl.firmware`) the plant serves them as a MAVLink component of its own. The ranges are
what flies (``tests/sitl/test_parameters.py``), except the rows marked as deliberate faults.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable, Iterator

from .vehicle import SimVehicle

__all__ = ["Row", "Param", "ParamTable", "PlantBinding", "SIM_ROWS", "THRUST_MAX_ROW", "build_plant_parameters",
           "ESTIMATE_ONLY",
           "V", "E", "D", "XYZ"]

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

THRUST_MAX_ROW = Row("SIM_THRUST_MAX", "scenario.vehicle.thrust_max_n", 0.0, 1e3, "N", "thrust at normalised 1.0",
                     read_only=True)
"""what a normalised thrust of 1 is in newtons: the companion's thrust scale on a simulated vehicle"""

SIM_ROWS: tuple[Row, ...] = (
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
    *(Row(f"SIM_POS_{kind}_{axis}", f"fault.position_{kind.lower()}", -100.0, 100.0, "m",
          f"position estimate reset now by this much {name}{how}", components=c, fault=True)
      for kind, how in (("RESET", ", announced (reset counter)"), ("JUMP", ", not announced"))
      for axis, name, c in (("N", "north", V), ("E", "east", E), ("D", "down", D))),
    Row("SIM_STATE_NAN", "fault.state_nan", 0.0, 1.0, "",
        "1: the plant's state turns NaN (tests the numerical-fault failsafe)", integer=True,
        fault=True),
    Row("SIM_SEED", "derived.seed", 0.0, 2.0**32 - 1, "", "random seed of this vehicle", read_only=True),
)
"""the simulation's own parameters: what the plant and its sensors do, whoever flies them"""

ESTIMATE_ONLY = frozenset(r.name for r in SIM_ROWS if r.field.startswith("fault.position_"))
"""rows that change the bundled autopilot's reported estimate, which a real autopilot's firmware
flying the plant computes itself: not served there"""


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
    live: Callable[[], float] | None = None
    """a read-only value that changes in flight (a learnt hover throttle): read when served"""

    def fresh(self) -> Param:
        if self.live is not None:
            self.value = self.live()
        return self


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
        return (p.fresh() for p in self._params)

    def index(self, name: str) -> int | None:
        return self._by_name.get(name)

    def at(self, index: int) -> Param | None:
        return self._params[index].fresh() if 0 <= index < len(self._params) else None

    def get(self, name: str) -> Param | None:
        i = self._by_name.get(name)
        return None if i is None else self._params[i].fresh()

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


class PlantBinding:
    """Reads and writes the plant's rows (roots ``scenario``, ``vehicle``, ``fault``,
    ``derived.seed``) on one live vehicle; ``say`` reports an injected fault."""

    def __init__(self, vehicle: SimVehicle, say: Callable[[str], None]) -> None:
        self.v = vehicle
        self.say = say

    def get(self, row: Row) -> float:
        root, *path = row.field.split(".")
        v = self.v
        if root == "scenario":
            if path == ["vehicle", "thrust_max_n"]:
                return float(v.scenario.vehicle.thrust_max_n)
            if path == ["wind", "turbulence", "sigma_m_s"]:
                return float(max(v.scenario.wind.turbulence.sigma_m_s))
            return _take(_get_path(v.scenario, path), row.components)
        if root == "vehicle":
            return _take(getattr(v, path[0]), row.components)
        if root == "fault":
            return 0.0
        if path == ["seed"]:
            return float(v.seeds if isinstance(v.seeds, int) else v.seeds[0])
        raise KeyError(row.field)

    def setter(self, row: Row) -> Callable[[float], None] | None:
        if row.read_only:
            return None
        root, *path = row.field.split(".")
        return getattr(self, f"_set_{root}")(row, path)  # type: ignore[no-any-return]

    def _after_scenario(self, table: str) -> Callable[[], None]:
        return {"wind": self._wind, "model_error": self._model_error, "airframe": self._airframe}[table]

    def _set_scenario(self, row: Row, path: list[str]) -> Callable[[float], None]:
        v = self.v
        after = self._after_scenario(path[0])

        def apply(x: float) -> None:
            v.scenario = _replace_path(v.scenario, path, _put(_get_path(v.scenario, path), row.components, x))
            after()
        return apply

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

    def _set_fault(self, row: Row, path: list[str]) -> Callable[[float], None]:
        """Setting the parameter starts the fault now, for that many seconds (0 ends it)."""
        v, window = self.v, path[0]

        def apply(x: float) -> None:
            assert v.faults is not None
            if window == "state_nan":
                if x:
                    self.say("Fault injected: NaN plant state")
                    s = v.plant.state
                    v.plant.state = s._replace(vel_ned_m_s=(math.nan, s.vel_ned_m_s[1], s.vel_ned_m_s[2]))
                return
            if window in ("position_reset", "position_jump"):
                if x:
                    shift = tuple(0.0 if k is None else k * x for k in row.components or XYZ)
                    announced = window == "position_reset"
                    v.faults.reset_position(shift, announced)  # type: ignore[arg-type]
                    self.say(f"Fault injected: position estimate reset by {x:g} m "
                             f"({'announced' if announced else 'not announced'})")
                return
            setattr(v.faults, window, (v.t, v.t + x) if x > 0 else (math.inf, math.inf))
            if x > 0:
                self.say(f"Fault injected: {window} for {x:g} s")
        return apply


def bind_rows(binding: Any, rows: tuple[Row, ...], live: Callable[[Row], bool] = lambda row: False) -> ParamTable:
    """A :class:`ParamTable` of ``rows`` read and written through ``binding``; rows for which
    ``live`` is true are re-read each time they are served."""
    params = []
    for row in rows:
        fresh = (lambda row=row: binding.get(row)) if live(row) else None
        params.append(Param(row.name, binding.get(row), row.minimum, row.maximum, row.description,
                            binding.setter(row), row.unit, row.integer, row.fault, fresh))
    return ParamTable(params)


def build_plant_parameters(vehicle: SimVehicle, say: Callable[[str], None],
                           exclude: frozenset[str] = frozenset()) -> ParamTable:
    """The plant's table on one vehicle, without the names in ``exclude`` (a real autopilot's
    own parameters are never shadowed)."""
    rows = (THRUST_MAX_ROW, *SIM_ROWS)
    return bind_rows(PlantBinding(vehicle, say), tuple(r for r in rows if r.name not in exclude))
