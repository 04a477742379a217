"""What goes into SET_ATTITUDE_TARGET, deliberately, per autopilot.

The controller produces an attitude ``q_d``, the body rates ``omega_d`` of (34) and a thrust. What
an autopilot does with them depends on ``type_mask`` (MAVLink: a set bit means *ignore*):

- **PX4 v1.16** (``mavlink_receiver.cpp``): attitude not ignored -> an attitude setpoint, with the
  yaw rate as feed-forward; roll *and* pitch rates not ignored -> a rate setpoint as well,
  published next to its own attitude controller's (two writers on one topic: do not send both);
- **ArduPilot** (GUIDED): rates not ignored are used *with* the attitude target, and it keeps
  rotating the target by them until ``GUID_TIMEOUT`` when the stream stops (a dead companion
  pitched a vehicle to 39 deg): never send them unless deliberately.

So the modes are:

- ``attitude``: ``q_d`` + thrust, roll and pitch rates ignored, yaw rate as feed-forward (PX4);
  on ArduPilot all three rates ignored;
- ``rates``: body rates + thrust, attitude ignored; the attitude loop is closed here
  (:func:`~companion.control.rate_command.body_rate_command`);
- ``attitude_rates``: all of it, as the paper's inner loop takes it (the bundled vehicle's
  ``paper`` flavour); never chosen automatically.
"""

from __future__ import annotations

from dataclasses import dataclass

from companion.control.quaternion import Quat
from companion.control.rate_command import body_rate_command
from companion.control.vector import Vec3, clip_norm
from companion.mavlink.setpoints import ATTITUDE_IGNORED, RATES_IGNORED, ROLL_PITCH_RATES_IGNORED

__all__ = ["OUTPUT_MODES", "Output", "choose_output"]

OUTPUT_MODES = ("auto", "attitude", "rates", "attitude_rates")

RATE_LOOP_GAIN_PER_S = 6.0
"""k of the attitude loop closed here in ``rates`` mode (PX4's MC_ROLL_P default is 6.5)"""


@dataclass(frozen=True)
class Output:
    mode: str
    autopilot: str

    @property
    def type_mask(self) -> int:
        if self.mode == "rates":
            return ATTITUDE_IGNORED
        if self.mode == "attitude_rates":
            return 0
        if self.autopilot == "ardupilot":
            return RATES_IGNORED
        return ROLL_PITCH_RATES_IGNORED

    def rates(self, q: Quat, q_d: Quat, omega_d_rad_s: Vec3) -> Vec3:
        """The body rates to put on the wire (ignored ones are sent as 0)."""
        if self.mode == "rates":
            return body_rate_command(q, q_d, omega_d_rad_s, RATE_LOOP_GAIN_PER_S)
        if self.mode == "attitude_rates":
            return omega_d_rad_s
        if self.autopilot == "ardupilot":
            return (0.0, 0.0, 0.0)
        return (0.0, 0.0, omega_d_rad_s[2])

    def wire_rates(self, q: Quat, q_d: Quat, omega_d_rad_s: Vec3, max_rate_rad_s: float) -> Vec3:
        """The body rates as they go on the wire: this mode's (:meth:`rates`), at most
        ``max_rate_rad_s`` in norm. The setpoint guard judges these, not the law's own."""
        return tuple(float(w) for w in clip_norm(self.rates(q, q_d, omega_d_rad_s), max_rate_rad_s))  # type: ignore[return-value]


def choose_output(requested: str, autopilot: str) -> Output:
    """``auto`` is ``attitude`` on every autopilot (on PX4 v1.16 SIH it tracked better than
    ``rates``: docs/autopilots.md); ``attitude_rates`` only when asked for."""
    return Output("attitude" if requested == "auto" else requested, autopilot)
