"""Vehicle and controller parameters: frozen dataclasses whose defaults are the paper's.

Units sit in every field name. The vehicle defaults describe the AscTec Hummingbird class of
SPEC section 5 (0.63 kg, "+" layout, 0.17 m arms, J = diag(3.5, 3.5, 6.5)e-3 kg m^2, about 3x
weight of collective thrust); the rotor constants come from public Hummingbird data (rotor
speed 1075..8600 rpm, hover near 5000 rpm) and are derived in docs/architecture.md.

:func:`from_mapping` builds any of these from a plain mapping (parsed TOML) and fails on an
unknown key or a wrong type with the key path and the expected type in the message. Reading
files is left to the caller (:mod:`companion.config`), so this module does no I/O.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass
from typing import Any, Mapping, TypeVar

from .vector import Vec3

__all__ = [
    "ParamError",
    "VehicleParams",
    "AttitudeGains",
    "PositionGains",
    "ReferenceParams",
    "TrajectoryParams",
    "from_mapping",
    "to_mapping",
    "attitude_stability_margin",
    "FORCE_SOURCES",
    "LAYOUTS",
]

LAYOUTS: dict[str, tuple[float, float]] = {"plus": (1.0, 0.0), "x": (math.sqrt(0.5), -math.sqrt(0.5))}
"""rotor layouts: the cosine and sine of the angle the "+" rotors are turned by about z_B (-45 deg for "x")"""

FORCE_SOURCES = ("commanded", "measured")
"""The force observer's force input (30): see :attr:`PositionGains.force_source`."""


class ParamError(ValueError):
    """A parameter mapping that does not fit its dataclass.

    ``key_path`` is the dotted path of the offending key (``attitude.omega_c_rad_s``), so a
    caller that knows the file can point at the line.
    """

    def __init__(self, key_path: str, message: str) -> None:
        super().__init__(f"{key_path}: {message}" if key_path else message)
        self.key_path = key_path
        self.detail = message


@dataclass(frozen=True)
class VehicleParams:
    """Rigid body and rotors. The plant uses the true values, a controller its nominal copy."""

    mass_kg: float = 0.63
    inertia_kg_m2: Vec3 = (3.5e-3, 3.5e-3, 6.5e-3)
    """Principal moments of inertia (body axes are principal axes)."""
    arm_length_m: float = 0.17
    k_thrust_n_s2: float = 5.72e-6
    """Rotor thrust coefficient k_F [N / (rad/s)^2]: F_i = k_F w_i^2."""
    k_torque_nm_s2: float = 9.15e-8
    """Rotor drag-torque coefficient k_Q [N m / (rad/s)^2] (k_Q / k_F = 0.016 m)."""
    rotor_speed_min_rad_s: float = 112.6
    rotor_speed_max_rad_s: float = 900.6
    gravity_m_s2: float = 9.81
    layout: str = "plus"
    """``"plus"``: rotors on the body axes (the paper's Hummingbird); ``"x"``: the same rotors turned
    45 degrees about z_B, rotor 1 front-left (:mod:`~companion.control.allocation`)"""

    def __post_init__(self) -> None:
        if self.layout not in LAYOUTS:
            raise ParamError("layout", f"expected one of {', '.join(LAYOUTS)}, got {self.layout!r}")

    @property
    def layout_cos(self) -> float:
        """cos of the angle the rotors are turned by about z_B (1 for "plus")"""
        return LAYOUTS[self.layout][0]

    @property
    def layout_sin(self) -> float:
        return LAYOUTS[self.layout][1]

    @property
    def thrust_max_n(self) -> float:
        """Collective thrust with every rotor at full speed."""
        return 4.0 * self.k_thrust_n_s2 * self.rotor_speed_max_rad_s**2

    @property
    def thrust_min_n(self) -> float:
        return 4.0 * self.k_thrust_n_s2 * self.rotor_speed_min_rad_s**2

    @property
    def weight_n(self) -> float:
        return self.mass_kg * self.gravity_m_s2

    def scaled(self, mass_factor: float = 1.0, inertia_factor: float = 1.0) -> VehicleParams:
        """A copy with mass and inertia scaled (a model mismatch between plant and controller)."""
        j = self.inertia_kg_m2
        return dataclasses.replace(
            self,
            mass_kg=self.mass_kg * mass_factor,
            inertia_kg_m2=(j[0] * inertia_factor, j[1] * inertia_factor, j[2] * inertia_factor),
        )


@dataclass(frozen=True)
class AttitudeGains:
    """Attitude loop (section III), one set for PD, PD+DO and ISM+DO.

    Error dynamics gains (8): ``K_v = 2 omega_c``, ``c = omega_c^2``. Inside the boundary layer
    the ISM term is ``-K s`` with ``K = sliding_gain_rad_s * J0`` (so ``s`` decays at
    ``sliding_gain_rad_s``) and ``K_w = K * boundary_layer_rad_s``.

    Stability condition (25) inside the layer: ``4 lambda_min(K) lambda_min(Gamma) > 1``; with
    the defaults and the Hummingbird inertia it is ``4 * 0.042 * 8 = 1.34``
    (:func:`attitude_stability_margin`).
    """

    omega_c_rad_s: float = 12.0
    observer_gain_rad_s: Vec3 = (8.0, 8.0, 8.0)
    """Gamma_a: bandwidth of the torque observer's low-pass (19)."""
    sliding_gain_rad_s: Vec3 = (12.0, 12.0, 12.0)
    boundary_layer_rad_s: Vec3 = (1.0, 1.0, 1.0)
    """epsilon of (23), in the units of s (rad/s)."""
    anti_windup: bool = True
    indi_filter_rad_s: float = 50.0
    """INDI: the second-order low-pass on the differentiated gyro and the applied torque
    (Smeur, Chu & de Croon 2016 used 50 rad/s)."""
    indi_actuator_time_constant_s: float = 0.02
    """INDI's rotor model: the applied torque reaches the body through this first-order lag."""


@dataclass(frozen=True)
class PositionGains:
    """Position loop (section IV and the baselines of section V), per NED axis.

    Local gains of every controller equal the PID's (section V): ``K_v = 2 omega_c``,
    ``K_p = omega_c^2``, ``K_i = omega_c / 4`` (the paper's expression, read with units 1/s^3).
    """

    omega_c_rad_s: Vec3 = (1.5, 1.5, 1.5)
    observer_gain_rad_s: Vec3 = (3.0, 3.0, 1.5)
    """Gamma_f of the force observer (30), section V's Gamma_p."""
    sliding_gain_rad_s: Vec3 = (1.5, 1.5, 1.5)
    """K_f / (m0 epsilon_p): the paper's K_sf = 1.5 m0 with epsilon = 1."""
    boundary_layer_m_s: Vec3 = (1.0, 1.0, 1.0)
    aibc_gamma_per_s: Vec3 = (4.0, 4.0, 2.0)
    """AIBC's velocity-based estimate: the bandwidth of its observer (``aibc_estimate``)."""
    aibc_estimate: str = "observer"
    """``"observer"``: a velocity-error observer, zero in nominal flight, so the AIBC keeps the
    PID's local gains (section V); ``"velocity_feedback"``: the literal ``h = gamma v~``, which
    adds gamma to the velocity gain (:mod:`~companion.control.position`)."""
    integral_limit_m_s2: float = 20.0
    """Bound on the PID/AIBC integral term K_i xi [m/s^2] (anti-windup). About 2 g: above the
    9.5 m/s^2 that the 45 degree hover of E5 needs, so it stops wind-up without capping a
    disturbance the vehicle could actually hold against."""
    anti_windup: bool = True
    indi_filter_rad_s: Vec3 = (10.0, 10.0, 10.0)
    """INDI (Tal & Karaman 2018): the second-order low-pass on the measured acceleration and the
    force, f = f_f + m0 (a_ref - a_f); 10 rad/s sits above the 1.5 rad/s loop and below the
    ~0.1 s of the tracking-data differentiation."""
    observer_uses_imu: bool = True
    """Acceleration source of the force DO: the accelerometer's specific force rotated to NED
    (true), or differentiated, filtered tracking positions (false: the paper's experiments, and
    the E1-E5 scenario files). A companion flying a real autopilot has the accelerometer."""
    force_source: str = "measured"
    """What the force DO (30) subtracts from ``m0 (r_dd - g e3)``:

    - ``"commanded"`` (the paper's): the virtual force ``f = -T R(q_d) e3`` the position loop
      sent (after the tilt and thrust limits). The estimate then also holds whatever the inner
      attitude loop fails to deliver, and the position loop compensates it: right for a
      sluggish or biased inner loop.
    - ``"measured"``: ``-T R(q) e3`` with the measured attitude. The estimate is the true
      external force (plus thrust-model error), and inner-loop error is left uncompensated:
      right when the force itself is wanted (interaction, logging, ``companion estimate``).

    The default is ``"measured"``: it is what the companion flies through an autopilot, where the
    setpoint reaches the inner loop 20-60 ms late and a commanded-force estimate learns that delay
    as a force (hover45 over a 10 % loss, 20 +- 10 ms link swings 27 % past on release with
    ``"commanded"``, under 10 % with ``"measured"``: tests/integration/test_link_faults.py). The
    E1-E5 scenario files choose ``"commanded"``, the paper's.
    """

    observer_match_delay_s: float = 0.0
    observer_match_cutoff_hz: float = 0.0
    """The force input of (30) is delayed by ``observer_match_delay_s`` and low-passed by
    ``observer_match_order`` first-order filters at ``observer_match_cutoff_hz`` (0: not
    filtered), to match how the acceleration was obtained: for differentiated tracking data
    (``observer_uses_imu = false``) its delay and filters, so that the difference in (30) sees
    the disturbance and not the force's change over that delay (:class:`MatchingFilter`)."""
    observer_match_order: int = 2

    def __post_init__(self) -> None:
        if self.aibc_estimate not in ("observer", "velocity_feedback"):
            raise ValueError(f"aibc_estimate: expected observer or velocity_feedback, got {self.aibc_estimate!r}")
        if self.force_source not in FORCE_SOURCES:
            raise ValueError(f"force_source: expected one of {', '.join(FORCE_SOURCES)}, got {self.force_source!r}")

    def k_v(self) -> Vec3:
        w = self.omega_c_rad_s
        return (2.0 * w[0], 2.0 * w[1], 2.0 * w[2])

    def k_p(self) -> Vec3:
        w = self.omega_c_rad_s
        return (w[0] * w[0], w[1] * w[1], w[2] * w[2])

    def k_i(self) -> Vec3:
        w = self.omega_c_rad_s
        return (0.25 * w[0], 0.25 * w[1], 0.25 * w[2])


@dataclass(frozen=True)
class ReferenceParams:
    """Force-to-attitude reference generation (section IV.B, (32)-(34))."""

    tilt_max_rad: float = math.radians(70.0)
    """The thrust direction is kept within this angle of vertical (45 degree hover must fit)."""
    min_up_force_fraction: float = 0.1
    """The force keeps at least this fraction of the nominal weight upwards: never straight down."""
    rate_limit_rad_s: float = math.radians(250.0)
    """|omega_d| limit: the paper's gyro-safe 250 deg/s."""
    rate_filter_time_constant_s: float = 0.05
    """Low-pass on omega_d of (34), which differentiates a reference that jumps with every new
    position sample (or on the attitude reference, with ``filter_attitude``); 0.05 s keeps the
    hover rate command near 4 deg/s RMS (docs/architecture.md)."""
    filter_attitude: bool = False
    """Filter and rate-limit the attitude reference itself so that omega_d is its exact motion
    (bounds the body rate by the limit; adds the filter's lag to the position loop), instead of
    the rate command alone: :class:`~companion.control.reference.RateReference`."""


@dataclass(frozen=True)
class TrajectoryParams:
    """Velocity-limited reference between waypoints (the filtered reference of E4)."""

    max_speed_m_s: float = 2.0
    max_accel_m_s2: float = 10.0
    max_jerk_m_s3: float = 40.0
    """how fast the reference acceleration may change: without a limit the acceleration, and
    with it the demanded tilt, steps at every new waypoint while the vehicle is still level"""
    bandwidth_rad_s: float = 2.0
    """Natural frequency of the critically damped reference filter."""
    max_yaw_rate_rad_s: float = math.radians(90.0)


# --- loading from mappings -----------------------------------------------------------

T = TypeVar("T")


def _coerce(tp: Any, value: Any, key_path: str) -> Any:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        members = [a for a in typing.get_args(tp) if a is not type(None)]
        if float in members:
            tp, origin = float, None  # Real: a float in files, a batch array only when built in code
        elif len(members) == 1:  # optional: a file value is the non-None type
            return _coerce(members[0], value, key_path)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, Mapping):
            raise ParamError(key_path, f"expected a table, got {value!r}")
        return from_mapping(tp, value, key_path)  # type: ignore[arg-type]
    if tp is bool:
        if not isinstance(value, bool):
            raise ParamError(key_path, f"expected true or false, got {value!r}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(key_path, f"expected a number, got {value!r}")
        v = float(value)
        if not math.isfinite(v):
            raise ParamError(key_path, f"expected a finite number, got {value!r}")
        return v
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ParamError(key_path, f"expected an integer, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ParamError(key_path, f"expected a string, got {value!r}")
        return value
    if origin is tuple and len(typing.get_args(tp)) == 2 and typing.get_args(tp)[1] is Ellipsis:
        item = typing.get_args(tp)[0]
        if not isinstance(value, (list, tuple)):
            raise ParamError(key_path, f"expected a list, got {value!r}")
        return tuple(_coerce(item, v, f"{key_path}[{i}]") for i, v in enumerate(value))
    if origin is tuple:
        args = typing.get_args(tp)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value] * len(args)
        if not isinstance(value, (list, tuple)) or len(value) != len(args):
            raise ParamError(key_path, f"expected a number or a list of {len(args)} numbers, got {value!r}")
        return tuple(_coerce(a, v, f"{key_path}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    raise ParamError(key_path, f"unsupported parameter type {tp}")


def from_mapping(cls: type[T], data: Mapping[str, Any], key_path: str = "") -> T:
    """Build the dataclass ``cls`` from ``data``; missing keys keep their defaults.

    Raises :class:`ParamError` naming the dotted key path, for an unknown key (with the
    accepted keys) or a value of the wrong type (with the expected type).
    """
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls) if f.init}  # type: ignore[arg-type]
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        path = f"{key_path}.{key}" if key_path else key
        if key not in names:
            raise ParamError(path, f"unknown key; expected one of: {', '.join(sorted(names))}")
        kwargs[key] = _coerce(hints[key], value, path)
    try:
        return cls(**kwargs)
    except ParamError:
        raise
    except (ValueError, TypeError) as exc:  # a constructor's own validation
        raise ParamError(key_path, str(exc)) from None


def to_mapping(obj: Any) -> dict[str, Any]:
    """The inverse of :func:`from_mapping` (tuples become lists), for logs and round trips."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            out[f.name] = to_mapping(v)
        elif isinstance(v, tuple):
            out[f.name] = list(v)
        else:
            out[f.name] = v
    return out


def attitude_stability_margin(gains: AttitudeGains, vehicle: VehicleParams) -> float:
    """``4 lambda_min(K) lambda_min(Gamma)`` of (25); the loop is stable in the layer when > 1."""
    j = vehicle.inertia_kg_m2
    k_min = min(gains.sliding_gain_rad_s[i] * j[i] for i in range(3))
    return float(4.0 * k_min * min(float(g) for g in gains.observer_gain_rad_s))

