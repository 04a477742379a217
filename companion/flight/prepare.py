"""Before the mission flies: the thrust scale, and the autopilot parameters the flight needs.

Every parameter the companion changes is changed through :class:`ParamChanges`, which remembers
the value it found and puts it back when the flight ends — completed, interrupted, aborted or
after a lost link (best effort then; what could not be put back is listed in the summary).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from companion.link import LinkError, VehicleLink

__all__ = ["ParamChanges", "thrust_scale"]


@dataclass
class ParamChanges:
    link: VehicleLink
    log: Callable[[str], None]
    originals: dict[str, float] = field(default_factory=dict)
    """name -> the value the autopilot had before our first change"""
    not_restored: dict[str, float] = field(default_factory=dict)

    async def set(self, name: str, value: float, why: str) -> bool:
        """Set ``name`` to ``value`` (remembering the original); False if the autopilot has no such
        parameter. LinkError if it refuses the value."""
        have = await self.link.get_param(name)
        if have is None:
            return False
        if math.isclose(have, value, rel_tol=1e-6, abs_tol=1e-9):
            return True
        echoed = await self.link.set_param(name, value)
        self.originals.setdefault(name, have)
        if not math.isclose(echoed, value, rel_tol=1e-6, abs_tol=1e-9):
            raise LinkError(f"{name} = {value:g} refused (the autopilot keeps {echoed:g})")
        self.log(f"{name} {have:g} -> {value:g} ({why}; put back when the flight ends)")
        return True

    async def set_bits(self, name: str, bits: int, why: str) -> bool:
        """Set ``bits`` in an integer bitmask parameter, leaving the others as they are."""
        have = await self.link.get_param(name)
        if have is None:
            return False
        return await self.set(name, float(int(have) | bits), why)

    async def restore(self) -> dict[str, float]:
        """Put back every changed parameter; returns those that could not be (name -> original).
        Cancelled (a deadline), what was not yet put back stays in ``originals``: see :meth:`give_up`."""
        for name, original in reversed(list(self.originals.items())):
            try:
                echoed = await self.link.set_param(name, original)
                if math.isclose(echoed, original, rel_tol=1e-6, abs_tol=1e-9):
                    self.log(f"{name} put back to {original:g}")
                    del self.originals[name]
                    continue
            except LinkError:
                pass
            del self.originals[name]
            self.not_restored[name] = original
            self.log(f"{name} could NOT be put back to {original:g}: set it by hand")
        return dict(self.not_restored)

    def give_up(self) -> None:
        """The link is gone: whatever was not put back is listed as such."""
        for name, original in self.originals.items():
            self.not_restored[name] = original
            self.log(f"{name} could NOT be put back to {original:g}: set it by hand")
        self.originals.clear()


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
