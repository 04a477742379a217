"""Time since boot on the wire: ``time_boot_ms`` wraps, ``time_usec`` does not.

MAVLink stamps most messages with ``time_boot_ms``, a uint32 of milliseconds since boot: it wraps
to 0 after 2^32 ms (49.7 days of uptime). Stamps in ``time_usec`` (uint64) run on. A receiver that
keeps one monotonic vehicle time therefore *unwraps* each ``time_boot_ms``: of the instants it can
stand for (``raw + k * BOOT_MS_PERIOD_S``, k = 0, 1, ...), the one nearest the time it already
holds. Unwrapped this way, a stamp just past 0 after one near 2^32 is a few milliseconds later (a
wrap), a stamp far behind stays far behind (refused elsewhere as going backwards), and the result
is the vehicle's real time since boot, the same number its ``time_usec`` fields carry.

Both ends use this copy: the companion's stamp gate (:mod:`companion.link.stamps`) and the
simulated vehicle (``sitl --boot-time``), which reads the stamps its companion sends back.
"""

from __future__ import annotations

__all__ = ["BOOT_MS_PERIOD_S", "BOOT_MS_MODULUS", "boot_ms", "unwrap_boot_s"]

BOOT_MS_MODULUS = 1 << 32
"""``time_boot_ms`` counts milliseconds modulo this"""
BOOT_MS_PERIOD_S = BOOT_MS_MODULUS * 1e-3
"""4294967.296 s (49.71 days): the time after which ``time_boot_ms`` wraps"""


def boot_ms(t_s: float) -> int:
    """Vehicle seconds since boot as a ``time_boot_ms`` field (rounded, wrapped); negative: 0."""
    return int(round(max(t_s, 0.0) * 1000.0)) % BOOT_MS_MODULUS


def unwrap_boot_s(raw_s: float, near_s: float) -> float:
    """The instant a ``time_boot_ms`` stamp (``raw_s`` = the field / 1000, in [0, 2^32 ms)) stands
    for: ``raw_s`` plus the whole number of periods (never negative) that puts it nearest
    ``near_s``, the unwrapped time the receiver already holds [s]."""
    k = max(round((near_s - raw_s) / BOOT_MS_PERIOD_S), 0)
    return raw_s + k * BOOT_MS_PERIOD_S
