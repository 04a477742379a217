"""One bad plant step must not kill the vehicle's process, and a vehicle out of control must not fly on.

:class:`StepGuard` runs every plant step of the MAVLink vehicle:

- **Numerical fault.** An exception inside the step, or a non-finite plant state after it (a NaN
  or an infinity anywhere in position, velocity, attitude or rates), is contained: the world is
  put back to the last finite state, at rest; the flight is terminated (motors off, disarmed,
  arming refused until restart: :meth:`~sitl.autopilot.logic.Autopilot.terminate`) with a CRITICAL
  STATUSTEXT naming the fault; and the world **halts**: from then on the clock runs and the
  vehicle keeps answering (heartbeat, telemetry of the frozen state, parameters, commands) but no
  physics is stepped, since whatever produced the fault would produce it again.
- **Loss of control** (PX4's failure detector, as attitude error): armed and in the air, the
  thrust axis more than 60° from the setpoint's for 0.25 s in all — counted by a leaky timer that
  drains at half the rate while the error is smaller, since a tumbling vehicle passes upright
  twice a turn — a dead motor, a torque beyond the airframe's authority — terminates the flight
  too: motors off rather than a vehicle tumbling on at full thrust. A tracked command, however
  steep, never trips it (the error counts, not the tilt); yaw is left out (its authority is small
  and a yaw step slow by design). The thresholds leave room for the worst recoverable transient
  found: entering LAND against a lateral push (4 N of wind drag and force), the thrust axis lags
  its setpoint by up to 66° for 0.1 s; a motor at 35 % or less trips it within 0.3 s.
"""

from __future__ import annotations

import math

from companion.control.vector import ZERO3

from ..plant.sensors import ImuSample
from . import world
from .logic import Autopilot, Severity
from .sensed import Sensed

__all__ = ["StepGuard", "LOSS_OF_CONTROL_RAD", "LOSS_OF_CONTROL_S"]

LOSS_OF_CONTROL_RAD = math.radians(60.0)
LOSS_OF_CONTROL_S = 0.25
CHECK_EVERY = 10
"""steps between loss-of-control checks (10 ms at 1 kHz)"""


def _thrust_axis(q: tuple) -> tuple[float, float, float]:
    """Body z (the thrust axis, down) in NED: the third column of R(q)."""
    w, x, y, z = q
    return 2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z


class StepGuard:
    """Steps one :class:`Autopilot` with numerical faults contained and loss of control detected."""

    def __init__(self, ap: Autopilot) -> None:
        self.ap = ap
        self.halted: str | None = None
        """the numerical fault that halted the world (None: running)"""
        self._good = self._snapshot()
        self._bad_s = 0.0
        """the leaky loss-of-control timer [simulated s]"""
        self._frozen = ap.vehicle.plant.state
        """the halted world's state"""
        self._k = 0

    def _snapshot(self) -> tuple:
        v = self.ap.vehicle
        return v.plant.state, v.estimator.q, v.mocap.latest, v.imu_sample

    def step(self, steps: int = 1) -> None:
        """``steps`` plant steps of the world (:func:`world.step`), or of the clock alone once halted."""
        ap = self.ap
        if self.halted is not None:
            ap.vehicle.t += steps * ap.dt  # the clock runs on; the world stands still, whatever is poked into it
            if ap.vehicle.plant.state is not self._frozen:
                ap.vehicle.plant.state = self._frozen
            ap.stand_still(Sensed.of(ap.vehicle))
            return
        try:
            world.step(ap, steps)
        except Exception as exc:  # noqa: BLE001 - anything a step raises is a numerical fault here
            self._fault(f"{type(exc).__name__}: {exc}")
            return
        s = ap.vehicle.plant.state
        # one sum: NaN or infinity anywhere makes it non-finite (finite values here never overflow)
        if not math.isfinite(sum(s.pos_ned_m) + sum(s.vel_ned_m_s) + sum(s.q) + sum(s.omega_rad_s)):
            self._fault("non-finite state")
            return
        self._good = self._snapshot()
        self._k += steps
        if self._k >= CHECK_EVERY:
            self._check_control(self._k * ap.dt)
            self._k = 0

    def _check_control(self, period: float) -> None:
        """The leaky timer over the last ``period`` [s]: loss of control held long enough terminates."""
        ap = self.ap
        if not ap.armed or ap.landed:
            self._bad_s = 0.0
            return
        a = _thrust_axis(ap.vehicle.estimator.q)
        b = _thrust_axis(ap.setpoint.q_d)
        cos = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / math.sqrt(
            (a[0] ** 2 + a[1] ** 2 + a[2] ** 2) * (b[0] ** 2 + b[1] ** 2 + b[2] ** 2))
        if cos >= math.cos(LOSS_OF_CONTROL_RAD):
            self._bad_s = max(0.0, self._bad_s - 0.5 * period)
            return
        self._bad_s += period
        if self._bad_s >= LOSS_OF_CONTROL_S - 1e-9:
            self._bad_s = 0.0
            ap.terminate(f"Loss of control ({math.degrees(math.acos(max(-1.0, cos))):.0f} deg off)")

    def _fault(self, what: str) -> None:
        ap = self.ap
        v = ap.vehicle
        state, q, tracked, imu = self._good
        v.plant.state = self._frozen = state._replace(vel_ned_m_s=ZERO3, omega_rad_s=ZERO3)
        v.estimator.q, v.mocap.latest, v.omega_est = q, tracked._replace(vel_ned_m_s=ZERO3), ZERO3
        v.imu_sample = ImuSample(ZERO3, imu.specific_force_body_m_s2)
        self.halted = what
        ap.stand_still(Sensed.of(v))  # the rules see the restored world, not the faulty step
        ap.terminate(f"Numerical fault ({what})")
        ap.say(Severity.CRITICAL, "World halted: restart the vehicle")
