"""The companion's side of the relay under MAVLink 2 signing: frames that arrive are checked, frames
that leave are signed.

The relay is the vehicle's signing end, as the bundled vehicle is: the firmware behind it is not
asked to sign (PX4 v1.16 has no MAVLink signing; ArduPilot keeps its key in its own storage), and
the hop from the relay to the firmware stays on 127.0.0.1. A frame the companion's side sends
unsigned, signed with another key, replayed or out of time is dropped and counted by reason (the
bundled vehicle's rules, :class:`~companion.mavlink.signing.SignatureCheck`); what the firmware and
the plant's component send is signed on its way out.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import all as every_dialect

from companion.mavlink.signing import VEHICLE_ACCEPTS_UNSIGNED, FrameSigner, SignatureCheck

from .frames import Frame, frames

__all__ = ["SignedLink"]


@dataclass
class SignedLink:
    key: bytes
    refused: Counter[str] = field(default_factory=Counter)
    """frames dropped on the way in, by reason and message (``"unsigned COMMAND_LONG"``), and frames
    that could not be signed on the way out (``"unsignable"``)"""

    def __post_init__(self) -> None:
        self.check = SignatureCheck(self.key, allow_unsigned=VEHICLE_ACCEPTS_UNSIGNED)
        self.signer = FrameSigner(self.key)

    def inbound(self, msgs: list[Frame]) -> list[Frame]:
        """The frames from the companion's side that may reach the firmware (unchanged)."""
        kept = []
        for m in msgs:
            entry = every_dialect.mavlink_map.get(m.msgid)
            name = entry.msgname if entry is not None else f"message {m.msgid}"
            reason = self.check.frame_verdict(m.raw, name, m.sysid, m.compid)
            if reason is None:
                kept.append(m)
            else:
                self.refused[f"{reason} {name}"] += 1
        return kept

    def outbound(self, data: bytes) -> bytes:
        """Whole frames for the companion's side, each signed."""
        out = bytearray()
        for m in frames(data)[0]:
            signed = self.signer.sign(m.raw)
            if signed is None:
                self.refused["unsignable"] += 1
            else:
                out += signed
        return bytes(out)
