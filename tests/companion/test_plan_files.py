"""Plans that nobody here wrote (MAVSDK's and QGroundControl's own test plans, tests/data/plans,
README there) and what people do with them: version-1 fences, versions the reader does not know,
fence-only plans beside TOML steps, the default volume's refusal and its fix, null altitudes, the
converted steps shown in NED, and missions too low for a vehicle on GPS (issue 21, items 3 and 5)."""

import dataclasses
import json
import math
import re
from pathlib import Path

import pytest

from companion.cli import main
from companion.config import ConfigError
from companion.mission import Step, load_mission, load_plan
from companion.mission.show import GPS_MIN_HEIGHT_M, GPS_SAFE_MISSION, lowest_height_m

ROOT = Path(__file__).resolve().parents[2]
PLANS = ROOT / "tests" / "data" / "plans"
R_M = 6378137.0
TOL_M = 0.02  # 7 decimals of a degree: 1.1 cm


def fixture(name):
    return json.loads((PLANS / name).read_text())


def ne_of(lat, lon, home):
    """Metres north and east of ``home`` (flat earth, WGS-84 equatorial radius): the expectation
    for a coordinate of the plan, worked from the numbers in the file."""
    return (math.radians(lat - home[0]) * R_M, math.radians(lon - home[1]) * R_M * math.cos(math.radians(home[0])))


def write(tmp_path, plan, name="p.plan"):
    p = tmp_path / name
    p.write_text(json.dumps(plan, indent=4))
    return p


def refusal(path):
    with pytest.raises(ConfigError) as e:
        load_mission(path)
    err = e.value
    assert str(err).startswith(f"{err.path}:{err.line}: {err.key}: ") and err.line, str(err)
    return err


def toml_beside(tmp_path, plan_name, body):
    p = tmp_path / "survey.toml"
    p.write_text(f'name = "survey"\nplan = "{plan_name}"\n{body}')
    return p


STEPS_5M = """
[safety.volume]
max_distance_m = 150
max_altitude_m = 10

[[steps]]
action = "takeoff"
altitude_m = 5.0

[[steps]]
action = "offboard"

[[steps]]
action = "goto"
waypoints = [[{n}, {e}, -5.0], [0.0, 0.0, -5.0]]
timeout_s = 120

[[steps]]
action = "land"
"""


# --- version-1 fences --------------------------------------------------------------------------


def test_a_version_1_fence_is_the_inclusion_polygon_it_draws(tmp_path):
    """fence_v1.plan: MAVSDK's sample with QGroundControl's older fence (one "polygon" of
    corners, version 1), 20 m around the square. It was dropped without a word (the default
    cylinder flew); now its corners bound the flight."""
    plan = fixture("fence_v1.plan")
    home = plan["mission"]["plannedHomePosition"]
    expected = [ne_of(lat, lon, home) for lat, lon in plan["geoFence"]["polygon"]]
    p = toml_beside(tmp_path, "fence_v1.plan", "[safety.volume]\nmax_distance_m = 110\nmax_altitude_m = 60\n")
    write(tmp_path, plan, "fence_v1.plan")
    m = load_mission(p)
    (poly,) = m.safety.volume.polygons
    assert poly.inclusion
    assert all(math.dist(v, w) <= TOL_M for v, w in zip(poly.vertices_ne_m, expected, strict=True))
    assert [tuple(round(c) for c in v) for v in poly.vertices_ne_m] == [(-20, -20), (80, -20), (80, 100), (-20, 100)]
    # a waypoint moved 30 m east of the fence's east edge (100 m) is refused, naming its item
    plan["mission"]["items"][1]["params"][5] += math.degrees(30.0 / (R_M * math.cos(math.radians(home[0]))))
    write(tmp_path, plan, "fence_v1.plan")
    err = refusal(p)
    assert err.path.endswith("fence_v1.plan") and err.key == "mission.items[1]"
    assert "outside every inclusion fence" in err.reason


def test_a_broken_version_1_fence_is_named_where_it_is(tmp_path):
    plan = fixture("fence_v1.plan")
    corners = plan["geoFence"]["polygon"]
    corners[1], corners[2] = corners[2], corners[1]  # edges cross
    write(tmp_path, plan, "fence_v1.plan")
    err = refusal(toml_beside(tmp_path, "fence_v1.plan", "[safety.volume]\nmax_distance_m = 110\n"
                              "max_altitude_m = 60\n"))
    assert err.key == "geoFence.polygon" and "simple polygon" in err.reason
    assert '"polygon"' in (tmp_path / "fence_v1.plan").read_text().splitlines()[err.line - 1]
    plan["geoFence"]["polygon"] = [[47.39, 8.54], None, [47.4, 8.55]]
    err = refusal(write(tmp_path, plan))
    assert err.key == "geoFence.polygon[1]" and "got null" in err.reason


def test_an_empty_version_1_fence_is_no_fence():
    """MAVSDK's 2018 sample, as QGroundControl wrote it then: "polygon": [] (version 1)."""
    plan = fixture("mavsdk_sample_2018.plan")
    assert plan["geoFence"] == {"polygon": [], "version": 1}
    err = refusal(PLANS / "mavsdk_sample_2018.plan")  # refused for its take-off 9 m from home, not its fence
    assert err.key == "mission.items[0].params[4]"


# --- versions --------------------------------------------------------------------------------


def test_versions_the_reader_does_not_know_are_refused_by_name(tmp_path):
    err = refusal(PLANS / "mavsdk_wrong_mission_version.plan")  # MAVSDK's own: mission version 7
    assert (err.key, err.line) == ("mission.version", 53)
    assert "mission version 7 is not one this reader knows: expected 2" in err.reason
    for version, told in ((3, "3"), (None, "null"), ("2", '"2"'), ([], "[]"), (1.5, "1.5")):
        plan = fixture("fence_v1.plan")
        plan["geoFence"]["version"] = version
        err = refusal(write(tmp_path, plan))
        assert err.key == "geoFence.version", str(err)
        assert f"geoFence version {told} is not one this reader knows: expected 1 (one polygon" in err.reason
    plan = fixture("mavsdk_sample.plan")
    del plan["mission"]["version"]
    assert refusal(write(tmp_path, plan)).key == "mission.version"


# --- fence-only plans ----------------------------------------------------------------------------


def test_a_fence_only_plan_gives_its_fence_to_the_toml_steps(tmp_path):
    # MAVSDK's plan without a mission: alone it is refused for what it is, and says what to do
    err = refusal(PLANS / "mavsdk_without_mission.plan")
    assert err.key == "mission.items" and "no mission items (a fence-only plan)" in err.reason
    assert 'plan = "mavsdk_without_mission.plan"' in err.reason
    write(tmp_path, fixture("mavsdk_without_mission.plan"), "fence.plan")
    m = load_mission(toml_beside(tmp_path, "fence.plan", STEPS_5M.format(n=4.0, e=4.0)))
    assert [s.action for s in m.steps] == ["takeoff", "offboard", "goto", "land"]
    assert m.safety.volume.polygons == () and m.safety.volume.circles == ()
    # a fence with corners, saved by QGroundControl with no mission items: its home converts it
    plan = fixture("fence_v1.plan")
    plan["mission"]["items"] = []
    write(tmp_path, plan, "fence.plan")
    m = load_mission(toml_beside(tmp_path, "fence.plan", STEPS_5M.format(n=70.0, e=90.0)))
    assert len(m.safety.volume.polygons) == 1 and m.steps[2].waypoints[0] == (70.0, 90.0, -5.0)
    # the TOML's waypoint outside the plan's fence: refused on the TOML's line
    p = toml_beside(tmp_path, "fence.plan", STEPS_5M.format(n=90.0, e=0.0))
    err = refusal(p)
    assert err.path == str(p) and err.key == "steps[2].waypoints[0]" and "outside every inclusion fence" in err.reason
    assert "waypoints = [[90.0" in p.read_text().splitlines()[err.line - 1]
    # corners but no home to put them around
    del plan["mission"]
    write(tmp_path, plan, "fence.plan")
    err = refusal(toml_beside(tmp_path, "fence.plan", STEPS_5M.format(n=4.0, e=4.0)))
    assert err.key == "mission.plannedHomePosition" and "got null" in err.reason


def test_steps_from_both_the_plan_and_the_toml_are_refused(tmp_path):
    write(tmp_path, fixture("fence_v1.plan"), "fence_v1.plan")
    p = toml_beside(tmp_path, "fence_v1.plan", STEPS_5M.format(n=4.0, e=4.0))
    err = refusal(p)
    assert err.path == str(p) and err.key == "steps" and "fence_v1.plan's mission items" in err.reason
    write(tmp_path, fixture("mavsdk_without_mission.plan"), "fence.plan")
    p = toml_beside(tmp_path, "fence.plan", "")
    err = refusal(p)
    assert err.key == "plan" and "expected [[steps]] in this file" in err.reason


# --- the default volume's refusal points at the fix -----------------------------------------------


def test_the_default_volume_refusal_gives_a_toml_that_flies_the_plan(tmp_path, capsys):
    """MAVSDK's sample flies QGroundControl's default 50 m up and 95 m out: the default volume
    (50 m cylinder, 30 m high) refuses it; the refusal's snippet, written beside the plan as it
    is printed, flies it."""
    plan_path = write(tmp_path, fixture("mavsdk_sample.plan"), "mavsdk_sample.plan")
    err = refusal(plan_path)
    assert err.key == "mission.items[0].params[6]" and "50.0 m above home, limit 30 m" in err.reason
    assert main(["check", str(plan_path)]) == 2
    printed = capsys.readouterr().err.splitlines()
    assert printed[0] == f"companion: error: {err}"
    snippet = [line.removeprefix("companion:     ") for line in printed if line.startswith("companion:     ")]
    assert snippet[:4] == ['name = "mavsdk_sample"', 'plan = "mavsdk_sample.plan"', "[safety.volume]",
                           "max_distance_m = 110    # the plan flies within 95.1 m of home"]
    (tmp_path / "mavsdk_sample.toml").write_text("\n".join(snippet) + "\n")
    m = load_mission(tmp_path / "mavsdk_sample.toml")
    assert (m.safety.volume.max_distance_m, m.safety.volume.max_altitude_m) == (110.0, 60.0)
    # the farthest waypoint, worked from the file: 95.1 m from home, within the 110 m given
    plan = fixture("mavsdk_sample.plan")
    home = plan["mission"]["plannedHomePosition"]
    far = max(math.hypot(*ne_of(it["params"][4], it["params"][5], home))
              for it in plan["mission"]["items"] if it["command"] == 16)
    assert far == pytest.approx(95.1, abs=0.05)


def test_a_fence_refusal_gets_no_volume_snippet(tmp_path):
    plan = fixture("fence_v1.plan")
    for it in plan["mission"]["items"]:
        if it.get("AltitudeMode") == 1:
            it["Altitude"] = it["params"][6] = 20
    home = plan["mission"]["plannedHomePosition"]
    plan["mission"]["items"][1]["params"][5] += math.degrees(30.0 / (R_M * math.cos(math.radians(home[0]))))
    err = refusal(write(tmp_path, plan))
    assert "outside every inclusion fence" in err.reason and err.hint == ""


# --- null, as JSON says it ----------------------------------------------------------------------


def test_null_altitudes_are_called_null(tmp_path):
    """QGroundControl's PX4 SITL test plan: item 5 is "calculated above terrain" (AltitudeMode 3)
    with params[6] null, as QGroundControl saves it without terrain data."""
    plan = fixture("qgc_px4sitl_multirotor.plan")
    items = plan["mission"]["items"]
    assert items[5]["AltitudeMode"] == 3 and items[5]["params"][6] is None
    items[0]["params"][4:6] = plan["mission"]["plannedHomePosition"][:2]  # its take-off is 300 m from home
    del items[4]  # DO_SET_ROI_LOCATION, refused by name
    err = refusal(write(tmp_path, plan))
    assert err.key == "mission.items[4].params[6]"
    assert "got null: AltitudeMode 3 (calculated above terrain) without the altitude" in err.reason
    assert "None" not in str(err)
    items[1]["params"][6] = None
    err = refusal(write(tmp_path, plan))
    assert err.key == "mission.items[1].params[6]" and err.reason == "expected an altitude in metres, got null"


# --- companion check --show ---------------------------------------------------------------------


def test_check_show_prints_the_converted_steps_in_ned(tmp_path, capsys):
    plan = fixture("mavsdk_sample.plan")
    write(tmp_path, plan, "mavsdk_sample.plan")
    p = toml_beside(tmp_path, "mavsdk_sample.plan", "[safety.volume]\nmax_distance_m = 110\nmax_altitude_m = 60\n")
    assert main(["check", "--show", str(p)]) == 0
    out = capsys.readouterr().out
    home = plan["mission"]["plannedHomePosition"]
    shown = [tuple(float(x) for x in m.groups())
             for m in re.finditer(r"waypoints\[\d+\] NED \((-?[\d.]+), (-?[\d.]+), (-?[\d.]+)\) m", out)]
    wps = [ne_of(it["params"][4], it["params"][5], home) for it in plan["mission"]["items"] if it["command"] == 16]
    expected = [(n, e, -50.0) for n, e in wps] + [(0.0, 0.0, -50.0)]
    assert len(shown) == len(expected) == 4  # three waypoints, then RTL: home at the height flown
    assert all(math.dist(a, b) <= 0.09 for a, b in zip(shown, expected))  # printed to 0.1 m: 0.05 per axis
    assert "steps[0] take-off: takeoff to 50 m above home (NED down -50)" in out
    assert out.rstrip().endswith("return and land: land")


# --- item 5: too low for a vehicle on GPS -------------------------------------------------------


def test_check_warns_a_mission_too_low_for_gps_and_names_one_that_is_not(capsys):
    assert main(["check", str(ROOT / "missions" / "waypoints.toml")]) == 0
    out = capsys.readouterr().out
    assert "warning: flies as low as 1.5 m above home" in out and GPS_SAFE_MISSION in out
    safe = load_mission(ROOT / GPS_SAFE_MISSION)
    assert lowest_height_m(safe) >= GPS_MIN_HEIGHT_M
    assert main(["check", str(ROOT / GPS_SAFE_MISSION)]) == 0
    assert "warning" not in capsys.readouterr().out


def test_the_readme_flies_px4_sitl_high_enough_for_its_gps():
    """The README's PX4 SITL line flies a mission whose lowest point is at least
    GPS_MIN_HEIGHT_M (it flew waypoints.toml, 1.5 m up, where SIH's height error reaches the
    ground)."""
    lines = [ln for ln in (ROOT / "README.md").read_text().splitlines()
             if "companion fly" in ln and "udpin://" in ln and "PX4 SITL" in ln]
    assert lines
    for line in lines:
        mission = re.search(r"(missions/\S+\.toml)", line).group(1)
        assert lowest_height_m(load_mission(ROOT / mission)) >= GPS_MIN_HEIGHT_M, line


def test_lowest_height_counts_takeoffs_holds_and_waypoints():
    m = load_plan(PLANS / "fenced_L.plan")
    assert lowest_height_m(m) == pytest.approx(8.0, abs=TOL_M)
    steps = list(m.steps)
    steps.insert(2, Step("hold", "low", duration_s=1.0, position_ned_m=(0.0, 0.0, -2.0)))
    assert lowest_height_m(dataclasses.replace(m, steps=tuple(steps))) == 2.0
    steps[0] = dataclasses.replace(steps[0], altitude_m=1.0)
    assert lowest_height_m(dataclasses.replace(m, steps=tuple(steps))) == 1.0
