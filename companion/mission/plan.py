"""QGroundControl ``.plan`` import: the mission items and the geofence, converted to local NED
around the plan's home (``plannedHomePosition``, where the vehicle is to arm) by a flat-earth
projection on a sphere of the WGS-84 equatorial radius (the autopilots' own spheres differ by up to
0.11 %: about 1 m at the envelope's 1000 m).

Items, as QGroundControl writes them (``"type": "SimpleItem"``, 7 ``params``, ``frame``, and for
items with an altitude also ``AltitudeMode``, ``Altitude``, ``AMSLAltAboveTerrain``):

- 22 take-off: the altitude (param 7) in the item's frame; a take-off where the vehicle is;
- 16 waypoint: param 1 hold time [s], param 2 acceptance radius [m] (0: the step default), param 4
  yaw must be empty (null); 19 loiter-time is a waypoint whose param 1 is the hold time;
- 178 DO_CHANGE_SPEED: param 2 [m/s] is the speed of the waypoints that follow (-1: unchanged,
  -2: back to the mission default); speed type (param 1) 0 air or 1 ground speed (no difference for
  these setpoints); climb/descent speeds (2, 3) and a throttle (param 3) are refused;
- 93 NAV_DELAY: hold (or wait on the ground) param 1 seconds;
- 21 land: fly to its latitude/longitude at the current height (unless empty or 0/0), then land;
  20 RTL: fly home at the current height, then land. Nothing may follow either;
- camera and gimbal commands (and DO_LAND_START) leave the path alone: they are skipped and listed
  in the mission's description; any other command is refused with its name.

Altitude frames (``frame``): 3 relative to home (param 7 as it is); 0 AMSL (param 7 minus
``plannedHomePosition``'s altitude: 498 m with home at 488 m is 10 m above home); 10 terrain is
refused (the companion flies heights above home and has no terrain model). ``AltitudeMode`` must
agree with the frame (1 relative <-> 3, 2 AMSL <-> 0, 3 "calculated above terrain" <-> 0, whose
param 7 QGroundControl computed as AMSL from its terrain data and is flown as such; 4 terrain
frame <-> 10, refused), and ``Altitude`` with param 7 where the mode says they are the same number.

Geofence: every circle and polygon becomes a fence of the mission's safety volume, inclusion or
exclusion as flagged; with an inclusion fence the fence, not the default cylinder, bounds the
horizontal extent (up to the envelope's 1000 m). The height limit is the default volume's.
``geoFence.version`` 2 has ``circles`` and ``polygons``; version 1, QGroundControl's older fence,
one ``polygon`` of corners, the area to stay inside (an inclusion polygon). The plan file's
``version`` (1), ``mission.version`` (2) and ``geoFence.version`` are checked: any other is
refused by name. A plan without mission items (a fence, rally points) is no mission on its own:
a TOML mission with ``[[steps]]`` and ``plan = ...`` takes its fence.

Errors name the file, the JSON line, the item path (``mission.items[3].params[6]``) and what was
expected, values spelt as JSON (``null``, ``true``); checks after conversion (the volume, the
envelope) are reported against the item that produced the offending step. A plan flown alone
that leaves the default volume's ceiling or distance gets, as the error's ``hint``, the TOML to
write beside it (:func:`volume_hint`).

:func:`load_plan` flies a plan with the default controller, failsafes and volume;
:func:`import_plan` gives the converted steps and fences to a TOML mission that names the plan
(``plan = "survey.plan"``) and sets its own.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeGuard

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.config import ConfigError, read_text
from companion.control.params import TrajectoryParams
from companion.control.vector import Vec3
from companion.mavlink.commands import command_name

from .envelope import (
    ENVELOPE,
    MAX_FENCE_VERTICES,
    MAX_FENCES,
    MAX_FILE_BYTES,
    MAX_PLAN_ITEMS,
    MAX_WAYPOINTS,
    Problem,
    check_range,
    safe_component,
)
from .model import Mission, SafetyConfig, Step
from .safety import FenceCircle, FencePolygon, SafetyVolume, Vec2
from .validate import extent, leg_time_s, validate

__all__ = ["load_plan", "import_plan", "ImportedPlan", "volume_hint", "json_line", "EARTH_RADIUS_M", "COMMAND_NAMES"]

EARTH_RADIUS_M = 6378137.0
"""WGS-84 equatorial radius"""

Path_ = tuple[str | int, ...]
"""a place in the JSON document: ("mission", "items", 3, "params", 6)"""

TAKEOFF, WAYPOINT = mavlink.MAV_CMD_NAV_TAKEOFF, mavlink.MAV_CMD_NAV_WAYPOINT
LOITER_TIME = mavlink.MAV_CMD_NAV_LOITER_TIME
LAND, RTL, DELAY = mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_CMD_NAV_DELAY
CHANGE_SPEED = mavlink.MAV_CMD_DO_CHANGE_SPEED


def _named(notes: dict[int, str]) -> dict[int, str]:
    """command -> its name as pymavlink spells it, with the note in brackets if there is one"""
    return {cmd: command_name(cmd) + (f" ({note})" if note else "") for cmd, note in notes.items()}


SKIPPED = _named({
    mavlink.MAV_CMD_DO_LAND_START: "a marker", mavlink.MAV_CMD_DO_DIGICAM_CONTROL: "camera",
    mavlink.MAV_CMD_DO_MOUNT_CONTROL: "gimbal", mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST: "camera",
    mavlink.MAV_CMD_DO_SET_CAM_TRIGG_INTERVAL: "camera", mavlink.MAV_CMD_SET_CAMERA_MODE: "camera",
    mavlink.MAV_CMD_SET_CAMERA_ZOOM: "camera", mavlink.MAV_CMD_SET_CAMERA_FOCUS: "camera",
    mavlink.MAV_CMD_DO_GIMBAL_MANAGER_PITCHYAW: "gimbal", mavlink.MAV_CMD_DO_GIMBAL_MANAGER_CONFIGURE: "gimbal",
    mavlink.MAV_CMD_IMAGE_START_CAPTURE: "camera", mavlink.MAV_CMD_IMAGE_STOP_CAPTURE: "camera",
    mavlink.MAV_CMD_VIDEO_START_CAPTURE: "camera", mavlink.MAV_CMD_VIDEO_STOP_CAPTURE: "camera",
})
"""commands that leave the flight path alone: skipped, and listed in the description"""

COMMAND_NAMES = _named({
    mavlink.MAV_CMD_NAV_LOITER_UNLIM: "never ends", mavlink.MAV_CMD_NAV_LOITER_TURNS: "",
    mavlink.MAV_CMD_NAV_LOITER_TO_ALT: "", mavlink.MAV_CMD_NAV_SPLINE_WAYPOINT: "",
    mavlink.MAV_CMD_NAV_VTOL_TAKEOFF: "", mavlink.MAV_CMD_NAV_VTOL_LAND: "", mavlink.MAV_CMD_CONDITION_DELAY: "",
    mavlink.MAV_CMD_CONDITION_DISTANCE: "", mavlink.MAV_CMD_CONDITION_YAW: "", mavlink.MAV_CMD_DO_JUMP: "a loop",
    mavlink.MAV_CMD_DO_SET_HOME: "", mavlink.MAV_CMD_DO_SET_RELAY: "", mavlink.MAV_CMD_DO_SET_SERVO: "",
    mavlink.MAV_CMD_DO_REPEAT_SERVO: "", mavlink.MAV_CMD_DO_SET_ROI_LOCATION: "turns the vehicle",
    mavlink.MAV_CMD_DO_SET_ROI_NONE: "", mavlink.MAV_CMD_DO_SET_ROI: "turns the vehicle",
    mavlink.MAV_CMD_DO_GRIPPER: "", mavlink.MAV_CMD_DO_VTOL_TRANSITION: "",
})
"""unsupported commands named in the refusal"""

_RELATIVE = (mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
_AMSL = (mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT)
_TERRAIN = (mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT, mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT)
_MODE_FRAMES = {1: _RELATIVE, 2: _AMSL, 3: _AMSL, 4: _TERRAIN}
_MODE_NAMES = {1: "relative to launch", 2: "AMSL", 3: "calculated above terrain", 4: "terrain frame"}


def _key(where: Path_) -> str:
    out = ""
    for part in where:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


class _Refusal(Exception):
    def __init__(self, where: Path_, reason: str) -> None:
        super().__init__(reason)
        self.where = where
        self.reason = reason


def _json(x: object) -> str:
    """A value as the plan's JSON spells it (null, true, "text"), cut to 40 characters."""
    try:
        text = json.dumps(x)
    except (TypeError, ValueError):
        text = repr(x)
    return text if len(text) <= 40 else text[:40] + "..."


def _number(x: object) -> TypeGuard[float]:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


@dataclass
class _Waypoint:
    ned: Vec3
    speed_m_s: float | None
    speed_from: Path_ | None
    hold_s: float
    tolerance_m: float
    where: Path_


class _Converter:
    """Items in, steps out, and where each step came from (for the errors found after conversion)."""

    def __init__(self, home: list[Any], has_home_alt: bool) -> None:
        self.lat0, self.lon0 = float(home[0]), float(home[1])
        self.home_alt = float(home[2]) if has_home_alt else math.nan
        self.steps: list[Step] = []
        self.origin: dict[str, Path_] = {}
        self.pending: list[_Waypoint] = []
        self.speed: float | None = None
        self.speed_from: Path_ | None = None
        self.phase = "ground"  # -> "air" -> "done"
        self.ended_by: Path_ | None = None
        self.pos: Vec3 = (0.0, 0.0, 0.0)
        self.skipped: list[str] = []
        self.waypoints = 0
        """all the waypoints so far (MAX_WAYPOINTS bounds them)"""

    # --- geometry ---------------------------------------------------------------------------

    def ne(self, lat: float, lon: float) -> Vec2:
        dlon = (lon - self.lon0 + 180.0) % 360.0 - 180.0
        return (math.radians(lat - self.lat0) * EARTH_RADIUS_M,
                math.radians(dlon) * EARTH_RADIUS_M * math.cos(math.radians(self.lat0)))

    def coordinate(self, lat: object, lon: object, where: Path_) -> Vec2:
        if not (_number(lat) and _number(lon) and abs(lat) <= 90.0 and abs(lon) <= 180.0):
            raise _Refusal(where, f"expected latitude and longitude in degrees, got {_json([lat, lon])}")
        return self.ne(float(lat), float(lon))

    def height(self, item: dict[str, Any], where: Path_) -> float:
        """Param 7 as metres above home, from the item's frame (and its AltitudeMode, if any)."""
        frame, alt = item.get("frame"), item["params"][6]
        if not _number(alt):
            why = ""
            if alt is None and item.get("AltitudeMode") == 3:
                why = (": AltitudeMode 3 (calculated above terrain) without the altitude QGroundControl computes from "
                       "its terrain data (it had none when it saved the plan); open the plan in QGroundControl with "
                       "terrain data, or choose 'Relative to launch'")
            raise _Refusal(where + ("params", 6), f"expected an altitude in metres, got {_json(alt)}{why}")
        if "AltitudeMode" in item:
            mode = item["AltitudeMode"]
            if not isinstance(mode, int) or isinstance(mode, bool) or mode not in _MODE_FRAMES:
                raise _Refusal(where + ("AltitudeMode",), f"expected 1 (relative to launch), 2 (AMSL), 3 (calculated "
                               f"above terrain) or 4 (terrain frame), got {_json(mode)}")
            if frame not in _MODE_FRAMES[mode]:
                raise _Refusal(where + ("frame",), f"AltitudeMode {mode} ({_MODE_NAMES[mode]}) expects frame "
                               f"{_MODE_FRAMES[mode][0]}, got {_json(frame)}: the item contradicts itself")
            same = item.get("Altitude") if mode in (1, 2) else item.get("AMSLAltAboveTerrain") if mode == 3 else alt
            if not (_number(same) and abs(float(same) - float(alt)) <= 0.01):
                k = "Altitude" if mode in (1, 2) else "AMSLAltAboveTerrain"
                raise _Refusal(where + (k,), f"expected {alt!r}, the altitude of params[6] for AltitudeMode {mode} "
                               f"({_MODE_NAMES[mode]}), got {_json(same)}")
        if frame in _RELATIVE:
            return float(alt)
        if frame in _AMSL:
            if math.isnan(self.home_alt):
                raise _Refusal(("mission", "plannedHomePosition", 2), "expected home's altitude (AMSL, m): the plan "
                               f"has AMSL altitudes (item frame {frame})")
            return float(alt) - self.home_alt
        if frame in _TERRAIN:
            raise _Refusal(where + ("frame",), f"frame {frame} is terrain-relative (MAV_FRAME_GLOBAL_TERRAIN_ALT): the "
                           "companion flies heights above home and has no terrain model; in QGroundControl choose "
                           "'Relative to launch' or 'AMSL'")
        raise _Refusal(where + ("frame",), f"expected frame {_RELATIVE[0]} (relative to home), {_AMSL[0]} (AMSL) or "
                       f"{_TERRAIN[0]} (terrain), "
                       f"got {_json(frame)}")

    # --- items --------------------------------------------------------------------------------

    def item(self, item: object, where: Path_) -> None:
        if not isinstance(item, dict):
            raise _Refusal(where, f"expected a mission item (an object), got {_json(item)}")
        if item.get("type") == "ComplexItem":
            raise _Refusal(where + ("type",), f"a complex item ({_json(item.get('complexItemType'))}) is not "
                           "supported; expected simple items")
        if item.get("type") != "SimpleItem":
            raise _Refusal(where + ("type",), f"expected \"SimpleItem\", got {_json(item.get('type'))}")
        cmd, params = item.get("command"), item.get("params")
        if not isinstance(params, list) or len(params) != 7:
            raise _Refusal(where + ("params",), "expected 7 params (null for the unused ones)")
        for k, v in enumerate(params):
            if (v is not None and not isinstance(v, int | float)) or isinstance(v, bool):
                raise _Refusal(where + ("params", k), f"expected a number or null, got {_json(v)}")
        if not isinstance(cmd, int) or isinstance(cmd, bool):
            raise _Refusal(where + ("command",), f"expected a MAVLink command number, got {_json(cmd)}")
        if self.phase == "done":
            assert self.ended_by is not None
            raise _Refusal(where, f"nothing may follow the land or RTL item {_key(self.ended_by)}: the mission ends "
                           "there")
        if cmd in SKIPPED:
            self.skipped.append(f"{where[-1]} {SKIPPED[cmd]}")
        elif cmd == TAKEOFF:
            self.takeoff(item, params, where)
        elif cmd in (WAYPOINT, LOITER_TIME):
            self.waypoint(item, params, where, cmd)
        elif cmd == CHANGE_SPEED:
            self.change_speed(params, where)
        elif cmd == DELAY:
            self.delay(params, where)
        elif cmd in (LAND, RTL):
            self.finish(item, params, where, cmd)
        else:
            name = COMMAND_NAMES.get(cmd, "")
            raise _Refusal(where + ("command",), f"command {cmd}{' ' + name if name else ''} is not supported; "
                           f"expected {TAKEOFF} take-off, {WAYPOINT} waypoint, {LOITER_TIME} loiter time, "
                           f"{CHANGE_SPEED} change speed, {DELAY} delay, {LAND} land, {RTL} RTL, or a camera/gimbal "
                           "command (skipped)")

    def takeoff(self, item: dict[str, Any], params: list[Any], where: Path_) -> None:
        if self.phase != "ground":
            raise _Refusal(where, "a second take-off: expected one, before the waypoints")
        h = self.height(item, where)
        lat, lon = params[4], params[5]
        if lat is not None and lon is not None and (lat, lon) != (0, 0):
            off = math.hypot(*self.coordinate(lat, lon, where + ("params", 4)))
            if off > 5.0:
                raise _Refusal(where + ("params", 4), f"a take-off {off:.0f} m from plannedHomePosition: the vehicle "
                               "takes off where it is, expected within 5 m of home")
        self.add(Step("takeoff", "take-off", altitude_m=h), where, {"altitude_m": where + ("params", 6)})
        self.add(Step("offboard", "offboard"), where)
        self.phase = "air"
        self.pos = (0.0, 0.0, -h)

    def waypoint(self, item: dict[str, Any], params: list[Any], where: Path_, cmd: int) -> None:
        if self.phase != "air":
            raise _Refusal(where, f"a waypoint before the take-off item ({TAKEOFF}): expected the take-off first")
        if cmd == WAYPOINT and params[3] is not None and not math.isnan(params[3]):
            raise _Refusal(where + ("params", 3), f"a waypoint yaw is not supported; expected null (QGroundControl's "
                           f"empty heading), got {_json(params[3])}")
        n, e = self.coordinate(params[4], params[5], where + ("params", 4))
        h = self.height(item, where)
        hold = params[0] or 0.0
        if not 0.0 <= hold <= ENVELOPE["steps[].hold_s"].hi:
            raise _Refusal(where + ("params", 0), f"expected a hold time of {ENVELOPE['steps[].hold_s'].text()}, "
                           f"got {_json(hold)}")
        radius = params[1] if cmd == WAYPOINT and params[1] else Step.tolerance_m
        self.push(_Waypoint((n, e, -h), self.speed, self.speed_from, float(hold), float(radius), where))

    def change_speed(self, params: list[Any], where: Path_) -> None:
        kind, speed, throttle = params[0], params[1], params[2]
        if kind not in (0, 1):
            raise _Refusal(where + ("params", 0), f"expected speed type 0 (air) or 1 (ground), got {_json(kind)}: "
                           "climb and descent speeds are not supported")
        if throttle not in (None, -1, 0):
            raise _Refusal(where + ("params", 2), f"expected no throttle (-1), got {_json(throttle)}: a multicopter's "
                           "offboard flight sets no throttle")
        if speed == -1:
            return
        if speed == -2:
            self.speed, self.speed_from = None, where
            return
        try:
            check_range(_key(where + ("params", 1)), speed if _number(speed) else math.nan, "steps[].speed_m_s")
        except Problem as exc:
            raise _Refusal(where + ("params", 1), exc.reason) from None
        self.speed, self.speed_from = float(speed), where + ("params", 1)

    def delay(self, params: list[Any], where: Path_) -> None:
        seconds = params[0]
        if not _number(seconds) or seconds < 0:
            raise _Refusal(where + ("params", 0), f"expected a delay in seconds, got {_json(seconds)} (a time of "
                           "day is not supported)")
        if seconds == 0:
            return
        self.flush()
        action = "hold" if self.phase == "air" else "wait"
        self.add(Step(action, f"delay {seconds:g} s", duration_s=float(seconds)), where,
                 {"duration_s": where + ("params", 0)})

    def finish(self, item: dict[str, Any], params: list[Any], where: Path_, cmd: int) -> None:
        if self.phase != "air":
            raise _Refusal(where, "a land or RTL item before the take-off: expected the take-off first")
        if cmd == RTL:
            target: Vec2 | None = (0.0, 0.0)
        elif params[4] is None or params[5] is None or (params[4], params[5]) == (0, 0):
            target = None
        else:
            target = self.coordinate(params[4], params[5], where + ("params", 4))
        if target is not None:
            last = self.pending[-1].ned if self.pending else self.pos
            if math.dist(target, last[:2]) > Step.tolerance_m:
                self.push(_Waypoint((target[0], target[1], last[2]), self.speed, self.speed_from, 0.0,
                                    Step.tolerance_m, where))
        self.flush()
        self.add(Step("land", "return and land" if cmd == RTL else "land"), where)
        self.phase, self.ended_by = "done", where

    # --- steps --------------------------------------------------------------------------------

    def push(self, wp: _Waypoint) -> None:
        self.pending.append(wp)
        self.waypoints += 1

    def add(self, step: Step, where: Path_, fields: dict[str, Path_] | None = None) -> None:
        """Append ``step``, made from the item at ``where`` (its ``fields`` from those places)."""
        key = f"steps[{len(self.steps)}]"
        self.origin[key] = where
        for name, place in (fields or {}).items():
            self.origin[f"{key}.{name}"] = place
        self.steps.append(step)

    def flush(self) -> None:
        """Consecutive waypoints with the same speed, hold and radius become one goto step, its
        timeout long enough for its longest leg."""
        group: list[_Waypoint] = []
        for wp in self.pending:
            if group and (wp.speed_m_s, wp.hold_s, wp.tolerance_m) != (
                    group[0].speed_m_s, group[0].hold_s, group[0].tolerance_m):
                self.goto(group)
                group = []
            group.append(wp)
        if group:
            self.goto(group)
        self.pending = []

    def goto(self, group: list[_Waypoint]) -> None:
        traj = TrajectoryParams()
        speed = group[0].speed_m_s or traj.max_speed_m_s
        legs, pos = [], self.pos
        for wp in group:
            if all(map(math.isfinite, wp.ned)):
                legs.append(math.dist(pos, wp.ned))
                pos = wp.ned
        # half as long again as the reference needs for the longest leg: room for the vehicle's lag
        timeout = min(3600.0, max(60.0, math.ceil(1.5 * leg_time_s(max(legs, default=0.0), speed, traj))))
        first = group[0]
        step = Step("goto", f"waypoints {first.where[-1]}..{group[-1].where[-1]}" if len(group) > 1 else
                    f"waypoint {first.where[-1]}", waypoints=tuple(wp.ned for wp in group), speed_m_s=first.speed_m_s,
                    tolerance_m=first.tolerance_m, hold_s=first.hold_s, timeout_s=timeout)
        fields = {f"waypoints[{j}]": wp.where for j, wp in enumerate(group)}
        fields.update({"tolerance_m": first.where + ("params", 1), "hold_s": first.where + ("params", 0)})
        if first.speed_from is not None:
            fields["speed_m_s"] = first.speed_from
        self.add(step, first.where, fields)
        self.pos = pos


def _fences(fence: object, conv: _Converter) -> tuple[tuple[FenceCircle, ...], tuple[FencePolygon, ...]]:
    """Version 2: circles and polygons, each inclusion or exclusion. Version 1 (QGroundControl
    before 3.3; MAVSDK's and QGroundControl's own test plans carry it): one ``polygon`` of
    [lat, lon] corners, the area to stay inside (the autopilots' single polygon fence of the time
    was an inclusion fence); its ``breachReturn`` point is not used, like version 2's."""
    if fence is None:
        return (), ()
    base: Path_ = ("geoFence",)
    if not isinstance(fence, dict):
        raise _Refusal(base, f"expected an object with circles and polygons, got {_json(fence)}")
    if _version(fence, base, FENCE_VERSIONS, "geoFence") == 1:
        corners = fence.get("polygon", [])
        if not isinstance(corners, list):
            raise _Refusal(base + ("polygon",), f"expected a list of [latitude, longitude] corners (version 1), "
                           f"got {_json(corners)}")
        if not corners:
            return (), ()
        return (), (_polygon(corners, True, base + ("polygon",), conv),)
    circles_raw, polygons_raw = fence.get("circles", []), fence.get("polygons", [])
    if not isinstance(circles_raw, list) or not isinstance(polygons_raw, list):
        raise _Refusal(base, "expected lists \"circles\" and \"polygons\" (version 2)")
    if len(circles_raw) + len(polygons_raw) > MAX_FENCES:
        raise _Refusal(base, f"expected at most {MAX_FENCES} fences, got {len(circles_raw) + len(polygons_raw)}")
    circles = []
    for i, c in enumerate(circles_raw):
        w: Path_ = base + ("circles", i)
        body = c.get("circle") if isinstance(c, dict) else None
        if not isinstance(c, dict) or not isinstance(body, dict) or not isinstance(body.get("center"), list) \
                or len(body["center"]) < 2:
            raise _Refusal(w, "expected {\"circle\": {\"center\": [lat, lon], \"radius\": r}, \"inclusion\": ...}")
        inclusion = c.get("inclusion")
        if not isinstance(inclusion, bool):
            raise _Refusal(w + ("inclusion",), f"expected true or false, got {_json(inclusion)}")
        radius = body.get("radius")
        if not _number(radius):
            raise _Refusal(w + ("circle", "radius"), f"expected a radius in metres, got {_json(radius)}")
        center = conv.coordinate(body["center"][0], body["center"][1], w + ("circle", "center"))
        circles.append(FenceCircle(center, float(radius), inclusion))
    polygons = []
    for i, poly in enumerate(polygons_raw):
        w = base + ("polygons", i)
        corners = poly.get("polygon") if isinstance(poly, dict) else None
        if not isinstance(poly, dict) or not isinstance(corners, list):
            raise _Refusal(w, "expected {\"polygon\": [[lat, lon], ...], \"inclusion\": ...}")
        inclusion = poly.get("inclusion")
        if not isinstance(inclusion, bool):
            raise _Refusal(w + ("inclusion",), f"expected true or false, got {_json(inclusion)}")
        polygons.append(_polygon(corners, inclusion, w + ("polygon",), conv))
    return tuple(circles), tuple(polygons)


def _polygon(corners: list[Any], inclusion: bool, where: Path_, conv: _Converter) -> FencePolygon:
    if not 3 <= len(corners) <= MAX_FENCE_VERTICES:
        raise _Refusal(where, f"expected 3..{MAX_FENCE_VERTICES} corners, got {len(corners)}")
    vertices = []
    for j, v in enumerate(corners):
        if not isinstance(v, list) or len(v) < 2:
            raise _Refusal(where + (j,), f"expected [latitude, longitude], got {_json(v)}")
        vertices.append(conv.coordinate(v[0], v[1], where + (j,)))
    return FencePolygon(tuple(vertices), inclusion)


@dataclass(frozen=True)
class ImportedPlan:
    """A plan converted: its steps and fences, and where in its JSON each came from."""

    path: Path
    text: str
    steps: tuple[Step, ...]
    circles: tuple[FenceCircle, ...]
    polygons: tuple[FencePolygon, ...]
    description: str
    origin: dict[str, Path_]
    """``steps[i]``, ``steps[i].waypoints[j]``, ... -> the item (or param) that made it"""
    fence_version: int = 2
    """1: ``geoFence.polygon`` is the one (inclusion) polygon; 2: ``geoFence.polygons[i].polygon``"""

    @property
    def has_inclusion_fence(self) -> bool:
        return any(f.inclusion for f in self.circles) or any(f.inclusion for f in self.polygons)

    def error(self, problem: Problem, circles_before: int = 0, polygons_before: int = 0) -> ConfigError | None:
        """``problem`` (a key of the mission made with this plan's steps, and its fences appended
        after ``circles_before`` / ``polygons_before`` others) as a refusal naming this plan's JSON
        line and item path; None if the key is not this plan's."""
        origin = dict(self.origin)
        for i in range(len(self.circles)):
            k = f"safety.volume.circles[{circles_before + i}]"
            w: Path_ = ("geoFence", "circles", i)
            origin.update({k: w, f"{k}.center_ne_m": w + ("circle", "center"),
                           f"{k}.radius_m": w + ("circle", "radius")})
        for i, poly in enumerate(self.polygons):
            k = f"safety.volume.polygons[{polygons_before + i}]"
            w = ("geoFence",) if self.fence_version == 1 else ("geoFence", "polygons", i)
            corners: Path_ = w + ("polygon",)
            origin.update({k: w, f"{k}.vertices_ne_m": corners})
            origin.update({f"{k}.vertices_ne_m[{j}]": corners + (j,) for j in range(len(poly.vertices_ne_m))})
        if not circles_before and not polygons_before and (self.circles or self.polygons):
            origin["safety.volume"] = ("geoFence",)
        where = _origin_of(problem.key, origin)
        if where is None:
            return None
        return ConfigError(self.path, json_line(self.text, where), _key(where), problem.reason)


def import_plan(path: str | Path) -> ImportedPlan:
    """Read and convert a QGroundControl ``.plan`` (see the module docstring); a refusal during
    reading or conversion is a :class:`ConfigError` with the JSON line and item path. The whole
    mission is checked by the caller (:func:`load_plan`, or a TOML mission's ``plan = ...``)."""
    p = Path(path)
    text = read_text(p, MAX_FILE_BYTES, syntax="json")
    try:
        plan = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(p, exc.lineno, "", f"not valid JSON: {exc.msg}") from None
    except (ValueError, RecursionError) as exc:  # e.g. an integer of more than 4300 digits
        m = re.search(r"[0-9]{4000,}", text)
        raise ConfigError(p, text.count("\n", 0, m.start()) + 1 if m else None, "",
                          f"not valid JSON: {str(exc)[:100]}") from None
    try:
        conv, circles, polygons = _convert(plan)
    except _Refusal as exc:
        raise ConfigError(p, json_line(text, exc.where), _key(exc.where), exc.reason) from None
    description = f"imported from {safe_component(p.stem)}.plan (QGroundControl)"
    if conv is None:
        description = f"fence from {safe_component(p.stem)}.plan (QGroundControl)"
    elif conv.skipped:
        description += "; not flown: items " + ", ".join(conv.skipped)
    rally = plan.get("rallyPoints")
    if isinstance(rally, dict) and rally.get("points"):
        description += "; rally points not used (RTL returns home)"
    if len(description) > 1000:
        description = description[:996] + " ..."
    steps, origin = (tuple(conv.steps), conv.origin) if conv is not None else ((), {})
    fence = plan.get("geoFence")
    return ImportedPlan(p, text, steps, circles, polygons, description, origin,
                        fence_version=1 if isinstance(fence, dict) and fence.get("version") == 1 else 2)


def load_plan(path: str | Path) -> Mission:
    """A QGroundControl ``.plan`` as a :class:`Mission` with the default controller, failsafes and
    volume (cylinder 50 m, 30 m high; with an inclusion fence, the fence bounds the extent, up to
    1000 m), checked whole like a TOML mission; every refusal is a :class:`ConfigError` naming the
    file, the JSON line, the item path and what was expected."""
    imp = import_plan(path)
    if not imp.steps:
        raise ConfigError(imp.path, json_line(imp.text, ("mission", "items")), "mission.items",
                          "the plan has no mission items (a fence-only plan): fly it from a TOML mission beside it "
                          f"that has the [[steps]] and plan = \"{imp.path.name}\" (the plan gives the fence)")
    volume = SafetyVolume(circles=imp.circles, polygons=imp.polygons)
    if imp.has_inclusion_fence:
        volume = dataclasses.replace(volume, max_distance_m=float(ENVELOPE["safety.volume.max_distance_m"].hi))
    mission = Mission(name=safe_component(imp.path.stem), description=imp.description,
                      safety=SafetyConfig(volume=volume), steps=imp.steps)
    try:
        validate(mission)
    except Problem as exc:
        err = imp.error(exc) or ConfigError(imp.path, None, exc.key, exc.reason)
        if "outside the safety volume" in exc.reason and re.search(r"m (from|above) home, limit", exc.reason):
            err.hint = volume_hint(mission, imp.path)
        raise err from None
    return mission


def _room_m(x_m: float) -> float:
    """A limit above ``x_m`` with room for tracking and a GPS height: 10 m or 10 %, whichever is
    more, rounded up to 10 m."""
    return 10.0 * math.ceil((x_m + max(10.0, 0.1 * x_m)) / 10.0)


def volume_hint(mission: Mission, plan_path: Path) -> str:
    """What to write to fly ``mission`` (a plan with the default volume) under a volume that holds
    it: a TOML mission beside the plan, with the snippet, limits rounded up from the plan's extent."""
    far_m, high_m = extent(mission)
    env_far = ENVELOPE["safety.volume.max_distance_m"].hi
    env_high = ENVELOPE["safety.volume.max_altitude_m"].hi
    if high_m > env_high or far_m > env_far:
        return (f"the plan flies {far_m:.1f} m from home and {high_m:.1f} m above it; a mission's volume goes up to "
                f"{env_far:g} m out and {env_high:g} m up: move its waypoints in QGroundControl")
    stem = safe_component(plan_path.stem)
    return "\n".join([
        f"a .plan sets no ceiling or distance limit (flown alone: {mission.safety.volume.describe()}); to fly "
        f"this plan, write {stem}.toml beside it, which sets them:",
        f"    name = \"{stem}\"",
        f"    plan = \"{plan_path.name}\"",
        "    [safety.volume]",
        f"    max_distance_m = {min(_room_m(far_m), env_far):g}    # the plan flies within {far_m:.1f} m of home",
        f"    max_altitude_m = {min(_room_m(high_m), env_high):g}    # and up to {high_m:.1f} m above it",
        f"then: companion check --show {stem}.toml",
    ])


PLAN_VERSION, MISSION_VERSION = 1, 2
"""the versions of the plan file and its mission object that QGroundControl writes"""
FENCE_VERSIONS = {1: "one polygon to stay inside, QGroundControl's older fence", 2: "circles and polygons"}


def _version(obj: dict[str, Any], where: Path_, known: dict[int, str], what: str) -> int:
    """The object's ``version``, refused by name unless it is one of ``known``."""
    v = obj.get("version")
    if not isinstance(v, int) or isinstance(v, bool) or v not in known:
        told = " or ".join(f"{k} ({name})" for k, name in known.items())
        raise _Refusal(where + ("version",), f"{what} version {_json(v)} is not one this reader knows: "
                       f"expected {told}")
    return int(v)


def _convert(plan: Any) -> tuple[_Converter | None, tuple[FenceCircle, ...], tuple[FencePolygon, ...]]:
    """The plan's steps (None when it has no mission items: a fence-only plan) and fences."""
    if not isinstance(plan, dict) or plan.get("fileType") != "Plan":
        raise _Refusal(("fileType",) if isinstance(plan, dict) else (), "expected a QGroundControl plan "
                       "(\"fileType\": \"Plan\")")
    _version(plan, (), {PLAN_VERSION: "QGroundControl's plan file"}, "plan file")
    mission = plan.get("mission")
    if mission is not None and not isinstance(mission, dict):
        raise _Refusal(("mission",), f"expected the mission object, got {_json(mission)}")
    if mission is not None:
        _version(mission, ("mission",), {MISSION_VERSION: "the mission of QGroundControl's plan file"}, "mission")
    home = mission.get("plannedHomePosition") if mission else None
    items = mission.get("items", []) if mission else []
    if not isinstance(items, list):
        raise _Refusal(("mission", "items"), f"expected a list of mission items, got {_json(items)}")
    fence = plan.get("geoFence")
    if fence is not None and not isinstance(fence, dict):
        raise _Refusal(("geoFence",), f"expected an object with circles and polygons, got {_json(fence)}")
    if fence is not None:
        _version(fence, ("geoFence",), FENCE_VERSIONS, "geoFence")
    if not items and not _fence_has_points(fence):
        return None, (), ()
    if not (isinstance(home, list) and len(home) == 3 and _number(home[0]) and _number(home[1])
            and abs(home[0]) <= 89.0 and abs(home[1]) <= 180.0):
        raise _Refusal(("mission", "plannedHomePosition"), f"expected [latitude, longitude, altitude AMSL] of home, "
                       f"latitude within 89 deg (the plan's coordinates are flown around it), got {_json(home)}")
    if len(items) > MAX_PLAN_ITEMS:
        raise _Refusal(("mission", "items", MAX_PLAN_ITEMS), f"expected at most {MAX_PLAN_ITEMS} items, "
                       f"got {len(items)}")
    conv = _Converter(home, _number(home[2]))
    for n, item in enumerate(items):
        conv.item(item, ("mission", "items", n))
        if conv.waypoints > MAX_WAYPOINTS:
            raise _Refusal(("mission", "items", n), f"expected at most {MAX_WAYPOINTS} waypoints")
    if items and conv.phase == "ground":
        raise _Refusal(("mission", "items"), f"expected a take-off item (command {TAKEOFF})")
    if conv.phase == "air":
        raise _Refusal(("mission", "items", len(items) - 1), f"the mission ends in the air: expected a land ({LAND}) "
                       f"or RTL ({RTL}) item last")
    circles, polygons = _fences(fence, conv)
    return (conv if items else None), circles, polygons


def _fence_has_points(fence: object) -> bool:
    return isinstance(fence, dict) and any(fence.get(k) for k in ("polygon", "polygons", "circles"))


def _origin_of(key: str, origin: dict[str, Path_]) -> Path_ | None:
    """The plan path of the longest prefix of ``key`` that a conversion recorded."""
    while key:
        if key in origin:
            return origin[key]
        cut = max(key.rfind("."), key.rfind("["))
        key = key[:cut] if cut > 0 else ""
    return None


# --- lines in JSON ------------------------------------------------------------------------------

_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|[{}\[\],:]|[^\s{}\[\],:"]+')


def json_line(text: str, where: Path_) -> int | None:
    """1-based line where the value at ``where`` starts in the JSON ``text`` (the nearest enclosing
    value's line if it is absent), or None. A tokenizer, not a parser: it runs only for errors."""
    stack: list[list[Any]] = []  # [kind "o"/"a", key or index, state]
    line, last, best = 1, 0, None
    for m in _TOKEN.finditer(text):
        tok, start = m.group(), m.start()
        line += text.count("\n", last, start)
        last = start
        top = stack[-1] if stack else None
        if top is not None and top[0] == "o" and top[2] == "key":
            if tok.startswith('"'):
                try:
                    top[1] = json.loads(tok)
                except ValueError:
                    top[1] = None
                top[2] = "colon"
            elif tok == "}":
                stack.pop()
                _after_value(stack)
            continue
        if tok == ":":
            if top is not None:
                top[2] = "value"
            continue
        if tok == ",":
            if top is not None:
                if top[0] == "o":
                    top[2] = "key"
                else:
                    top[1] += 1
                    top[2] = "value"
            continue
        if tok in "]}":
            if stack:
                stack.pop()
            _after_value(stack)
            continue
        here = tuple(frame[1] for frame in stack)
        if here == where:
            return line
        if where[: len(here)] == here:
            best = line
        if tok == "{":
            stack.append(["o", None, "key"])
        elif tok == "[":
            stack.append(["a", 0, "value"])
        else:
            _after_value(stack)
    return best


def _after_value(stack: list[list[Any]]) -> None:
    if stack:
        stack[-1][2] = "comma"
