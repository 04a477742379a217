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

**A wrap is not a jump.** ``time_boot_ms`` (uint32 ms) wraps to 0 after 49.7 days of uptime;
``time_usec`` runs on. The link says which kind each stamp is (``wraps``), and a wrapping stamp
is unwrapped about the newest believed one (:func:`companion.mavlink.boot_time.unwrap_boot_s`)
before the rules above judge it. A stamp just past 0 after one near 2^32 ms is then a few
milliseconds later, believed (counted ``stamp_wrapped``) and placed at the vehicle's true time
since boot, where its ``time_usec`` streams already are. What the rules refuse stays refused: a
stamp far behind the newest unwraps to far behind; a stamp near 0 that would put the vehicle
further past the wrap than it can have lived since is a jump forward.

Which wrap a vehicle is on cannot be told from ``time_boot_ms`` alone. The first stamp of a
link is taken as wrap 0; when the link's first believed stamps were all ``time_boot_ms`` and,
within ``epoch_learn_s`` (wall) of the first, a ``time_usec`` stamp arrives a whole number of
periods ahead of them (a vehicle up for more than 49.7 days), that is the vehicle's time: the
base moves there once (counted ``stamp_epoch_learned``; the clock and the held stamps start over,
as for a rebase), before anything can have flown on it.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

from companion.mavlink.boot_time import BOOT_MS_PERIOD_S, unwrap_boot_s

__all__ = ["StampGate", "Admitted", "UNIX_EPOCH_MIN_S"]

SEEN_RATE_SPAN_S = 0.1
"""wall seconds of believed stamps before their own rate counts for the jump bound"""
UNIX_EPOCH_MIN_S = 1.0e9
"""stamps at or above this many seconds are UNIX time (2001-09-09), not time since boot"""


MAX_REBASE_CANDIDATES = 1000
"""samples kept while judging a new base (the newest; bounds a flood)"""


@dataclass(frozen=True)
class Admitted:
    """What to do with a sample: use its data at ``t_s`` (vehicle seconds); feed the clock or not."""

    t_s: float
    feeds_clock: bool


@dataclass
class StampGate:
    max_rate: float = 4.0
    """the most vehicle seconds per wall second a stamp may advance, as a factor of the fitted
    clock rate (``rate`` below); a simulated vehicle fitted at 10x may advance 40 s per wall s.
    A free-running simulator changes pace with its host's load and with lockstep: PX4 flew at
    ~8x in lockstep and up to its 20x bound outside it, and at a factor of 2 every stamp was
    refused as a jump until a rebase, while the vehicle flew blind for seconds"""
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
    epoch_learn_s: float = 2.0
    """wall seconds after the first stamp within which a ``time_usec`` stamp may still say which
    wrap of ``time_boot_ms`` the vehicle is on (see the module's docstring)"""
    rebases: int = 0
    wraps: int = 0
    """wraps of ``time_boot_ms`` believed (the newest wrapping stamp's whole periods)"""
    _candidate: list[tuple[float, float]] = field(default_factory=list)
    _base: tuple[float, float] = (math.nan, math.nan)
    """(stamp, wall) of this base's first believed stamp: the rate the stamps show"""
    _first_wall: float = -math.inf
    _epoch_known: bool = False
    """a believed stamp of a field that does not wrap has fixed which wrap the vehicle is on"""

    def admit(self, stamp_s: float, wall: float, rate: float = 1.0, wraps: bool = False) -> Admitted | None:
        """Judge one sample's stamp (seconds as sent) that arrived at ``wall``; ``rate`` is the
        clock's fitted vehicle seconds per wall second; ``wraps``: the stamp may be a
        ``time_boot_ms`` (seconds modulo 2^32 ms), unwrapped here (one of a period or more has not
        wrapped). None: refuse the sample."""
        if not math.isfinite(stamp_s) or stamp_s < 0.0:
            self.counts["stamp_invalid"] += 1
            return None
        if wraps and stamp_s < BOOT_MS_PERIOD_S:
            return self._admit_wrapping(stamp_s, wall, rate)
        if stamp_s >= UNIX_EPOCH_MIN_S:
            self.counts["stamp_unix_time"] += 1
            if not math.isfinite(self.newest_s):
                return None  # nothing to place it at yet
            return Admitted(self.newest_s, False)
        if self._learns_epoch(stamp_s, wall, rate):
            return Admitted(stamp_s, True)
        admitted = self._judge(stamp_s, stamp_s, wall, rate, wraps=False)
        if admitted is not None:
            self._epoch_known = True
        return admitted

    def _admit_wrapping(self, raw_s: float, wall: float, rate: float) -> Admitted | None:
        """A ``time_boot_ms`` stamp: unwrapped about the newest believed stamp, then judged. A
        change of base starts from the raw value (a vehicle that restarted is up for less than a wrap)."""
        stamp_s = unwrap_boot_s(raw_s, self.newest_s) if math.isfinite(self.newest_s) else raw_s
        admitted = self._judge(stamp_s, raw_s, wall, rate, wraps=True)
        if admitted is not None:
            wraps = round((admitted.t_s - raw_s) / BOOT_MS_PERIOD_S)
            if wraps > self.wraps:
                self.counts["stamp_wrapped"] += wraps - self.wraps
                self.wraps = wraps
        return admitted

    def _allowed_ahead(self, wall: float, rate: float) -> float:
        """How far past the newest believed stamp the vehicle can have lived by ``wall`` [vehicle s],
        at the fitted ``rate`` or the rate the believed stamps of this base show, whichever is more
        (the clock starts at 1x and fits only after half a second: a fast simulated vehicle and a
        stall of ours before that had every later stamp refused)."""
        rate = max(rate, 1.0, self._seen_rate())
        return max(self.max_rate * rate * max(wall - self.newest_wall, 0.0), 0.0) + self.slack_s

    def _seen_rate(self) -> float:
        """Vehicle seconds per wall second between this base's first and newest believed stamps."""
        span = self.newest_wall - self._base[1]
        return (self.newest_s - self._base[0]) / span if span >= SEEN_RATE_SPAN_S else 0.0

    def _judge(self, stamp_s: float, rebase_s: float, wall: float, rate: float, wraps: bool) -> Admitted | None:
        """The rules of the module's docstring for one (unwrapped) stamp; ``rebase_s``: the value a
        change of base would start from."""
        if not math.isfinite(self.newest_s):
            self._first_wall = wall
            self._accept(stamp_s, wall)
            return Admitted(stamp_s, True)
        ahead = stamp_s - self.newest_s
        if -self.back_window_s <= ahead <= self._allowed_ahead(wall, rate):
            if ahead > 0.0:
                self._accept(stamp_s, wall)
            self.consistent_wall = max(self.consistent_wall, wall)
            self._candidate.clear()
            return Admitted(stamp_s, True)
        self.counts["stamp_jump_forward" if ahead > 0.0 else "stamp_backwards"] += 1
        if self._consider_rebase(rebase_s, wall, rate):
            self.wraps, self._epoch_known, self._first_wall = 0, not wraps, wall
            return Admitted(rebase_s, True)
        return None

    def _learns_epoch(self, stamp_s: float, wall: float, rate: float) -> bool:
        """A ``time_usec`` stamp whole wraps ahead of the ``time_boot_ms`` stamps believed so far,
        early in the link: the vehicle has been up that long. The base moves there once."""
        if self._epoch_known or not math.isfinite(self.newest_s) or wall - self._first_wall > self.epoch_learn_s:
            return False
        ahead = stamp_s - self.newest_s
        k = round(ahead / BOOT_MS_PERIOD_S)
        if k < 1 or not -self.back_window_s <= ahead - k * BOOT_MS_PERIOD_S <= self._allowed_ahead(wall, rate):
            return False
        self.counts["stamp_epoch_learned"] += 1
        self.rebases += 1
        self.wraps += k
        self._epoch_known = True
        self._candidate.clear()
        self._accept(stamp_s, wall)
        return True

    def _accept(self, stamp_s: float, wall: float) -> None:
        if not math.isfinite(self.newest_s):
            self._base = (stamp_s, wall)
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
        # the newest samples that are both enough and span enough wall time (several streams
        # interleave: 20 samples of attitude, position and IMU span only ~0.08 s)
        while len(c) > self.rebase_samples and (c[-1][1] - c[1][1] >= self.rebase_span_s
                                                or len(c) > MAX_REBASE_CANDIDATES):
            del c[0]
        if (len(c) >= self.rebase_samples and c[-1][1] - c[0][1] >= self.rebase_span_s
                and wall - self.consistent_wall >= self.rebase_silence_s):
            self.counts["stamp_rebased"] += 1
            self.rebases += 1
            self.newest_s = math.nan  # a new base: its rate is learnt afresh
            self._accept(stamp_s, wall)
            c.clear()
            return True
        return False
