"""The safety volume the runtime asks in flight: breach (None or why), margin (metres to the nearest
limit), and the straight path between two points; and every step of a mission checked against it."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from companion.mission import FenceCircle, FencePolygon, SafetyVolume, load_mission
from helpers.missions import goto_mission, refusal

CYL = SafetyVolume(max_distance_m=10.0, max_altitude_m=5.0)
BOX = SafetyVolume(shape="box", max_distance_m=50.0, max_altitude_m=5.0, north_m=(-2.0, 8.0), east_m=(-3.0, 3.0))
# an L-shaped inclusion fence (not convex) around home, and a no-fly circle north-east
L_SHAPE = FencePolygon(((-5.0, -5.0), (20.0, -5.0), (20.0, 5.0), (5.0, 5.0), (5.0, 20.0), (-5.0, 20.0)))
FENCED = SafetyVolume(max_distance_m=1000.0, max_altitude_m=30.0, polygons=(L_SHAPE,),
                      circles=(FenceCircle((-2.0, 12.0), 1.5, inclusion=False),))


def test_defaults_are_the_documented_cylinder():
    v = SafetyVolume()
    assert (v.shape, v.max_distance_m, v.max_altitude_m) == ("cylinder", 50.0, 30.0)
    assert v.breach((0, 0, 0)) is None and v.breach((49.9, 0, -29.9)) is None
    assert v.breach((500.0, 0, -2)) == "500.0 m from home, limit 50 m"


def test_breach_reasons_name_the_limit():
    assert CYL.breach((0.0, 0.0, -1.0)) is None
    assert CYL.breach((12.3, 0.0, -1.0)) == "12.3 m from home, limit 10 m"
    assert CYL.breach((6.0, 8.0001, -1.0)) == "10.0 m from home, limit 10 m"
    assert CYL.breach((1.0, 1.0, -5.5)) == "5.5 m above home, limit 5 m"
    assert BOX.breach((9.0, 0.0, -1.0)) == "9.0 m north of home, box -2..8 m"
    assert BOX.breach((0.0, -3.5, -1.0)) == "-3.5 m east of home, box -3..3 m"
    assert "not finite" in CYL.breach((math.nan, 0.0, -1.0))
    assert "not finite" in CYL.breach((0.0, math.inf, -1.0))


def test_on_the_ground_and_a_little_below_home_is_not_a_breach():
    """The vehicle sits at down = 0 (or an estimator's few cm below): that is home, not a breach."""
    assert CYL.breach((0.0, 0.0, 0.0)) is None and CYL.breach((0.0, 0.0, 0.05)) is None


def test_margin_is_the_distance_to_the_nearest_limit():
    assert CYL.margin_m((3.0, 4.0, -1.0)) == pytest.approx(4.0)  # ceiling 4 m above, wall 5 m away
    assert CYL.margin_m((3.0, 4.0, -4.5)) == pytest.approx(0.5)
    assert CYL.margin_m((12.0, 0.0, -1.0)) == pytest.approx(-2.0)
    assert BOX.margin_m((7.0, 0.0, -1.0)) == pytest.approx(1.0)
    assert BOX.margin_m((0.0, -3.25, -1.0)) == pytest.approx(-0.25)
    assert CYL.margin_m((math.nan, 0.0, 0.0)) == -math.inf


def test_a_nonconvex_inclusion_fence_and_an_exclusion_circle():
    assert FENCED.breach((15.0, 0.0, -2.0)) is None  # in the north arm
    assert FENCED.breach((0.0, 15.0, -2.0)) is None  # in the east arm
    assert FENCED.breach((15.0, 15.0, -2.0)) == "outside every inclusion fence (10.0 m beyond polygon 0)"
    assert FENCED.breach((-2.0, 12.0, -2.0)) == "inside exclusion circle 0 (1.5 m from its edge)"
    assert FENCED.margin_m((15.0, 0.0, -2.0)) == pytest.approx(5.0)
    assert FENCED.margin_m((15.0, 15.0, -2.0)) == pytest.approx(-10.0)
    # the direct path between the arms cuts the inside corner; around it through home is fine
    assert "leaves the inclusion fence" in FENCED.segment_breach((15.0, 0.0, -2.0), (0.0, 15.0, -2.0))
    assert FENCED.segment_breach((15.0, 0.0, -2.0), (0.0, 0.0, -2.0)) is None
    assert FENCED.segment_breach((0.0, 0.0, -2.0), (0.0, 10.0, -2.0)) is None
    # the path along the south of the east arm passes the no-fly circle
    assert "crosses exclusion circle 0" in FENCED.segment_breach((-2.0, 8.0, -2.0), (-2.0, 16.0, -2.0))
    assert FENCED.segment_breach((2.0, 8.0, -2.0), (2.0, 16.0, -2.0)) is None


def test_two_inclusion_fences_are_a_union():
    v = SafetyVolume(max_distance_m=1000.0, circles=(FenceCircle((0.0, 0.0), 10.0), FenceCircle((100.0, 0.0), 10.0)))
    assert v.breach((95.0, 0.0, -2.0)) is None and v.breach((50.0, 0.0, -2.0)) is not None
    assert v.segment_breach((0.0, 0.0, -2.0), (95.0, 0.0, -2.0)) is not None


@given(st.tuples(st.floats(-30, 30), st.floats(-30, 30), st.floats(-40, 5)))
def test_breach_and_margin_agree(p):
    for v in (CYL, BOX, FENCED):
        m = v.margin_m(p)
        if abs(m) > 1e-9:
            assert (v.breach(p) is None) == (m > 0), (v, p, m)


# --- missions against their volume -------------------------------------------------------------

HOLD_STEP = """[[steps]]
action = "hold"
duration_s = 1
position_ned_m = [0, 0, -1.5]

"""
MISSION = goto_mission("\n[safety.volume]\nmax_distance_m = 10\nmax_altitude_m = 5\n", before_land=HOLD_STEP)


def test_the_mission_inside_its_volume_loads(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(MISSION)
    assert load_mission(p).safety.volume == SafetyVolume(max_distance_m=10.0, max_altitude_m=5.0)


@pytest.mark.parametrize("far", ["500", "1e9", "-12"])
def test_a_far_waypoint_is_refused_with_its_line(tmp_path, far):
    e = refusal(tmp_path, MISSION.replace("[1, 1, -1.5]]", f"[1, {far}, -1.5]]"))
    assert (e.line, e.key) == (16, "steps[2].waypoints[1]")
    assert "outside the safety volume (cylinder 10 m, 5 m high)" in e.reason and "limit 10 m" in e.reason


def test_a_far_waypoint_is_refused_by_the_default_volume_too(tmp_path):
    e = refusal(tmp_path, MISSION.replace("max_distance_m = 10\nmax_altitude_m = 5\n", "").replace(
        "[1, 1, -1.5]]", "[500, 0, -1.5]]"))
    assert e.key == "steps[2].waypoints[1]" and "500.0 m from home, limit 50 m" in e.reason


def test_a_takeoff_above_the_ceiling(tmp_path):
    e = refusal(tmp_path, MISSION.replace("altitude_m = 1.5", "altitude_m = 8"))
    assert (e.line, e.key) == (9, "steps[0].altitude_m") and "8.0 m above home, limit 5 m" in e.reason


def test_a_hold_position_outside(tmp_path):
    e = refusal(tmp_path, MISSION.replace("position_ned_m = [0, 0, -1.5]", "position_ned_m = [0, 0, -6]"))
    assert (e.line, e.key) == (21, "steps[3].position_ned_m") and "6.0 m above home" in e.reason


def test_too_low_and_below_ground(tmp_path):
    e = refusal(tmp_path, MISSION.replace("[1, 1, -1.5]]", "[1, 1, -0.1]]"))
    assert e.key == "steps[2].waypoints[1]" and "at least 0.3 m" in e.reason
    e = refusal(tmp_path, MISSION.replace("[1, 1, -1.5]]", "[1, 1, 2.0]]"))
    assert e.key == "steps[2].waypoints[1]" and "below the ground" in e.reason


def test_a_box_volume(tmp_path):
    box = MISSION.replace("max_distance_m = 10", 'shape = "box"\nnorth_m = [-1, 2]\neast_m = [-1, 0.5]\n'
                                                 'max_distance_m = 10')
    e = refusal(tmp_path, box)
    assert e.key == "steps[2].waypoints[1]" and "1.0 m east of home, box -1..0.5 m" in e.reason
    e = refusal(tmp_path, box.replace("north_m = [-1, 2]", "north_m = [1, 2]"))
    assert e.key == "safety.volume.north_m" and e.line == 5 and "min < 0 < max" in e.reason
    e = refusal(tmp_path, box.replace("north_m = [-1, 2]\n", ""))
    assert e.key == "safety.volume.shape" and "needs north_m" in e.reason
    e = refusal(tmp_path, MISSION.replace("max_distance_m = 10", "max_distance_m = 10\nnorth_m = [-1, 2]"))
    assert e.key == "safety.volume.north_m" and "only for shape" in e.reason


def test_fences_written_in_toml(tmp_path):
    fenced = MISSION.replace("max_altitude_m = 5\n", 'max_altitude_m = 5\ncircles = [{center_ne_m = [1, 5], '
                             'radius_m = 1.2, inclusion = false}]\n')
    p = tmp_path / "m.toml"
    p.write_text(fenced)
    assert load_mission(p).safety.volume.circles == (FenceCircle((1.0, 5.0), 1.2, False),)
    e = refusal(tmp_path, fenced.replace("[1, 1, -1.5]]", "[1, 1, -1.5], [1, 8, -1.5]]"))
    assert e.key == "steps[2].waypoints[2]" and "crosses exclusion circle 0" in e.reason
    e = refusal(tmp_path, fenced.replace("center_ne_m = [1, 5], radius_m = 1.2", "center_ne_m = [0, 0], radius_m = 2"))
    assert e.key == "safety.volume" and "home (where the vehicle arms) must be inside" in e.reason
    e = refusal(tmp_path, MISSION.replace("max_altitude_m = 5\n", "max_altitude_m = 5\npolygons = [{vertices_ne_m = "
                                          "[[-1, -1], [1, 1], [1, -1], [-1, 1]]}]\n"))
    assert e.key == "safety.volume.polygons[0].vertices_ne_m" and "simple polygon" in e.reason
    assert e.line == 6  # the line of the inline array that holds the polygon


def test_a_goto_timeout_too_short_for_its_leg(tmp_path):
    text = MISSION.replace("[[1, 0, -1.5], [1, 1, -1.5]]", "[[9, 0, -1.5]]\nspeed_m_s = 0.5\ntimeout_s = 10")
    e = refusal(tmp_path, text)
    # 9 m at 0.5 m/s, + 0.5 / 10 to brake, + 10 / 40 of jerk limit, + 14 / 2 to settle: 25.3 s
    assert e.key == "steps[2].timeout_s" and e.line == 18 and "expected at least 26 s" in e.reason
