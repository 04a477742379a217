"""Fuzzing the mission-file parser: the bundled missions with values replaced by anything TOML can
hold, keys dropped or invented, lines cut or duplicated, bytes garbled; and QGroundControl plans
the same way.

The contract: ``load_mission`` returns a mission whose every number is finite, or raises
:class:`ConfigError` naming the file and where (a line, or the key) — never anything else."""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from companion.config import ConfigError
from companion.mission import Mission, load_mission

from .strategies import FUZZ
from .watchdog import no_hang

ROOT = Path(__file__).resolve().parents[2]
MISSIONS = sorted((ROOT / "missions").glob("*.toml"))
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
    path.write_text(json.dumps({"mission": {"items": items, "plannedHomePosition": home}}))
    check(path)


@pytest.mark.parametrize("path", sorted(CORPUS.glob("*")), ids=lambda p: p.name)
def test_regression_corpus(path: Path) -> None:
    """Mission files that once broke the parser (or let a bad value through)."""
    check(path)
