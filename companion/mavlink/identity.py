"""Which vehicle on a link is ours: the target system (and component), every autopilot heard, and
two senders that claim one identity.

A link behind a router (mavlink-router, MAVProxy with several outputs, a swarm radio) carries
several vehicles, told apart only by the MAVLink header's system and component ids. The companion
flies exactly one: the :class:`VehicleTarget` the user chose (``--target-system``, or the mission's
``[target]``), or, with none chosen, the only autopilot heard. :class:`AutopilotsHeard` records
every autopilot heartbeat; :func:`connection_problem` decides, without sockets, whether the link
may be flown.

Two senders with the same system and component ids are told apart in two ways:

* **by address**: heartbeats of one identity from two UDP source addresses (vehicles that send
  straight to a ``udpin://`` port);
* **by sequence number**: behind a router every frame comes from the router's address, but each
  sender numbers its frames with its own 8-bit counter (MAVLink's ``seq``, +1 per frame sent on
  the link). One sender's frames step forward by 1 (a few more over loss); two interleaved senders
  make two such runs. :class:`SequenceStreams` follows the runs ("heads"): a frame extends the head
  it is at most :data:`SEQ_FORWARD` ahead of (the nearest), is a repeat or a late frame if it is at
  most :data:`SEQ_BEHIND` behind one, and starts a new head otherwise. A new head restarts every
  head's count, so an outage (the old head never moves again) is not a second sender; two heads
  that each advance :data:`SEQ_ADVANCES` times after the younger one began are. One autopilot
  reaching the router by two links (a radio and a cable) looks the same on the wire and is
  refused too: its frames arrive twice, with two counters. Two counters within SEQ_BEHIND of each
  other make a single run in which the slower sender's frames repeat numbers just seen: a share
  of repeats above :data:`REPEAT_SHARE` is two senders as well. The limit: a run that meets another
  merges with it, so a sender with under a tenth of the other's rate (a bare heartbeat beside a
  streaming autopilot) is passed over and not seen; two autopilots that both stream telemetry
  are (tests/companion/test_target.py). A forger that wants to be unseen is kept out by signing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["VehicleTarget", "SequenceStreams", "AutopilotsHeard", "connection_problem", "resolve_target", "SURVEY_S",
           "SURVEY_HEARTBEATS", "SURVEY_FRAMES", "SEQ_FORWARD", "SEQ_BEHIND", "SEQ_ADVANCES", "REPEAT_SHARE"]

SEQ_FORWARD = 32
"""a frame at most this far ahead of a head extends it (31 frames lost in a row at most)"""
SEQ_BEHIND = 16
"""a frame at most this far behind a head (or equal) is late or repeated, not another sender"""
SEQ_ADVANCES = 3
"""frames each of two heads must add after the younger began to count as two senders"""
REPEAT_WINDOW = 2 * SEQ_FORWARD
"""a number that arrives again within this many frames is a repeat (past it, the 8-bit counter wrapped)"""
REPEAT_SHARE = 0.25
"""repeats above this share of one identity's frames are a second sender: a poor link duplicates a
few percent (and reordering fills gaps, it repeats nothing); two senders with close counters, half"""
REPEATS_MIN = 20
"""...and at least this many of them (a few duplicates in the first frames are not a second sender)"""
MAX_HEADS = 4
SURVEY_S = 2.0
"""wall seconds the link is listened to after the first autopilot heartbeat before it is flown:
autopilots send a heartbeat a second, so every one on the link is heard even if one is lost"""
SURVEY_FRAMES = 100
"""...and this many of its frames: two senders of one identity each add SEQ_ADVANCES to a run"""
SURVEY_HEARTBEATS = 3
"""...or until the chosen autopilot's third heartbeat, if sooner: two of its own periods, which a
simulated vehicle at 8x sends in 0.25 s of wall time (others on the link run at the same pace)"""


@dataclass(frozen=True)
class VehicleTarget:
    """The vehicle to fly. ``system_id`` 0: the only autopilot on the link (refused if there are
    more); ``component_id`` 0: that system's autopilot, whichever component it is."""

    system_id: int = 0
    component_id: int = 0

    def __post_init__(self) -> None:
        for name in ("system_id", "component_id"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= 255:
                raise ValueError(f"{name}: expected 1..255 (or 0: any), got {v!r}")
        if self.component_id and not self.system_id:
            raise ValueError("component_id: needs a system_id too")

    @property
    def chosen(self) -> bool:
        return self.system_id != 0

    def matches(self, sysid: int, compid: int) -> bool:
        return (self.system_id in (0, sysid)) and (self.component_id in (0, compid))

    def describe(self) -> str:
        if not self.system_id:
            return "the only autopilot on the link"
        return f"system {self.system_id}" + (f" component {self.component_id}" if self.component_id else "")


@dataclass
class _Head:
    seq: int
    advances: int = 0
    last: int = 0
    """the frame count at which it was begun or last extended"""


@dataclass
class SequenceStreams:
    """The runs of sequence numbers in the frames of one identity from one address."""

    heads: list[_Head] = field(default_factory=list)
    late: int = 0
    """frames behind a head or repeated (reordered or duplicated on the way)"""
    repeats: int = 0
    """frames whose number arrived already within the last REPEAT_WINDOW frames (duplicated on the
    way, or a second sender's counter running close behind the first's)"""
    frames: int = 0
    extended: int = 0
    """frames that extended a head (a counting sender's ordinary frames)"""
    seen: list[int] = field(default_factory=lambda: [-REPEAT_WINDOW - 1] * 256)
    """the frame count at which each sequence number last arrived"""

    def add(self, seq: int) -> None:
        self.frames += 1
        if self.frames - self.seen[seq] <= REPEAT_WINDOW:
            self.repeats += 1
        self.seen[seq] = self.frames
        ahead = [((seq - h.seq) % 256, h) for h in self.heads if 1 <= (seq - h.seq) % 256 <= SEQ_FORWARD]
        if ahead:
            _, head = min(ahead, key=lambda it: it[0])
            head.seq, head.advances, head.last = seq, head.advances + 1, self.frames
            self.extended += 1
            self.heads = [h for h in self.heads if h is head or h.seq != seq]  # two runs met: one run
            return
        if any((h.seq - seq) % 256 <= SEQ_BEHIND for h in self.heads):
            self.late += 1
            return
        for h in self.heads:
            h.advances = 0
        self.heads = [*self.heads[-(MAX_HEADS - 1):], _Head(seq, last=self.frames)]

    @property
    def senders(self) -> int:
        """How many senders these frames show: 1, or 2 when two runs both went on, or when repeated
        numbers and numbers counted on are each over :data:`REPEAT_SHARE` of the frames (two
        counters that run within SEQ_BEHIND of each other make one run, every frame of the slower
        sender a repeat; a sender that does not count, every frame number 0, counts nothing on)."""
        if sum(h.advances >= SEQ_ADVANCES for h in self.heads) >= 2:
            return 2
        share = REPEAT_SHARE * self.frames
        return 2 if self.repeats >= REPEATS_MIN and self.repeats > share and self.extended > share else 1


@dataclass
class AutopilotsHeard:
    """Every autopilot identity heard on the link: where its frames came from and their runs."""

    addresses: dict[tuple[int, int], set[object]] = field(default_factory=dict)
    streams: dict[tuple[int, int, object], SequenceStreams] = field(default_factory=dict)

    def heartbeat(self, sysid: int, compid: int, address: object) -> None:
        self.addresses.setdefault((sysid, compid), set()).add(address)
        if len(self.addresses) > 64:  # a flood of invented identities: keep the first ones
            self.addresses.pop((sysid, compid))

    def frame(self, sysid: int, compid: int, address: object, seq: int) -> None:
        """A frame from an identity already heard as an autopilot (others are not followed)."""
        if (sysid, compid) in self.addresses:
            self.streams.setdefault((sysid, compid, address), SequenceStreams()).add(seq)

    def systems(self) -> list[int]:
        return sorted({s for s, _ in self.addresses})

    def claimants(self, sysid: int, compid: int) -> int:
        """How many senders claim this identity: its addresses, or the runs within one."""
        addresses = self.addresses.get((sysid, compid), set())
        if len(addresses) > 1:
            return len(addresses)
        return max((s.senders for (si, ci, _), s in self.streams.items() if (si, ci) == (sysid, compid)), default=1)


def _systems_text(systems: list[int]) -> str:
    return ", ".join(map(str, systems)) if systems else "none"


def connection_problem(target: VehicleTarget, heard: AutopilotsHeard, locked: tuple[int, int] | None) -> str | None:
    """Why the link must not be flown (None: it may). ``locked``: the identity the link follows
    (None: no autopilot matching the target has been heard)."""
    systems = heard.systems()
    if locked is None:
        if target.chosen:
            return (f"no heartbeat from {target.describe()}; heard systems {_systems_text(systems)}"
                    + ("" if systems else " (no autopilot at all)"))
        return None
    if heard.claimants(*locked) > 1:
        return (f"two autopilots claim system {locked[0]} component {locked[1]} (heartbeats from two senders): "
                f"give each vehicle its own system id (PX4 MAV_SYS_ID, ArduPilot SYSID_THISMAV), or reach the "
                f"autopilot by one link; nothing was armed or commanded")
    if not target.chosen and len(systems) > 1:
        return (f"more than one autopilot on this link: systems {_systems_text(systems)}; choose one with "
                f"--target-system N (or [target] system_id = N in the mission)")
    if not target.chosen and len(heard.addresses) > 1:
        comps = sorted(c for _, c in heard.addresses)
        return (f"more than one autopilot component in system {locked[0]}: components {_systems_text(comps)}; "
                f"choose one with --target-component C")
    return None


def resolve_target(command_line: VehicleTarget | None, mission: VehicleTarget) -> tuple[VehicleTarget, str | None]:
    """The target flown, and the line that says the command line overrode the mission's (or None).
    A command-line target replaces the mission's whole (a system without a component means any
    autopilot component of it, not the mission's component of another system)."""
    if command_line is None or not command_line.chosen:
        return mission, None
    if mission.chosen and mission != command_line:
        return command_line, (f"target: {command_line.describe()} from the command line, overriding the "
                              f"mission's [target] ({mission.describe()})")
    return command_line, None
