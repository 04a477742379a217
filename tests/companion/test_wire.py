"""The datagram parser's two paths agree, datagrams carry several frames, and the .tlog keeps one
record per frame (companion/mavlink/wire.py, udp.py; the recorder)."""

from __future__ import annotations

import asyncio
import random
import socket
import struct

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink import wire
from companion.mavlink.udp import UdpEndpoint


def _telemetry(seed: int) -> list[bytes]:
    """Frames of the kinds a vehicle streams, random fields (MAVLink 2, a few MAVLink 1)."""
    rng = random.Random(seed)
    v2 = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    v1 = mavlink.MAVLink(None, srcSystem=1, srcComponent=1, use_native=False)
    v1.WIRE_PROTOCOL_VERSION = "1.0"
    out = []
    for i in range(60):
        u = [rng.uniform(-10, 10) for _ in range(9)]
        kind = i % 5
        if kind == 0:
            make = v2.attitude_quaternion_encode(i, 1.0, *u[:6])
        elif kind == 1:
            make = v2.local_position_ned_encode(i, *u[:6])
        elif kind == 2:
            make = v2.highres_imu_encode(i, *u[:9], 1000.0, 0.0, 0.0, 20.0, 0xFFFF)
        elif kind == 3:
            make = v2.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                                       mavlink.MAV_STATE_ACTIVE)
        else:
            make = v2.statustext_encode(mavlink.MAV_SEVERITY_WARNING, b"x" * rng.randrange(0, 50))
        mav = v1 if i % 7 == 0 else v2
        out.append(bytes(make.pack(mav)))
    return out


def _as_robust(data: bytes) -> wire.Parsed:
    return wire._robust(wire.new_parser(), data)


def _same(a: wire.Parsed, b: wire.Parsed) -> bool:
    return (a.bad, a.truncated) == (b.bad, b.truncated) and [bytes(m.get_msgbuf()) for m in a.messages] == [
        bytes(m.get_msgbuf()) for m in b.messages]


def test_clean_datagrams_of_several_frames_parse_as_pymavlinks_parser_reads_them():
    frames = _telemetry(1)
    for k in range(0, len(frames), 4):
        data = b"".join(frames[k:k + 4])
        parsed = wire.parse_datagram(wire.new_parser(), data)
        assert parsed.bad == 0 and not parsed.truncated and len(parsed.messages) == len(frames[k:k + 4])
        assert _same(parsed, _as_robust(data))
        assert wire.frames(data) == frames[k:k + 4]


def test_a_damaged_datagram_gets_what_the_robust_parser_gives_it():
    """Flipped bytes, cut ends, garbage before, between and after frames, unknown ids: whatever the
    fast path cannot vouch for goes to pymavlink's robust parser, so the two always agree (a fast
    path that let a bad CRC through, or dropped a good frame after a bad one, fails here)."""
    rng = random.Random(7)
    frames = _telemetry(2)
    kinds = {"flip": 0, "cut": 0, "garbage": 0}
    for trial in range(600):
        data = bytearray(b"".join(rng.sample(frames, rng.randrange(1, 5))))
        how = ("flip", "cut", "garbage")[trial % 3]
        if how == "flip":
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        elif how == "cut":
            del data[rng.randrange(1, len(data)):]
        else:
            at = rng.randrange(len(data) + 1)
            data[at:at] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 6)))
        fast = wire.parse_datagram(wire.new_parser(), bytes(data))
        assert _same(fast, _as_robust(bytes(data))), (how, bytes(data).hex())
        kinds[how] += fast.bad > 0 or fast.truncated
    assert min(kinds.values()) > 50  # each kind of damage was seen as damage, many times


def test_frames_sent_in_one_stretch_share_datagrams_of_bounded_size_in_order():
    frames = _telemetry(3)

    async def scenario() -> list[bytes]:
        rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        rx.bind(("127.0.0.1", 0))
        rx.setblocking(False)
        ep = UdpEndpoint(lambda data, addr: None, coalesce_bytes=400)
        ep.open(("127.0.0.1", 0))
        for f in frames[:30]:  # one stretch: no await between them
            ep.sendto(f, rx.getsockname())
        await asyncio.sleep(0.05)
        ep.sendto(frames[30], rx.getsockname())
        ep.close()  # closing sends what waits
        got = []
        while True:
            try:
                got.append(rx.recv(65535))
            except BlockingIOError:
                break
        rx.close()
        return got

    got = asyncio.run(scenario())
    assert b"".join(got) == b"".join(frames[:31])  # every frame, in order
    assert all(len(d) <= 400 for d in got)
    assert 1 < len(got) < 31  # several frames per datagram, never more than the bound
    assert wire.frames(got[-1]) == [frames[30]]  # a frame after a wait is a datagram of its own
    assert all(wire.frames(d) is not None for d in got)  # never a frame split across datagrams


def test_the_tlog_holds_one_record_per_frame_that_pymavlink_reads_back(tmp_path):
    from companion.flight.recorder import FlightRecorder

    frames = _telemetry(4)
    rec = FlightRecorder(tmp_path)
    rec.traffic(b"".join(frames[:5]))
    rec.traffic(b"\x00\x01not mavlink")  # written as it came, one record
    rec.traffic(frames[5])
    rec.close({})
    raw = (tmp_path / "traffic.tlog").read_bytes()
    assert len(raw) == sum(8 + len(f) for f in frames[:6]) + 8 + 13
    log = mavutil.mavlink_connection(str(tmp_path / "traffic.tlog"))
    kinds = []
    while (m := log.recv_match()) is not None:
        if m.get_type() != "BAD_DATA":
            kinds.append(m.get_type())
    assert kinds == [mavlink.MAVLink(None).decode(bytearray(f)).get_type() for f in frames[:6]]
    assert struct.unpack(">Q", raw[:8])[0] > 0


def test_frames_a_real_arducopter_sent_parse_alike_on_both_paths(tmp_path):
    """Every frame of a ground station's .tlog of ArduCopter SITL (tests/data: its own encoder, its
    own message mix), one per datagram and five to a datagram as a UDP link packs them: the fast
    path gives what pymavlink's robust parser gives, and takes them all as clean."""
    from pathlib import Path

    hexed = Path(__file__).parents[1] / "data" / "arducopter_force_step.tlog.hex"
    (tmp_path / "a.tlog").write_bytes(bytes.fromhex(hexed.read_text()))
    log = mavutil.mavlink_connection(str(tmp_path / "a.tlog"))
    sent = []
    while (m := log.recv_match()) is not None:
        if m.get_type() != "BAD_DATA":
            sent.append(bytes(m.get_msgbuf()))
    assert len(sent) > 1000
    for group in (1, 5):
        for k in range(0, len(sent), group):
            data = b"".join(sent[k:k + group])
            assert wire._clean_frames(wire.new_parser(), data) is not None
            assert _same(wire.parse_datagram(wire.new_parser(), data), _as_robust(data))
