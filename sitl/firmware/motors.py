"""The motor interface between a real autopilot's outputs and the plant's rotors.

An autopilot commands each motor with a normalised output ``u`` in [0, 1] (PX4's
HIL_ACTUATOR_CONTROLS; ArduPilot's PWM, 1000-2000 us, as ``(pwm - 1000) / 1000``). The plant's
electronic speed controllers hold the rotor at a speed proportional to it, ``w = u w_max``, never
below the idle speed ``w_min`` (``u <= 0``, what both send for a stopped or disarmed motor, stops
it), on the same 8-bit grid as the bundled vehicle's motor interface
(:func:`sitl.plant.onboard.command_level`). Thrust is then ``u^2`` of full thrust: the quadratic
thrust curve both autopilots model exactly (PX4 THR_MDL_FAC 1; ArduPilot MOT_THST_EXPO 1 over the
whole output range), so their normalised thrust is the plant's.

Both autopilots number a quad's motors 1 front-right, 2 back-left, 3 front-left, 4 back-right for
"x", and 1 right, 2 left, 3 front, 4 back for "+" (PX4 through the rotor geometry this project
sets, ArduPilot by its frame type): the plant's rotors 4, 2, 1, 3 in either layout
(:mod:`companion.control.allocation`).
"""

from __future__ import annotations

from companion.control.allocation import Rotors4
from companion.control.params import VehicleParams
from sitl.plant.onboard import command_level

__all__ = ["FIRMWARE_TO_PLANT", "rotor_commands", "thrust_model_factor"]

FIRMWARE_TO_PLANT = (3, 1, 0, 2)
"""the plant rotor (0-based) each firmware motor output 1-4 drives"""


def rotor_commands(outputs: tuple[float, ...], vehicle: VehicleParams, levels: int, armed: bool = True) -> Rotors4:
    """Rotor speed commands [rad/s] in the plant's order for the firmware's first four motor
    outputs (normalised, firmware order); NaN or a disarmed vehicle stops the motors."""
    lo, hi = vehicle.rotor_speed_min_rad_s, vehicle.rotor_speed_max_rad_s
    step = (hi - lo) / (levels - 1)
    if not armed:
        return (0.0, 0.0, 0.0, 0.0)
    cmd = [0.0, 0.0, 0.0, 0.0]
    for i, plant_rotor in enumerate(FIRMWARE_TO_PLANT):
        u = outputs[i]
        if not u > 0.0:  # zero, below or NaN: the ESC stops the motor
            continue
        w = min(u, 1.0) * hi
        cmd[plant_rotor] = command_level(w * w, lo, hi, step)
    return (cmd[0], cmd[1], cmd[2], cmd[3])


def thrust_model_factor(vehicle: VehicleParams) -> float:
    """The quadratic share ``f`` of the thrust curve ``T / T_max = f u^2 + (1 - f) u`` of the motor
    interface above (PX4's THR_MDL_FAC, ArduPilot's MOT_THST_EXPO): 1, exact above the idle speed
    (``u > w_min / w_max``, 12.5 % for the default rotors, 1.6 % of full thrust)."""
    return 1.0
