"""QGroundControl .plan import, on plans shaped exactly as QGroundControl writes them
(tests/data/plans/): each accepted plan becomes the expected NED waypoints, speeds, holds and
fence; each refusal names the file, the JSON line, the item path and what was expected."""

import copy
import json
import math
from pathlib import Path

import pytest

from companion.cli import main
from companion.config import ConfigError
from companion.mission import FenceCircle, load_mission, load_plan
from companion.mission.plan import json_line

PLANS = Path(__file__).resolve().parents[1] / "data" / "plans"
TOL_M = 0.02  # QGroundControl writes 7 decimals of a degree: 1.1 cm


def fixture(name):
    return json.loads((PLANS / name).read_text())


def near(actual, expected, tol=TOL_M):
    return len(actual) == len(expected) and all(abs(a - e) <= tol for a, e in zip(actual, expected))


def goto_steps(m):
    return [s for s in m.steps if s.action == "goto"]


# --- accepted plans ------------------------------------------------------------------------


def test_relative_altitudes_speed_changes_and_rtl():
    m = load_mission(PLANS / "square_relative.plan")
    assert m.name == "square_relative"
    assert [s.action for s in m.steps] == ["takeoff", "offboard", "goto", "goto", "goto", "land"]
    assert m.steps[0].altitude_m == 10.0
    a, b, c = goto_steps(m)
    # DO_CHANGE_SPEED 3 m/s applies to the waypoints after it ...
    assert a.speed_m_s == 3.0 and near(a.waypoints[0], (20, 0, -10)) and near(a.waypoints[1], (20, 20, -10))
    # ... including one with a hold time (param 1), which becomes its own step
    assert b.speed_m_s == 3.0 and b.hold_s == 2.0 and near(b.waypoints[0], (0, 20, -12))
    # ... until DO_CHANGE_SPEED -2 returns to the mission default; RTL flies home at its height
    assert c.speed_m_s is None and near(c.waypoints[0], (-10, 0, -10)) and near(c.waypoints[1], (0, 0, -10))
    assert all(s.tolerance_m == 0.15 for s in (a, b, c))
    v = m.safety.volume
    assert len(v.polygons) == 1 and v.polygons[0].inclusion
    assert all(near((abs(n), abs(e)), (40, 40)) for n, e in v.polygons[0].vertices_ne_m)
    assert len(v.circles) == 1 and not v.circles[0].inclusion and near(v.circles[0].center_ne_m, (-30, 30))
    assert v.max_altitude_m == 30.0 and v.max_distance_m == 1000.0  # the fence bounds the extent


def test_amsl_altitudes_become_heights_above_home():
    """Home at 488 m AMSL: a waypoint at 498 m AMSL is 10 m above home, not 498."""
    m = load_plan(PLANS / "amsl_camera.plan")
    assert [s.action for s in m.steps] == ["takeoff", "offboard", "goto", "goto", "goto", "land"]
    assert m.steps[0].altitude_m == pytest.approx(5.0)  # take-off at 493 m AMSL
    a, b, c = goto_steps(m)
    assert near(a.waypoints[0], (10, 5, -10.0))
    # AltitudeMode 3: QGroundControl computed 500.5 m AMSL from terrain data (12 m above the terrain there)
    assert near(a.waypoints[1], (25, 5, -12.5))
    assert a.speed_m_s is None
    # airspeed (type 0) 4 m/s, waypoint hold 3 s and acceptance radius 0.5 m
    assert b.speed_m_s == 4.0 and b.hold_s == 3.0 and b.tolerance_m == 0.5 and near(b.waypoints[0], (25, -10, -8))
    # land at its point: fly there at the height the vehicle has, then land
    assert c.speed_m_s == 4.0 and c.hold_s == 0.0 and near(c.waypoints[0], (0, 15, -8))
    assert m.safety.volume.circles == (FenceCircle((0.0, 0.0), 80.0, True),)
    assert "not flown: items 1 IMAGE_START_CAPTURE (camera), 6 IMAGE_STOP_CAPTURE (camera)" in m.description
    assert "rally points not used" in m.description


def test_a_nonconvex_fence_flown_around_its_corner():
    m = load_plan(PLANS / "fenced_L.plan")
    (g,) = goto_steps(m)
    assert [tuple(round(c) for c in w) for w in g.waypoints] == [(50, 0, -8), (0, 0, -8), (0, 50, -8), (0, 0, -8)]
    assert [p.inclusion for p in m.safety.volume.polygons] == [True, False]


def test_timeouts_leave_time_for_long_legs(tmp_path):
    plan = fixture("square_relative.plan")
    items = plan["mission"]["items"]
    items[1]["params"][1] = 0.5  # 0.5 m/s over 20 m legs: 40 s each
    m = load_plan(write(tmp_path, plan))
    assert all(s.timeout_s >= 20 / 0.5 + 5 for s in goto_steps(m)[:2])


def test_check_prints_the_volume_and_what_was_skipped(capsys):
    assert main(["check", str(PLANS / "amsl_camera.plan")]) == 0
    out = capsys.readouterr().out
    assert "ok (6 steps" in out and "cylinder 1000 m, 30 m high, 1 fence" in out
    assert "IMAGE_START_CAPTURE" in out


# --- refusals --------------------------------------------------------------------------------


def write(tmp_path, plan, name="p.plan"):
    p = tmp_path / name
    p.write_text(json.dumps(plan, indent=4, sort_keys=True))
    return p


def refused(tmp_path, plan, key, *words, line_has=None):
    p = write(tmp_path, plan)
    with pytest.raises(ConfigError) as e:
        load_mission(p)
    err = e.value
    assert err.key == key, str(err)
    assert str(err).startswith(f"{p}:{err.line}: {key}: "), str(err)
    for w in words:
        assert w in err.reason, str(err)
    if line_has is not None:
        assert line_has in p.read_text().splitlines()[err.line - 1], (str(err), line_has)
    return err


def item(plan, n):
    return plan["mission"]["items"][n]


def test_terrain_frame(tmp_path):
    plan = fixture("square_relative.plan")
    item(plan, 3).update({"frame": 10, "AltitudeMode": 4})
    refused(tmp_path, plan, "mission.items[3].frame", "terrain-relative", "Relative to launch", line_has='"frame": 10')


def test_altitude_mode_must_agree_with_the_frame(tmp_path):
    plan = fixture("square_relative.plan")
    item(plan, 3)["frame"] = 0  # AltitudeMode 1 (relative) but an AMSL frame
    refused(tmp_path, plan, "mission.items[3].frame", "AltitudeMode 1 (relative to launch) expects frame 3",
            line_has='"frame": 0')
    plan = fixture("square_relative.plan")
    item(plan, 3)["Altitude"] = 17.25
    refused(tmp_path, plan, "mission.items[3].Altitude", "expected 10", line_has="17.25")
    plan = fixture("amsl_camera.plan")
    item(plan, 3)["AMSLAltAboveTerrain"] = 777.5
    refused(tmp_path, plan, "mission.items[3].AMSLAltAboveTerrain", "expected 500.5", line_has="777.5")
    plan = fixture("square_relative.plan")
    item(plan, 3)["AltitudeMode"] = 0
    refused(tmp_path, plan, "mission.items[3].AltitudeMode", "expected 1 (relative to launch)")


def test_amsl_needs_the_home_altitude(tmp_path):
    plan = fixture("amsl_camera.plan")
    plan["mission"]["plannedHomePosition"][2] = None
    refused(tmp_path, plan, "mission.plannedHomePosition[2]", "home's altitude", line_has="null")


def test_an_amsl_altitude_below_home(tmp_path):
    plan = fixture("amsl_camera.plan")
    for k in ("Altitude",):
        item(plan, 2)[k] = 480.0
    item(plan, 2)["params"][6] = 480.0
    refused(tmp_path, plan, "mission.items[2]", "below the ground")


@pytest.mark.parametrize("cmd, name", [(177, "DO_JUMP"), (183, "DO_SET_SERVO"), (17, "NAV_LOITER_UNLIM"),
                                       (201, "DO_SET_ROI"), (4242, "")])
def test_unsupported_commands_are_named(tmp_path, cmd, name):
    plan = fixture("square_relative.plan")
    item(plan, 5)["command"] = cmd
    refused(tmp_path, plan, "mission.items[5].command", f"command {cmd} {name}".strip(), "is not supported",
            line_has=f'"command": {cmd}')


def test_a_complex_item(tmp_path):
    plan = fixture("square_relative.plan")
    plan["mission"]["items"][4] = {"complexItemType": "survey", "type": "ComplexItem", "version": 5}
    refused(tmp_path, plan, "mission.items[4].type", 'complex item ("survey")', line_has='"ComplexItem"')


def test_change_speed_variants(tmp_path):
    plan = fixture("square_relative.plan")
    item(plan, 1)["params"][0] = 2
    refused(tmp_path, plan, "mission.items[1].params[0]", "climb and descent speeds are not supported")
    plan = fixture("square_relative.plan")
    item(plan, 1)["params"][2] = 60
    refused(tmp_path, plan, "mission.items[1].params[2]", "no throttle")
    plan = fixture("square_relative.plan")
    item(plan, 1)["params"][1] = 40
    refused(tmp_path, plan, "mission.items[1].params[1]", "expected 0.1..15 m/s, got 40", line_has="40")
    plan = fixture("square_relative.plan")
    item(plan, 1)["params"][1] = -1  # no change: the mission default
    assert goto_steps(load_plan(write(tmp_path, plan)))[0].speed_m_s is None


def test_waypoint_yaw_and_hold(tmp_path):
    plan = fixture("square_relative.plan")
    item(plan, 2)["params"][3] = 90
    refused(tmp_path, plan, "mission.items[2].params[3]", "yaw is not supported")
    plan = fixture("square_relative.plan")
    item(plan, 2)["params"][0] = -4
    refused(tmp_path, plan, "mission.items[2].params[0]", "hold time")


def test_order_of_items(tmp_path):
    plan = fixture("square_relative.plan")
    plan["mission"]["items"].append(copy.deepcopy(item(plan, 2)))
    refused(tmp_path, plan, "mission.items[8]", "nothing may follow the land or RTL item mission.items[7]")
    plan = fixture("square_relative.plan")
    del plan["mission"]["items"][7]
    refused(tmp_path, plan, "mission.items[6]", "ends in the air")
    plan = fixture("square_relative.plan")
    del plan["mission"]["items"][0]
    refused(tmp_path, plan, "mission.items[1]", "before the take-off")
    plan = fixture("square_relative.plan")
    plan["mission"]["items"].insert(3, copy.deepcopy(item(plan, 0)))
    refused(tmp_path, plan, "mission.items[3]", "a second take-off")


def test_a_takeoff_away_from_home(tmp_path):
    plan = fixture("square_relative.plan")
    item(plan, 0)["params"][4] += 0.001  # 111 m north
    refused(tmp_path, plan, "mission.items[0].params[4]", "take-off 111 m from plannedHomePosition")


@pytest.mark.parametrize("far_deg", [0.0045, 9.0])
def test_a_far_waypoint_is_refused_with_its_item(tmp_path, far_deg):
    """500 m (or 1000 km) north, with no geofence: the default volume's 50 m."""
    plan = fixture("square_relative.plan")
    plan["geoFence"] = {"circles": [], "polygons": [], "version": 2}
    item(plan, 6)["params"][4] += far_deg
    err = refused(tmp_path, plan, "mission.items[6]", "outside the safety volume (cylinder 50 m, 30 m high)",
                  "m from home, limit 50 m")
    lines = (tmp_path / "p.plan").read_text().splitlines()
    assert lines[err.line - 1].strip() == "{" and '"AMSLAltAboveTerrain"' in lines[err.line]


def test_fences_refuse_paths(tmp_path):
    plan = fixture("fenced_L.plan")
    del plan["mission"]["items"][2]  # from the north arm straight to the east arm: across the corner
    refused(tmp_path, plan, "mission.items[2]", "leaves the inclusion fence")
    plan = fixture("fenced_L.plan")
    lat, lon = plan["geoFence"]["polygons"][1]["polygon"][0]
    item(plan, 1)["params"][4:6] = [lat + 2e-5, lon + 2e-5]  # inside the no-fly square
    refused(tmp_path, plan, "mission.items[1]", "inside exclusion polygon 1")
    plan = fixture("square_relative.plan")
    plan["geoFence"]["circles"][0]["circle"]["center"] = plan["mission"]["plannedHomePosition"][:2]
    refused(tmp_path, plan, "geoFence", "home (where the vehicle arms) must be inside")
    plan = fixture("fenced_L.plan")
    poly = plan["geoFence"]["polygons"][0]["polygon"]
    poly[1], poly[2] = poly[2], poly[1]
    refused(tmp_path, plan, "geoFence.polygons[0].polygon", "simple polygon")
    plan = fixture("fenced_L.plan")
    plan["geoFence"]["polygons"][0]["polygon"] = plan["geoFence"]["polygons"][0]["polygon"][:2]
    refused(tmp_path, plan, "geoFence.polygons[0].polygon", "3..200 corners")
    plan = fixture("amsl_camera.plan")
    plan["geoFence"]["circles"][0]["circle"]["radius"] = 5000
    refused(tmp_path, plan, "geoFence.circles[0].circle.radius", "1..1000 m", line_has="5000")


def test_not_a_plan(tmp_path):
    plan = fixture("square_relative.plan")
    plan["fileType"] = "Mission"
    refused(tmp_path, plan, "fileType", '"fileType": "Plan"', line_has='"Mission"')
    plan = fixture("square_relative.plan")
    plan["version"] = 2
    refused(tmp_path, plan, "version", "plan file version 2 is not one this reader knows", "expected 1")
    p = tmp_path / "x.plan"
    p.write_text('{\n  "fileType": "Plan",\n  "mission": {\n    "items": [1, 2,]\n  }\n}\n')
    with pytest.raises(ConfigError) as e:
        load_mission(p)
    assert e.value.line == 4 and "not valid JSON" in e.value.reason


def test_item_shapes(tmp_path):
    plan = fixture("square_relative.plan")
    item(plan, 2)["params"] = [0, 0, 0]
    refused(tmp_path, plan, "mission.items[2].params", "expected 7 params")
    plan = fixture("square_relative.plan")
    item(plan, 2)["params"][4] = 123.0
    refused(tmp_path, plan, "mission.items[2].params[4]", "latitude and longitude")
    plan = fixture("square_relative.plan")
    item(plan, 2)["params"][6] = "high"
    refused(tmp_path, plan, "mission.items[2].params[6]", "a number or null", line_has='"high"')
    plan = fixture("square_relative.plan")
    plan["mission"]["items"] = plan["mission"]["items"][:1] * 2001
    p = tmp_path / "many.plan"
    p.write_text(json.dumps(plan))  # on one line: 2001 items as QGroundControl indents them pass 1 MB
    with pytest.raises(ConfigError) as e:
        load_mission(p)
    assert (e.value.key, e.value.line) == ("mission.items[2000]", 1) and "at most 2000 items" in e.value.reason


def test_json_line_finds_values():
    text = '{\n "a": [\n  1,\n  {"b": 2,\n   "c": [3,\n    4]}\n ],\n "d": "x"\n}\n'
    assert json_line(text, ("a",)) == 2
    assert json_line(text, ("a", 0)) == 3
    assert json_line(text, ("a", 1)) == 4
    assert json_line(text, ("a", 1, "c", 1)) == 6
    assert json_line(text, ("d",)) == 8
    assert json_line(text, ("a", 1, "zz")) == 4  # absent: the nearest enclosing value
    assert json_line(text, ()) == 1
    assert math.isfinite(json_line('{"x": "a\\"[{,:"}', ("x",)))


# --- a TOML mission flying a plan: its controller, failsafes and volume ----------------------


def at_height(plan, height):
    for it in plan["mission"]["items"]:
        if it.get("AltitudeMode") == 1 and it["command"] != 21:
            it["Altitude"] = it["params"][6] = height
    return plan


def toml_with_plan(tmp_path, body, plan):
    write(tmp_path, plan, "survey.plan")
    p = tmp_path / "survey.toml"
    p.write_text(body)
    return p


def test_a_toml_mission_flies_a_plan_under_its_own_volume(tmp_path):
    plan = at_height(fixture("square_relative.plan"), 50)  # QGroundControl's default altitude
    with pytest.raises(ConfigError, match="50.0 m above home, limit 30 m"):
        load_plan(write(tmp_path, plan))
    p = toml_with_plan(tmp_path, 'name = "survey"\nplan = "survey.plan"\n\n[controller]\nposition = "pd_do"\n\n'
                       '[safety.volume]\nmax_distance_m = 60\nmax_altitude_m = 55\n', plan)
    m = load_mission(p)
    assert m.name == "survey" and m.controller.position == "pd_do"
    assert m.steps[0].altitude_m == 50 and near(goto_steps(m)[0].waypoints[0], (20, 0, -50))
    v = m.safety.volume
    assert (v.max_distance_m, v.max_altitude_m) == (60.0, 55.0) and len(v.polygons) == 1 and len(v.circles) == 1


def test_a_plan_waypoint_outside_the_toml_volume_names_the_plan(tmp_path):
    p = toml_with_plan(tmp_path, 'plan = "survey.plan"\n\n[safety.volume]\nmax_distance_m = 25\n',
                       fixture("square_relative.plan"))
    with pytest.raises(ConfigError) as e:
        load_mission(p)
    # (20, 20) is 28 m from home: outside the TOML's 25 m; the error points into the plan
    assert e.value.path == str(tmp_path / "survey.plan") and e.value.key == "mission.items[3]"
    assert "28.3 m from home, limit 25 m" in e.value.reason
    lines = (tmp_path / "survey.plan").read_text().splitlines()
    assert lines[e.value.line - 1].strip() == "{"


def test_plan_key_errors_name_the_toml(tmp_path):
    for value, words in (('"../survey.plan"', "no directories"), ('"/etc/x.plan"', "no directories"),
                         ('"survey.toml"', ".plan next to this file"), ("3", ".plan next to this file")):
        p = toml_with_plan(tmp_path, f'name = "s"\nplan = {value}\n', fixture("square_relative.plan"))
        with pytest.raises(ConfigError) as e:
            load_mission(p)
        assert (e.value.path, e.value.line, e.value.key) == (str(p), 2, "plan") and words in e.value.reason
    p = toml_with_plan(tmp_path, 'plan = "survey.plan"\n\n[[steps]]\naction = "land"\n', fixture("fenced_L.plan"))
    with pytest.raises(ConfigError, match="the steps come from survey.plan") as e:
        load_mission(p)
    p = toml_with_plan(tmp_path, 'plan = "survey.plan"\n\n[safety.volume]\nmax_altitude_m = 5\n',
                       fixture("fenced_L.plan"))
    with pytest.raises(ConfigError) as e:
        load_mission(p)
    assert e.value.path == str(tmp_path / "survey.plan") and "8.0 m above home, limit 5 m" in e.value.reason
    p = toml_with_plan(tmp_path, 'plan = "missing.plan"\n', fixture("fenced_L.plan"))
    with pytest.raises(ConfigError, match="cannot read file"):
        load_mission(p)
