"""``sitl --firmware``: one command starts the firmware on the plant, prints where to connect, and
Ctrl-C stops both processes, leaving nothing running."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from helpers.firmware import worker_instance
from sitl.firmware.builds import arducopter_binary, px4_build


pytestmark = [pytest.mark.autopilot, pytest.mark.integration]

def where(firmware: str) -> tuple[str, str, list[str]]:
    """A firmware instance of this test process's own (tests/helpers/firmware.py): its number, the
    companion's URL, and the words of the firmware's command line that name it."""
    n = worker_instance(4)
    if firmware == "px4":
        return str(n), f"udpin://0.0.0.0:{14540 + n}", ["px4", "-d", "-i", str(n)]
    return str(n), f"tcp://127.0.0.1:{5760 + 10 * n}", ["arducopter", "-I", str(n)]


def _running(argv_fragment: list[str]) -> list[str]:
    """The processes whose program is named ``argv_fragment[0]`` and whose arguments hold the rest
    in order, word for word (a word's tail is not a match: ``px4`` ends in 4, the instance number)."""
    program, args = argv_fragment[0], argv_fragment[1:]
    found = []
    for line in subprocess.run(["ps", "-eww", "-o", "pid,args"], capture_output=True, text=True).stdout.splitlines():
        words = line.split()[1:]
        if (words and Path(words[0]).name == program and "pytest" not in line
                and any(words[i:i + len(args)] == args for i in range(1, len(words)))):
            found.append(line)
    return found


@pytest.mark.parametrize("firmware", ["px4", "ardupilot"])
def test_ctrl_c_stops_the_firmware_and_the_bridge(firmware):  # type: ignore[no-untyped-def]
    build, why = (px4_build if firmware == "px4" else arducopter_binary)()
    if build is None:
        pytest.skip(why)
    instance, url, argv = where(firmware)
    p = subprocess.Popen([sys.executable, "-m", "sitl", "--firmware", firmware, "--instance", instance,
                          "--speedup", "4"],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        banner = p.stdout.readline()  # type: ignore[union-attr]
        assert f"companion {url}" in banner, banner
        time.sleep(3.0)
        assert _running(argv), f"{firmware} is not running"
        p.send_signal(signal.SIGINT)
        out, _ = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0 and "sitl: stopped" in out, out
    assert '"firmware_exited": false' in out
    end = time.monotonic() + 5
    while _running(argv) and time.monotonic() < end:
        time.sleep(0.2)
    assert not _running(argv), _running(argv)


@pytest.mark.parametrize("firmware", ["px4", "ardupilot"])
def test_with_a_signing_key_the_firmware_answers_only_signed_frames_and_signs_its_own(firmware, tmp_path):  # type: ignore[no-untyped-def]
    """``sitl --firmware X --signing-key-file K``: the relay is the vehicle's signing end. A client
    with the key hears the firmware's heartbeat and the plant's parameters signed with it, and its
    signed read is answered; the same client's unsigned read of another parameter is dropped and
    counted in the exit report."""
    from pymavlink import mavutil

    from companion.mavlink.signing import SignatureCheck, enable_signing, write_key_file

    build, why = (px4_build if firmware == "px4" else arducopter_binary)()
    if build is None:
        pytest.skip(why)
    key = write_key_file(tmp_path / "key")
    instance, url, _ = where(firmware)
    p = subprocess.Popen([sys.executable, "-m", "sitl", "--firmware", firmware, "--instance", instance,
                          "--speedup", "4", "--signing-key-file", str(tmp_path / "key")],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    conn = None
    try:
        assert "signing on" in p.stdout.readline()  # type: ignore[union-attr]
        p.stdout.readline()  # type: ignore[union-attr]  # the banner
        address = url.replace("udpin://", "udpin:").replace("tcp://", "tcp:")
        conn = mavutil.mavlink_connection(address, source_system=255, source_component=190, autoreconnect=True)
        check = SignatureCheck(key)  # the project's check of what arrives: signed with the key, in time
        heartbeat = None
        end = time.monotonic() + 60
        while heartbeat is None and time.monotonic() < end:
            if firmware == "ardupilot":
                conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                        mavlink.MAV_STATE_ACTIVE)  # ArduPilot's serial speaks when spoken to
            heartbeat = conn.recv_match(type="HEARTBEAT", blocking=True, timeout=1.0)
        assert heartbeat is not None and check.verdict(heartbeat) is None, "no heartbeat signed with the key"
        sysid = heartbeat.get_srcSystem()
        plain = mavutil.mavlink.MAVLink(conn, srcSystem=255, srcComponent=190)
        enable_signing(conn.mav, key)
        answers: dict[str, object] = {}
        end = time.monotonic() + 30
        while "SIM_FORCE_X" not in answers and time.monotonic() < end:
            conn.write(plain.param_request_read_encode(sysid, 25, b"SIM_FORCE_Y", -1).pack(plain))
            conn.mav.param_request_read_send(sysid, 25, b"SIM_FORCE_X", -1)
            msg = conn.recv_match(type="PARAM_VALUE", blocking=True, timeout=1.0)
            if msg is not None:
                answers[msg.param_id] = msg
        assert "SIM_FORCE_X" in answers and check.verdict(answers["SIM_FORCE_X"]) is None
        assert "SIM_FORCE_Y" not in answers
        p.send_signal(signal.SIGINT)
        out, _ = p.communicate(timeout=30)
    finally:
        if conn is not None:
            conn.close()
        if p.poll() is None:  # a failed assertion: stop it as Ctrl-C does, so the firmware goes too
            p.send_signal(signal.SIGINT)
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
    assert '"unsigned PARAM_REQUEST_READ"' in out, out
