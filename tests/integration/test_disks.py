"""Files and disks that fail: a disk that fills mid-flight stops the recording, never the flight; an
--out that cannot be written is refused before anything connects."""

from __future__ import annotations

import resource
import subprocess
import sys

import pytest

from helpers.processes import LOCKSTEP, LOCKSTEP_SPEEDUP, PAPER, PAPER_OUTPUT, ROOT, child_env

pytestmark = pytest.mark.integration

LIMIT_BYTES = 400_000
"""what the companion may write per file: the traffic log passes it a few vehicle seconds into the flight"""


def _small_disk() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT_BYTES, LIMIT_BYTES))  # writes beyond fail: EFBIG


def test_a_disk_that_fills_mid_flight_stops_the_record_and_the_flight_lands(sitl, tmp_path):
    """Each file may hold 400 kB (RLIMIT_FSIZE, the way a full card behaves for a writer: the write
    fails with an error; Python ignores SIGXFSZ): the .tlog reaches it mid-flight. The companion
    says once that the record stopped, flies the mission to the end and lands (exit 0)."""
    s = sitl(*PAPER, *LOCKSTEP, speedup=LOCKSTEP_SPEEDUP)
    r = subprocess.run([sys.executable, "-m", "companion", "fly", str(ROOT / "missions/hold.toml"), "--connect",
                        f"udp://{s.url}", "--out", str(tmp_path), "--no-plots", *PAPER_OUTPUT], cwd=ROOT,
                       capture_output=True, text=True, env=child_env(), timeout=180, preexec_fn=_small_disk)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out
    assert out.count("WARNING: the flight record stopped") == 1, out
    assert "File too large" in out
    assert not s.stop()["armed"]  # landed and disarmed


def test_an_unwritable_out_is_exit_2_with_one_line(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    r = subprocess.run([sys.executable, "-m", "companion", "fly", str(ROOT / "missions/hold.toml"), "--out",
                        str(blocker / "flights")], cwd=ROOT, capture_output=True, text=True, env=child_env(),
                       timeout=30)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and "cannot write the flight record" in lines[0], r.stderr
