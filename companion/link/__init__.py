"""Links to an autopilot: one interface (:class:`~companion.link.base.VehicleLink`), two backends.

- :mod:`.pymavlink_link` talks MAVLink on the wire itself (PX4 and ArduPilot; records every
  datagram for the ``.tlog``);
- :mod:`.mavsdk_link` uses MAVSDK 4 (in-process core) for arming, mode changes and telemetry on
  PX4, and MavlinkDirect for the raw SET_ATTITUDE_TARGET.

What the companion knows of the vehicle lives beside them: :mod:`.state` (the newest telemetry),
:mod:`.stamps` (which timestamps are believed), :mod:`.clock` (the vehicle's clock). The control
loop only sees the interface; :func:`open_link` is the one place that knows the backends.
"""

from __future__ import annotations

from .base import LinkError, TrafficHook, VehicleLink

__all__ = ["LinkError", "VehicleLink", "open_link"]


def open_link(url: str, backend: str = "pymavlink", traffic: TrafficHook | None = None,
              **options: object) -> VehicleLink:
    if backend == "pymavlink":
        from .pymavlink_link import PymavlinkLink

        return PymavlinkLink(url, traffic=traffic, **options)  # type: ignore[arg-type]
    if backend == "mavsdk":
        from .mavsdk_link import MavsdkLink

        return MavsdkLink(url, traffic=traffic, **options)  # type: ignore[arg-type]
    raise ValueError(f"unknown backend {backend!r}; expected pymavlink or mavsdk")
