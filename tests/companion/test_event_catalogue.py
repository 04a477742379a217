"""PX4's event catalogue as it arrives over MAVLink FTP: a good one reads, and anything else (a
corrupt or cut download, two vehicles' answers interleaved, an xz bomb, JSON of the wrong shape)
is one ValueError the link reports, never a crash of the companion."""

import lzma

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.events import CATALOGUE_MAX_BYTES, Event, EventCatalogue
from sitl.autopilot.events import catalogue


def test_the_bundled_vehicles_catalogue_reads():
    cat = EventCatalogue.from_bytes(catalogue())
    assert len(cat) > 0
    assert len(EventCatalogue.from_bytes(lzma.decompress(catalogue()))) == len(cat)  # the plain .json too


def _corrupt(blob: bytes) -> bytes:
    mid = len(blob) // 2
    return blob[:mid] + bytes(b ^ 0x5A for b in blob[mid:mid + 64]) + blob[mid + 64:]


@pytest.mark.parametrize("name, blob", [
    ("corrupt", _corrupt(catalogue())),
    ("cut short", catalogue()[: len(catalogue()) // 2]),
    ("interleaved", b"".join(catalogue()[i:i + 239] for i in range(0, len(catalogue()), 478))),
    ("bomb", lzma.compress(b"[" + b" " * (CATALOGUE_MAX_BYTES + 1) + b"]")),
    ("not json", b"\x00\x01garbage"),
    ("deeply nested", b"[" * 100_000),
    ("wrong shape", b'{"components": {"1": {"event_groups": {"g": 7}}}}'),
    ("enums not a table", b'{"components": {"1": {"enums": [1, 2]}}}'),
])
def test_anything_but_a_catalogue_is_one_clear_value_error(name, blob):
    with pytest.raises(ValueError, match="event catalogue unreadable"):
        EventCatalogue.from_bytes(blob)


def test_an_event_without_a_catalogue_entry_still_reads():
    cat = EventCatalogue.from_bytes(b'{"components": {}}')
    assert cat.text(Event(id=0x0102089D, time_boot_ms=0, sequence=0, severity=mavlink.MAV_SEVERITY_ERROR,
                          arguments=b"")) == \
        "PX4 event 0x0102089d"
