"""Connection strings: where the autopilot is and how to reach it."""

from __future__ import annotations

__all__ = ["parse_url"]


def parse_url(url: str) -> tuple[str, str, int]:
    """``udp://HOST:PORT`` / ``udpout://HOST:PORT`` (send to a vehicle that listens there) or
    ``udpin://HOST:PORT`` (listen there for a vehicle that sends first, as PX4 SITL does)."""
    scheme, sep, rest = url.partition("://")
    if not sep:
        scheme, rest = "udp", url
    host, _, port = rest.rpartition(":")
    if scheme not in ("udp", "udpout", "udpin") or not port.isdigit():
        raise ValueError(f"expected udp://HOST:PORT, udpout://HOST:PORT or udpin://HOST:PORT, got {url!r}")
    return ("in" if scheme == "udpin" else "out"), host or "127.0.0.1", int(port)
