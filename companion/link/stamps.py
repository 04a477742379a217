"""Which telemetry timestamps are believed: the gate in front of the vehicle clock.

Every timestamped sample (ATTITUDE_QUATERNION, LOCAL_POSITION_NED, HIGHRES_IMU, ...) passes
here before it updates :class:`~companion.link.state.VehicleState` or the
:class:`~companion.link.clock.VehicleClock`. One bad stamp used to be enough to wreck a flight: ten
HIGHRES_IMU frames stamped in UNIX time (MAVLink allows either UNIX or boot time in
``time_usec``) moved the clock 1.7e9 s ahead; the controller's time stuck there, the same tilted
setpoint was re-sent forever and no mission timeout fired.

The rules, all in vehicle (boot) seconds:

- **another time base** — ``time_usec`` at UNIX-epoch magnitude (MAVLink: "the receiving end can
  infer the format by checking the magnitude"; boot time would need 31 years of uptime): the
  sample's *data* may be used, placed at the newest believed stamp, but its stamp never reaches
  the clock (counted ``stamp_unix_time``);
- **a jump forward** — further ahead of the newest believed stamp than the vehicle could have
  lived since (``max_rate`` times the wall time since, plus ``slack_s``): refused
  (``stamp_jump_forward``);
- **going backwards** — more than ``back_window_s`` behind the newest: refused
  (``stamp_backwards``); a little behind is a normal, slightly older sample of another stream
  (position lags attitude) and is passed on — :class:`VehicleState` never lets a sample replace a
  newer one of its own stream;
- **a repeat** moves nothing: the clock ignores stamps it has (its "stood still" rule needs the
  newest stamp repeated after a silence, which only the vehicle itself can produce while nothing
  else arrives).

A vehicle that really restarted (its clock back near zero) or a stream that really changed base
would be refused for ever. So refused stamps that agree with *each other* — ``rebase_samples`` of
them, advancing at a plausible rate, over at least ``rebase_span_s`` of wall time — while nothing consistent
with the old base has arrived for ``rebase_silence_s`` (wall), become the new base (counted
``stamp_rebased``). An attacker mixing a few frames into a live stream can never meet that: the
live stream keeps the old base from falling silent.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

__all__ = ["StampGate", "Admitted", "UNIX_EPOCH_MIN_S"]

UNIX_EPOCH_MIN_S = 1.0e9
"""stamps at or above this many seconds are UNIX time (2001-09-09), not time since boot"""


@dataclass(frozen=True)
class Admitted:
    """What to do with a sample: use its data at ``t_s`` (vehicle seconds); feed the clock or not."""

    t_s: float
    feeds_clock: bool


@dataclass
class StampGate:
    max_rate: float = 2.0
    """the most vehicle seconds per wall second a stamp may advance, as a factor of the fitted
    clock rate (``rate`` below); a simulated vehicle at 10x may advance 20 s per wall s"""
    slack_s: float = 0.5
    """vehicle seconds a stamp may lead beyond that (telemetry bursts after a stall of ours)"""
    back_window_s: float = 1.0
    """vehicle seconds behind the newest stamp within which a sample is an older sample, not a jump"""
    rebase_samples: int = 20
    rebase_span_s: float = 0.15
    rebase_silence_s: float = 1.0
    counts: Counter[str] = field(default_factory=Counter)
    newest_s: float = -math.inf
    """the newest believed stamp [vehicle s]"""
    newest_wall: float = -math.inf
    """arrival of the newest believed stamp [wall s]"""
    consistent_wall: float = -math.inf
    """arrival of the latest sample consistent with the current base [wall s]"""
    rebases: int = 0
    _candidate: list[tuple[float, float]] = field(default_factory=list)

    def admit(self, stamp_s: float, wall: float, rate: float = 1.0) -> Admitted | None:
        """Judge one sample's stamp (seconds as sent) that arrived at ``wall``; ``rate`` is the
        clock's fitted vehicle seconds per wall second. None: refuse the sample."""
        if not math.isfinite(stamp_s) or stamp_s < 0.0:
            self.counts["stamp_invalid"] += 1
            return None
        if stamp_s >= UNIX_EPOCH_MIN_S:
            self.counts["stamp_unix_time"] += 1
            if not math.isfinite(self.newest_s):
                return None  # nothing to place it at yet
            return Admitted(self.newest_s, False)
        if not math.isfinite(self.newest_s):
            self._accept(stamp_s, wall)
            return Admitted(stamp_s, True)
        ahead = stamp_s - self.newest_s
        allowed = max(self.max_rate * max(rate, 1.0) * max(wall - self.newest_wall, 0.0), 0.0) + self.slack_s
        if -self.back_window_s <= ahead <= allowed:
            if ahead > 0.0:
                self._accept(stamp_s, wall)
            self.consistent_wall = max(self.consistent_wall, wall)
            self._candidate.clear()
            return Admitted(stamp_s, True)
        self.counts["stamp_jump_forward" if ahead > 0.0 else "stamp_backwards"] += 1
        if self._consider_rebase(stamp_s, wall, rate):
            return Admitted(stamp_s, True)
        return None

    def _accept(self, stamp_s: float, wall: float) -> None:
        self.newest_s, self.newest_wall = stamp_s, wall
        self.consistent_wall = max(self.consistent_wall, wall)

    def _consider_rebase(self, stamp_s: float, wall: float, rate: float) -> bool:
        c = self._candidate
        if c:
            t0, w0 = c[-1]
            step, dwall = stamp_s - t0, wall - w0
            if not (-1e-9 <= step <= self.max_rate * max(rate, 1.0) * max(dwall, 0.0) + self.slack_s):
                c.clear()  # not a consistent new base: start over from this sample
        c.append((stamp_s, wall))
        if len(c) > self.rebase_samples:
            del c[0]
        if (len(c) >= self.rebase_samples and c[-1][1] - c[0][1] >= self.rebase_span_s
                and wall - self.consistent_wall >= self.rebase_silence_s):
            self.counts["stamp_rebased"] += 1
            self.rebases += 1
            self._accept(stamp_s, wall)
            c.clear()
            return True
        return False
