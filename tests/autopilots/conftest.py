"""The real-autopilot tier: PX4 v1.16 SIH and ArduCopter SITL, found through PX4_SITL_BUILD and
ARDUCOPTER_SITL (tests/helpers/firmware.py). Without a build each test is reported skipped with the reason."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from helpers.processes import CompanionProcess, kill_left_over
from helpers.firmware import find_arducopter, find_px4


@pytest.fixture(scope="session")
def px4_build() -> Path:
    build, why = find_px4()
    if build is None:
        pytest.skip(why)
    return build


@pytest.fixture(scope="session")
def arducopter_binary() -> Path:
    binary, why = find_arducopter()
    if binary is None:
        pytest.skip(why)
    return binary


@pytest.fixture
def companion(tmp_path):
    procs: list[CompanionProcess] = []

    def start(mission: str, url: str, *args: str) -> CompanionProcess:
        p = CompanionProcess(mission, url, tmp_path / "flights", *args)
        procs.append(p)
        return p

    yield start
    kill_left_over(procs)


def segments(flight: Path) -> dict:
    data = json.loads((flight / "segments.json").read_text())
    return {s["name"]: s for s in data["segments"]} | {"_summary": data}
