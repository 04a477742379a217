"""The mission envelope: every number a mission file may set, with its range and unit, in one table.

A mission outside it is refused by ``companion check`` and ``companion fly`` alike (they share
:func:`companion.mission.load_mission`). The ranges are wide enough for any multicopter the
companion is meant for and narrow enough that no value switches a failsafe off or makes it absurd
(a telemetry timeout of 0 or of an hour, a tilt limit beyond 70 degrees, a rate limit beyond a
gyro's range). docs/missions.md shows this table as :func:`envelope_markdown` renders it.

Besides the numbers, a file is bounded in size, nesting and counts (``MAX_*``), and its names in
the characters they may use (:func:`safe_component`, since a mission's name becomes part of the
folder the flight writes its record to).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

__all__ = [
    "Problem", "Range", "ENVELOPE", "CROSS_RULES", "MAX_FILE_BYTES", "MAX_NESTING", "MAX_STEPS", "MAX_WAYPOINTS",
    "MAX_PLAN_ITEMS", "MAX_FENCES", "MAX_FENCE_VERTICES", "MAX_FENCE_CORNERS", "MAX_NAME_CHARS", "MAX_TEXT_CHARS",
    "MIN_HEIGHT_M", "MAX_FENCE_DISTANCE_M", "safe_component", "is_safe_component", "check_range", "envelope_markdown",
]


class Problem(ValueError):
    """A mission that must not fly: ``key`` (dotted path, ``steps[2].speed_m_s``) and the reason,
    which says what was expected. The loaders add the file and the line (:class:`ConfigError`)."""

    def __init__(self, key: str, reason: str) -> None:
        super().__init__(f"{key}: {reason}")
        self.key = key
        self.reason = reason


@dataclass(frozen=True)
class Range:
    lo: float
    hi: float
    unit: str
    why: str
    zero_means: str = ""
    """if set, 0 is accepted too and means this (e.g. 'ask the vehicle')"""
    degrees: bool = False
    """a value in radians whose range reads better in degrees"""

    def accepts(self, x: float) -> bool:
        return math.isfinite(x) and (self.lo <= x <= self.hi or (bool(self.zero_means) and x == 0.0))

    def text(self) -> str:
        """The range for people: ``0.05..2 s``, ``5..70 deg, given in rad``, ``..., or 0 (meaning)``."""
        if self.degrees:
            unit = self.unit.replace("rad", "deg")
            r = f"{_num(math.degrees(self.lo))}..{_num(math.degrees(self.hi))} {unit}, given in {self.unit}"
        else:
            r = f"{_num(self.lo)}..{_num(self.hi)}" + (f" {self.unit}" if self.unit else "")
        return r + (f", or 0 ({self.zero_means})" if self.zero_means else "")


def _num(x: float) -> str:
    return str(int(round(x))) if abs(x - round(x)) < 1e-9 * max(1.0, abs(x)) and abs(x) < 1e9 else f"{x:g}"


MIN_HEIGHT_M = 0.3
"""the lowest a take-off, hold or waypoint may be above home [m]: below is the ground"""


def _deg(lo: float, hi: float, unit: str, why: str) -> Range:
    return Range(math.radians(lo), math.radians(hi), unit, why, degrees=True)


ENVELOPE: dict[str, Range] = {
    # key: the dotted path in the file; `steps[]` is every step that uses the key
    "controller.rate_hz": Range(10, 250, "Hz", "the control loop in vehicle time: the range the companion is built "
                                "and tested for (fly's --rate too)"),
    "vehicle.mass_kg": Range(0.05, 30, "kg", "the controller's nominal mass: a multicopter, not a typo"),
    "vehicle.inertia_kg_m2": Range(1e-6, 10, "kg m^2", "principal moments of inertia"),
    "vehicle.arm_length_m": Range(0.02, 2, "m", "rotor arm"),
    "vehicle.k_thrust_n_s2": Range(1e-9, 1e-2, "N s^2", "rotor thrust coefficient"),
    "vehicle.k_torque_nm_s2": Range(1e-12, 1e-3, "N m s^2", "rotor drag-torque coefficient"),
    "vehicle.rotor_speed_min_rad_s": Range(0, 1e4, "rad/s", "idle rotor speed"),
    "vehicle.rotor_speed_max_rad_s": Range(10, 1e4, "rad/s", "full rotor speed"),
    "vehicle.gravity_m_s2": Range(9.76, 9.84, "m/s^2", "Earth's surface gravity (9.78 at the equator, 9.83 at the "
                                  "poles): 98.1 is a typo, not a planet"),
    "gains.omega_c_rad_s": Range(0.1, 10, "rad/s", "position-loop bandwidth; it must stay below the attitude "
                                 "loop's (12 rad/s by default)"),
    "gains.observer_gain_rad_s": Range(0, 50, "rad/s", "force-observer bandwidth (0: no disturbance estimate)"),
    "gains.sliding_gain_rad_s": Range(0, 50, "rad/s", "sliding-mode gain"),
    "gains.boundary_layer_m_s": Range(0.01, 10, "m/s", "boundary layer; it divides the sliding variable, so "
                                      "not 0"),
    "gains.aibc_gamma_per_s": Range(0, 50, "1/s", "AIBC adaptation rate"),
    "gains.indi_filter_rad_s": Range(1, 100, "rad/s", "INDI low-pass on the measured acceleration and force; it "
                                     "must stay above the position loop and below the control rate"),
    "gains.observer_match_delay_s": Range(0, 0.5, "s", "delay of the force fed to the observer, to match a "
                                          "differentiated acceleration (0: none)"),
    "gains.observer_match_cutoff_hz": Range(1, 100, "Hz", "low-pass of that force, to match the differentiation's "
                                            "filters", zero_means="not filtered"),
    "gains.observer_match_order": Range(1, 4, "", "first-order stages of that low-pass"),
    "gains.integral_limit_m_s2": Range(0, 30, "m/s^2", "anti-windup bound of the integral term (3 g)"),
    "reference.tilt_max_rad": _deg(5, 70, "rad", "thrust direction from vertical"),
    "reference.min_up_force_fraction": Range(0.05, 1, "", "of the weight, always upwards"),
    "reference.rate_limit_rad_s": _deg(10, 2000, "rad/s", "body-rate command; 2000 deg/s is a gyro's full range"),
    "reference.rate_filter_time_constant_s": Range(0, 0.5, "s", "low-pass on the rate command (0: none)"),
    "trajectory.max_speed_m_s": Range(0.1, 15, "m/s", "reference speed between waypoints"),
    "trajectory.max_accel_m_s2": Range(0.1, 20, "m/s^2", "reference acceleration (2 g)"),
    "trajectory.max_jerk_m_s3": Range(0.5, 500, "m/s^3", "reference jerk"),
    "trajectory.bandwidth_rad_s": Range(0.1, 5, "rad/s", "reference filter, stepped at the control rate (down "
                                        "to 10 Hz): above 0.5 per step it does not settle"),
    "trajectory.max_yaw_rate_rad_s": _deg(1, 360, "rad/s", "reference yaw rate"),
    "thrust.thrust_max_n": Range(0.1, 2000, "N", "thrust at full throttle", zero_means="ask the vehicle"),
    "thrust.hover_throttle": Range(0.05, 0.9, "", "normalised hover thrust; above 0.9 nothing is left to "
                                   "climb or correct with", zero_means="not given"),
    "safety.telemetry_timeout_s": Range(0.05, 2, "s", "position/attitude older than this stops the setpoints; 0 "
                                        "would stop them always, and beyond 2 s the vehicle flies blind"),
    "safety.stale_hold_s": Range(0.1, 10, "s", "stale telemetry this long also commands hold"),
    "safety.link_lost_s": Range(0.5, 30, "s", "no telemetry at all this long (wall time) ends the flight"),
    "safety.max_tilt_deg": Range(5, 70, "deg", "setpoint guard: tilt"),
    "safety.max_rate_deg_s": Range(10, 2000, "deg/s", "setpoint guard: body rate; 2000 deg/s is a gyro's full "
                                   "range"),
    "safety.volume.max_distance_m": Range(1, 1000, "m", "horizontal distance from home"),
    "safety.volume.max_altitude_m": Range(1, 120, "m", "height above home (120 m: the open-category ceiling)"),
    "safety.volume.north_m": Range(-1000, 1000, "m", "box: [min, max] north of home; min < 0 < max"),
    "safety.volume.east_m": Range(-1000, 1000, "m", "box: [min, max] east of home; min < 0 < max"),
    "safety.volume.circles[].radius_m": Range(1, 1000, "m", "fence circle"),
    "target.system_id": Range(1, 255, "", "the MAVLink system id of the vehicle to fly (PX4 MAV_SYS_ID, ArduPilot "
                              "SYSID_THISMAV)", zero_means="the only autopilot on the link"),
    "target.component_id": Range(1, 255, "", "its autopilot's component id (1 on PX4 and ArduPilot)",
                                 zero_means="that system's autopilot, whichever component"),
    "steps[].altitude_m": Range(MIN_HEIGHT_M, 120, "m", "take-off height above home"),
    "steps[].duration_s": Range(0.01, 3600, "s", "hold / wait"),
    "steps[].speed_m_s": Range(0.1, 15, "m/s", "goto speed (default: trajectory.max_speed_m_s)"),
    "steps[].tolerance_m": Range(0.05, 10, "m", "a waypoint is reached within this distance"),
    "steps[].hold_s": Range(0, 3600, "s", "stay at each waypoint"),
    "steps[].timeout_s": Range(1, 3600, "s", "per take-off, offboard switch, waypoint or landing"),
    "steps[].yaw_deg": Range(-360, 360, "deg", "hold heading"),
    "steps[].value": Range(-1e7, 1e7, "", "set_param value (MAVLink parameters are float32)"),
}

CROSS_RULES = (
    "`thrust.thrust_max_n`, if given, puts the hover throttle `vehicle.mass_kg * vehicle.gravity_m_s2 / "
    "thrust_max_n` within 0.05..0.9",
    "`safety.telemetry_timeout_s` <= `safety.stale_hold_s` <= `safety.link_lost_s`",
    "`vehicle.rotor_speed_min_rad_s` < `vehicle.rotor_speed_max_rad_s`",
    "every position of the mission (take-off height, hold positions, waypoints, and the straight paths between "
    f"them) lies in the safety volume and at least {MIN_HEIGHT_M:g} m above home (NED down <= -{MIN_HEIGHT_M:g})",
    "the waypoint reference settles on the straight line to a waypoint (else it overshoots by metres or circles "
    "it for ever): `trajectory.max_jerk_m_s3` >= `max_accel_m_s2 * bandwidth_rad_s`, and every speed "
    "(`trajectory.max_speed_m_s`, a goto's `speed_m_s`) <= `2 * max_accel_m_s2 / bandwidth_rad_s`",
    "a goto's `timeout_s` leaves time to fly each leg and settle: timeout_s >= leg / speed + speed / max_accel_m_s2 "
    "+ max_accel_m_s2 / max_jerk_m_s3 + 14 / bandwidth_rad_s",
    "order: `offboard` after `takeoff`; `hold`/`goto` after `offboard`; no `takeoff` while airborne; a mission "
    "that takes off ends with `land`",
)

MAX_FILE_BYTES = 1_000_000
"""a mission file is a few kB; a plan with a thousand waypoints is about 400 kB"""
MAX_NESTING = 16
"""brackets and braces inside one another (a mission needs 3)"""
MAX_STEPS = 1000
"""a soak test's ten hours of squares and holds is 960"""
MAX_WAYPOINTS = 2000
"""in the whole mission"""
MAX_PLAN_ITEMS = 2000
MAX_FENCES = 16
MAX_FENCE_VERTICES = 200
MAX_FENCE_CORNERS = 500
"""all polygons together: each path is checked against every edge"""
MAX_FENCE_DISTANCE_M = 2000.0
"""a fence's corners and centres, from home"""
MAX_NAME_CHARS = 64
MAX_TEXT_CHARS = 1000

_SAFE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")


def is_safe_component(text: str) -> bool:
    """Whether ``text`` can be one component of a file name as it is: letters, digits, '-', '_'
    and '.', not starting with '.', no '..', at most MAX_NAME_CHARS characters."""
    return (isinstance(text, str) and 0 < len(text) <= MAX_NAME_CHARS and _SAFE.fullmatch(text) is not None
            and ".." not in text)


def safe_component(text: str) -> str:
    """``text`` made safe as one component of a file name: every other character becomes '_',
    a leading '.' and any '..' too, cut to MAX_NAME_CHARS; empty becomes 'mission'.
    ``is_safe_component(safe_component(x))`` holds for every string."""
    s = re.sub(r"[^A-Za-z0-9_.\-]", "_", text)[:MAX_NAME_CHARS]
    while ".." in s:
        s = s.replace("..", "_.")
    if s.startswith("."):
        s = "_" + s[1:]
    return s or "mission"


def check_range(key: str, value: float, table_key: str | None = None) -> None:
    """Raise :class:`Problem` unless ``value`` is within the envelope row ``table_key`` (default: ``key``)."""
    row = ENVELOPE[table_key or key]
    if not row.accepts(value):
        shown = (f"{math.degrees(value):g} {row.unit.replace('rad', 'deg')} ({value:g} {row.unit})"
                 if row.degrees and math.isfinite(value) else f"{value:g}")
        raise Problem(key, f"expected {row.text()}, got {shown}")


def envelope_markdown() -> str:
    """The envelope as the Markdown table in docs/missions.md (a test keeps the two equal)."""
    lines = ["| key | range | why |", "|---|---|---|"]
    for key, row in ENVELOPE.items():
        lines.append(f"| `{key}` | {row.text()} | {row.why} |")
    lines += ["", "Rules across keys:", ""] + [f"- {rule}" for rule in CROSS_RULES]
    lines += ["", "| bound | value |", "|---|---|"]
    for name, value, unit in (
        ("file size", MAX_FILE_BYTES, "bytes"), ("nesting of [ ] and { }", MAX_NESTING, "levels"),
        ("steps", MAX_STEPS, ""), ("waypoints (whole mission)", MAX_WAYPOINTS, ""),
        ("`.plan` mission items", MAX_PLAN_ITEMS, ""), ("fences", MAX_FENCES, ""),
        ("corners per fence polygon", MAX_FENCE_VERTICES, ""), ("corners of all fence polygons", MAX_FENCE_CORNERS, ""),
        ("fence corner or centre from home", MAX_FENCE_DISTANCE_M, "m"),
        ("`name`, step names", MAX_NAME_CHARS, "characters"), ("`description`", MAX_TEXT_CHARS, "characters"),
    ):
        lines.append(f"| {name} | {_num(value)}{' ' + unit if unit else ''} |")
    return "\n".join(lines) + "\n"
