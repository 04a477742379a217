"""What the autopilot knows of its vehicle at one plant step: one immutable reading.

The rules (:mod:`sitl.autopilot.logic`) read the vehicle only through this record, taken by the
world (:mod:`sitl.autopilot.world`) before and after each plant step; a rule test builds one by
hand and runs the rules on a clock, with no plant to fly.
"""

from __future__ import annotations

from typing import NamedTuple

from companion.control.quaternion import Quat

from ..plant.sensors import ImuSample, MocapSample
from ..plant.vehicle import SimVehicle

__all__ = ["Sensed"]


class Sensed(NamedTuple):
    t: float
    """vehicle time [s]"""
    tracked: MocapSample
    """the newest tracking sample: position, velocity, acceleration (NED) and attitude"""
    q_est: Quat
    """the onboard attitude estimate (body to NED)"""
    imu: ImuSample
    """the newest IMU sample (gyro [rad/s], specific force [m/s^2], body frame)"""
    position_age_s: float
    """time since the newest tracking sample was taken"""
    imu_failed: str | None
    """why the firmware's IMU check failed, or None"""

    @classmethod
    def of(cls, vehicle: SimVehicle) -> Sensed:
        """The vehicle's readings now."""
        return cls(vehicle.t, vehicle.mocap.latest, vehicle.estimator.q, vehicle.imu_sample,
                   vehicle.t - vehicle.mocap.latest.time_s, vehicle.imu_failed)
