"""``sitl --firmware``: one command starts the firmware on the plant, prints where to connect, and
Ctrl-C stops both processes, leaving nothing running."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

from sitl.firmware.builds import arducopter_binary, px4_build

pytestmark = [pytest.mark.autopilot, pytest.mark.integration]

WHERE = {"px4": ("udpin://0.0.0.0:14546", ["px4", "-d", "-i", "6"]),
         "ardupilot": ("tcp://127.0.0.1:5820", ["arducopter", "-I", "6"])}


def _running(argv_fragment: list[str]) -> list[str]:
    out = subprocess.run(["ps", "-eww", "-o", "pid,args"], capture_output=True, text=True).stdout.splitlines()
    return [line for line in out if all(f" {a}" in f" {line} " or line.split()[1].endswith(a) for a in argv_fragment)
            and "pytest" not in line]


@pytest.mark.parametrize("firmware", ["px4", "ardupilot"])
def test_ctrl_c_stops_the_firmware_and_the_bridge(firmware):  # type: ignore[no-untyped-def]
    build, why = (px4_build if firmware == "px4" else arducopter_binary)()
    if build is None:
        pytest.skip(why)
    url, argv = WHERE[firmware]
    p = subprocess.Popen([sys.executable, "-m", "sitl", "--firmware", firmware, "--instance", "6", "--speedup", "4"],
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
