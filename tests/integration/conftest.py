"""Real processes over real UDP on 127.0.0.1: the simulated vehicle and clients that talk to it
(the process helpers are in tests/helpers/processes.py)."""

from __future__ import annotations

import pytest

from helpers.processes import (  # noqa: F401  (re-exported for the tests of this folder)
    Client, CompanionProcess, RelayProcess, SitlProcess, Staller, kill_left_over, child_env, free_udp_port,
    quat_angle_deg)


@pytest.fixture
def sitl():
    procs: list[SitlProcess] = []

    def start(*args: str, speedup: float = 2.0, env: dict[str, str] | None = None,
              port: int | None = None) -> SitlProcess:
        p = SitlProcess(*args, speedup=speedup, env=env, port=port)
        procs.append(p)
        return p

    yield start
    kill_left_over(procs)


@pytest.fixture
def relay():
    procs: list[RelayProcess] = []

    def start(to: str, *args: str) -> RelayProcess:
        p = RelayProcess(to, *args)
        procs.append(p)
        return p

    yield start
    kill_left_over(procs)


@pytest.fixture
def client():
    made: list[Client] = []

    def connect(url: str, source_system: int = 255) -> Client:
        c = Client(url, source_system)
        made.append(c)
        return c

    yield connect
    for c in made:
        c.close()


@pytest.fixture
def companion(tmp_path):
    procs: list[CompanionProcess] = []

    def start(mission: str, url: str, *args: str, env: dict[str, str] | None = None) -> CompanionProcess:
        p = CompanionProcess(mission, url, tmp_path / "flights", *args, env=env)
        procs.append(p)
        return p

    yield start
    kill_left_over(procs)

