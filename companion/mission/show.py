"""What ``companion check`` tells people about a mission it accepted: the steps as they will be
flown (in local NED around home, the frame a ``.plan`` is converted to), the fences, and a warning
for missions flown too low for a vehicle that knows its height from GPS. Pure: a
:class:`~.model.Mission` in, lines of text out.
"""

from __future__ import annotations

import math

from companion.control.vector import Vec3

from .model import Mission, Step

__all__ = ["GPS_MIN_HEIGHT_M", "GPS_SAFE_MISSION", "steps_in_ned", "lowest_height_m", "gps_height_warning"]

GPS_HEIGHT_ERROR_M = 1.6
"""how far a GPS-positioned vehicle's height estimate was off its true height: PX4 v1.16's EKF2 on
SIH's GPS and barometer, against SIH's GPS altitude averaged over 1 s, -1.55..+1.62 m in 28 flights
(docs/autopilots.md, "Ground contact, not a simulator fault")"""
GPS_MIN_HEIGHT_M = 3.0
"""the lowest height the companion recommends flying a GPS-positioned vehicle at: the height error
(1.6 m) and as much again for tracking and a landing gear. Measured on PX4 SIH: flown at 1.5 m, the
true height dipped to 0.44-0.68 m in six of twelve squares and to the ground in one; flown at 5 m,
it never went below 3.2 m (1.8 m under the setpoint), so at 3 m a vehicle keeps about a metre"""
GPS_SAFE_MISSION = "missions/square_gps.toml"
"""the bundled mission for GPS-positioned vehicles (PX4 and ArduPilot SITL): the square, 5 m up"""


def _ned(p: Vec3) -> str:
    return "(" + ", ".join(f"{float(c):.1f}" for c in p) + ")"


def _step_line(i: int, s: Step, m: Mission) -> list[str]:
    head = f"  steps[{i}] {s.name}: {s.action}"
    if s.action == "takeoff":
        return [f"{head} to {s.altitude_m:g} m above home (NED down {-s.altitude_m:g})"]
    if s.action in ("hold", "wait"):
        where = f" at NED {_ned(s.position_ned_m)} m" if s.action == "hold" and s.position_ned_m is not None else ""
        return [f"{head} {s.duration_s:g} s{where}"]
    if s.action == "goto":
        speed = (f"{s.speed_m_s:g} m/s" if s.speed_m_s is not None
                 else f"{m.trajectory.max_speed_m_s:g} m/s (trajectory.max_speed_m_s)")
        lines = [f"{head} at {speed}, within {s.tolerance_m:g} m, hold {s.hold_s:g} s, timeout {s.timeout_s:g} s"]
        lines += [f"      waypoints[{j}] NED {_ned(wp)} m" for j, wp in enumerate(s.waypoints)]
        return lines
    if s.action == "set_param":
        return [f"{head} {s.param} = {s.value:g}{' (simulator only)' if s.sim_only else ''}"]
    return [head]


def steps_in_ned(m: Mission) -> list[str]:
    """One line per step (and per waypoint) with positions in metres north, east, down of home,
    then the fences' corners and centres in metres north, east of home."""
    lines = ["  NED: metres north, east and down of home (where the vehicle arms): 10 m up is down -10"]
    for i, s in enumerate(m.steps):
        lines += _step_line(i, s, m)
    vol = m.safety.volume
    for i, c in enumerate(vol.circles):
        kind = "inclusion" if c.inclusion else "exclusion"
        lines.append(f"  safety.volume.circles[{i}] {kind}: centre NE ({c.center_ne_m[0]:.1f}, "
                     f"{c.center_ne_m[1]:.1f}) m, radius {c.radius_m:g} m")
    for i, p in enumerate(vol.polygons):
        kind = "inclusion" if p.inclusion else "exclusion"
        corners = " ".join(f"({v[0]:.1f}, {v[1]:.1f})" for v in p.vertices_ne_m)
        lines.append(f"  safety.volume.polygons[{i}] {kind}: corners NE {corners} m")
    return lines


def lowest_height_m(m: Mission) -> float | None:
    """The lowest height above home [m] the mission flies at in the air: its take-off heights, hold
    positions and waypoints (None if it never takes off)."""
    heights: list[float] = []
    for s in m.steps:
        if s.action == "takeoff":
            heights.append(float(s.altitude_m))
        points = list(s.waypoints) + ([s.position_ned_m] if s.position_ned_m is not None else [])
        heights += [-float(p[2]) for p in points]
    finite = [h for h in heights if math.isfinite(h)]
    return min(finite) if finite else None


def gps_height_warning(m: Mission) -> str | None:
    """A warning if the mission flies lower than :data:`GPS_MIN_HEIGHT_M`: fine for the bundled
    vehicle and motion capture (its height to a centimetre), not for a vehicle on GPS."""
    low = lowest_height_m(m)
    if low is None or low >= GPS_MIN_HEIGHT_M:
        return None
    return (f"flies as low as {low:g} m above home: fine for the bundled vehicle (motion capture), too low for one "
            f"positioned by GPS, whose height can be {GPS_HEIGHT_ERROR_M:g} m off (docs/autopilots.md): fly PX4 or "
            f"ArduPilot SITL {GPS_MIN_HEIGHT_M:g} m up or more, e.g. {GPS_SAFE_MISSION} (5 m)")
