"""Whole-mission checks shared by every loader: names, counts, the envelope, the safety volume,
the order of the steps and the path they fly. Pure: a :class:`Mission` in, nothing or a
:class:`~.envelope.Problem` (key and reason) out; the loader that read the file adds its line.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, Sequence

from companion.control.params import TrajectoryParams
from companion.control.position import POSITION_CONTROLLERS
from companion.control.vector import Vec3

from .envelope import (
    MAX_FENCE_CORNERS,
    MAX_FENCE_DISTANCE_M,
    MAX_FENCE_VERTICES,
    MAX_FENCES,
    MAX_NAME_CHARS,
    MAX_STEPS,
    MAX_TEXT_CHARS,
    MAX_WAYPOINTS,
    MIN_HEIGHT_M,
    Problem,
    check_range,
    is_safe_component,
)
from .model import ACTIONS, ALLOWED, Mission, Step
from .safety import VOLUME_SHAPES, SafetyVolume, polygon_is_simple

__all__ = ["validate", "check_volume", "extent", "RANGE_CHECKED_ELSEWHERE", "STEP_NUMBERS", "leg_time_s"]

STEP_NUMBERS = ("altitude_m", "duration_s", "speed_m_s", "tolerance_m", "hold_s", "timeout_s", "yaw_deg", "value")
"""a step's numbers with an envelope row (``steps[].<key>``), checked where the action uses them"""

RANGE_CHECKED_ELSEWHERE = ("steps", "safety.volume.north_m", "safety.volume.east_m", "safety.volume.circles",
                           "safety.volume.polygons")
"""fields whose numbers have a dedicated check here rather than one envelope row each"""

SETTLE_BANDWIDTHS = 14.0
"""the reference filter settles within this many 1/bandwidth after braking (measured over the envelope)"""
FILTER_JERK_PER_ACCEL_BANDWIDTH = 1.0
FILTER_ACCEL_PER_BANDWIDTH_SPEED = 0.5

_PARAM_ID = re.compile(r"[A-Za-z0-9_]{1,16}")


def validate(m: Mission) -> None:
    """Raise :class:`Problem` for the first thing about ``m`` that must not fly."""
    _check_text(m)
    _check_counts(m.steps)
    _walk_numbers(m, "")
    for i, s in enumerate(m.steps):
        for k in STEP_NUMBERS:
            v = getattr(s, k)
            if k in ALLOWED[s.action] and v is not None:
                check_range(f"steps[{i}].{k}", v, f"steps[].{k}")
    _check_across(m)
    check_volume(m.safety.volume, "safety.volume")
    _check_order(m.steps)
    _check_path(m)


def _text_problem(text: object, max_chars: int) -> str | None:
    if not isinstance(text, str):
        return f"expected a string, got {text!r}"
    if len(text) > max_chars:
        return f"expected at most {max_chars} characters, got {len(text)}"
    if not text.isprintable():
        bad = next(c for c in text if not c.isprintable())
        return f"expected printable text on one line, got the control character {bad!r}"
    return None


def _check_text(m: Mission) -> None:
    if not is_safe_component(m.name):
        raise Problem("name", f"expected 1..{MAX_NAME_CHARS} letters, digits, '-', '_' or '.' (not first, no '..'): "
                      f"the name becomes part of the flight record's folder; got {m.name[:80]!r}")
    why = _text_problem(m.description, MAX_TEXT_CHARS)
    if why:
        raise Problem("description", why)
    if m.controller.position not in POSITION_CONTROLLERS:
        raise Problem("controller.position", f"expected one of {', '.join(POSITION_CONTROLLERS)}, "
                      f"got {m.controller.position!r}")
    for i, s in enumerate(m.steps):
        if s.action not in ACTIONS:
            raise Problem(f"steps[{i}].action", f"expected one of {', '.join(ACTIONS)}, got {s.action!r}")
        why = _text_problem(s.name, MAX_NAME_CHARS) or ("expected no '|' (the summary is a table)" if "|" in s.name
                                                         else None)
        if why:
            raise Problem(f"steps[{i}].name", why)
        if s.action == "set_param" and not _PARAM_ID.fullmatch(s.param):
            raise Problem(f"steps[{i}].param", f"expected a parameter name of 1..16 letters, digits or '_', "
                          f"got {s.param[:40]!r}")


def _check_counts(steps: Sequence[Step]) -> None:
    if not steps:
        raise Problem("steps", "expected at least one step")
    if len(steps) > MAX_STEPS:
        raise Problem(f"steps[{MAX_STEPS}]", f"expected at most {MAX_STEPS} steps, got {len(steps)}")
    total = 0
    for i, s in enumerate(steps):
        total += len(s.waypoints)
        if total > MAX_WAYPOINTS:
            raise Problem(f"steps[{i}].waypoints", f"expected at most {MAX_WAYPOINTS} waypoints in a mission, "
                          f"got {total} by this step")


def _walk_numbers(obj: Any, prefix: str) -> None:
    for f in dataclasses.fields(obj):
        key = prefix + f.name
        if key in RANGE_CHECKED_ELSEWHERE:
            continue
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            _walk_numbers(v, key + ".")
        elif isinstance(v, bool | str) or v is None:
            continue
        elif isinstance(v, int | float):
            check_range(key, float(v))
        elif isinstance(v, tuple):
            for i, x in enumerate(v):
                check_range(f"{key}[{i}]", float(x), key)
        else:
            raise Problem(key, f"unexpected value {v!r}")


def leg_time_s(leg_m: float, speed_m_s: float, t: TrajectoryParams) -> float:
    """An upper bound on the time the velocity-limited reference takes to reach a waypoint
    ``leg_m`` away at ``speed_m_s`` and settle there (within 1 mm and 1 mm/s, which a goto waits
    for): cruise, accelerate and brake, the jerk limit, and the filter's settling. Measured with
    :class:`~companion.control.trajectory.ReferenceFilter` over a grid spanning the envelope, for
    parameters that keep the rules of :func:`_check_filter`."""
    return (leg_m / speed_m_s + speed_m_s / t.max_accel_m_s2 + t.max_accel_m_s2 / t.max_jerk_m_s3
            + SETTLE_BANDWIDTHS / t.bandwidth_rad_s)


def _filter_speed_problem(speed: float, t: TrajectoryParams) -> str | None:
    """The reference filter overshoots a waypoint (by metres) or circles it for ever when it
    cannot brake from its speed within its bandwidth: accel >= 0.5 bandwidth speed keeps it on the
    straight line to the waypoint (measured: under 1 cm off it over the envelope)."""
    need = FILTER_ACCEL_PER_BANDWIDTH_SPEED * t.bandwidth_rad_s * speed
    if t.max_accel_m_s2 < need * (1.0 - 1e-9):  # on the bound is fine (and the bound's rounding)
        return (f"expected at most {t.max_accel_m_s2 / (FILTER_ACCEL_PER_BANDWIDTH_SPEED * t.bandwidth_rad_s):.3g} "
                f"m/s (2 trajectory.max_accel_m_s2 / bandwidth_rad_s): faster, the reference cannot brake within "
                f"its bandwidth, overshoots the waypoint or circles it for ever; got {speed:g} m/s")
    return None


def _check_filter(t: TrajectoryParams) -> None:
    if t.max_jerk_m_s3 < FILTER_JERK_PER_ACCEL_BANDWIDTH * t.max_accel_m_s2 * t.bandwidth_rad_s * (1.0 - 1e-9):
        raise Problem("trajectory.max_jerk_m_s3", f"expected at least max_accel_m_s2 * bandwidth_rad_s = "
                      f"{t.max_accel_m_s2 * t.bandwidth_rad_s:.3g} m/s^3: with less, the reference overshoots and "
                      f"circles a waypoint for ever; got {t.max_jerk_m_s3:g}")
    why = _filter_speed_problem(t.max_speed_m_s, t)
    if why:
        raise Problem("trajectory.max_speed_m_s", why)


def _check_across(m: Mission) -> None:
    t = m.thrust.thrust_max_n
    if t > 0.0:
        hover = m.vehicle.weight_n / t
        if not 0.05 <= hover <= 0.9:
            raise Problem("thrust.thrust_max_n", f"expected a thrust that puts the hover throttle within 0.05..0.9 "
                          f"(mass_kg * gravity / thrust_max_n), got {hover:.3g} for {t:g} N and "
                          f"{m.vehicle.mass_kg:g} kg")
    s = m.safety
    if s.stale_hold_s < s.telemetry_timeout_s:
        raise Problem("safety.stale_hold_s", f"expected at least telemetry_timeout_s ({s.telemetry_timeout_s:g} s): "
                      f"the hold comes after the setpoints stop, got {s.stale_hold_s:g} s")
    if s.link_lost_s < s.stale_hold_s:
        raise Problem("safety.link_lost_s", f"expected at least stale_hold_s ({s.stale_hold_s:g} s): the flight "
                      f"gives up after it asked for a hold, got {s.link_lost_s:g} s")
    _check_filter(m.trajectory)
    v = m.vehicle
    if v.rotor_speed_min_rad_s >= v.rotor_speed_max_rad_s:
        raise Problem("vehicle.rotor_speed_max_rad_s", f"expected more than rotor_speed_min_rad_s "
                      f"({v.rotor_speed_min_rad_s:g}), got {v.rotor_speed_max_rad_s:g}")


def _finite(*xs: object) -> bool:
    return all(isinstance(x, int | float) and math.isfinite(x) for x in xs)


def check_volume(vol: SafetyVolume, key: str) -> None:
    """The volume itself: its shape, box, fences, and home inside it."""
    if vol.shape not in VOLUME_SHAPES:
        raise Problem(f"{key}.shape", f"expected one of {', '.join(VOLUME_SHAPES)}, got {vol.shape!r}")
    check_range(f"{key}.max_distance_m", vol.max_distance_m, "safety.volume.max_distance_m")
    check_range(f"{key}.max_altitude_m", vol.max_altitude_m, "safety.volume.max_altitude_m")
    for axis in ("north_m", "east_m"):
        span = getattr(vol, axis)
        if vol.shape == "box":
            if span is None:
                raise Problem(f"{key}.shape", f"a box needs {axis} = [min, max] (metres from home)")
            for i in range(2):
                check_range(f"{key}.{axis}[{i}]", span[i], f"safety.volume.{axis}")
            if not span[0] < 0.0 < span[1]:
                raise Problem(f"{key}.{axis}", f"expected [min, max] with min < 0 < max (home inside the box), "
                              f"got {list(span)}")
        elif span is not None:
            raise Problem(f"{key}.{axis}", "only for shape = \"box\"")
    if len(vol.circles) + len(vol.polygons) > MAX_FENCES:
        raise Problem(key, f"expected at most {MAX_FENCES} fences, got {len(vol.circles) + len(vol.polygons)}")
    for i, c in enumerate(vol.circles):
        ck = f"{key}.circles[{i}]"
        if not _finite(*c.center_ne_m) or math.hypot(*c.center_ne_m) > MAX_FENCE_DISTANCE_M:
            raise Problem(f"{ck}.center_ne_m", f"expected a centre within {MAX_FENCE_DISTANCE_M:g} m of home, "
                          f"got {list(c.center_ne_m)}")
        check_range(f"{ck}.radius_m", c.radius_m, "safety.volume.circles[].radius_m")
    corners = sum(len(p.vertices_ne_m) for p in vol.polygons)
    if corners > MAX_FENCE_CORNERS:
        raise Problem(f"{key}.polygons", f"expected at most {MAX_FENCE_CORNERS} corners in all, got {corners}")
    for i, p in enumerate(vol.polygons):
        pk = f"{key}.polygons[{i}].vertices_ne_m"
        if not 3 <= len(p.vertices_ne_m) <= MAX_FENCE_VERTICES:
            raise Problem(pk, f"expected 3..{MAX_FENCE_VERTICES} corners, got {len(p.vertices_ne_m)}")
        for j, v in enumerate(p.vertices_ne_m):
            if not _finite(*v) or math.hypot(*v) > MAX_FENCE_DISTANCE_M:
                raise Problem(f"{pk}[{j}]", f"expected a corner within {MAX_FENCE_DISTANCE_M:g} m of home, "
                              f"got {list(v)}")
        if not polygon_is_simple(p.vertices_ne_m):
            raise Problem(pk, "expected a simple polygon (its edges do not cross, no corner twice)")
    why = vol.breach((0.0, 0.0, 0.0))
    if why is not None:
        raise Problem(key, f"home (where the vehicle arms) must be inside the volume: {why}")


def _check_order(steps: Sequence[Step]) -> None:
    """Offboard flying needs an 'offboard' step first, which needs to be airborne; a mission that
    takes off ends on the ground."""
    airborne = offboard = False
    for i, s in enumerate(steps):
        key = f"steps[{i}]"
        if s.action == "takeoff":
            if airborne:
                raise Problem(key, "already airborne: another 'takeoff' needs a 'land' step before it")
            airborne = True
        elif s.action == "offboard":
            if not airborne:
                raise Problem(key, "an 'offboard' step needs a 'takeoff' step before it")
            offboard = True
        elif s.action in ("hold", "goto") and not offboard:
            raise Problem(key, f"a {s.action!r} step needs an 'offboard' step before it")
        elif s.action == "land":
            airborne = offboard = False
    if airborne:
        raise Problem(f"steps[{len(steps) - 1}]", "the mission ends in the air: expected a 'land' step last")


def _fmt(p: Vec3) -> str:
    return "(" + ", ".join(f"{float(c):.1f}" for c in p) + ")"


def _check_path(m: Mission) -> None:
    """Every position the mission flies to, and the straight path there, inside the volume."""
    vol = m.safety.volume
    pos: Vec3 = (0.0, 0.0, 0.0)
    settled: Vec3 = pos
    """where the reference is known to have arrived: a hold too short to reach its position leaves
    it anywhere between there and ``pos``, and the next leg may start from either end"""

    def go(target: Vec3, key: str, what: str) -> None:
        nonlocal pos
        if not _finite(*target):
            raise Problem(key, f"expected finite [north, east, down] metres, got {list(target)}")
        if target[2] > 0.0:
            raise Problem(key, f"down = {target[2]:g} m is below the ground (NED: up is negative)")
        if target[2] > -MIN_HEIGHT_M:
            raise Problem(key, f"down = {target[2]:g} m is {-target[2]:g} m above home; expected at least "
                          f"{MIN_HEIGHT_M:g} m (down <= -{MIN_HEIGHT_M:g})")
        why = vol.breach(target)
        if why is None:
            why = vol.segment_breach(pos, target)
            if why is not None:
                why = f"from {_fmt(pos)}: {why}"
        if why is not None:
            raise Problem(key, f"{what} {_fmt(target)} m is outside the safety volume ({vol.describe()}): {why}")
        pos = target

    for i, s in enumerate(m.steps):
        key = f"steps[{i}]"
        if s.action == "takeoff":
            go((pos[0], pos[1], -s.altitude_m), f"{key}.altitude_m", "the take-off to")
            settled = pos
        elif s.action == "hold":
            if s.position_ned_m is not None:
                go(s.position_ned_m, f"{key}.position_ned_m", "the hold position")
            far = math.dist(settled, pos)
            if s.duration_s >= leg_time_s(far, m.trajectory.max_speed_m_s, m.trajectory):
                settled = pos
        elif s.action == "goto":
            speed = s.speed_m_s if s.speed_m_s is not None else m.trajectory.max_speed_m_s
            why = _filter_speed_problem(speed, m.trajectory) if s.speed_m_s is not None else None
            if why:
                raise Problem(f"{key}.speed_m_s", why)
            for j, wp in enumerate(s.waypoints):
                start = pos
                if settled != pos:  # the reference may still be short of the last hold's position
                    why = vol.segment_breach(settled, wp)
                    if why is not None:
                        raise Problem(f"{key}.waypoints[{j}]", f"the waypoint {_fmt(wp)} m from {_fmt(settled)}, "
                                      f"where the reference may still be: outside the safety volume "
                                      f"({vol.describe()}): {why}")
                go(wp, f"{key}.waypoints[{j}]", "the waypoint")
                leg = max(math.dist(start, wp), math.dist(settled, wp))
                settled = wp
                need = leg_time_s(leg, speed, m.trajectory)
                if s.timeout_s < need:
                    raise Problem(f"{key}.timeout_s", f"expected at least {math.ceil(need)} s to fly the {leg:.1f} m "
                                  f"to waypoint {j} at {speed:g} m/s and settle there, got {s.timeout_s:g} s")
        elif s.action == "land":
            pos = (pos[0], pos[1], 0.0)


def extent(m: Mission) -> tuple[float, float]:
    """How far from home [m] and how high above it [m] the mission's positions go (the take-off
    heights, hold positions and waypoints), for people checking a mission."""
    far = high = 0.0
    for s in m.steps:
        points = list(s.waypoints) + ([s.position_ned_m] if s.position_ned_m is not None else [])
        for p in points:
            far, high = max(far, math.hypot(float(p[0]), float(p[1]))), max(high, -float(p[2]))
        if s.action == "takeoff":
            high = max(high, s.altitude_m)
    return far, high
