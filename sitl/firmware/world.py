"""The world a real autopilot's firmware flies: the project's plant, its environment and every
sensor the firmware's estimator reads, stepped by the firmware's motor outputs.

One copy of the plant: :class:`~sitl.plant.vehicle.SimVehicle` (rotor lag and quantisation,
drag, Dryden wind, external forces and torques, IMU and tracking noise, injected faults) without
its own onboard loop, plus the barometer, magnetometer and GNSS of :mod:`sitl.plant.nav_sensors`.
A frame is what the firmware receives between two of its outputs: the IMU averaged over the
frame (what an IMU's own filter delivers at the firmware's rate), the navigation sensors at its
end, and the tracking samples delivered during it. Pure: the bridges (:mod:`.px4`,
:mod:`.ardupilot`) do the I/O.
"""

from __future__ import annotations

from typing import NamedTuple

from companion.control.vector import Vec3
from sitl.plant.dynamics import RigidBodyState
from sitl.plant.geo import GeoOrigin
from sitl.plant.nav_sensors import BaroSample, GnssSample, NavSensors
from sitl.plant.scenario import Scenario
from sitl.plant.sensors import MocapSample
from sitl.plant.vehicle import SimVehicle

from .motors import rotor_commands

__all__ = ["SensorFrame", "FirmwareWorld"]


class SensorFrame(NamedTuple):
    t_s: float
    """world time at the end of the frame"""
    gyro_rad_s: Vec3
    """body rates measured, averaged over the frame"""
    accel_m_s2: Vec3
    """specific force measured, body axes, averaged over the frame"""
    mag_gauss: Vec3
    baro: BaroSample
    gnss: GnssSample | None
    """a fix delivered during the frame"""
    tracked: tuple[MocapSample, ...]
    """tracking samples delivered during the frame (external vision)"""
    state: RigidBodyState
    """the truth at the end of the frame"""


class FirmwareWorld:
    """One vehicle of ``scenario`` on the ground at the origin, flown by a firmware's outputs."""

    def __init__(self, scenario: Scenario, seed: int, origin: GeoOrigin) -> None:
        self.scenario = scenario
        self.vehicle = SimVehicle(scenario, "pd", seed, (0.0, 0.0, scenario.airframe.ground_z_m), 0.0,
                                  hovering=False)
        self.vehicle.enable_fault_checks(monitor=False)  # the firmware checks its own sensors
        self.nav = NavSensors(scenario.nav_sensors, origin, seed)
        self.origin = origin
        self.rotor_cmd_rad_s = (0.0, 0.0, 0.0, 0.0)

    @property
    def t(self) -> float:
        return self.vehicle.t

    @property
    def dt(self) -> float:
        return self.vehicle.dt

    def step(self, outputs: tuple[float, ...], armed: bool, steps: int) -> SensorFrame:
        """``steps`` plant steps with the rotors at the firmware's ``outputs`` (normalised, firmware
        order), held for the frame; what the firmware's sensors read at its end."""
        v = self.vehicle
        cmd = rotor_commands(outputs, v.plant.vehicle, v.scenario.airframe.rotor_command_levels, armed)
        self.rotor_cmd_rad_s = cmd
        gx = gy = gz = 0.0
        tracked = []
        for _ in range(steps):
            sample = v.advance(cmd)
            if sample is not None:
                tracked.append(sample)
            g = v.imu_sample.gyro_rad_s
            gx += g[0]
            gy += g[1]
            gz += g[2]
        k = 1.0 / steps
        state = v.plant.state
        nav = self.nav
        return SensorFrame(v.t, (gx * k, gy * k, gz * k), v.mean_specific_force_body(), nav.mag(state),
                           nav.baro(state), nav.gnss(v.t, state), tuple(tracked), state)
