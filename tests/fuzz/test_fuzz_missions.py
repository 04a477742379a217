"""Fuzzing the mission-file parser: the bundled missions with values replaced by anything TOML can
hold, keys dropped or invented, lines cut or duplicated, bytes garbled; QGroundControl plans (the
fixtures in tests/data/plans, shaped as QGroundControl writes them) the same way; and missions
generated around the edges of the envelope.

The contract: ``load_mission`` raises :class:`ConfigError` naming the file and where (a line, or
the key) — never anything else — or returns a mission that is inside the envelope and can be
flown by the step types (:mod:`.flyable`: every number within its row, every position inside the
volume, the reference reaching each waypoint within its timeout without leaving the volume, and
the controller's setpoints finite and passed by the guard). What ``check`` accepts, ``fly`` can
fly: they load with this one function."""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import event, given
from hypothesis import strategies as st

from companion.config import ConfigError
from companion.mission import Mission, load_mission

from .flyable import assert_flyable
from .strategies import FUZZ
from .watchdog import no_hang

ROOT = Path(__file__).resolve().parents[2]
MISSIONS = sorted((ROOT / "missions").glob("*.toml"))
PLANS = sorted((ROOT / "tests" / "data" / "plans").glob("*.plan"))
CORPUS = Path(__file__).parent / "corpus" / "missions"

# --- a small TOML writer (enough for mission files: scalars, arrays, tables, arrays of tables) ---


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(data: dict[str, Any]) -> str:
    lines = [f"{json.dumps(k)} = {_value(v)}" for k, v in data.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v))]
    for k, v in data.items():
        if isinstance(v, dict):
            lines.append(f"\n[{json.dumps(k)}]")
            lines += [f"{json.dumps(kk)} = {_value(vv)}" for kk, vv in v.items()]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for item in v:
                lines.append(f"\n[[{json.dumps(k)}]]")
                lines += [f"{json.dumps(kk)} = {_value(vv)}" for kk, vv in item.items()]
    return "\n".join(lines) + "\n"


# --- mutations --------------------------------------------------------------------------------

scalars = st.one_of(
    st.integers(-10**6, 10**6), st.floats(allow_nan=True, allow_infinity=True), st.booleans(),
    st.text(max_size=12), st.sampled_from(["ism_do", "pid", "takeoff", "goto", "hold", "SIM_FORCE_X", ""]),
)
values = st.one_of(scalars, st.lists(scalars, max_size=4), st.lists(st.lists(scalars, max_size=4), max_size=4),
                   st.dictionaries(st.text(max_size=8), scalars, max_size=3))


def _paths(data: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix] if prefix else []
    if isinstance(data, dict):
        for k, v in data.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            out += _paths(v, prefix + (i,))
    return out


def _apply(data: Any, path: tuple, op: str, value: Any, new_key: str) -> None:
    parent = data
    for p in path[:-1]:
        parent = parent[p]
    last = path[-1]
    if op == "replace":
        parent[last] = value
    elif op == "delete":
        del parent[last]
    elif op == "invent" and isinstance(parent, dict):
        parent[new_key or "x"] = value


@st.composite
def mutated_mission(draw: st.DrawFn) -> str:
    base = tomllib.loads(draw(st.sampled_from(MISSIONS)).read_text())
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(base)
        if not paths:
            break
        _apply(base, draw(st.sampled_from(paths)), draw(st.sampled_from(["replace", "replace", "delete", "invent"])),
               draw(values), draw(st.text(max_size=10)))
    text = to_toml(base)
    if draw(st.booleans()):  # and then damage the text itself
        lines = text.splitlines()
        i = draw(st.integers(0, max(0, len(lines) - 1)))
        how = draw(st.integers(0, 3))
        if how == 0:
            del lines[i]
        elif how == 1:
            lines.insert(i, lines[i] if lines else "")
        elif how == 2 and lines:
            j = draw(st.integers(0, len(lines[i])))
            lines[i] = lines[i][:j] + draw(st.text(max_size=5)) + lines[i][j:]
        else:
            lines = lines[:i]
        text = "\n".join(lines)
    return text


# --- the contract ---------------------------------------------------------------------------


def _numbers(obj: Any) -> list[float]:
    if dataclasses.is_dataclass(obj):
        return [x for f in dataclasses.fields(obj) for x in _numbers(getattr(obj, f.name))]
    if isinstance(obj, (list, tuple)):
        return [x for v in obj for x in _numbers(v)]
    if isinstance(obj, float):
        return [obj]
    return []


def check(path: Path) -> Mission | ConfigError:
    with no_hang(seconds=20):
        try:
            mission = load_mission(path)
        except ConfigError as exc:
            assert str(exc).startswith(str(path)), exc
            assert exc.line is not None or exc.key, f"{exc} names neither a line nor a key"
            return exc
    nonfinite = [x for x in _numbers(mission) if not math.isfinite(x)]
    assert not nonfinite, f"{path.read_text()}\nloaded with non-finite numbers"
    assert mission.steps
    with no_hang(seconds=60):
        assert_flyable(mission)
    return mission


@FUZZ
@given(mutated_mission())
def test_a_damaged_mission_loads_clean_or_fails_with_its_line(tmp_path_factory, text: str) -> None:
    path = tmp_path_factory.mktemp("m") / "mission.toml"
    path.write_text(text)
    check(path)


@FUZZ
@given(st.binary(max_size=400))
def test_arbitrary_bytes_are_a_config_error(tmp_path_factory, raw: bytes) -> None:
    path = tmp_path_factory.mktemp("m") / "mission.toml"
    path.write_bytes(raw)
    assert isinstance(check(path), ConfigError) or raw.strip()


plan_items = st.fixed_dictionaries({
    "type": st.sampled_from(["SimpleItem", "ComplexItem", 3]),
    "command": st.one_of(st.sampled_from([16, 22, 20, 21, 178]), st.integers(), st.none(), st.text(max_size=3)),
    "params": st.lists(st.one_of(st.floats(), st.integers(), st.none(), st.text(max_size=3)), max_size=8),
})


@FUZZ
@given(st.lists(plan_items, max_size=6), st.one_of(st.lists(st.floats(), min_size=3, max_size=3),
                                                   st.lists(st.integers(), max_size=4), st.none()))
def test_a_damaged_plan_loads_clean_or_fails(tmp_path_factory, items: list, home: Any) -> None:
    path = tmp_path_factory.mktemp("p") / "survey.plan"
    path.write_text(json.dumps({"fileType": "Plan", "version": 1,
                                "mission": {"items": items, "plannedHomePosition": home}}))
    check(path)


plan_values = st.one_of(values, st.none(), st.sampled_from([0, 2, 3, 10, 16, 20, 21, 22, 93, 178, 2000, -1, -2,
                                                            488.0, 47.3977, 8.5456, 1e9]))


@st.composite
def mutated_plan(draw: st.DrawFn) -> str:
    """A QGroundControl-shaped fixture with 1-3 values replaced, keys dropped or invented."""
    base = json.loads(draw(st.sampled_from(PLANS)).read_text())
    for _ in range(draw(st.integers(1, 3))):
        _apply(base, draw(st.sampled_from(_paths(base))), draw(st.sampled_from(["replace", "replace", "delete",
                                                                                "invent"])),
               draw(plan_values), draw(st.text(max_size=10)))
    return json.dumps(base, indent=4, sort_keys=True, allow_nan=True)


@FUZZ
@given(mutated_plan())
def test_a_damaged_qgroundcontrol_plan_loads_flyable_or_fails_with_its_line(tmp_path_factory, text: str) -> None:
    path = tmp_path_factory.mktemp("p") / "survey.plan"
    path.write_text(text)
    result = check(path)
    event("accepted" if isinstance(result, Mission) else "refused")
    if isinstance(result, ConfigError):
        assert result.line is not None, result


# --- missions generated around the envelope's edges --------------------------------------------


@st.composite
def generated_mission(draw: st.DrawFn) -> str:
    """A mission whose every value is inside or on the edge of its range, except (most of the time)
    one value somewhere that is beyond it; positions anywhere in and around the volume."""
    fields = ["r", "h", "north", "east", "circle", "speed", "accel", "jerk", "bandwidth", "rate", "telemetry",
              "stale", "link", "tilt", "rate_deg", "thrust", "takeoff", "duration", "goto_speed", "timeout",
              "tolerance", "name", "position", "land"]
    bad = draw(st.sampled_from(fields + [None] * 8))

    def val(name: str, lo: float, hi: float) -> float:
        lo, hi = min(lo, hi), max(lo, hi)
        if name == bad:
            span = max(hi - lo, 1.0)
            return draw(st.one_of(st.floats(hi + 1e-6 * span, hi + span), st.floats(lo - span, lo - 1e-6 * span),
                                  st.sampled_from([0.0, -1.0, 1e9])))
        return draw(st.one_of(st.sampled_from([lo, hi]), st.floats(lo, hi)) if lo < hi else st.just(lo))

    def clamp(x: float, lo: float, hi: float) -> float:
        return min(max(x, lo), hi)

    def point(r: float, h: float) -> list[float]:
        k = 1.3 if bad == "position" else 0.7
        r, h = clamp(r, 1.0, 60.0), clamp(h, 1.0, 40.0)
        return [draw(st.floats(-k * r, k * r)), draw(st.floats(-k * r, k * r)), draw(st.floats(-k * h, -0.3))]

    r, h = val("r", 1.0, 60.0), val("h", 1.0, 40.0)
    volume: dict[str, Any] = {"max_distance_m": r, "max_altitude_m": h}
    if draw(st.booleans()):
        rp = clamp(r, 1.0, 60.0)
        volume.update(shape="box", north_m=[val("north", -rp, -0.5), val("north", 0.5, rp)],
                      east_m=[val("east", -rp, -0.5), val("east", 0.5, rp)])
    if draw(st.integers(0, 3)) == 0:  # a fence circle that keeps home in the volume (or, when bad, not)
        rp, inclusion = clamp(r, 1.0, 60.0), draw(st.booleans())
        radius = val("circle", 1.0, rp)
        off = draw(st.floats(0.0, 0.9)) * (radius if inclusion else rp)
        if not inclusion and off <= clamp(radius, 1.0, 1000.0):
            off = clamp(radius, 1.0, 1000.0) + 0.5
        angle = draw(st.floats(0.0, 6.28))
        volume["circles"] = [{"center_ne_m": [off * math.cos(angle), off * math.sin(angle)], "radius_m": radius,
                              "inclusion": inclusion}]
    bw = val("bandwidth", 0.1, 5.0)
    bwp = clamp(bw, 0.1, 5.0)  # for the ranges that depend on it
    accel = val("accel", clamp(0.2 * bwp, 0.1, 20.0), 20.0)  # at least 0.4 m/s possible: 2 accel / bandwidth
    ap = clamp(accel, 0.1, 20.0)
    telemetry = val("telemetry", 0.05, 2.0)
    stale = val("stale", clamp(telemetry, 0.1, 10.0), 10.0)
    data: dict[str, Any] = {
        "name": "../x" if bad == "name" else draw(st.sampled_from(["gen", "a.b-c_1", "_9"])),
        "controller": {"position": draw(st.sampled_from(["ism_do", "pd_do", "pid", "aibc"])),
                       "rate_hz": val("rate", 10.0, 250.0)},
        "trajectory": {"max_speed_m_s": val("speed", 0.1, min(15.0, 2 * ap / bwp)), "max_accel_m_s2": accel,
                       "max_jerk_m_s3": val("jerk", clamp(ap * bwp, 0.5, 500.0), 500.0), "bandwidth_rad_s": bw},
        "safety": {"telemetry_timeout_s": telemetry, "stale_hold_s": stale,
                   "link_lost_s": val("link", clamp(stale, 0.5, 30.0), 30.0), "max_tilt_deg": val("tilt", 5.0, 70.0),
                   "max_rate_deg_s": val("rate_deg", 10.0, 2000.0), "volume": volume},
        "thrust": {"thrust_max_n": draw(st.just(0.0)) if draw(st.booleans()) else val("thrust", 6.9, 123.0)},
    }
    steps: list[dict[str, Any]] = [{"action": "takeoff", "altitude_m": val("takeoff", 0.3, clamp(h, 0.3, 40.0))},
                                   {"action": "offboard"}]
    for _ in range(draw(st.integers(0, 3))):
        if draw(st.booleans()):
            steps.append({"action": "hold", "duration_s": val("duration", 0.01, 30.0),
                          "position_ned_m": point(r, h)})
        else:
            speed = val("goto_speed", 0.1, min(15.0, 2 * ap / bwp))
            # long enough for legs across the volume (the bound the loader checks), or not
            sp = clamp(speed, 0.1, 15.0)
            need = 2.0 * clamp(r, 1.0, 60.0) / sp + sp / ap + ap / 0.5 + 14.0 / bwp
            steps.append({"action": "goto", "waypoints": [point(r, h) for _ in range(draw(st.integers(1, 3)))],
                          "speed_m_s": speed, "timeout_s": val("timeout", min(need, 3600.0), 3600.0),
                          "tolerance_m": val("tolerance", 0.05, 10.0)})
    if bad != "land":
        steps.append({"action": "land"})
    data["steps"] = steps
    return to_toml(data)


@FUZZ
@given(generated_mission())
def test_what_check_accepts_is_inside_the_envelope_and_flyable(tmp_path_factory, text: str) -> None:
    path = tmp_path_factory.mktemp("g") / "gen.toml"
    path.write_text(text)
    result = check(path)
    event("accepted" if isinstance(result, Mission) else f"refused: {result.key.split('[')[0]}")


@pytest.mark.parametrize("path", sorted(CORPUS.glob("*")), ids=lambda p: p.name)
def test_regression_corpus(path: Path) -> None:
    """Mission files that once broke the parser (or let a bad value through)."""
    check(path)
