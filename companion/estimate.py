"""The external force on a vehicle, from a flight that already happened (``companion estimate``).

Runs the force observer of the control core over a log: (30) with the logged acceleration (the
accelerometer's specific force rotated into NED), or its momentum form with the logged velocity
when there is no accelerometer, against the thrust force ``-T R(q) e3`` of the logged attitude
and collective thrust. The estimate is the lumped external force, drag included, in NED [N].

The log is first brought to the project's conventions by the readers of
:mod:`companion.logs` (NED, FRD body, scalar-first quaternions body to NED; the explicit
converters :func:`enu_to_ned`, :func:`flu_to_frd`, :func:`quat_from_scalar_last` and
:func:`quat_enu_flu_to_ned_frd` are here for CSV files in other frames). Thrust comes either in
newtons or normalised; normalised, it is either the collective (1.0: every rotor at full) or the
sum of the motors' commands (1.0: one rotor at full), and the log says which. The thrust scale
(:class:`ThrustScale`, total or per motor, converted with the log's motor count) is given or
estimated from the log, as the scale that makes the mean vertical external force zero over the
airborne samples (a wrong scale is a vertical force: SPEC section 6).

Only a flight is estimated: a log whose land detector never says airborne, or (an autopilot's log,
which starts on the ground) that never climbs :data:`NEVER_AIRBORNE_CLIMB_M`, is refused — on the
ground the "external force" is the ground holding the vehicle up, and a thrust scale fitted there
is the weight over whatever thrust the ground took.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from companion.control import quaternion as quat
from companion.control.observers import ForceObserver, MomentumObserver
from companion.control.vector import E3

__all__ = [
    "FlightSeries",
    "ForceEstimate",
    "ThrustScale",
    "NEVER_AIRBORNE_CLIMB_M",
    "climb_m",
    "never_airborne",
    "series_thrust_scale",
    "enu_to_ned",
    "flu_to_frd",
    "quat_from_scalar_last",
    "quat_enu_flu_to_ned_frd",
    "thrust_force_ned",
    "estimate_thrust_scale",
    "estimate_force",
    "write_csv",
    "plot",
]

Array = NDArray[np.float64]
GRAVITY_M_S2 = 9.81
NEVER_AIRBORNE_CLIMB_M = 0.5
"""a log that starts on the ground and never climbs this far above its start never flew (the
estimated height of a vehicle on the ground wanders: 4 mm in ArduCopter's SITL, 1 m down in a real
PX4 1.11 log at boot; a take-off climbs a metre and more, clear of the ground effect)"""
AIRBORNE_THRUST = 0.05
"""the samples a thrust scale is fitted over have a normalised thrust above this"""


@dataclass(frozen=True)
class FlightSeries:
    """One flight on one time base, in the project's conventions. Arrays of shape (N,) or (N, k).

    ``q`` (N, 4): scalar-first, body (FRD) to NED. ``specific_force_body_m_s2`` (N, 3): the
    accelerometer (FRD), or ``None``; ``vel_ned_m_s`` (N, 3) or ``None``: one of the two is needed.
    ``thrust``: collective thrust, in newtons if ``thrust_is_newtons`` else normalised: the
    collective 0..1, or with ``thrust_per_motor`` the sum of the motors' normalised commands.
    ``motor_count``: the rotors, where the log says (converts a total scale to one per motor).
    ``truth_force_ned_n``: the true external force where the log knows it (a simulated flight).
    ``airborne`` (N,) bool: the autopilot's land detector, ``airborne_source`` naming it, or None.
    ``down_m`` (N,): the position down (NED) where logged, else None (the height is then the
    velocity's integral). ``starts_on_ground``: the log begins before any take-off, as an
    autopilot's logs do (from boot or from arming), so a height that never changes means no flight.
    """

    t_s: Array
    q: Array
    thrust: Array
    thrust_is_newtons: bool
    specific_force_body_m_s2: Array | None = None
    vel_ned_m_s: Array | None = None
    truth_force_ned_n: Array | None = None
    source: str = ""
    thrust_per_motor: bool = False
    motor_count: int | None = None
    airborne: NDArray[np.bool_] | None = None
    airborne_source: str = ""
    down_m: Array | None = None
    starts_on_ground: bool = False

    def __post_init__(self) -> None:
        n = len(self.t_s)
        if n < 3:
            raise ValueError("the log has fewer than 3 samples")
        if self.specific_force_body_m_s2 is None and self.vel_ned_m_s is None:
            raise ValueError("the log has neither accelerometer nor velocity: nothing to estimate from")
        for name in ("q", "thrust", "specific_force_body_m_s2", "vel_ned_m_s", "truth_force_ned_n", "airborne",
                     "down_m"):
            a = getattr(self, name)
            if a is not None and len(a) != n:
                raise ValueError(f"{name} has {len(a)} samples, t has {n}")
        where = f"{self.source}: " if self.source else ""
        for name in ("t_s", "q", "thrust", "specific_force_body_m_s2", "vel_ned_m_s", "down_m"):
            a = getattr(self, name)
            if a is not None and not np.all(np.isfinite(a)):
                i = int(np.argmax(~np.isfinite(a).reshape(n, -1).all(axis=1)))
                raise ValueError(f"{where}{name} is not finite at sample {i} (t = {self.t_s[i]:.3f} s)")
        back = np.flatnonzero(np.diff(self.t_s) < 0)
        if back.size:
            i = int(back[0]) + 1
            raise ValueError(f"{where}time goes backwards at sample {i} ({self.t_s[i]:.6f} s after "
                             f"{self.t_s[i - 1]:.6f} s)")


@dataclass(frozen=True)
class ThrustScale:
    """Newtons at full thrust, of all rotors together (``per_motor`` False) or of one rotor."""

    newtons: float
    per_motor: bool

    def describe(self) -> str:
        return f"{self.newtons:.3f} N {'per motor' if self.per_motor else 'total'}"


@dataclass(frozen=True)
class ForceEstimate:
    t_s: Array
    force_ned_n: Array
    """(N, 3) external force estimate, NED [N]"""
    thrust_scale_n: float | None
    """newtons per unit of the log's thrust (None: the log's thrust was in newtons): per motor
    when ``thrust_per_motor``, else total"""
    thrust_scale_estimated: bool
    method: str
    """'accelerometer' or 'velocity'"""
    truth_force_ned_n: Array | None = None
    thrust_per_motor: bool = False
    motor_count: int | None = None
    airborne: NDArray[np.bool_] | None = None
    """the land detector's word per sample, None where the log has none"""
    airborne_source: str = ""

    @property
    def airborne_s(self) -> float:
        """time the land detector says airborne (each sample holds until the next)"""
        if self.airborne is None:
            return float("nan")
        return float(np.sum(np.diff(self.t_s)[self.airborne[:-1]]))

    @property
    def thrust_scale_total_n(self) -> float | None:
        """newtons with every rotor at full"""
        if self.thrust_scale_n is None or (self.thrust_per_motor and self.motor_count is None):
            return None
        return self.thrust_scale_n * (self.motor_count or 1) if self.thrust_per_motor else self.thrust_scale_n

    @property
    def thrust_scale_per_motor_n(self) -> float | None:
        """newtons of one rotor at full"""
        if self.thrust_scale_n is None or (not self.thrust_per_motor and self.motor_count is None):
            return None
        return self.thrust_scale_n if self.thrust_per_motor else self.thrust_scale_n / (self.motor_count or 1)

    def describe_scale(self) -> str:
        """One line: the scale both ways where the motor count is known, and what the log's thrust is."""
        if self.thrust_scale_n is None:
            return "thrust in newtons (no scale)"
        total, each = self.thrust_scale_total_n, self.thrust_scale_per_motor_n
        n = self.motor_count
        both = " = ".join(x for x in (
            f"{total:.3f} N total" if total is not None else "",
            f"{each:.3f} N per motor" + (f" x {n}" if n else "") if each is not None else "") if x)
        what = (f"the log's thrust is the sum of {n or 'the'} motors' normalised commands" if self.thrust_per_motor
                else "the log's thrust is the normalised collective")
        how = " (estimated)" if self.thrust_scale_estimated else ""
        return f"thrust scale {both} at full thrust{how}; {what}"


# --- frame converters ------------------------------------------------------------------------


def enu_to_ned(v: Array) -> Array:
    """(x east, y north, z up) -> (north, east, down), row-wise."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def flu_to_frd(v: Array) -> Array:
    """Body (forward, left, up) -> (forward, right, down), row-wise."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 0], -v[..., 1], -v[..., 2]], axis=-1)


def quat_from_scalar_last(q: Array) -> Array:
    """[x, y, z, w] (ROS, SciPy's default) -> [w, x, y, z]."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., 3:4], q[..., 0:3]], axis=-1)


_ENU_FROM_NED = quat.from_rotmat(((0.0, 1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0)))
_FLU_FROM_FRD = quat.from_rotmat(((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0)))


def quat_enu_flu_to_ned_frd(q: Array) -> Array:
    """Scalar-first q rotating FLU body vectors into ENU -> the one rotating FRD into NED:
    ``q_ned_frd = q_ned_enu ⊗ q_enu_flu ⊗ q_flu_frd`` (both frame changes are their own inverse)."""
    q = np.asarray(q, dtype=float)
    comps = (q[:, 0], q[:, 1], q[:, 2], q[:, 3])
    out = quat.mul(quat.mul(_ENU_FROM_NED, comps), _FLU_FROM_FRD)  # type: ignore[arg-type]
    return np.stack([np.broadcast_to(np.asarray(c, dtype=float), q[:, 0].shape) for c in out], axis=-1)


# --- the estimate ----------------------------------------------------------------------------


def thrust_force_ned(q: Array, thrust_n: Array) -> Array:
    """``-T R(q) e3`` per sample (N, 3)."""
    comps = (q[:, 0], q[:, 1], q[:, 2], q[:, 3])
    z = quat.rotate(comps, E3)  # type: ignore[arg-type]
    axis = np.stack([np.broadcast_to(np.asarray(c, dtype=float), thrust_n.shape) for c in z], axis=-1)
    return -thrust_n[:, None] * axis


def _specific_force_ned(series: FlightSeries) -> Array:
    sf = series.specific_force_body_m_s2
    assert sf is not None
    q = series.q
    out = quat.rotate((q[:, 0], q[:, 1], q[:, 2], q[:, 3]), (sf[:, 0], sf[:, 1], sf[:, 2]))  # type: ignore[arg-type]
    return np.stack([np.asarray(c, dtype=float) for c in out], axis=-1)


def _acceleration_ned(series: FlightSeries) -> Array:
    """r_dd - g e3 (what the accelerometer measures, in NED), from whichever the log has."""
    if series.specific_force_body_m_s2 is not None:
        return _specific_force_ned(series)
    v = series.vel_ned_m_s
    assert v is not None
    a = np.gradient(v, series.t_s, axis=0)
    a[:, 2] -= GRAVITY_M_S2
    return a


def climb_m(series: FlightSeries) -> Array | None:
    """Height above the log's first sample, for a log that starts on the ground: the logged
    position, else the integral of the vertical velocity; None for a log that may start in the
    air, or with neither (an accelerometer alone cannot tell)."""
    if not series.starts_on_ground:
        return None
    if series.down_m is not None:
        return series.down_m[0] - series.down_m
    if series.vel_ned_m_s is None:
        return None
    vz = series.vel_ned_m_s[:, 2]
    steps = 0.5 * (vz[1:] + vz[:-1]) * np.diff(series.t_s)
    return -np.concatenate([[0.0], np.cumsum(steps)])


def never_airborne(series: FlightSeries) -> str | None:
    """Why the log shows no flight, or None: its land detector never says airborne, or (a log that
    starts on the ground) it never climbs NEVER_AIRBORNE_CLIMB_M above where it started. Land
    detectors say airborne on the ground too: ArduCopter's as soon as the throttle leaves its lower
    limit, PX4 1.11's during a spool-up. A log that may start in the air (a CSV) is judged by its
    land detector only, if it maps one."""
    if series.airborne is not None and not series.airborne.any():
        return f"{series.airborne_source} says landed throughout"
    h = climb_m(series)
    if h is not None and h.max() < NEVER_AIRBORNE_CLIMB_M:
        return (f"it never climbs {NEVER_AIRBORNE_CLIMB_M:g} m above where the log starts (at most "
                f"{max(h.max(), 0.0):.2f} m)")
    return None


def _fit_samples(series: FlightSeries) -> NDArray[np.bool_]:
    """The samples a thrust scale is fitted over: with some thrust, airborne by the land detector
    where the log has one, and NEVER_AIRBORNE_CLIMB_M above the start where the log starts on the
    ground (a vehicle on the ground is held up by the ground, and land detectors say airborne early)."""
    fit = series.thrust > AIRBORNE_THRUST
    if series.airborne is not None:
        fit = fit & series.airborne
    h = climb_m(series)
    if h is not None:
        fit = fit & (h >= NEVER_AIRBORNE_CLIMB_M)
    return fit


def estimate_thrust_scale(series: FlightSeries, mass_kg: float) -> float:
    """Newtons per unit of the log's thrust such that the mean vertical external force is zero:
    least squares of ``m (r_dd - g e3)_z = k (-u R(q) e3)_z`` over the airborne samples."""
    unit = thrust_force_ned(series.q, series.thrust)[:, 2]  # per unit of k
    meas = mass_kg * _acceleration_ned(series)[:, 2]
    air = _fit_samples(series)
    if air.sum() < 10:
        said = f"airborne by {series.airborne_source}, " if series.airborne is not None else ""
        said += f"{NEVER_AIRBORNE_CLIMB_M:g} m above the start, " if climb_m(series) is not None else ""
        raise ValueError(f"{series.source}: too few samples {said}with thrust above {AIRBORNE_THRUST:g} "
                         f"({int(air.sum())}) to estimate the thrust scale: give it")
    return float(np.dot(meas[air], unit[air]) / np.dot(unit[air], unit[air]))


def series_thrust_scale(series: FlightSeries, scale: ThrustScale) -> float:
    """``scale`` in newtons per unit of the log's thrust: a total scale divided among the log's
    motors when its thrust is a sum of motor commands, a per-motor scale multiplied by them when
    its thrust is the collective."""
    if scale.per_motor == series.thrust_per_motor:
        return scale.newtons
    n = series.motor_count
    if n is None:
        give = "per motor" if series.thrust_per_motor else "total"
        raise ValueError(f"{series.source}: the log does not say how many motors there are, so a "
                         f"{scale.describe()} thrust scale cannot be converted: give it {give}")
    return scale.newtons / n if series.thrust_per_motor else scale.newtons * n


def estimate_force(
    series: FlightSeries,
    mass_kg: float,
    bandwidth_rad_s: float = 5.0,
    thrust_scale: ThrustScale | None = None,
    method: str = "auto",
    motor_time_constant_s: float = 0.0,
) -> ForceEstimate:
    """The external force (NED, N) over the flight; a log that never flew is a ValueError
    (:func:`never_airborne`).

    ``method``: 'accelerometer' (ForceObserver, (30)), 'velocity' (its momentum form, which
    needs no differentiation), or 'auto' (the accelerometer if logged). ``bandwidth_rad_s`` is
    the observer's Gamma: the estimate is the true force through a first-order low-pass of it.
    ``motor_time_constant_s``: when the log holds motor *commands*, the first-order lag through
    which the rotors follow them (PX4 SIH: SIH_T_TAU), so that the force is the one produced.
    """
    if method == "auto":
        method = "accelerometer" if series.specific_force_body_m_s2 is not None else "velocity"
    if method == "accelerometer" and series.specific_force_body_m_s2 is None:
        raise ValueError("the log has no accelerometer; use method='velocity'")
    if method == "velocity" and series.vel_ned_m_s is None:
        raise ValueError("the log has no velocity; use method='accelerometer'")
    if method not in ("accelerometer", "velocity"):
        raise ValueError(f"unknown method {method!r}")
    why = never_airborne(series)
    if why is not None:
        raise ValueError(f"{series.source}: never airborne: {why}; on the ground the force is the ground's, "
                         "not a disturbance")
    estimated = False
    if series.thrust_is_newtons:
        scale, thrust_n = None, series.thrust
    else:
        if thrust_scale is None:
            scale, estimated = estimate_thrust_scale(series, mass_kg), True
        else:
            scale = series_thrust_scale(series, thrust_scale)
        thrust_n = series.thrust * scale
    t = series.t_s
    if motor_time_constant_s > 0.0:  # a log of commands: the rotors reach them through their lag
        lagged = np.empty_like(thrust_n)
        lagged[0] = thrust_n[0]
        for k in range(1, len(t)):
            a = 1.0 - math.exp(-max(t[k] - t[k - 1], 0.0) / motor_time_constant_s)
            lagged[k] = lagged[k - 1] + a * (thrust_n[k - 1] - lagged[k - 1])
        thrust_n = lagged
    force = thrust_force_ned(series.q, thrust_n)
    out = np.zeros((len(t), 3))
    gains = (bandwidth_rad_s,) * 3
    if method == "accelerometer":
        sf = _specific_force_ned(series)
        obs = ForceObserver(mass_kg, gains)
        for k in range(1, len(t)):
            dt = float(t[k] - t[k - 1])
            if dt <= 0.0:  # a repeated stamp (a vehicle waiting, a log writing twice): nothing new
                out[k] = out[k - 1]
                continue
            # the acceleration over step k-1 -> k was produced by the force of sample k-1
            out[k] = obs.update(tuple(sf[k]), tuple(force[k - 1]), dt)  # type: ignore[arg-type]
    else:
        v = series.vel_ned_m_s
        assert v is not None
        mom = MomentumObserver(mass_kg, gains)
        g = (0.0, 0.0, GRAVITY_M_S2)
        mom.update(tuple(v[0]), tuple(force[0]), g, 1.0)  # type: ignore[arg-type]
        for k in range(1, len(t)):
            dt = float(t[k] - t[k - 1])
            if dt <= 0.0:
                out[k] = out[k - 1]
                continue
            out[k] = mom.update(tuple(v[k]), tuple(force[k - 1]), g, dt)  # type: ignore[arg-type]
    return ForceEstimate(t, out, scale, estimated, method, series.truth_force_ned_n, series.thrust_per_motor,
                         series.motor_count, series.airborne, series.airborne_source)


def write_csv(est: ForceEstimate, path: str | Path) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        head = ["t_s", "force_north_n", "force_east_n", "force_down_n"]
        if est.truth_force_ned_n is not None:
            head += ["truth_north_n", "truth_east_n", "truth_down_n"]
        if est.airborne is not None:
            head += ["airborne"]  # the land detector's word: on the ground the force is the ground's
        w.writerow(head)
        for k in range(len(est.t_s)):
            row = [f"{est.t_s[k]:.4f}", *(f"{x:.4f}" for x in est.force_ned_n[k])]
            if est.truth_force_ned_n is not None:
                row += [f"{x:.4f}" for x in est.truth_force_ned_n[k]]
            if est.airborne is not None:
                row.append("1" if est.airborne[k] else "0")
            w.writerow(row)


def plot(est: ForceEstimate, path: str | Path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for i, (ax, name) in enumerate(zip(axes, ("north", "east", "down"))):
        ax.plot(est.t_s, est.force_ned_n[:, i], lw=1.0, label="estimate")
        if est.truth_force_ned_n is not None:
            ax.plot(est.t_s, est.truth_force_ned_n[:, i], "k--", lw=0.8, label="truth")
        if est.airborne is not None:
            ax.fill_between(est.t_s, 0, 1, where=~est.airborne, transform=ax.get_xaxis_transform(),
                            color="0.85", lw=0, label="landed")
        ax.set_ylabel(f"{name} [N]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    axes[-1].set_xlabel("t [s]")
    scale = "" if est.thrust_scale_n is None else (
        f", thrust scale {est.thrust_scale_n:.2f} N {'per motor' if est.thrust_per_motor else 'total'}"
        f"{' (estimated)' if est.thrust_scale_estimated else ''}")
    fig.suptitle(f"{title}\nexternal force ({est.method}{scale})" if title else f"external force ({est.method}{scale})")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def rms(x: Sequence[float] | Array) -> float:
    a = np.asarray(x, dtype=float)
    return float(math.sqrt(np.mean(a * a))) if a.size else math.nan
