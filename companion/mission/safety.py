"""The safety volume: where a mission may fly, around home, as a pure value the flight runtime asks.

Home is the local NED origin, ``(0, 0, 0)``: the take-off point, where the vehicle armed. Mission
coordinates are in that frame, so the volume is too. The volume is the intersection of

- a vertical limit: ``max_altitude_m`` above home;
- a horizontal limit: ``max_distance_m`` from home (a cylinder, the default shape);
- with ``shape = "box"``, also ``north_m = [min, max]`` and ``east_m = [min, max]``;
- geofences (imported from a QGroundControl plan, or written in TOML): the vehicle must be inside at
  least one *inclusion* fence, if there is any, and outside every *exclusion* fence — PX4's rule.

Nothing here does I/O; every method is a pure function of the volume and its arguments::

    volume.breach((12.3, 0.0, -2.0))     # '12.3 m from home, limit 10 m'  (None inside)
    volume.margin_m((3.0, 4.0, -2.0))    # 5.0: how far inside the nearest limit [m]; < 0 outside
    volume.segment_breach(a, b)          # the straight path a -> b, or None

The loaders check every step of a mission against it before anything arms (:mod:`.validate`);
the flight runtime calls :meth:`SafetyVolume.breach` on each position sample (breach -> hold, then
land) and may use :meth:`SafetyVolume.margin_m` to act before the boundary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from companion.control.vector import Real



__all__ = ["Vec2", "Point", "FenceCircle", "FencePolygon", "SafetyVolume", "VOLUME_SHAPES", "polygon_is_simple"]

Vec2 = tuple[float, float]
"""(north, east) [m] from home"""
Point = Sequence[Real]
"""(north, east, down) [m] from home: a Vec3, a list, a numpy array"""

VOLUME_SHAPES = ("cylinder", "box")


@dataclass(frozen=True)
class FenceCircle:
    """A vertical cylinder of the geofence: centre (north, east) [m] from home, radius [m]."""

    center_ne_m: Vec2
    radius_m: float
    inclusion: bool = True
    """True: the vehicle must stay inside (of at least one inclusion fence); False: outside."""


@dataclass(frozen=True)
class FencePolygon:
    """A vertical prism of the geofence: its corners (north, east) [m] from home, in order."""

    vertices_ne_m: tuple[Vec2, ...]
    inclusion: bool = True


@dataclass(frozen=True)
class SafetyVolume:
    """Where the vehicle may be, around home; see the module docstring for the rule.

    Defaults (docs/missions.md): a cylinder of 50 m radius, 30 m high. The mission envelope
    bounds what a file may ask for (:mod:`.envelope`)."""

    shape: str = "cylinder"
    """"cylinder" (max_distance_m only) or "box" (also north_m and east_m)"""
    max_distance_m: float = 50.0
    """horizontal distance from home [m]; the cylinder's radius (a box is cut by it too)"""
    max_altitude_m: float = 30.0
    """height above home [m] (up is -down in NED)"""
    north_m: Vec2 | None = None
    """box only: [min, max] north of home [m]"""
    east_m: Vec2 | None = None
    """box only: [min, max] east of home [m]"""
    circles: tuple[FenceCircle, ...] = ()
    polygons: tuple[FencePolygon, ...] = ()

    # --- what the runtime calls -------------------------------------------------------------

    def breach(self, pos_ned_m: Point) -> str | None:
        """None if ``pos_ned_m`` (NED [m] from home) is inside the volume, else why not, in words
        (``"12.3 m from home, limit 10 m"``). A non-finite position is a breach."""
        n, e, d = (float(c) for c in pos_ned_m[:3])
        if not (math.isfinite(n) and math.isfinite(e) and math.isfinite(d)):
            return f"position not finite ({n}, {e}, {d})"
        if -d > self.max_altitude_m:
            return f"{-d:.1f} m above home, limit {self.max_altitude_m:g} m"
        dist = math.hypot(n, e)
        if dist > self.max_distance_m:
            return f"{dist:.1f} m from home, limit {self.max_distance_m:g} m"
        for axis, value, span in (("north", n, self._box(self.north_m)), ("east", e, self._box(self.east_m))):
            if span is not None and not span[0] <= value <= span[1]:
                return f"{value:.1f} m {axis} of home, box {span[0]:g}..{span[1]:g} m"
        inc = self._inclusions()
        if inc:
            best, name = max((_signed_distance((n, e), f), name) for name, f in inc)
            if best < 0.0:
                return f"outside every inclusion fence ({-best:.1f} m beyond {name})"
        for name, f in self._exclusions():
            inside = _signed_distance((n, e), f)
            if inside > 0.0:
                return f"inside exclusion {name} ({inside:.1f} m from its edge)"
        return None

    def margin_m(self, pos_ned_m: Point) -> float:
        """Distance [m] from ``pos_ned_m`` to the nearest limit of the volume: positive inside,
        negative outside (how far beyond the worst limit); -inf for a non-finite position.

        Every limit counts on its own, so near a corner this is the distance to the nearer face.
        A runtime can slow down or hold when it falls below its stopping distance."""
        n, e, d = (float(c) for c in pos_ned_m[:3])
        if not (math.isfinite(n) and math.isfinite(e) and math.isfinite(d)):
            return -math.inf
        margins = [self.max_altitude_m + d, self.max_distance_m - math.hypot(n, e)]
        for value, span in ((n, self._box(self.north_m)), (e, self._box(self.east_m))):
            if span is not None:
                margins.append(min(value - span[0], span[1] - value))
        inc = self._inclusions()
        if inc:
            margins.append(max(_signed_distance((n, e), f) for _, f in inc))
        margins += [-_signed_distance((n, e), f) for _, f in self._exclusions()]
        return min(margins)

    def segment_breach(self, a_ned_m: Point, b_ned_m: Point) -> str | None:
        """None if the straight path from ``a`` to ``b`` stays in the volume, else why not.

        Altitude, distance and box are convex, so the ends decide. A path must lie in one
        inclusion fence (conservative where fences overlap) and cross no exclusion fence."""
        for p in (a_ned_m, b_ned_m):
            why = self.breach(p)
            if why is not None:
                return why
        a, b = (float(a_ned_m[0]), float(a_ned_m[1])), (float(b_ned_m[0]), float(b_ned_m[1]))
        inc = self._inclusions()
        if inc and not any(_segment_inside(a, b, f) for _, f in inc):
            return "the straight path between them leaves the inclusion fence"
        for name, f in self._exclusions():
            if _segment_touches(a, b, f):
                return f"the straight path between them crosses exclusion {name}"
        return None

    def describe(self) -> str:
        """One line for people: ``cylinder 50 m, 30 m high`` (+ box and fences)."""
        text = f"{self.shape} {self.max_distance_m:g} m, {self.max_altitude_m:g} m high"
        nb, eb = self._box(self.north_m), self._box(self.east_m)
        if nb is not None and eb is not None:
            text += f", north {nb[0]:g}..{nb[1]:g} m, east {eb[0]:g}..{eb[1]:g} m"
        fences = len(self.circles) + len(self.polygons)
        if fences:
            text += f", {fences} fence{'s' if fences > 1 else ''}"
        return text

    # --- parts ------------------------------------------------------------------------------

    def _box(self, span: Vec2 | None) -> Vec2 | None:
        return span if self.shape == "box" else None

    def _fences(self) -> list[tuple[str, FenceCircle | FencePolygon]]:
        return ([(f"circle {i}", c) for i, c in enumerate(self.circles)]
                + [(f"polygon {i}", p) for i, p in enumerate(self.polygons)])

    def _inclusions(self) -> list[tuple[str, FenceCircle | FencePolygon]]:
        return [(name, f) for name, f in self._fences() if f.inclusion]

    def _exclusions(self) -> list[tuple[str, FenceCircle | FencePolygon]]:
        return [(name, f) for name, f in self._fences() if not f.inclusion]


# --- plane geometry (north, east) ---------------------------------------------------------


def _signed_distance(p: Vec2, fence: FenceCircle | FencePolygon) -> float:
    """Distance from ``p`` to the fence's edge: positive inside, negative outside."""
    if isinstance(fence, FenceCircle):
        c = fence.center_ne_m
        return fence.radius_m - math.hypot(p[0] - c[0], p[1] - c[1])
    v = fence.vertices_ne_m
    if len(v) < 3:
        return -math.inf
    edge = min(_point_segment_distance(p, v[i - 1], v[i]) for i in range(len(v)))
    return edge if _point_in_polygon(p, v) else -edge


def _point_in_polygon(p: Vec2, v: Sequence[Vec2]) -> bool:
    """Even-odd rule (a ray towards +east)."""
    inside = False
    x, y = p
    for i in range(len(v)):
        (x1, y1), (x2, y2) = v[i - 1], v[i]
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


def _point_segment_distance(p: Vec2, a: Vec2, b: Vec2) -> float:
    dx, dy = b[0] - a[0], b[1] - a[1]
    ll = dx * dx + dy * dy
    t = 0.0 if ll == 0.0 else min(1.0, max(0.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / ll))
    return math.hypot(p[0] - a[0] - t * dx, p[1] - a[1] - t * dy)


def _orient(a: Vec2, b: Vec2, c: Vec2) -> float:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _segments_meet(a: Vec2, b: Vec2, c: Vec2, d: Vec2) -> bool:
    """Whether segments ab and cd share a point (touching and overlapping count)."""
    o1, o2, o3, o4 = _orient(a, b, c), _orient(a, b, d), _orient(c, d, a), _orient(c, d, b)
    if ((o1 > 0) != (o2 > 0) and o1 != 0 and o2 != 0) and ((o3 > 0) != (o4 > 0) and o3 != 0 and o4 != 0):
        return True
    return any(o == 0 and _on_segment(p, q, r) for o, p, q, r in ((o1, a, b, c), (o2, a, b, d), (o3, c, d, a),
                                                                   (o4, c, d, b)))


def _on_segment(a: Vec2, b: Vec2, p: Vec2) -> bool:
    return min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])


def _segment_inside(a: Vec2, b: Vec2, fence: FenceCircle | FencePolygon) -> bool:
    if _signed_distance(a, fence) < 0.0 or _signed_distance(b, fence) < 0.0:
        return False
    if isinstance(fence, FenceCircle):
        return True  # convex
    v = fence.vertices_ne_m
    # the ends are inside; the path stays inside unless it crosses an edge (touching one is
    # counted as leaving: conservative at a reflex corner)
    return not any(_segments_meet(a, b, v[i - 1], v[i]) for i in range(len(v))) or _convex(v)


def _segment_touches(a: Vec2, b: Vec2, fence: FenceCircle | FencePolygon) -> bool:
    if isinstance(fence, FenceCircle):
        return _point_segment_distance(fence.center_ne_m, a, b) < fence.radius_m
    v = fence.vertices_ne_m
    return (_signed_distance(a, fence) > 0.0 or _signed_distance(b, fence) > 0.0
            or any(_segments_meet(a, b, v[i - 1], v[i]) for i in range(len(v))))


def _convex(v: Sequence[Vec2]) -> bool:
    signs = {_orient(v[i - 2], v[i - 1], v[i]) > 0 for i in range(len(v)) if _orient(v[i - 2], v[i - 1], v[i]) != 0}
    return len(signs) <= 1


def polygon_is_simple(v: Sequence[Vec2]) -> bool:
    """No two non-adjacent edges meet (and no edge has zero length): a fence that is one region."""
    n = len(v)
    if n < 3 or any(v[i - 1] == v[i] for i in range(n)):
        return False
    for i in range(n):
        for j in range(i + 1, n):
            if j == i + 1 or (i == 0 and j == n - 1):
                continue  # neighbours share a corner
            if _segments_meet(v[i - 1], v[i], v[j - 1], v[j]):
                return False
    return True
