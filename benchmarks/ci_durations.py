"""The durations README.md states for ``make test``, read from its output.

    (time bash .ci/run) 2>&1 | tee ci.log
    python benchmarks/ci_durations.py ci.log

``make test`` prints three pytest summaries in order: everything but the firmware, then PX4's tier,
then ArduPilot's (docs/autopilots.md). This prints each one's count and wall time and, where the
log has it (bash's ``time`` or a line ``EXIT n after T s``), the whole run.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

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


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    runs, total = durations(Path(argv[0]).read_text(errors="replace"))
    names = ["everything but the firmware", "PX4's tier", "ArduPilot's tier"]
    for name, (failed, passed, seconds) in zip(names, runs):
        print(f"{name}: {passed} passed{f', {failed} failed' if failed else ''} in {seconds:.0f} s")
    if len(runs) == 3:
        print(f"the two tiers: {runs[1][2] + runs[2][2]:.0f} s one after the other, "
              f"{max(runs[1][2], runs[2][2]):.0f} s if side by side")
    if total is not None:
        print(f"in all: {total:.0f} s ({total / 60:.1f} minutes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
