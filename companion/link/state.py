"""What the companion knows about the vehicle: the latest telemetry, as plain values.

Filled by a link backend (:mod:`companion.link`) from MAVLink, read by the control loop and the
mission runner. Timestamps ``t_*`` are the vehicle's clock [s]; ``wall_*`` are this process's
monotonic clock when the sample arrived (for staleness).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control.quaternion import Quat
from companion.control.vector import Vec3

from .resets import ResetDetector

__all__ = ["VehicleState", "MAX_POSITION_M", "MAX_SPEED_M_S",
           "MAX_RATE_RAD_S", "MAX_SPECIFIC_FORCE_M_S2"]

# telemetry beyond these is not a multicopter's, it is a fault: refused, never fed to the controller
MAX_POSITION_M = 1e5
MAX_SPEED_M_S = 150.0
MAX_RATE_RAD_S = 50.0
"""2900 deg/s"""
MAX_SPECIFIC_FORCE_M_S2 = 1000.0
"""100 g; IMUs saturate long before"""
QUAT_NORM_TOLERANCE = 0.01


def _within(values: tuple[float, ...], limit: float) -> bool:
    return all(math.isfinite(v) and abs(v) <= limit for v in values)


@dataclass
class VehicleState:
    autopilot: str = ""
    """"px4" or "ardupilot", from the heartbeat"""
    sysid: int = 0
    compid: int = 0
    vehicle_type: int = 0
    """MAV_TYPE from the autopilot's first heartbeat"""
    armed: bool = False
    mode: str = "UNKNOWN"
    """the flavour's mode name (PX4: OFFBOARD, HOLD, TAKEOFF, LAND, ...; ArduPilot: GUIDED, LOITER, ...)"""
    offboard: bool = False
    """the autopilot is in the mode that flies our attitude setpoints"""
    landed_state: int = mavlink.MAV_LANDED_STATE_UNDEFINED
    """MAV_LANDED_STATE from EXTENDED_SYS_STATE (0: the autopilot does not say)"""
    failsafe: bool = False
    """the heartbeat's system status is MAV_STATE_CRITICAL or EMERGENCY: PX4 and ArduPilot say so while
    a failsafe is active"""
    armable: bool | None = None
    """the autopilot's pre-arm checks pass (SYS_STATUS pre-arm bit); None if it does not say"""
    wall_heartbeat: float = -math.inf

    pos_ned_m: Vec3 = (0.0, 0.0, 0.0)
    """the position in the frame the flight began in: the autopilot's estimate less the estimator
    resets found (:mod:`companion.link.resets`); what the controller and the mission fly"""
    pos_estimate_ned_m: Vec3 = (0.0, 0.0, 0.0)
    """the autopilot's estimate as reported (LOCAL_POSITION_NED)"""
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
    texts_seen: int = 0
    """how many texts have arrived in all (statustexts keeps the last 100)"""
    params: dict[str, float] = field(default_factory=dict)
    resets: ResetDetector = field(default_factory=ResetDetector)
    """estimator resets found in the position stream and the autopilot's reset counter"""

    # --- updates: each refuses (returns False, changes nothing) what cannot be a real sample ---

    older_samples: int = 0
    """valid samples not stored because one as new or newer of the same stream was already held"""

    def _older(self, t: float, held: float) -> bool:
        if t <= held:
            self.older_samples += 1  # reordered, repeated or replayed: never replaces what is held
            return True
        return False

    def restart_time(self) -> None:
        """The vehicle's time base changed (see :mod:`companion.link.stamps`): forget the stamps held."""
        self.t_pos = self.t_att = self.t_imu = -math.inf

    def set_attitude(self, q: Quat, omega_rad_s: Vec3 | None, t: float, wall: float) -> bool:
        """Attitude (renormalised) and, if given, body rates, sampled at vehicle time ``t``.
        False: not a possible sample (refused); a valid sample older than the one held is
        accepted as valid but not stored."""
        if not (_within(q, 1.5) and math.isfinite(t) and t >= 0.0):
            return False
        n = math.sqrt(sum(c * c for c in q))
        if abs(n - 1.0) > QUAT_NORM_TOLERANCE:
            return False
        if omega_rad_s is not None and not _within(omega_rad_s, MAX_RATE_RAD_S):
            return False
        if self._older(t, self.t_att):
            return True
        if omega_rad_s is not None:
            self.omega_rad_s = omega_rad_s
        self.q = (q[0] / n, q[1] / n, q[2] / n, q[3] / n)
        self.t_att, self.wall_att = t, wall
        return True

    def add_text(self, severity: int, text: str) -> None:
        """A STATUSTEXT or a decoded EVENT (MAV_SEVERITY)."""
        self.statustexts.append((severity, text))
        self.texts_seen += 1

    def texts_since(self, seen: int) -> list[tuple[int, str]]:
        """The texts that arrived after ``texts_seen`` was ``seen`` (as many as are kept)."""
        n = min(self.texts_seen - seen, len(self.statustexts))
        return list(self.statustexts)[len(self.statustexts) - n:] if n > 0 else []

    def set_rates(self, omega_rad_s: Vec3) -> bool:
        if not _within(omega_rad_s, MAX_RATE_RAD_S):
            return False
        self.omega_rad_s = omega_rad_s
        return True

    def set_position(self, pos_ned_m: Vec3, vel_ned_m_s: Vec3, t: float, wall: float) -> bool:
        if not (_within(pos_ned_m, MAX_POSITION_M) and _within(vel_ned_m_s, MAX_SPEED_M_S) and math.isfinite(t)):
            return False
        if self._older(t, self.t_pos):
            return True
        self.resets.observe(t, pos_ned_m, vel_ned_m_s)
        self.pos_estimate_ned_m, self.vel_ned_m_s = pos_ned_m, vel_ned_m_s
        self._anchor()
        self.t_pos, self.wall_pos = t, wall
        return True

    def set_reset_counter(self, counter: int, t: float) -> None:
        """The autopilot's estimator reset counter (ODOMETRY ``reset_counter``) at vehicle time ``t``:
        it labels resets, it never moves the position by itself."""
        self.resets.announce(counter, t)

    def _anchor(self) -> None:
        p, o = self.pos_estimate_ned_m, self.resets.offset_ned_m
        self.pos_ned_m = (p[0] - o[0], p[1] - o[1], p[2] - o[2])

    def set_imu(self, specific_force_body_m_s2: Vec3, t: float, wall: float) -> bool:
        if not (_within(specific_force_body_m_s2, MAX_SPECIFIC_FORCE_M_S2) and math.isfinite(t) and t >= 0.0):
            return False
        if self._older(t, self.t_imu):
            return True
        self.specific_force_body_m_s2 = specific_force_body_m_s2
        self.t_imu, self.wall_imu = t, wall
        return True

    @property
    def t(self) -> float:
        """The vehicle's newest timestamp."""
        return max(self.t_pos, self.t_att, self.t_imu)

    @property
    def on_ground(self) -> bool:
        """The autopilot says the vehicle is on the ground (MAV_LANDED_STATE_ON_GROUND)."""
        return self.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND

    @property
    def has_navigation(self) -> bool:
        return math.isfinite(self.t_pos) and math.isfinite(self.t_att)
