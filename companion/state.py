"""What the companion knows about the vehicle: the latest telemetry, as plain values.

Filled by a link backend (:mod:`companion.link`) from MAVLink, read by the control loop and the
mission runner. Timestamps ``t_*`` are the vehicle's clock [s]; ``wall_*`` are this process's
monotonic clock when the sample arrived (for staleness).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from companion.control.quaternion import Quat
from companion.control.vector import Vec3

__all__ = ["VehicleState", "LANDED_ON_GROUND", "LANDED_IN_AIR"]

LANDED_ON_GROUND = 1
LANDED_IN_AIR = 2


@dataclass
class VehicleState:
    autopilot: str = ""
    """"px4" or "ardupilot", from the heartbeat"""
    sysid: int = 0
    compid: int = 0
    armed: bool = False
    mode: str = "UNKNOWN"
    """the flavour's mode name (PX4: OFFBOARD, HOLD, TAKEOFF, LAND, ...; ArduPilot: GUIDED, LOITER, ...)"""
    offboard: bool = False
    """the autopilot is in the mode that flies our attitude setpoints"""
    landed_state: int = 0
    armable: bool | None = None
    """the autopilot's pre-arm checks pass (SYS_STATUS pre-arm bit); None if it does not say"""
    wall_heartbeat: float = -math.inf

    pos_ned_m: Vec3 = (0.0, 0.0, 0.0)
    vel_ned_m_s: Vec3 = (0.0, 0.0, 0.0)
    t_pos: float = -math.inf
    wall_pos: float = -math.inf

    q: Quat = (1.0, 0.0, 0.0, 0.0)
    omega_rad_s: Vec3 = (0.0, 0.0, 0.0)
    t_att: float = -math.inf
    wall_att: float = -math.inf

    specific_force_body_m_s2: Vec3 | None = None
    t_imu: float = -math.inf
    wall_imu: float = -math.inf

    wall_last: float = -math.inf
    """arrival of the newest message of any kind from the vehicle"""
    statustexts: deque[tuple[int, str]] = field(default_factory=lambda: deque(maxlen=100))
    params: dict[str, float] = field(default_factory=dict)

    @property
    def t(self) -> float:
        """The vehicle's newest timestamp."""
        return max(self.t_pos, self.t_att, self.t_imu)

    @property
    def has_navigation(self) -> bool:
        return math.isfinite(self.t_pos) and math.isfinite(self.t_att)
