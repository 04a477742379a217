"""The durations README.md states for ``make test``, read from its output.

    (time bash .ci/run) 2>&1 | tee ci.log
    python benchmarks/ci_durations.py ci.log
    python benchmarks/ci_durations.py ci.log --readme README.md --commit abc1234   # and write them there

``make test`` prints four pytest summaries in order, one run after the other (tests/run_tiers.sh):
everything but the firmware; PX4 SIH and its clients, one at a time; PX4 on our plant and MAVSDK's
examples on SIH, one at a time; ArduPilot's tier. This prints each one's count and wall time and,
where the log has it (bash's ``time`` or a line ``EXIT n after T s``), the whole run.
``--readme`` replaces the sentence between README's ``<!-- ci-durations -->`` markers with them,
so that no duration in the README is typed by hand.
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


def durations(text: str) -> tuple[list[tuple[int, int, float]], float | None]:
    """(failed, passed, seconds) of each pytest summary in order, and the whole run [s] if logged."""
    runs, total = [], None
    for line in text.splitlines():
        m = SUMMARY.match(line.strip())
        if m:
            runs.append((int(m.group(1) or 0), int(m.group(2)), float(m.group(3))))
        t = TOTAL.match(line.strip())
        if t:
            total = float(t.group(3)) if t.group(3) else 60.0 * int(t.group(1)) + float(t.group(2))
    return runs, total


def sentence(runs: list[tuple[int, int, float]], total: float, commit: str, date: str) -> str:
    """README's words for one fresh-clone run (four summaries, the whole run)."""
    (_, main, main_s), (_, px4, px4_s), (_, examples, examples_s), (_, ap, ap_s) = runs
    return (f"From a fresh clone with both builds found (no pip cache, no compiled-kernel cache; "
            f"`.ci/run`, {date}, commit {commit}): {total / 60:.1f} minutes in all ({total:.0f} s) — install "
            f"and lint, {main} tests in {main_s:.0f} s, {px4} PX4 SIH tests one at a time in {px4_s:.0f} s, "
            f"{examples} more (PX4 on our plant, MAVSDK's examples) one at a time in {examples_s:.0f} s, "
            f"{ap} ArduPilot tests in {ap_s:.0f} s.")


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
    runs, total = durations(args.log.read_text(errors="replace"))
    names = ["everything but the firmware", "PX4 SIH, one at a time", "PX4 on the plant and the examples",
             "ArduPilot's tier"]
    for name, (failed, passed, seconds) in zip(names, runs):
        print(f"{name}: {passed} passed{f', {failed} failed' if failed else ''} in {seconds:.0f} s")
    if len(runs) == 4:
        print(f"pytest in all: {sum(r[2] for r in runs):.0f} s")
    if total is not None:
        print(f"in all: {total:.0f} s ({total / 60:.1f} minutes)")
    if args.readme is not None:
        if len(runs) != 4 or total is None or any(failed for failed, _, _ in runs):
            raise SystemExit("--readme: the log must hold four passing summaries and the whole run's time")
        write_readme(args.readme, sentence(runs, total, args.commit, args.date))
        print(f"written to {args.readme}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
