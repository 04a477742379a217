"""The simulated firmware's attitude loop: the observer sees the torque the rotors applied."""

import math

from companion.control import quaternion as quat
from companion.control import vector as vec
from companion.control.allocation import wrench_from_rotor_speeds
from companion.control.outer_loop import AttitudeSetpoint
from companion.control.params import VehicleParams
from sitl.plant.onboard import OnboardAttitudeLoop

V = VehicleParams()
DT = 0.001


def test_saturated_rotors_are_not_mistaken_for_a_disturbance():
    """Fig. 4: the torque observer is fed the saturated (applied) torque. A 150 deg roll step asks
    for far more torque than four rotors give; the rigid body (J = J0, rotors without lag) moves
    by the applied torque, so the measurement of (15) is zero but for the Euler step (the
    gyroscopic term taken at the step's end: ~1e-4 N m at the rates reached here). Fed the
    request instead, the observer would see request - applied (tenths of a N m) as a disturbance
    and the loop would fight its own saturation."""
    loop = OnboardAttitudeLoop.create("ism_do", V)
    target = quat.from_axis_angle((1.0, 0.0, 0.0), math.radians(150))
    sp = AttitudeSetpoint(target, (0.0, 0.0, 0.0), V.weight_n)
    q, w = quat.IDENTITY, (0.0, 0.0, 0.0)
    saturated, worst = 0, 0.0
    for _ in range(600):
        cmd = loop.update(q, w, sp, DT)
        tau, _ = wrench_from_rotor_speeds(cmd, V)
        saturated += any(c in (V.rotor_speed_min_rad_s, V.rotor_speed_max_rad_s) for c in cmd)
        acc = vec.div(vec.sub(tau, vec.cross(w, vec.mul(V.inertia_kg_m2, w))), V.inertia_kg_m2)
        w = vec.add(w, vec.scale(DT, acc))
        q = quat.integrate(q, w, DT)
        worst = max(worst, vec.norm(loop.controller.disturbance_estimate_nm))
    assert saturated > 50  # the rotors did saturate
    assert worst < 1e-3
