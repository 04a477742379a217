"""Links to an autopilot: one interface (:class:`~companion.link.base.VehicleLink`), two backends.

- :mod:`.pymavlink_link` talks MAVLink on the wire itself (PX4 and ArduPilot; records every
  datagram for the ``.tlog``);
- :mod:`.mavsdk_link` uses MAVSDK 4 (in-process core) for arming, mode changes and telemetry on
  PX4, and MavlinkDirect for the raw SET_ATTITUDE_TARGET.

The control loop only sees the interface.
"""

from .base import LinkError, VehicleLink, open_link

__all__ = ["LinkError", "VehicleLink", "open_link"]
