"""README's test durations are written from a CI log, never typed (benchmarks/ci_durations.py)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOG = """\
.ruff check companion sitl tests benchmarks

=== everything but the firmware
........................................................................ [100%]
============================= slowest 25 durations =============================
889 passed in 363.29s (0:06:03)

=== ArduCopter SITL, three at a time
.....................                                                    [100%]
21 passed, 918 deselected in 399.79s (0:06:39)

=== PX4 on our plant, and MAVSDK's examples on SIH, one at a time
.............                                                            [100%]
13 passed, 13 deselected in 50.31s

=== PX4 SIH and its clients, one at a time
................                                                         [100%]
16 passed, 19 deselected in 382.96s (0:06:22)

everything but the firmware ended after 370 s (exit 0)
PX4 on our plant, and MAVSDK's examples on SIH, one at a time ended after 421 s (exit 0)
ArduCopter SITL, three at a time ended after 770 s (exit 0)
PX4 SIH and its clients, one at a time ended after 1155 s (exit 0)
EXIT 0 after 1181 s
"""


def run(tmp_path: Path, log: str, *args: str) -> subprocess.CompletedProcess[str]:
    (tmp_path / "ci.log").write_text(log)
    return subprocess.run([sys.executable, str(ROOT / "benchmarks/ci_durations.py"), str(tmp_path / "ci.log"), *args],
                          capture_output=True, text=True, timeout=60)


def test_the_durations_are_read_from_the_four_runs_the_lanes_and_the_whole_run(tmp_path):
    r = run(tmp_path, LOG)
    assert r.returncode == 0, r.stderr
    assert "everything but the firmware: 889 passed in 363 s" in r.stdout
    assert "PX4 SIH, one at a time: 16 passed in 383 s" in r.stdout
    assert "ArduPilot's tier: 21 passed in 400 s" in r.stdout
    assert "PX4 on the plant and the examples: 13 passed in 50 s" in r.stdout
    assert "the real autopilots (two lanes side by side, then PX4 SIH alone): 785 s" in r.stdout
    assert "in all: 1181 s (19.7 minutes)" in r.stdout


def test_the_readme_sentence_is_replaced_between_its_markers_and_nothing_else(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("before\n<!-- ci-durations -->\nold words\n<!-- /ci-durations -->\nafter\n")
    r = run(tmp_path, LOG, "--readme", str(readme), "--commit", "abc1234", "--date", "2026-12-05")
    assert r.returncode == 0, r.stderr
    text = readme.read_text()
    assert text.startswith("before\n<!-- ci-durations -->\n") and text.endswith("<!-- /ci-durations -->\nafter\n")
    assert "old words" not in text
    assert ("`.ci/run`, 2026-12-05, commit abc1234): 19.7 minutes in all (1181 s) — install and lint, "
            "889 tests in 363 s, then the real autopilots in 785 s: 21 ArduPilot tests (400 s) beside 13 more "
            "(PX4 on our plant, MAVSDK's examples) one at a time (50 s), then 16 PX4 SIH tests one at a time, "
            "alone (383 s).") in text


def test_a_failed_or_partial_run_is_not_written(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text("<!-- ci-durations -->\nold\n<!-- /ci-durations -->\n")
    r = run(tmp_path, LOG.replace("21 passed, 918", "1 failed, 20 passed, 918"), "--readme", str(readme))
    assert r.returncode != 0 and "old" in readme.read_text()
    r = run(tmp_path, LOG.replace("EXIT 0 after 1181 s\n", ""), "--readme", str(readme))
    assert r.returncode != 0 and "old" in readme.read_text()


def test_the_readme_carries_the_markers():
    text = (ROOT / "README.md").read_text()
    start, end = text.index("<!-- ci-durations -->"), text.index("<!-- /ci-durations -->")
    assert "minutes in all" in text[start:end]
