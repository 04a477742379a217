"""PX4's events (MAVLink EVENT, id 410) as readable text.

PX4 v1.16 reports arming refusals, failsafes and mode-change failures as EVENTs, not STATUSTEXT:
an event is a 32-bit id (component << 24 | sub-id), log levels and up to 40 bytes of arguments;
the text lives in a catalogue the autopilot serves over MAVLink FTP
(``/etc/extras/all_events.json.xz``, libevents' format: components -> event groups -> events with a
``message`` template whose ``{N}`` is argument N, arguments typed as C integers, floats or enums).
Our pymavlink dialect has no EVENT message, so the frame is decoded here from its payload.

Without a catalogue an event still reads as ``PX4 event 0x0102089d``: never dropped, never a crash.
"""

from __future__ import annotations

import json
import lzma
import re
import struct
from dataclasses import dataclass
from typing import Any

from .framing import frame

__all__ = ["MSG_ID_EVENT", "Event", "parse_event", "EventCatalogue", "SEVERITY_OF_LEVEL", "EVENT_CRC_EXTRA",
           "encode_event_frame", "catalogue_json", "CATALOGUE_PATH", "CATALOGUE_MAX_BYTES"]

MSG_ID_EVENT = 410
_HEADER = struct.Struct("<IIHBBB")  # id, event_time_boot_ms, sequence, destination comp, destination sys, log_levels
_C_TYPES = {"uint8_t": "<B", "int8_t": "<b", "uint16_t": "<H", "int16_t": "<h", "uint32_t": "<I", "int32_t": "<i",
            "uint64_t": "<Q", "int64_t": "<q", "float": "<f"}
CATALOGUE_MAX_BYTES = 16 << 20
"""the unpacked catalogue's size limit (PX4 v1.16's is 0.2 MB): an xz bomb stops here"""
SEVERITY_OF_LEVEL = {0: 0, 1: 1, 2: 2, 3: 3, 4: 4, 5: 5, 6: 6, 7: 7}
"""libevents' external log levels are MAV_SEVERITY's numbers (0 emergency .. 7 debug)"""
_TAG = re.compile(r"</?[a-zA-Z]+[^>]*>")
_PLACEHOLDER = re.compile(r"\{(\d+)(?::([^}]*))?\}")


CATALOGUE_PATH = "/etc/extras/all_events.json.xz"
"""where PX4 serves its event catalogue over MAVLink FTP"""


def _crc_extra() -> int:
    """MAVLink's CRC_EXTRA of EVENT, from its definition in common.xml (fields in wire order)."""
    from pymavlink.generator.mavcrc import x25crc

    crc = x25crc(b"EVENT ")
    for ctype, name, length in (("uint32_t", "id", 0), ("uint32_t", "event_time_boot_ms", 0),
                                ("uint16_t", "sequence", 0), ("uint8_t", "destination_component", 0),
                                ("uint8_t", "destination_system", 0), ("uint8_t", "log_levels", 0),
                                ("uint8_t", "arguments", 40)):
        crc.accumulate_str(f"{ctype} ")
        crc.accumulate_str(f"{name} ")
        if length:
            crc.accumulate([length])
    return (crc.crc & 0xFF) ^ (crc.crc >> 8)


EVENT_CRC_EXTRA = _crc_extra()


def encode_event_frame(seq: int, sysid: int, compid: int, event_id: int, time_boot_ms: int, sequence: int,
                       severity: int, arguments: bytes = b"") -> bytes:
    """An EVENT as a MAVLink 2 frame (trailing zeros trimmed, as MAVLink 2 does), unsigned."""
    payload = _HEADER.pack(event_id, time_boot_ms & 0xFFFFFFFF, sequence & 0xFFFF, 0, 0, severity & 0x0F)
    return frame(MSG_ID_EVENT, EVENT_CRC_EXTRA, payload + arguments[:40].ljust(40, b"\x00"), seq, sysid, compid)


def catalogue_json(component_namespace: str, events: dict[int, tuple[str, str]]) -> bytes:
    """A libevents catalogue (xz-compressed JSON) for component 1: sub-id -> (name, message)."""
    data = {"version": 2, "components": {"1": {"namespace": component_namespace, "event_groups": {
        "default": {"events": {str(sub): {"name": name, "message": message}
                               for sub, (name, message) in events.items()}}}}}}
    return lzma.compress(json.dumps(data).encode())


@dataclass(frozen=True)
class Event:
    id: int
    time_boot_ms: int
    sequence: int
    severity: int
    """MAV_SEVERITY of the event's external log level"""
    arguments: bytes


def parse_event(payload: bytes) -> Event | None:
    """An EVENT's payload (MAVLink 2 trims trailing zeros: it is padded back); None if too short."""
    if len(payload) < 4:
        return None
    raw = bytes(payload[:53]).ljust(53, b"\x00")
    event_id, t_ms, seq, _comp, _sys, levels = _HEADER.unpack_from(raw)
    return Event(event_id, t_ms, seq, SEVERITY_OF_LEVEL.get(levels & 0x0F, 6), raw[13:53])


class EventCatalogue:
    """Event ids to message templates, from the autopilot's own libevents JSON (or its .xz)."""

    def __init__(self, data: dict[str, Any]) -> None:
        self._events: dict[int, tuple[dict[str, Any], dict[str, Any]]] = {}
        self._enums: dict[str, dict[str, Any]] = {}
        components = data.get("components", {}) if isinstance(data, dict) else {}
        for comp_id, comp in sorted(components.items(), key=lambda kv: kv[0] != "0"):  # common (0) first
            if not isinstance(comp, dict):
                continue
            self._enums.update(comp.get("enums", {}))
            for group in comp.get("event_groups", {}).values():
                for sub_id, ev in group.get("events", {}).items():
                    try:
                        self._events[(int(comp_id) << 24) | int(sub_id)] = (ev, comp.get("enums", {}))
                    except ValueError:
                        continue

    @classmethod
    def from_bytes(cls, blob: bytes) -> EventCatalogue:
        """From ``all_events.json`` or its ``.xz``: ValueError for anything else (a corrupt or cut
        file, two vehicles' answers interleaved, more than :data:`CATALOGUE_MAX_BYTES` unpacked)."""
        try:
            if blob[:6] == b"\xfd7zXZ\x00":
                unpack = lzma.LZMADecompressor()
                blob = unpack.decompress(blob, max_length=CATALOGUE_MAX_BYTES)
                if not unpack.eof:
                    raise ValueError(f"cut short or over {CATALOGUE_MAX_BYTES} bytes unpacked")
            return cls(json.loads(blob.decode("utf-8")))
        except ValueError as exc:
            raise ValueError(f"event catalogue unreadable: {exc}") from None
        except (lzma.LZMAError, EOFError, RecursionError, AttributeError, TypeError) as exc:
            raise ValueError(f"event catalogue unreadable: {type(exc).__name__}: {exc}") from None

    def __len__(self) -> int:
        return len(self._events)

    def text(self, event: Event) -> str:
        found = self._events.get(event.id)
        if found is None:
            return f"PX4 event 0x{event.id:08x}"
        ev, enums = found
        values = self._arguments(ev.get("arguments", []), event.arguments, enums)
        message = str(ev.get("message", ev.get("name", "")))

        def fill(m: re.Match[str]) -> str:
            k = int(m.group(1)) - 1
            if not 0 <= k < len(values):
                return m.group(0)
            v = values[k]
            fmt = (m.group(2) or "").strip()
            if isinstance(v, float) and fmt.startswith(".") and fmt[1:2].isdigit():
                return f"{v:.{int(fmt[1:2])}f}"
            return f"{v:g}" if isinstance(v, float) else str(v)

        return _TAG.sub("", _PLACEHOLDER.sub(fill, message)).strip()

    def _arguments(self, specs: list[dict[str, Any]], raw: bytes, enums: dict[str, Any]) -> list[object]:
        out: list[object] = []
        offset = 0
        for spec in specs:
            kind = str(spec.get("type", ""))
            enum = enums.get(kind) or self._enums.get(kind)
            fmt = _C_TYPES.get(str(enum.get("type")) if enum else kind)
            if fmt is None:
                break
            size = struct.calcsize(fmt)
            if offset + size > len(raw):
                break
            (value,) = struct.unpack_from(fmt, raw, offset)
            offset += size
            if enum:
                entry = enum.get("entries", {}).get(str(value))
                out.append(entry.get("description", entry.get("name")) if entry else value)
            else:
                out.append(value)
        return out
