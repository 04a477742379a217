"""The durations README.md states for ``make test``, read from its output.

    (time bash .ci/run) 2>&1 | tee ci.log
    python benchmarks/ci_durations.py ci.log
    python benchmarks/ci_durations.py ci.log --readme README.md --commit abc1234   # and write them there

``make test`` prints four pytest runs, each under its ``=== name`` line (tests/run_tiers.sh):
everything but the firmware; then, in two lanes side by side, ArduPilot's tier and PX4 on our plant
with MAVSDK's examples on SIH; then PX4 SIH and its clients alone; and a line per run, "NAME ended
after T s", T counted from the suite's start. This prints each run's count and wall time, the real
autopilots' phase (from the end of the first run to the end of the last) and, where the
log has it (bash's ``time`` or a line ``EXIT n after T s``), the whole run. ``--readme`` replaces
the sentence between README's ``<!-- ci-durations -->`` markers with them, so that no duration
in the README is typed by hand.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

MARKERS = ("<!-- ci-durations -->", "<!-- /ci-durations -->")
SUMMARY = re.compile(r"^=*\s*(?:(\d+) failed, )?(\d+) passed.*? in ([\d.]+)s")
TOTAL = re.compile(r"^(?:real\s+(\d+)m([\d.]+)s|EXIT \d+ after (\d+) s)")
HEADER = re.compile(r"^=== (.+)$")
ENDED = re.compile(r"^(.+) ended after (\d+) s \(exit \d+\)$")
RUNS = {"main": ("everything but the firmware", "everything but the firmware"),
        "px4": ("PX4 SIH", "PX4 SIH, one at a time"),
        "examples": ("PX4 on our plant", "PX4 on the plant and the examples"),
        "ap": ("ArduCopter", "ArduPilot's tier")}
"""key: (how its ``===`` line begins, the name printed)"""

Run = tuple[int, int, float]
"""(failed, passed, seconds) of one pytest run"""


def _key(name: str) -> str | None:
    return next((k for k, (start, _) in RUNS.items() if name.startswith(start)), None)


def durations(text: str) -> tuple[dict[str, Run], dict[str, int], float | None]:
    """Each run's summary by key (:data:`RUNS`), when each ended [s from the suite's start], and the
    whole run [s] if logged."""
    runs: dict[str, Run] = {}
    ended: dict[str, int] = {}
    total, current = None, None
    for line in text.splitlines():
        line = line.strip()
        h = HEADER.match(line)
        if h:
            current = _key(h.group(1))
        m = SUMMARY.match(line)
        if m and current is not None:
            runs[current] = (int(m.group(1) or 0), int(m.group(2)), float(m.group(3)))
        e = ENDED.match(line)
        if e and _key(e.group(1)) is not None:
            ended[_key(e.group(1))] = int(e.group(2))  # type: ignore[index]
        t = TOTAL.match(line)
        if t:
            total = float(t.group(3)) if t.group(3) else 60.0 * int(t.group(1)) + float(t.group(2))
    return runs, ended, total


def firmware_phase_s(ended: dict[str, int]) -> int | None:
    """Wall seconds from the end of the first run to the end of the last (the real autopilots)."""
    if "main" not in ended or len(ended) < 2:
        return None
    return max(ended.values()) - ended["main"]


def sentence(runs: dict[str, Run], firmware_s: int, total: float, commit: str, date: str) -> str:
    """README's words for one fresh-clone run (four summaries, the real autopilots' phase, the whole run)."""
    (main, main_s), (px4, px4_s), (ex, ex_s), (ap, ap_s) = (runs[k][1:] for k in ("main", "px4", "examples", "ap"))
    return (f"From a fresh clone with both builds found (no pip cache, no compiled-kernel cache; "
            f"`.ci/run`, {date}, commit {commit}): {total / 60:.1f} minutes in all ({total:.0f} s) — install "
            f"and lint, {main} tests in {main_s:.0f} s, then the real autopilots in {firmware_s} s: {ap} ArduPilot "
            f"tests ({ap_s:.0f} s) beside {ex} more (PX4 on our plant, MAVSDK's examples) one at a time "
            f"({ex_s:.0f} s), then {px4} PX4 SIH tests one at a time, alone ({px4_s:.0f} s).")


def write_readme(readme: Path, text: str) -> None:
    """``text`` between README's markers (whatever was there goes)."""
    doc = readme.read_text()
    start, end = doc.find(MARKERS[0]), doc.find(MARKERS[1])
    if start < 0 or end < start:
        raise SystemExit(f"{readme}: no {MARKERS[0]} ... {MARKERS[1]} to write between")
    readme.write_text(doc[:start + len(MARKERS[0])] + "\n" + text + "\n" + doc[end:])


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", type=Path)
    ap.add_argument("--readme", type=Path, help="write the durations between this file's markers")
    ap.add_argument("--commit", default="?", help="the commit the run tested (README states it)")
    ap.add_argument("--date", default=time.strftime("%Y-%m-%d", time.gmtime()))
    args = ap.parse_args(argv)
    runs, ended, total = durations(args.log.read_text(errors="replace"))
    for key, (_, name) in RUNS.items():
        if key in runs:
            failed, passed, seconds = runs[key]
            print(f"{name}: {passed} passed{f', {failed} failed' if failed else ''} in {seconds:.0f} s")
    firmware_s = firmware_phase_s(ended)
    if firmware_s is not None:
        print(f"the real autopilots (two lanes side by side, then PX4 SIH alone): {firmware_s} s")
    if total is not None:
        print(f"in all: {total:.0f} s ({total / 60:.1f} minutes)")
    if args.readme is not None:
        if len(runs) != 4 or firmware_s is None or total is None or any(r[0] for r in runs.values()):
            raise SystemExit("--readme: the log must hold four passing runs, when each ended, and the whole run's time")
        write_readme(args.readme, sentence(runs, firmware_s, total, args.commit, args.date))
        print(f"written to {args.readme}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
