"""What only the plant knows about the airframe: rotor dynamics, aerodynamics, build errors.

The controller's model (:class:`companion.control.VehicleParams`) has mass, inertia, arm length
and rotor constants; everything here is a model error or an effect it lumps into ``h_f`` and
``h_tau``.

Drag (SPEC section 5): the paper's 3 m/s wind gives a ~15 degree hover tilt, i.e.
``m g tan 15 deg = 0.63 * 9.81 * 0.268 = 1.66 N`` of drag. We split it into linear rotor drag
(dominant at low speed on a small quadrotor) and quadratic body drag:
``0.40 N s/m * 3 m/s + 0.052 N s^2/m^2 * 9 m^2/s^2 = 1.20 + 0.47 = 1.67 N``. The drag acts at the
rotor plane, 3 cm above the centre of mass, so gusts also disturb the attitude loop.
"""

from __future__ import annotations

from dataclasses import dataclass

from companion.control.vector import Vec3

__all__ = ["AirframeParams"]


@dataclass(frozen=True)
class AirframeParams:
    rotor_time_constant_s: float = 0.02
    """first-order lag from commanded to actual rotor speed"""
    rotor_command_levels: int = 256
    """speed commands are quantised to this many levels between the min and max speed (8 bit)"""
    motor_efficiency: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    """per-rotor thrust and torque factor (a damaged or weak motor is < 1)"""
    drag_linear_n_s_m: Vec3 = (0.40, 0.40, 0.20)
    """rotor drag, body axes, proportional to the air-relative velocity"""
    drag_quadratic_n_s2_m2: float = 0.052
    """body drag, proportional to |v_rel| v_rel"""
    center_of_pressure_m: Vec3 = (0.0, 0.0, -0.03)
    """where drag acts, relative to the centre of mass, FRD (rotor plane above the CoM)"""
    center_of_mass_offset_m: Vec3 = (0.0, 0.0, 0.0)
    """centre of mass relative to the rotors' geometric centre, FRD (a badly placed battery)"""
    ground_z_m: float = 0.0
    """NED height of the ground; the vehicle rests on it when thrust is below weight"""
    ground_decel_m_s2: float = 50.0
    """the most the ground decelerates a vehicle that reaches it (5 g: landing gear and foam spread
    a touchdown at 0.7 m/s over 14 ms and 5 mm; an instant stop would be a 70 g spike no MEMS
    accelerometer reports, and an estimator that missed it would keep descending)"""
