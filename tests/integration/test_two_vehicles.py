"""More than one vehicle on a link (issue 22 item 1): two bundled vehicles (sysid 1 and 2) behind a
router that fans every vehicle's datagrams in to the companion and the companion's out to every
vehicle, as mavlink-router or MAVProxy with several outputs does. The router reads what the
companion addresses, and what each vehicle says, from the real frames it forwards."""

from __future__ import annotations

import select
import socket
import threading
from collections import Counter

from pymavlink.dialects.v20 import common as mavlink

from companion.mavlink.wire import new_parser, parse_datagram
from helpers.missions import hold_mission

MISSION = hold_mission("two", 2.0, controller=False, volume=(10.0, 6.0), hold_name=None)


class Router(threading.Thread):
    """One UDP port for the companion; one socket per vehicle. Counts, per system id, the frames
    the companion addressed to it (by kind), and for each vehicle whether it armed and how high
    it went."""

    def __init__(self, vehicles: list[str]) -> None:
        super().__init__(daemon=True)
        self.front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.front.bind(("127.0.0.1", 0))
        self.url = f"udp://127.0.0.1:{self.front.getsockname()[1]}"
        self.backs = []
        for v in vehicles:
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            s.bind(("127.0.0.1", 0))
            host, port = v.rsplit(":", 1)
            self.backs.append((s, (host, int(port))))
        self.client: tuple[str, int] | None = None
        self.addressed: Counter[tuple[int, str]] = Counter()
        self.armed: set[int] = set()
        self.lowest_z: dict[int, float] = {}
        self.stop = threading.Event()
        self._up, self._down = new_parser(), new_parser()

    def run(self) -> None:
        socks = [self.front] + [s for s, _ in self.backs]
        while not self.stop.is_set():
            for s in select.select(socks, [], [], 0.1)[0]:
                data, addr = s.recvfrom(65536)
                if s is self.front:
                    self.client = addr
                    for msg in parse_datagram(self._up, data).messages:
                        target = getattr(msg, "target_system", None)
                        if target is not None:
                            self.addressed[(target, msg.get_type())] += 1
                    for back, vehicle in self.backs:
                        back.sendto(data, vehicle)
                else:
                    for msg in parse_datagram(self._down, data).messages:
                        src = msg.get_srcSystem()
                        if msg.get_type() == "HEARTBEAT" and msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED:
                            self.armed.add(src)
                        elif msg.get_type() == "LOCAL_POSITION_NED":
                            self.lowest_z[src] = min(self.lowest_z.get(src, 0.0), msg.z)
                    if self.client is not None:
                        self.front.sendto(data, self.client)

    def close(self) -> None:
        self.stop.set()
        self.join()
        for s in [self.front] + [s for s, _ in self.backs]:
            s.close()

    def to(self, sysid: int) -> dict[str, int]:
        return {kind: n for (t, kind), n in self.addressed.items() if t == sysid}


def _mission(tmp_path) -> str:
    p = tmp_path / "two.toml"
    p.write_text(MISSION)
    return str(p)


def fly_behind_a_router(tmp_path, sitl, companion, sysids: tuple[int, ...], *args: str):  # type: ignore[no-untyped-def]
    """Bundled vehicles of these system ids behind one router, the companion flying the mission
    through it with ``args``: (exit code, output, router, vehicles)."""
    vehicles = [sitl("--sysid", str(n), speedup=4.0) for n in sysids]
    router = Router([v.url for v in vehicles])
    router.start()
    try:
        code, out = companion(_mission(tmp_path), router.url, *args).finish()
    finally:
        router.close()
    return code, out, router, vehicles


def test_the_chosen_vehicle_flies_and_the_other_is_never_addressed(tmp_path, sitl, companion):
    code, out, router, (v1, v2) = fly_behind_a_router(tmp_path, sitl, companion, (1, 2), "--target-system", "2")
    assert code == 0, out
    assert "flying system 2 component 1 (system 2); ignoring systems 1 on this link" in out
    assert 2 in router.armed and router.lowest_z[2] < -1.2  # vehicle 2 armed and climbed to ~1.5 m
    to2 = router.to(2)
    assert to2["SET_ATTITUDE_TARGET"] > 100 and to2["COMMAND_LONG"] >= 4 and to2["PARAM_SET"] >= 1, to2
    assert 1 not in router.armed and router.lowest_z.get(1, 0.0) > -0.1  # vehicle 1 stayed on the ground
    assert router.to(1) == {}  # not one frame addressed to system 1
    assert not v1.stop()["armed"] and not v2.stop()["armed"]


def test_an_absent_target_is_refused_naming_the_systems_heard(tmp_path, sitl, companion):
    code, out, router, _ = fly_behind_a_router(tmp_path, sitl, companion, (1, 3), "--target-system", "2",
                                               "--connect-timeout", "4")
    assert code != 0 and "no heartbeat from system 2; heard systems 1, 3" in out, out
    assert router.to(1) == {} and router.to(3) == {} and not router.armed


def test_without_a_target_two_autopilots_are_refused(tmp_path, sitl, companion):
    code, out, router, _ = fly_behind_a_router(tmp_path, sitl, companion, (1, 2), "--connect-timeout", "10")
    assert code != 0 and "more than one autopilot on this link: systems 1, 2" in out, out
    assert router.to(1) == {} and router.to(2) == {} and not router.armed


def test_two_vehicles_with_the_same_system_id_are_refused(tmp_path, sitl, companion):
    code, out, router, _ = fly_behind_a_router(tmp_path, sitl, companion, (2, 2), "--target-system", "2",
                                               "--connect-timeout", "10")
    assert code != 0 and "two autopilots claim system 2 component 1" in out, out
    assert not router.armed
    assert "SET_ATTITUDE_TARGET" not in router.to(2) and "PARAM_SET" not in router.to(2), router.to(2)
