"""What PX4's simulator MAVLink API carries (module ``simulator_mavlink``, as jMAVSim and Gazebo
Classic use it): a :class:`~.world.SensorFrame` out as HIL_SENSOR, HIL_GPS and ODOMETRY (external
vision), PX4's motor outputs back as HIL_ACTUATOR_CONTROLS.

HIL_SENSOR with ``id`` 0 sets PX4's clock (``time_usec``) and lets it run one step (lockstep);
``fields_updated`` says which of its fields are new. ODOMETRY of estimator type VISION is
published as PX4's visual odometry, stamped when it arrives (PX4 v1.16,
``SimulatorMavlink.cpp``): the bridge sends each tracking sample when it is delivered, and
EKF2_EV_DELAY carries the tracking system's latency.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.plant.sensors import MocapSample

from .world import SensorFrame

__all__ = ["ACCEL", "GYRO", "MAG", "BARO", "Px4Wire", "MotorOutputs"]

ACCEL = mavlink.HIL_SENSOR_UPDATED_XACC | mavlink.HIL_SENSOR_UPDATED_YACC | mavlink.HIL_SENSOR_UPDATED_ZACC
GYRO = mavlink.HIL_SENSOR_UPDATED_XGYRO | mavlink.HIL_SENSOR_UPDATED_YGYRO | mavlink.HIL_SENSOR_UPDATED_ZGYRO
MAG = mavlink.HIL_SENSOR_UPDATED_XMAG | mavlink.HIL_SENSOR_UPDATED_YMAG | mavlink.HIL_SENSOR_UPDATED_ZMAG
BARO = (mavlink.HIL_SENSOR_UPDATED_ABS_PRESSURE | mavlink.HIL_SENSOR_UPDATED_PRESSURE_ALT
        | mavlink.HIL_SENSOR_UPDATED_TEMPERATURE)
MODE_FLAG_ARMED = mavlink.MAV_MODE_FLAG_SAFETY_ARMED
NAN21 = [math.nan] + [0.0] * 20


class MotorOutputs(NamedTuple):
    time_usec: int
    controls: tuple[float, ...]
    """normalised, firmware order: motors in [0, 1]"""
    armed: bool


class Px4Wire:
    """Encodes frames for one PX4 instance (its system id) and decodes its outputs."""

    def __init__(self, sysid: int = 1, compid: int = 51) -> None:
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.mav.robust_parsing = True

    def frame(self, f: SensorFrame, vision: bool) -> list[bytes]:
        """The datagrams for one frame: HIL_SENSOR, then the tracking samples delivered during it
        (``vision``: the firmware positions by external vision; the paper's laboratory has no
        GNSS, and a fix beside it made PX4 v1.16 move its height origin by the field's altitude
        after a landing) or else the GNSS fix, if one is due."""
        mav = self.mav
        t_us = int(round(f.t_s * 1e6))
        a, g, m, b = f.accel_m_s2, f.gyro_rad_s, f.mag_gauss, f.baro
        out = [mav.hil_sensor_encode(t_us, a[0], a[1], a[2], g[0], g[1], g[2], m[0], m[1], m[2],
                                     b.pressure_pa * 0.01, 0.0, b.altitude_m, b.temperature_c,
                                     ACCEL | GYRO | MAG | BARO, 0).pack(mav)]
        if f.gnss is not None and not vision:
            fix = f.gnss
            v = fix.vel_ned_m_s
            speed = math.hypot(v[0], v[1])
            cog = int(round(math.degrees(math.atan2(v[1], v[0])) % 360.0 * 100)) if speed > 0.2 else 65535
            out.append(mav.hil_gps_encode(t_us, mavlink.GPS_FIX_TYPE_3D_FIX, int(round(fix.lat_deg * 1e7)),
                                          int(round(fix.lon_deg * 1e7)),
                                          int(round(fix.alt_m * 1000)), int(fix.eph_m * 100), int(fix.epv_m * 100),
                                          int(round(speed * 100)), int(round(v[0] * 100)), int(round(v[1] * 100)),
                                          int(round(v[2] * 100)), cog, 12, 0, 0).pack(mav))
        if vision:
            out.extend(self.vision(t_us, s) for s in f.tracked)
        return out

    def vision(self, t_us: int, s: MocapSample, pos_var_m2: float = 1e-4, att_var_rad2: float = 1e-4) -> bytes:
        """One tracking sample as ODOMETRY (pose only: PX4 fuses position and yaw)."""
        cov = list(NAN21)
        cov[0] = cov[6] = cov[11] = pos_var_m2
        cov[15] = cov[18] = cov[20] = att_var_rad2
        p = s.pos_ned_m
        return self.mav.odometry_encode(t_us, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_BODY_FRD,
                                        p[0], p[1], p[2], list(s.q), math.nan, math.nan, math.nan,
                                        math.nan, math.nan, math.nan, cov, NAN21, 0,
                                        mavlink.MAV_ESTIMATOR_TYPE_VISION, 100).pack(self.mav)

    def parse(self, data: bytes) -> list[MotorOutputs]:
        """PX4's motor outputs in ``data`` (a chunk of the TCP stream; partial frames are kept)."""
        out = []
        try:
            msgs = self.mav.parse_buffer(data) or []
        except Exception:
            return out
        for m in msgs:
            if m.get_msgId() == mavlink.MAVLINK_MSG_ID_HIL_ACTUATOR_CONTROLS:
                out.append(MotorOutputs(m.time_usec, tuple(m.controls), bool(m.mode & MODE_FLAG_ARMED)))
        return out
