"""Outgoing MAVLink: every message the simulated vehicle sends, built from its state.

The one place where the vehicle's state becomes wire messages (pymavlink, MAVLink 2, the
``ardupilotmega`` dialect, which includes ``common``). Timestamps are the simulated clock.
Units and frames are MAVLink's, which are ours: NED, FRD, scalar-first body-to-NED quaternions.
What the telemetry reports is what an autopilot would know: the tracking system's position
(moved by any injected estimator reset) and differenced velocity, the onboard attitude estimate
and bias-corrected rates, the IMU.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Union

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control import quaternion as quat
from companion.mavlink.boot_time import BOOT_MS_MODULUS, unwrap_boot_s
from companion.mavlink.framing import Payload
from companion.control.vector import Vec3

from ..plant.geo import GeoOrigin
from .logic import Autopilot, custom_mode

__all__ = ["GeoOrigin", "Telemetry", "DEFAULT_RATES_HZ", "SYS_STATUS_SENSORS", "PREARM_CHECK", "PX4_VERSION"]

POSITION_STALE_S = 0.1
"""tracking samples normally arrive every 17 ms, 10 ms late"""


# SYS_STATUS sensor bits MAVSDK reads for its health flags (gyro, accel, mag calibrated; GPS and
# vision position for local/global position ok; motor outputs) and the pre-arm check bit.
SYS_STATUS_SENSORS = (
    mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mavlink.MAV_SYS_STATUS_SENSOR_GPS
    | mavlink.MAV_SYS_STATUS_SENSOR_VISION_POSITION
    | mavlink.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mavlink.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
)
PREARM_CHECK = mavlink.MAV_SYS_STATUS_PREARM_CHECK

PX4_VERSION = (1, 16, 0)
"""the PX4 release whose behaviour the bundled vehicle imitates (docs/sitl.md), reported in AUTOPILOT_VERSION"""

DEFAULT_RATES_HZ: dict[int, float] = {
    mavlink.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    mavlink.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 5.0,
    mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: 100.0,
    mavlink.MAVLINK_MSG_ID_ATTITUDE: 20.0,
    mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 60.0,
    mavlink.MAVLINK_MSG_ID_ODOMETRY: 30.0,
    mavlink.MAVLINK_MSG_ID_HIGHRES_IMU: 100.0,
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,
    mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: 1.0,
    mavlink.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
    mavlink.MAVLINK_MSG_ID_ATTITUDE_TARGET: 50.0,
    mavlink.MAVLINK_MSG_ID_SYSTEM_TIME: 1.0,
}
"""Default stream rates (simulated Hz), PX4's onboard-link set; SET_MESSAGE_INTERVAL changes them."""


Message = Union[mavlink.MAVLink_message, Payload]
"""what an encoder returns: pymavlink's object, or (the streams sent most) the fields alone"""


_f: Callable[[Any], float] = float
"""a field's value as the float MAVLink sends (the builtin itself: a wrapper cost a call per field)"""


def _estimate(p: Vec3, offset: Vec3) -> tuple[float, float, float]:
    """The reported position estimate: the tracked position plus the injected resets' offset."""
    return (_f(p[0]) + offset[0], _f(p[1]) + offset[1], _f(p[2]) + offset[2])


class Telemetry:
    """Builds messages from an :class:`Autopilot`; ``encoders`` maps message id to builder."""

    def __init__(self, ap: Autopilot, mav: mavlink.MAVLink, origin: GeoOrigin, autopilot_type: int,
                 boot_offset_ms: int = 0) -> None:
        self.ap = ap
        self.boot_offset_ms = boot_offset_ms
        """milliseconds the vehicle had been up when the simulation started (``sitl --boot-time``):
        added to every stamp sent, so a flight can cross the wrap of ``time_boot_ms``"""
        self.mav = mav
        self.origin = origin
        self.autopilot_type = autopilot_type
        self.encoders: dict[int, Callable[[], Message | None]] = {
            mavlink.MAVLINK_MSG_ID_HEARTBEAT: self.heartbeat,
            mavlink.MAVLINK_MSG_ID_SYS_STATUS: self.sys_status,
            mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: self.extended_sys_state,
            mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: self.attitude_quaternion,
            mavlink.MAVLINK_MSG_ID_ATTITUDE: self.attitude,
            mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: self.local_position_ned,
            mavlink.MAVLINK_MSG_ID_ODOMETRY: self.odometry,
            mavlink.MAVLINK_MSG_ID_HIGHRES_IMU: self.highres_imu,
            mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self.global_position_int,
            mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: self.gps_raw_int,
            mavlink.MAVLINK_MSG_ID_HOME_POSITION: self.home_position,
            mavlink.MAVLINK_MSG_ID_ATTITUDE_TARGET: self.attitude_target,
            mavlink.MAVLINK_MSG_ID_SYSTEM_TIME: self.system_time,
            mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION: self.autopilot_version,
        }

    # --- time ----------------------------------------------------------------------------

    @property
    def time_boot_ms(self) -> int:
        return (self.boot_offset_ms + int(round(self.ap.t * 1000.0))) % BOOT_MS_MODULUS  # t: a sum of 1 ms steps

    @property
    def time_usec(self) -> int:
        return self.boot_offset_ms * 1000 + int(round(self.ap.t * 1e6))

    def sim_time_of(self, time_boot_ms: int) -> float:
        """The simulation time [s, as ``ap.t``] a ``time_boot_ms`` stamp received now stands for:
        unwrapped about the vehicle's own uptime, so a stamp from before a wrap stays before it."""
        since_start_ms = (time_boot_ms - self.boot_offset_ms) % BOOT_MS_MODULUS
        return unwrap_boot_s(since_start_ms * 1e-3, self.ap.t)

    # --- messages --------------------------------------------------------------------------

    def heartbeat(self) -> Message:
        ap = self.ap
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if ap.armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        status = mavlink.MAV_STATE_ACTIVE if ap.armed else mavlink.MAV_STATE_STANDBY
        if ap.failsafe:
            status = mavlink.MAV_STATE_CRITICAL
        return self.mav.heartbeat_encode(
            mavlink.MAV_TYPE_QUADROTOR, self.autopilot_type, base, custom_mode(ap.reported_mode, ap.params.flavour),
            status
        )

    def armable(self) -> bool:
        ap = self.ap
        return ap.landed and ap.t >= 1.0 and ap.has_position

    def sys_status(self) -> Message:
        health = SYS_STATUS_SENSORS | (PREARM_CHECK if self.armable() or self.ap.armed else 0)
        present = SYS_STATUS_SENSORS | PREARM_CHECK
        return self.mav.sys_status_encode(
            present, present, health, 250, 16000, -1, 100, 0, 0, 0, 0, 0, 0
        )

    def extended_sys_state(self) -> Message:
        return self.mav.extended_sys_state_encode(mavlink.MAV_VTOL_STATE_UNDEFINED, int(self.ap.landed_state))

    def attitude_quaternion(self) -> Message:
        v = self.ap.vehicle
        q, w = v.estimator.q, v.omega_est
        return Payload(mavlink.MAVLink_attitude_quaternion_message, (
            self.time_boot_ms, _f(q[0]), _f(q[1]), _f(q[2]), _f(q[3]), _f(w[0]), _f(w[1]), _f(w[2]), [0.0] * 4))

    def attitude(self) -> Message:
        v = self.ap.vehicle
        r, p, y = quat.to_euler(v.estimator.q)
        w = v.omega_est
        return Payload(mavlink.MAVLink_attitude_message,
                       (self.time_boot_ms, _f(r), _f(p), _f(y), _f(w[0]), _f(w[1]), _f(w[2])))

    def local_position_ned(self) -> Message | None:
        """None (not sent) while the tracking system is silent: a stale position must not look fresh,
        and while the estimator has no origin (ArduCopter: ~40 s after boot)."""
        if self.ap.vehicle.position_age_s > POSITION_STALE_S or not self.ap.has_position:
            return None
        ms = self.ap.vehicle.tracked
        p, vel = _estimate(ms.pos_ned_m, self.ap.vehicle.estimate_offset_ned_m), ms.vel_ned_m_s
        return Payload(mavlink.MAVLink_local_position_ned_message, (
            self.time_boot_ms, _f(p[0]), _f(p[1]), _f(p[2]), _f(vel[0]), _f(vel[1]), _f(vel[2])))

    def odometry(self) -> Message:
        v = self.ap.vehicle
        ms = v.tracked
        q, w = v.estimator.q, v.omega_est
        vb = quat.rotate_inverse(q, ms.vel_ned_m_s)  # ODOMETRY velocity is in the child frame
        nan21 = [math.nan] + [0.0] * 20
        p = _estimate(ms.pos_ned_m, v.estimate_offset_ned_m)
        return Payload(mavlink.MAVLink_odometry_message, (
            self.time_usec, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD,
            p[0], p[1], p[2], [_f(c) for c in q], _f(vb[0]), _f(vb[1]), _f(vb[2]),
            _f(w[0]), _f(w[1]), _f(w[2]), nan21, nan21, v.estimator_resets & 0xFF,
            mavlink.MAV_ESTIMATOR_TYPE_VISION, 100))

    def highres_imu(self) -> Message:
        v = self.ap.vehicle
        s = v.imu_sample
        a, g = s.specific_force_body_m_s2, s.gyro_rad_s
        # magnetometer: a fixed Earth field (0.21 north, 0.43 down, gauss) seen from the body
        m = quat.rotate_inverse(v.state.q, (0.21, 0.0, 0.43))
        alt = self.origin.alt_m - _f(v.state.pos_ned_m[2])
        pressure_hpa = 1013.25 * (1.0 - 2.25577e-5 * alt) ** 5.25588
        fields = 0x1FFF  # acc, gyro, mag, abs pressure, diff pressure, pressure alt, temperature
        return Payload(mavlink.MAVLink_highres_imu_message, (
            self.time_usec, _f(a[0]), _f(a[1]), _f(a[2]), _f(g[0]), _f(g[1]), _f(g[2]),
            _f(m[0]), _f(m[1]), _f(m[2]), pressure_hpa, 0.0, alt, 20.0, fields, 0))

    def global_position_int(self) -> Message:
        ap = self.ap
        ms = ap.vehicle.tracked
        p, vel = _estimate(ms.pos_ned_m, ap.vehicle.estimate_offset_ned_m), ms.vel_ned_m_s
        lat, lon, alt = self.origin.to_global(p[0], p[1], p[2])
        yaw = _f(quat.to_euler(ap.vehicle.estimator.q)[2])
        hdg = int(round(math.degrees(yaw) % 360.0 * 100)) % 36000
        return Payload(mavlink.MAVLink_global_position_int_message, (
            self.time_boot_ms, lat, lon, alt, int(round((_f(ap.home[2]) - _f(p[2])) * 1000)),
            int(round(_f(vel[0]) * 100)), int(round(_f(vel[1]) * 100)), int(round(_f(vel[2]) * 100)), hdg))

    def gps_raw_int(self) -> Message:
        v = self.ap.vehicle
        p = _estimate(v.tracked.pos_ned_m, v.estimate_offset_ned_m)
        lat, lon, alt = self.origin.to_global(p[0], p[1], p[2])
        return self.mav.gps_raw_int_encode(self.time_usec, mavlink.GPS_FIX_TYPE_3D_FIX, lat, lon, alt, 80, 120, 0,
                                           65535, 16)

    def home_position(self) -> Message:
        h = self.ap.home
        lat, lon, alt = self.origin.to_global(_f(h[0]), _f(h[1]), _f(h[2]))
        return self.mav.home_position_encode(
            lat, lon, alt, _f(h[0]), _f(h[1]), _f(h[2]), [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, self.time_usec
        )

    def attitude_target(self) -> Message:
        ap = self.ap
        sp = ap.setpoint
        q, w = sp.q_d, sp.omega_d_rad_s
        thrust = _f(sp.thrust_n) / ap.vehicle.scenario.vehicle.thrust_max_n
        return Payload(mavlink.MAVLink_attitude_target_message, (
            self.time_boot_ms, 0, [_f(c) for c in q], _f(w[0]), _f(w[1]), _f(w[2]), thrust))

    def system_time(self) -> Message:
        return self.mav.system_time_encode(0, self.time_boot_ms)

    def autopilot_version(self) -> Message:
        caps = (
            mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
            | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
            | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            | mavlink.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
            | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
            | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT  # it speaks the mission protocol: lists none, refuses uploads
        )
        major, minor, patch = PX4_VERSION
        version = (major << 24) | (minor << 16) | (patch << 8) | mavlink.FIRMWARE_VERSION_TYPE_OFFICIAL
        return self.mav.autopilot_version_encode(
            caps, version, version, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0x15D0_0001, [0] * 18
        )

    def statustext(self, severity: int, text: str) -> Message:
        return self.mav.statustext_encode(severity, text.encode("ascii", "replace")[:50], 0, 0)
