"""The mission envelope: every row refuses a value just outside it (with the file's line and the key),
the failsafe settings that would switch a failsafe off or make it absurd are refused by name, the
rules across keys hold, and docs/missions.md shows the table the code enforces."""

import math
from pathlib import Path

import pytest

from companion.cli import main
from companion.mission import ENVELOPE, load_mission
from companion.mission.envelope import envelope_markdown
from helpers.missions import refusal

ROOT = Path(__file__).resolve().parents[2]

BASE = """name = "m"

[[steps]]
action = "set_param"
param = "SIM_FORCE_X"
value = 0

[[steps]]
action = "takeoff"
altitude_m = 1.5

[[steps]]
action = "offboard"

[[steps]]
action = "hold"
duration_s = 1
yaw_deg = 0

[[steps]]
action = "goto"
waypoints = [[1, 0, -1.5]]
speed_m_s = 1
tolerance_m = 0.15
hold_s = 0
timeout_s = 30

[[steps]]
action = "land"
"""

STEP_OF = {"value": 0, "altitude_m": 1, "duration_s": 3, "yaw_deg": 3, "speed_m_s": 4, "tolerance_m": 4,
           "hold_s": 4, "timeout_s": 4}
"""which step of BASE carries each step key"""

SPECIAL = {"safety.volume.north_m", "safety.volume.east_m", "safety.volume.circles[].radius_m"}
"""rows tested in test_safety_volume (box and fences need more than one key)"""


def with_value(key: str, value: float) -> tuple[str, str, int]:
    """BASE with ``key`` set to ``value``; the key path the error names, and the line it is on."""
    if key.startswith("steps[]."):
        name = key.split(".", 1)[1]
        i = STEP_OF[name]
        lines = BASE.splitlines()
        start = [n for n, line in enumerate(lines) if line == "[[steps]]"][i]
        end = start + 1
        while end < len(lines) and lines[end]:
            end += 1
        body = [line for line in lines[start + 1:end] if not line.startswith(f"{name} =")] + [f"{name} = {value!r}"]
        lines[start + 1:end] = body
        return "\n".join(lines) + "\n", f"steps[{i}].{name}", start + len(body) + 1
    table, name = key.rsplit(".", 1)
    text = f"[{table}]\n{name} = {value!r}\n\n"
    nameline = BASE.index("\n") + 1
    suffix = "[0]" if isinstance(getattr(_default(table), name), tuple) else ""
    return BASE[:nameline] + "\n" + text + BASE[nameline:], key + suffix, 4


def _default(table: str):
    from companion.mission import Mission

    obj = Mission(name="m")
    for part in table.split("."):
        obj = getattr(obj, part)
    return obj


def test_the_base_mission_is_inside(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(BASE)
    assert len(load_mission(p).steps) == 6


@pytest.mark.parametrize("key", sorted(set(ENVELOPE) - SPECIAL))
def test_every_row_refuses_just_outside(tmp_path, key):
    row = ENVELOPE[key]
    span = row.hi - row.lo
    for value in (row.hi + max(1e-6 * abs(row.hi), 0.01 * span), row.lo - max(1e-6 * abs(row.lo), 0.01 * span)):
        if row.zero_means and value <= 0:
            value = row.lo / 2 if row.lo > 0 else -1.0  # 0 itself means something
        text, key_path, line = with_value(key, value)
        e = refusal(tmp_path, text)
        assert e.key == key_path and e.line == line, (key, value, str(e))
        assert "expected" in e.reason and row.unit in e.reason, str(e)


@pytest.mark.parametrize("key", sorted(k for k in set(ENVELOPE) - SPECIAL if not k.startswith("steps[]")))
def test_every_row_accepts_its_default(tmp_path, key):
    """The dataclasses' defaults sit inside the envelope: a file that says nothing is flyable."""
    table, name = key.rsplit(".", 1)
    value = getattr(_default(table), name)
    for v in value if isinstance(value, tuple) else (value,):
        assert ENVELOPE[key].accepts(v), (key, v)


@pytest.mark.parametrize("table, setting, words", [
    ("safety", "telemetry_timeout_s = 0", ["0.05..2 s"]),
    ("safety", "telemetry_timeout_s = -1", ["0.05..2 s"]),
    ("safety", "telemetry_timeout_s = 3600", ["0.05..2 s"]),
    ("safety", "link_lost_s = 1e9", ["0.5..30 s"]),
    ("safety", "stale_hold_s = 0", ["0.1..10 s"]),
    ("safety", "max_tilt_deg = 80", ["5..70 deg"]),
    ("safety", "max_tilt_deg = 0", ["5..70 deg"]),
    ("safety", "max_tilt_deg = -30", ["5..70 deg"]),
    ("safety", "max_rate_deg_s = 5000", ["10..2000 deg/s"]),
    ("reference", "rate_limit_rad_s = 50", ["10..2000 deg/s, given in rad/s", "2864.79 deg/s"]),
    ("controller", "rate_hz = 1000", ["10..250 Hz"]),
    ("controller", "rate_hz = 1", ["10..250 Hz"]),
    ("thrust", "thrust_max_n = -5", ["0.1..2000 N, or 0 (ask the vehicle)"]),
    ("thrust", "hover_throttle = 1.2", ["0.05..0.9"]),
    ("vehicle", "gravity_m_s2 = 98.1", ["9.76..9.84 m/s^2"]),
    ("safety.volume", "max_distance_m = 1e9", ["1..1000 m"]),
    ("safety.volume", "max_altitude_m = 500", ["1..120 m"]),
    ("safety.volume", "max_altitude_m = 0", ["1..120 m"]),
])
def test_failsafes_cannot_be_switched_off_or_made_absurd(tmp_path, capsys, table, setting, words):
    p = tmp_path / "m.toml"
    p.write_text(BASE.replace('name = "m"\n', f'name = "m"\n\n[{table}]\n{setting}\n'))
    assert main(["check", str(p)]) == 2
    err = capsys.readouterr().err
    key = f"{table}.{setting.split(' =')[0]}"
    assert f"{p}:4: {key}" in err, err
    for w in words:
        assert w in err, err


@pytest.mark.parametrize("setting, key, words", [
    ("[thrust]\nthrust_max_n = 6.5", "thrust.thrust_max_n", ["hover throttle within 0.05..0.9", "0.951"]),
    ("[thrust]\nthrust_max_n = 200", "thrust.thrust_max_n", ["0.0309"]),
    ("[safety]\ntelemetry_timeout_s = 1.5\nstale_hold_s = 1", "safety.stale_hold_s", ["at least telemetry_timeout_s"]),
    ("[safety]\nstale_hold_s = 5\nlink_lost_s = 3", "safety.link_lost_s", ["at least stale_hold_s"]),
    ("[vehicle]\nrotor_speed_min_rad_s = 900\nrotor_speed_max_rad_s = 800", "vehicle.rotor_speed_max_rad_s",
     ["more than rotor_speed_min_rad_s"]),
    # the waypoint reference circles a waypoint for ever with these (measured: tests/fuzz/test_fuzz_missions.py)
    ("[trajectory]\nmax_accel_m_s2 = 20\nmax_jerk_m_s3 = 40\nbandwidth_rad_s = 5", "trajectory.max_jerk_m_s3",
     ["at least max_accel_m_s2 * bandwidth_rad_s = 100"]),
    ("[trajectory]\nmax_speed_m_s = 15\nmax_accel_m_s2 = 4\nbandwidth_rad_s = 2", "trajectory.max_speed_m_s",
     ["at most 4 m/s", "cannot brake"]),
])
def test_rules_across_keys(tmp_path, setting, key, words):
    e = refusal(tmp_path, BASE.replace('name = "m"\n', f'name = "m"\n\n{setting}\n'))
    assert e.key == key and e.line is not None and e.line >= 4, str(e)
    for w in words:
        assert w in e.reason, str(e)


def test_thrust_zero_means_ask_the_vehicle(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(BASE.replace('name = "m"\n', 'name = "m"\n\n[thrust]\nthrust_max_n = 0\nhover_throttle = 0\n'))
    assert load_mission(p).thrust.thrust_max_n == 0.0


def test_non_finite_numbers(tmp_path):
    for bad in ("nan", "inf", "-inf"):
        e = refusal(tmp_path, BASE.replace("duration_s = 1", f"duration_s = {bad}"))
        assert e.key == "steps[3].duration_s" and "finite" in e.reason


def test_step_order(tmp_path):
    e = refusal(tmp_path, BASE.replace('[[steps]]\naction = "land"\n', ""))
    assert e.key == "steps[4]" and "ends in the air" in e.reason
    e = refusal(tmp_path, BASE.replace('action = "offboard"', 'action = "takeoff"\naltitude_m = 2'))
    assert e.key == "steps[2]" and "already airborne" in e.reason


def test_the_docs_show_the_table_the_code_enforces():
    docs = (ROOT / "docs" / "missions.md").read_text()
    assert envelope_markdown() in docs, "docs/missions.md: paste companion.mission.envelope.envelope_markdown()"


def test_degrees_read_as_degrees():
    row = ENVELOPE["reference.tilt_max_rad"]
    assert row.text() == "5..70 deg, given in rad"
    assert row.accepts(math.radians(70)) and not row.accepts(math.radians(71))


def test_a_goto_speed_the_reference_cannot_brake_from(tmp_path):
    text = BASE.replace("\nspeed_m_s = 1\n", "\nspeed_m_s = 3\n")  # the goto's
    e = refusal(tmp_path, text.replace('name = "m"\n', 'name = "m"\n\n[trajectory]\nmax_accel_m_s2 = 1\n'
                                       'max_jerk_m_s3 = 10\nmax_speed_m_s = 1\n'))
    assert e.key == "steps[4].speed_m_s" and "at most 1 m/s" in e.reason
