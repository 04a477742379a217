"""A newcomer's first hour: the demo, a wrong port, a malformed --connect, a folder without a record."""

from __future__ import annotations

import os
import selectors
import signal
import subprocess
import sys
import time

import pytest

from helpers.processes import ROOT, child_env, free_udp_port

pytestmark = pytest.mark.integration


def test_ctrl_c_in_the_demo_lands_the_vehicle_and_ends_the_demo(tmp_path):
    """Ctrl-C from the terminal reaches the whole foreground process group. The vehicle runs in a
    session of its own, so only the companion gets it: it holds, lands and disarms the vehicle, and
    the demo does not fly its next mission (it used to: the vehicle died in the air and the demo flew
    on)."""
    demo = subprocess.Popen([sys.executable, "-m", "companion", "demo", "--out", str(tmp_path)], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=child_env(),
                            start_new_session=True)
    sel = selectors.DefaultSelector()
    sel.register(demo.stdout, selectors.EVENT_READ)  # type: ignore[arg-type]
    lines: list[str] = []
    end = time.monotonic() + 120
    while time.monotonic() < end:
        if sel.select(timeout=0.5):
            line = demo.stdout.readline()  # type: ignore[union-attr]
            lines.append(line)
            if "step hover" in line:
                break
    else:
        demo.kill()
        raise AssertionError("".join(lines))
    os.killpg(demo.pid, signal.SIGINT)  # as the terminal does
    out = "".join(lines) + demo.communicate(timeout=120)[0]
    assert demo.returncode == 130, out
    assert "interrupted: holding, then landing" in out and "landed and disarmed" in out, out
    assert "the remaining flights are not flown" in out and "=== waypoints" not in out, out


def test_no_vehicle_says_what_to_check_within_5_s_and_leaves_no_empty_folder(tmp_path):
    """Nothing on the port: within 5 s the companion says what to check (running? port? udp vs
    udpin?), before any hint about signing, and goes on listening (a vehicle may boot after its
    companion) until --connect-timeout; then exit 1 with the same advice, and no flight folder."""
    port = free_udp_port()
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "companion", "fly", "missions/hold.toml", "--connect",
                             f"udp://127.0.0.1:{port}", "--out", str(tmp_path / "flights"), "--no-plots",
                             "--connect-timeout", "8"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, env=child_env())
    hinted_after = None
    lines = []
    for line in proc.stdout:  # type: ignore[union-attr]
        lines.append(line)
        if hinted_after is None and "is the vehicle running" in line:
            hinted_after = time.monotonic() - t0
    proc.wait(timeout=60)
    took = time.monotonic() - t0
    out = "".join(lines)
    assert proc.returncode == 1, out
    assert hinted_after is not None and hinted_after < 5.0 + 1.0, (hinted_after, out)  # 1 s spare: busy host
    assert "still listening" in out and took >= 8.0, (took, out)
    last = out[out.rindex("is the vehicle running"):]
    assert "udpin" in last and last.index("udpin") < last.find("signing")  # hints first
    assert not (tmp_path / "flights").exists() or not any((tmp_path / "flights").iterdir())


@pytest.mark.parametrize("url", ["udp://localhost", "tcp:/x", "udp://127.0.0.1:99999", "serial://", "bogus"])
def test_a_malformed_connect_is_one_line_and_exit_2(tmp_path, url):
    r = subprocess.run([sys.executable, "-m", "companion", "fly", "missions/hold.toml", "--connect", url, "--out",
                        str(tmp_path)], cwd=ROOT, capture_output=True, text=True, env=child_env(), timeout=30)
    assert r.returncode == 2, r.stdout + r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "--connect" in lines[0] and "Traceback" not in r.stderr, r.stderr


def test_plot_of_a_folder_without_a_record_says_so(tmp_path):
    r = subprocess.run([sys.executable, "-m", "companion", "plot", str(tmp_path)], cwd=ROOT, capture_output=True,
                       text=True, env=child_env(), timeout=30)
    assert r.returncode == 2 and "not a flight folder" in r.stderr, r.stderr
