"""The flavour rules as pure answers: no vehicle, no plant, no socket (each test runs in microseconds)."""

import math

import pytest

from sitl.autopilot.flavours import RULES, CopterRules, Mode, Px4Rules, rules_for

PX4, COPTER = Px4Rules(), CopterRules()


@pytest.mark.parametrize("rules", list(RULES.values()), ids=list(RULES))
def test_every_mode_a_flavour_has_comes_back_from_its_own_number(rules):
    """custom_mode and mode_from_command are inverse on the flavour's modes (ArduCopter's take-off runs
    inside GUIDED, so its number reads back as GUIDED)."""
    for mode in Mode:
        if not rules.has_mode(mode):
            continue
        number = rules.custom_mode(mode)
        p2, p3 = (number, 0) if rules is RULES["ardupilot"] else ((number >> 16) & 0xFF, (number >> 24) & 0xFF)
        back = rules.mode_from_command(p2, p3)
        assert back == (Mode.GUIDED if rules.name == "ardupilot" and mode == Mode.TAKEOFF else mode), mode


def test_each_flavour_refuses_the_others_stream_mode():
    assert not PX4.has_mode(Mode.GUIDED) and PX4.has_mode(Mode.OFFBOARD)
    assert not COPTER.has_mode(Mode.OFFBOARD) and COPTER.has_mode(Mode.GUIDED)


def test_px4_takes_off_to_an_amsl_altitude_and_copter_to_a_height_above_home_only_in_guided():
    origin = 488.0
    assert PX4.takeoff_height(Mode.HOLD, origin + 2.5, origin, 1.5) == pytest.approx(2.5)
    assert PX4.takeoff_height(Mode.HOLD, math.nan, origin, 1.5) == 1.5  # MIS_TAKEOFF_ALT
    assert PX4.takeoff_height(Mode.HOLD, 2.5, origin, 1.5) == "Takeoff denied: altitude -485.5 m above home"
    assert COPTER.takeoff_height(Mode.GUIDED, 2.5, origin, 1.5) == 2.5
    assert COPTER.takeoff_height(Mode.HOLD, 2.5, origin, 1.5) == "Takeoff denied: not in GUIDED"
    assert COPTER.takeoff_height(Mode.GUIDED, math.nan, origin, 1.5) == "Takeoff denied: altitude nan"
    assert COPTER.takeoff_height(Mode.GUIDED, 150.0, origin, 1.5) == "Takeoff denied: altitude 150.0"


def test_what_each_flavour_shows_and_where_it_returns():
    """PX4 v1.16 shows POSCTL during its offboard-loss descent; ArduCopter shows its mode. After a landing
    PX4 returns to the user's mode, ArduCopter to GUIDED; a take-off ends in HOLD or GUIDED."""
    assert PX4.reported_mode(Mode.LAND, True) == Mode.POSCTL and PX4.reported_mode(Mode.LAND, False) == Mode.LAND
    assert COPTER.reported_mode(Mode.LAND, True) == Mode.LAND
    assert PX4.mode_after_disarm(Mode.OFFBOARD) == Mode.OFFBOARD
    assert COPTER.mode_after_disarm(Mode.OFFBOARD) == Mode.GUIDED
    assert (PX4.after_takeoff, COPTER.after_takeoff) == (Mode.HOLD, Mode.GUIDED)
    assert (PX4.initial_mode, COPTER.initial_mode) == (Mode.HOLD, Mode.MANUAL)
    assert PX4.disarmed_offboard_is_intention and not COPTER.disarmed_offboard_is_intention


def test_an_unknown_flavour_flies_px4s_rules():
    assert rules_for("paper") is RULES["px4"] and rules_for("ardupilot") is RULES["ardupilot"]
