"""Before the mission flies: the thrust scale, and the autopilot parameters the flight needs.

Every parameter the companion changes — a preparation's, a mission step's, the take-off
altitude — is changed through :class:`ParamChanges`, which records the value it found
(:mod:`.param_record`) and puts it back when the flight ends: completed, interrupted (SIGINT,
SIGTERM), aborted, or after a lost link (tried for RESTORE_WITHIN_S; what could not be put back
is listed in the summary, as are those a step marked ``keep``).
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from companion.link import LinkError, VehicleLink

from .param_record import ParamRecord, same_value

__all__ = ["ParamChanges", "thrust_scale", "RESTORE_WITHIN_S"]

RESTORE_WITHIN_S = 10.0
"""wall seconds the companion keeps trying to put its parameters back when the flight ends (a lost
link that comes back within them gets them back)"""
RETRY_S = 0.5
"""wall seconds between passes over the parameters not yet put back"""


@dataclass
class ParamChanges:
    """Every parameter write of a flight, through one door: the value found is recorded
    (:class:`~.param_record.ParamRecord`) before the write is sent, and :meth:`restore` puts back
    what the record says."""

    link: VehicleLink
    log: Callable[[str], None]
    record: ParamRecord = field(default_factory=ParamRecord)

    @property
    def pending(self) -> bool:
        """Some parameter still has to be put back."""
        return self.record.pending

    @property
    def not_restored(self) -> dict[str, float]:
        return self.record.summary()["not_restored"]

    async def set(self, name: str, value: float, why: str, keep: bool = False) -> bool:
        """Set ``name`` to ``value``; False if the autopilot has no such parameter. LinkError if it
        refuses the value, or says nothing about a parameter this flight has already written (it
        exists: the answers were lost). ``keep``: the value stays after the flight (a mission step's
        ``keep``)."""
        known = self.record.get(name) is not None
        # a parameter this flight wrote exists: silence about it is lost answers (10 % loss each way
        # loses all three of a read's in 0.7 % of reads), so it is asked twice as often
        have = await self.link.get_param(name, retries=6 if known else 3)
        if have is None:
            if known:
                raise LinkError(f"parameter {name}: no answer from the vehicle (it was written earlier in this flight)")
            return False
        if same_value(have, value):
            if known:  # written before in this flight: a keep moves what it is put back to
                self.record = self.record.written(name, have, value, keep)
            return True
        self.record = self.record.written(name, have, value, keep)
        echoed = await self.link.set_param(name, value)
        if not same_value(echoed, value):
            self.record = self.record.written(name, have, echoed, keep)
            raise LinkError(f"{name} = {value:g} refused (the autopilot keeps {echoed:g})")
        after = "kept after the flight" if keep else "put back when the flight ends"
        self.log(f"{name} {have:g} -> {value:g} ({why}; {after})")
        return True

    async def set_bits(self, name: str, bits: int, why: str) -> bool:
        """Set ``bits`` in an integer bitmask parameter, leaving the others as they are."""
        have = await self.link.get_param(name)
        if have is None:
            return False
        return await self.set(name, float(int(have) | bits), why)

    async def restore(self, within_s: float = RESTORE_WITHIN_S) -> dict[str, float]:
        """Put back every changed parameter, trying again every RETRY_S while the link does not
        answer, for at most ``within_s`` wall seconds (a link that comes back in that time gets
        them); returns those that could not be (name -> the value to set by hand). Cancelled,
        what was not yet put back stays pending: see :meth:`give_up`."""
        end = time.monotonic() + within_s
        while self.record.pending:
            for name, value in self.record.to_restore():
                try:
                    echoed = await self.link.set_param(name, value)
                except LinkError:
                    continue  # no answer: tried again on the next pass
                if same_value(echoed, value):
                    self.record = self.record.restored(name)
                    self.log(f"{name} put back to {value:g}")
                else:  # refused: asking again will not change the autopilot's mind
                    self.record = self.record.not_restored(name)
                    self.log(f"{name} could NOT be put back to {value:g} (the autopilot keeps {echoed:g}): "
                             "set it by hand")
            if not self.record.pending or time.monotonic() >= end:
                break
            await asyncio.sleep(RETRY_S)
        self.give_up()
        return self.not_restored

    def give_up(self) -> None:
        """No more tries: whatever was not put back is listed as such."""
        for name, value in self.record.to_restore():
            self.log(f"{name} could NOT be put back to {value:g}: set it by hand")
        self.record = self.record.give_up()


async def thrust_scale(link: VehicleLink, weight_n: float, configured_n: float, hover_throttle: float
                       ) -> tuple[float, str] | None:
    """Newtons at full normalised thrust, and where the figure came from: the configuration, the
    simulated vehicle's SIM_THRUST_MAX, the autopilot's hover throttle (weight / hover), or the
    mission's ``hover_throttle``. Look-ups of parameters the autopilot does not have end at once on
    an autopilot that answers PARAM_ERROR, else after their retries."""
    if configured_n:
        return configured_n, "configuration"
    sim = await link.get_param("SIM_THRUST_MAX", 0.3, 3)
    if sim:
        return sim, "vehicle SIM_THRUST_MAX"
    names = ("MOT_THST_HOVER", "MPC_THR_HOVER") if link.state.autopilot == "ardupilot" else (
        "MPC_THR_HOVER", "MOT_THST_HOVER")
    for name in names:
        hover = await link.get_param(name, 0.5, 3)
        if hover and 0.05 < hover < 0.95:
            return weight_n / hover, f"vehicle {name} = {hover:.3f}"
    if hover_throttle:
        return weight_n / hover_throttle, "mission hover_throttle"
    return None


GUIDED_TIMEOUT_S = 0.5
"""ArduPilot GUID_TIMEOUT while the companion flies: its default (3 s) keeps a dead companion's last
attitude target, rotated by the last body rates, for 3 s (a vehicle pitched to 39 deg and flew 35 m)"""


async def prepare_ardupilot(params: ParamChanges, log: Callable[[str], None], keep_shaping: bool = False) -> None:
    """What GUIDED needs to fly this controller's attitude targets as the paper means them, each
    change put back at the end:

    - GUID_OPTIONS bit 3: thrust is throttle, not a climb rate;
    - GUID_TIMEOUT short (GUIDED_TIMEOUT_S): a silent companion is noticed in half a second;
    - ATC_RATE_FF_ENAB 0: ArduPilot shapes a commanded attitude by its input time constant
      (ATC_INPUT_TC) when feed-forward is on; that lag alone was 10.3 vs 2.0 cm RMS on the square
      (``keep_shaping``: the mission's or the command line's choice to leave it on);
    - angle boost off: ArduPilot multiplies throttle by 1/cos(tilt) on top of the full thrust we
      send (the vehicle climbed ~15 cm in every turn).

    ANGLE_MAX is left alone: GUIDED does not limit attitude targets to it (37.6 deg flown with 30 set).
    """
    await params.set_bits("GUID_OPTIONS", 8, "thrust is throttle")
    if not await params.set("GUID_TIMEOUT", GUIDED_TIMEOUT_S, "a silent companion is noticed at once"):
        log("GUID_TIMEOUT: no such parameter; a dead companion's last target is held for ArduPilot's default")
    if keep_shaping:
        log("ATC_RATE_FF_ENAB left as it is (ardupilot_shaping): attitude targets are shaped by ATC_INPUT_TC")
    else:
        await params.set("ATC_RATE_FF_ENAB", 0.0, "attitude targets flown as sent, not shaped")
    for name in ("ATC_ANGLE_BOOST", "ANGLE_BOOST"):  # 4.8 / older
        if await params.set(name, 0.0, "no extra throttle in tilt: the controller sends the full thrust"):
            break
