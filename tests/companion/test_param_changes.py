"""A mission's parameter writes on a link that stops answering: a parameter this flight has already
read and written exists, so silence about it is a lost answer (a link error, the mission stops
and says so), never "no such parameter" (a sim_only step would be skipped without a word: a flight
under 10 % loss once left its weight attached that way). Fed to the real link's receive path."""

from __future__ import annotations

import asyncio

import pytest
from pymavlink.dialects.v20 import common as mavlink

from companion.flight.prepare import ParamChanges
from companion.link.base import LinkError
from companion.link.pymavlink_link import PymavlinkLink
from helpers.links import VEHICLE_PEER, locked_link


async def _vehicle(link: PymavlinkLink, ap: mavlink.MAVLink, sent: list, answering: list[bool],
                   lose: list[int] | None = None) -> None:
    """Answers every read and write of SIM_FORCE_X while ``answering[0]``, as the autopilot's
    component does (its value echoed); the answers to the next ``lose[0]`` reads are lost."""
    value, seen = 0.0, 0
    while True:
        await asyncio.sleep(0.005)
        for m in sent[seen:]:
            if not answering[0] or m.get_type() not in ("PARAM_REQUEST_READ", "PARAM_SET"):
                continue
            if lose and lose[0] > 0 and m.get_type() == "PARAM_REQUEST_READ":
                lose[0] -= 1
                continue
            if m.get_type() == "PARAM_SET":
                value = m.param_value
            link._received(ap.param_value_encode(b"SIM_FORCE_X", value, mavlink.MAV_PARAM_TYPE_REAL32, 40, 7)
                           .pack(ap), VEHICLE_PEER)
        seen = len(sent)


def test_silence_about_a_parameter_written_earlier_in_the_flight_is_a_link_error_not_a_missing_parameter():
    async def main() -> tuple[bool, str, bool]:
        link, ap, _, sent = locked_link(plant=False)
        changes = ParamChanges(link, log=lambda text: None)
        stop, answering = asyncio.Event(), [True]
        reader = asyncio.create_task(link.run(stop))
        vehicle = asyncio.create_task(_vehicle(link, ap, sent, answering))
        await asyncio.sleep(0.02)  # the reader takes in the heartbeat: the autopilot is chosen
        try:
            attached = await changes.set("SIM_FORCE_X", 6.0, "step attach weight")
            answering[0] = False  # the link goes quiet: the reads of the release get no answer
            with pytest.raises(LinkError) as err:
                await changes.set("SIM_FORCE_X", 0.0, "step release weight")
            unknown = await changes.set("SIM_NEVER_HEARD", 1.0, "step")  # never answered, never seen
        finally:
            vehicle.cancel()
            stop.set()
            await reader
        return attached, str(err.value), unknown

    attached, why, unknown = asyncio.run(main())
    assert attached
    assert "SIM_FORCE_X" in why and "no answer" in why, why
    assert unknown is False  # a name never heard of may be missing: the caller decides (sim_only: skipped)


def test_a_parameter_written_earlier_is_asked_for_again_before_its_silence_is_an_error():
    """The three answers to one read lost (10 % loss each way loses all three in 0.7 % of reads: a
    mission under loss once stopped at its release that way): asked as many times again, the fourth
    answer arrives and the write goes through."""
    async def main() -> tuple[bool, bool, int]:
        link, ap, _, sent = locked_link(plant=False)
        changes = ParamChanges(link, log=lambda text: None)
        stop, answering, lose = asyncio.Event(), [True], [0]
        reader = asyncio.create_task(link.run(stop))
        vehicle = asyncio.create_task(_vehicle(link, ap, sent, answering, lose))
        await asyncio.sleep(0.02)
        try:
            attached = await changes.set("SIM_FORCE_X", 6.0, "step attach weight")
            lose[0] = 3
            released = await changes.set("SIM_FORCE_X", 0.0, "step release weight")
        finally:
            vehicle.cancel()
            stop.set()
            await reader
        return attached, released, sum(m.get_type() == "PARAM_REQUEST_READ" for m in sent)

    attached, released, reads = asyncio.run(main())
    assert attached and released
    assert reads >= 5  # the attach's read, then three unanswered and a fourth answered for the release
