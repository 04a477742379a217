"""Scenarios: everything that defines a simulated flight, as data loaded from TOML.

The same file drives the offline experiments (E1-E5) and the simulated MAVLink vehicle's
disturbances. Tables are named after the fields below; see ``sitl/plant/scenarios/*.toml``.
The controller's model is ``vehicle``; the plant is ``vehicle`` with ``model_error`` applied.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

from companion.config import load_dataclass, load_toml
from companion.control.attitude import ATTITUDE_CONTROLLERS
from companion.control.params import (
    from_mapping,
    to_mapping,
    AttitudeGains,
    PositionGains,
    ReferenceParams,
    TrajectoryParams,
    VehicleParams,
)
from companion.control.position import POSITION_CONTROLLERS
from companion.control.vector import Vec3

from .airframe import AirframeParams
from .disturbances import Profile
from .nav_sensors import NavSensorParams
from .onboard import EstimatorGains
from .sensors import SensorParams
from .wind import WindParams

__all__ = ["ModelError", "Waypoint", "Setpoint", "Segment", "Runs", "Scenario", "load_scenario", "SCENARIO_DIR",
           "apply_settings", "parse_setting"]

SCENARIO_DIR = Path(__file__).parent / "scenarios"


@dataclass(frozen=True)
class ModelError:
    """Plant relative to the controller's model: ``m = mass_factor * m0``, ``J = inertia_factor * J0``."""

    mass_factor: float = 1.0
    inertia_factor: float = 1.0


@dataclass(frozen=True)
class Waypoint:
    """Target that becomes active at ``at_s``; the reference filter flies there."""

    at_s: float
    position_ned_m: Vec3
    yaw_deg: float = 0.0


@dataclass(frozen=True)
class Setpoint:
    """Hover at ``position_ned_m`` with ``yaw_deg``, or fly ``waypoints`` through the filter."""

    position_ned_m: Vec3 = (0.0, 0.0, -1.0)
    yaw_deg: float = 0.0
    waypoints: tuple[Waypoint, ...] = ()

    def target_at(self, t_s: float) -> tuple[Vec3, float]:
        pos, yaw = self.position_ned_m, self.yaw_deg
        for wp in self.waypoints:
            if t_s >= wp.at_s:
                pos, yaw = wp.position_ned_m, wp.yaw_deg
        return pos, math.radians(yaw)


@dataclass(frozen=True)
class Segment:
    """A window of the flight over which metrics are computed (e.g. force on, force released)."""

    name: str
    start_s: float
    stop_s: float
    settle_band_m: float = 0.05
    """settling time: from start_s until the position error stays within this band"""

    def __post_init__(self) -> None:
        if not self.stop_s > self.start_s:
            raise ValueError(f"segment {self.name!r}: stop_s must be after start_s")


@dataclass(frozen=True)
class Runs:
    """Which controller combinations and seeds an experiment runs."""

    position: tuple[str, ...] = ("ism_do",)
    attitude: tuple[str, ...] = ("ism_do",)
    seeds: tuple[int, ...] = (1,)

    def __post_init__(self) -> None:
        for name in self.position:
            if name not in POSITION_CONTROLLERS:
                raise ValueError(f"position controller {name!r}: expected one of {', '.join(POSITION_CONTROLLERS)}")
        for name in self.attitude:
            if name not in ATTITUDE_CONTROLLERS:
                raise ValueError(f"attitude controller {name!r}: expected one of {', '.join(ATTITUDE_CONTROLLERS)}")


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str = ""
    duration_s: float = 20.0
    plant_rate_hz: float = 1000.0
    position_rate_hz: float = 100.0
    log_rate_hz: float = 200.0
    runs: Runs = field(default_factory=Runs)
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    airframe: AirframeParams = field(default_factory=AirframeParams)
    model_error: ModelError = field(default_factory=ModelError)
    sensors: SensorParams = field(default_factory=SensorParams)
    nav_sensors: NavSensorParams = field(default_factory=NavSensorParams)
    """what a real autopilot's estimator navigates by when its firmware flies the plant (``sitl --firmware``)"""
    estimator: EstimatorGains = field(default_factory=EstimatorGains)
    wind: WindParams = field(default_factory=WindParams)
    forces: tuple[Profile, ...] = ()
    """external forces, NED [N]"""
    torques: tuple[Profile, ...] = ()
    """external torques, body [N m]"""
    setpoint: Setpoint = field(default_factory=Setpoint)
    attitude: AttitudeGains = field(default_factory=AttitudeGains)
    position: PositionGains = field(default_factory=PositionGains)
    reference: ReferenceParams = field(default_factory=ReferenceParams)
    trajectory: TrajectoryParams = field(default_factory=TrajectoryParams)
    segments: tuple[Segment, ...] = ()
    figure: str = "generic"
    """which figure the experiment runner draws: step_force, chirp_torque, boxplot, waypoints,
    suspended_weight or generic"""

    def __post_init__(self) -> None:
        ratio = self.plant_rate_hz / self.position_rate_hz
        if abs(ratio - round(ratio)) > 1e-9 or ratio < 1:
            raise ValueError("position_rate_hz must divide plant_rate_hz")
        if self.duration_s <= 0:
            raise ValueError("duration_s must be positive")

    @property
    def plant_vehicle(self) -> VehicleParams:
        me = self.model_error
        return self.vehicle.scaled(me.mass_factor, me.inertia_factor)

    def with_changes(self, **changes: object) -> Scenario:
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]


def load_scenario(path: str | Path) -> Scenario:
    """A scenario from a TOML file; errors name the file, line and key."""
    p = Path(path)
    if not p.exists() and (SCENARIO_DIR / f"{path}.toml").exists():
        p = SCENARIO_DIR / f"{path}.toml"
    data, text = load_toml(p)
    data.setdefault("name", p.stem)
    return load_dataclass(Scenario, data, p, text)


def parse_setting(text: str) -> tuple[str, object]:
    """``"position.force_source=measured"`` -> ``("position.force_source", "measured")``; the value
    is read as a TOML value (``false``, ``1.5``, ``[3, 3, 1.5]``), or else kept as a string."""
    import tomllib

    key, sep, raw = text.partition("=")
    if not sep or "." not in key:
        raise ValueError(f"{text!r}: expected TABLE.KEY=VALUE, e.g. position.force_source=measured")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key.strip(), value


def apply_settings(sc: Scenario, settings: dict[str, object]) -> Scenario:
    """The scenario with ``{"table.key": value}`` applied, each checked like a file's value."""
    for path, value in settings.items():
        table, _, key = path.partition(".")
        sub = getattr(sc, table, None)
        if not dataclasses.is_dataclass(sub):
            raise ValueError(f"{path!r}: {table!r} is not a table of the scenario")
        data = to_mapping(sub)
        data[key] = value
        sc = sc.with_changes(**{table: from_mapping(type(sub), data, table)})
    return sc
