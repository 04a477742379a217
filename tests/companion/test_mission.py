"""Mission files: every mistake is named with its file, line, key and what was expected."""


from companion.mission import load_mission
from helpers.missions import goto_mission, load_text, refusal

GOOD = goto_mission('[controller]\nposition = "pd_do"\n')


def test_a_good_mission_loads(tmp_path):
    m = load_text(tmp_path, GOOD)
    assert m.controller.position == "pd_do"
    assert [s.action for s in m.steps] == ["takeoff", "offboard", "goto", "land"]
    assert m.steps[2].waypoints == ((1.0, 0.0, -1.5), (1.0, 1.0, -1.5))


def test_unknown_action(tmp_path):
    e = refusal(tmp_path, GOOD.replace('action = "goto"', 'action = "fly_to"'))
    assert e.line == 13 and e.key == "steps[2].action" and "expected one of" in e.reason


def test_key_that_does_not_belong_to_the_action(tmp_path):
    e = refusal(tmp_path, GOOD.replace('altitude_m = 1.5', 'altitude_m = 1.5\nduration_s = 3'))
    assert e.line == 8 and e.key == "steps[0].duration_s" and "altitude_m" in e.reason


def test_missing_required_key(tmp_path):
    e = refusal(tmp_path, GOOD.replace("waypoints = [[1, 0, -1.5], [1, 1, -1.5]]\n", ""))
    assert e.key == "steps[2].action" and "'waypoints'" in e.reason


def test_wrong_type_names_the_expected_type(tmp_path):
    e = refusal(tmp_path, GOOD.replace("altitude_m = 1.5", 'altitude_m = "high"'))
    assert e.line == 7 and "expected a number" in e.reason


def test_waypoint_below_ground(tmp_path):
    e = refusal(tmp_path, GOOD.replace("[1, 1, -1.5]]", "[1, 1, 2.0]]"))
    assert e.key == "steps[2].waypoints[1]" and "below the ground" in e.reason


def test_flying_offboard_without_the_offboard_step(tmp_path):
    e = refusal(tmp_path, GOOD.replace('[[steps]]\naction = "offboard"\n\n', ""))
    assert "needs an 'offboard' step" in e.reason and e.line == 9


def test_controller_section_errors(tmp_path):
    e = refusal(tmp_path, GOOD.replace('position = "pd_do"', 'position = "lqr"'))
    assert e.key == "controller.position" and "lqr" in str(e) and e.line == 3
    e = refusal(tmp_path, GOOD.replace('position = "pd_do"', 'position = "pd_do"\nrate_hz = 1000'))
    assert "10..250" in str(e)


def test_no_steps(tmp_path):
    assert "[[steps]]" in refusal(tmp_path, 'name = "x"\n').reason


def test_bundled_missions_load():
    from companion.demo import MISSIONS_DIR

    for p in sorted(MISSIONS_DIR.glob("*.toml")):
        assert load_mission(p).steps


# QGroundControl plans: tests/companion/test_plan.py
