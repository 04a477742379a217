"""The simulated vehicle's autopilot: PX4-like modes, arming, take-off, landing, offboard, failsafe.

Pure logic: it reads the vehicle as a :class:`~sitl.autopilot.sensed.Sensed` record and commands its
motors and onboard loop; it never steps the plant (:mod:`sitl.autopilot.world` does, between
:meth:`Autopilot.decide` and :meth:`Autopilot.observe`). No sockets, no clock. The MAVLink edge
(:mod:`sitl.autopilot.server`) decodes messages into the calls below and encodes the state back.

Rules, as PX4 has them:

- arming needs the vehicle on the ground; disarming in the air needs the force code 21196;
  armed but never lifted off for ``disarm_preflight_s`` disarms, as does ``disarm_land_s`` after
  touch-down;
- take-off climbs to ``takeoff_alt_m`` above home at ``takeoff_speed_m_s`` and then holds;
  land descends at ``land_speed_m_s`` below MPC_LAND_ALT2 (5 m), faster above it as PX4 does (up to
  MPC_Z_VEL_MAX_DN above MPC_LAND_ALT1, 10 m), and disarms on the ground; RTL flies home, then lands;
- a setpoint (SET_ATTITUDE_TARGET or SET_POSITION_TARGET_LOCAL_NED) counts as proof of life in any
  mode but is flown only in OFFBOARD; switching to OFFBOARD needs one from the requesting system
  within the loss timeout (PX4 v1.16's offboard check: a single fresh setpoint, no rate); in
  OFFBOARD only the system that switched to it may steer;
- a position mode entered from OFFBOARD brakes first (:mod:`sitl.autopilot.shaping`), at bounded
  accelerations, and holds, lands or returns from where it stopped;
- **offboard-loss failsafe**: no setpoint for ``offboard_loss_timeout_s`` -> HOLD at the current
  position; still nothing after ``failsafe_hold_s`` more -> LAND, then disarm. An explicit mode
  change by the operator ends the failsafe.
"""

from __future__ import annotations

import dataclasses
import enum
import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

from pymavlink.dialects.v20 import ardupilotmega as mavlink
from pymavlink.dialects.v20.ardupilotmega import (
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_SET_MODE,
    MAV_CMD_NAV_LAND,
    MAV_CMD_NAV_LOITER_UNLIM,
    MAV_CMD_NAV_RETURN_TO_LAUNCH,
    MAV_CMD_NAV_TAKEOFF,
)

from companion.control import quaternion as quat
from companion.mavlink.commands import FORCE_ARM_DISARM
from companion.control.outer_loop import AttitudeSetpoint, PositionLoop, PositionMeasurement
from companion.control.trajectory import PositionReference, ReferenceFilter
from companion.control.vector import ZERO3, Vec3, sub

from .blind import BlindDescent, blind_start, blind_step, blind_thrust_n, counted_down, learn_bias
from .flavours import FlavourRules, Mode, rules_for
from .guided import ShapedAttitude, climb_rate_m_s, guided_target, level_keeping_altitude
from ..plant.vehicle import SimVehicle
from .sensed import Sensed
from .shaping import BRAKE, ShapedReference, ShapingLimits, TrajectoryTarget, at_rest, shape_step

__all__ = [
    "Mode",
    "LandedState",
    "MavResult",
    "Severity",
    "AutopilotParams",
    "CommandResult",
    "Failsafe",
    "Autopilot",
]


def custom_mode(mode: Mode, flavour: str) -> int:
    """The heartbeat's custom_mode for ``mode`` in ``flavour`` (:mod:`.flavours`)."""
    return rules_for(flavour).custom_mode(mode)


def mode_from_command(flavour: str, p2: int, p3: int) -> Mode | None:
    """The mode a DO_SET_MODE asks for (param2, param3), in the flavour's numbering."""
    return rules_for(flavour).mode_from_command(p2, p3)


class LandedState(enum.IntEnum):
    """MAV_LANDED_STATE"""

    UNDEFINED = mavlink.MAV_LANDED_STATE_UNDEFINED
    ON_GROUND = mavlink.MAV_LANDED_STATE_ON_GROUND
    IN_AIR = mavlink.MAV_LANDED_STATE_IN_AIR
    TAKEOFF = mavlink.MAV_LANDED_STATE_TAKEOFF
    LANDING = mavlink.MAV_LANDED_STATE_LANDING


class MavResult(enum.IntEnum):
    ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
    TEMPORARILY_REJECTED = mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    DENIED = mavlink.MAV_RESULT_DENIED
    UNSUPPORTED = mavlink.MAV_RESULT_UNSUPPORTED
    FAILED = mavlink.MAV_RESULT_FAILED


class Severity(enum.IntEnum):
    """MAV_SEVERITY"""

    CRITICAL = mavlink.MAV_SEVERITY_CRITICAL
    ERROR = mavlink.MAV_SEVERITY_ERROR
    WARNING = mavlink.MAV_SEVERITY_WARNING
    NOTICE = mavlink.MAV_SEVERITY_NOTICE
    INFO = mavlink.MAV_SEVERITY_INFO


@dataclass(frozen=True)
class AutopilotParams:
    """Behaviour of the firmware, named after PX4's parameters where one exists."""

    offboard_loss_timeout_s: float = 1.0
    """COM_OF_LOSS_T"""
    failsafe_hold_s: float = 5.0
    """COM_FAIL_ACT_T: hold this long after offboard loss, then land"""
    takeoff_alt_m: float = 2.5
    """MIS_TAKEOFF_ALT"""
    takeoff_speed_m_s: float = 1.5
    """MPC_TKO_SPEED"""
    land_speed_m_s: float = 0.7
    """MPC_LAND_SPEED"""
    disarm_preflight_s: float = 10.0
    """COM_DISARM_PRFLT"""
    disarm_land_s: float = 2.0
    """COM_DISARM_LAND"""
    max_rate_setpoint_rad_s: float = math.radians(2000.0)
    """body-rate setpoints beyond this are rejected as out of range"""
    paper_inner_loop: bool = False
    """the paper's inner loop: an attitude *and* its body rates, both used (the ``paper`` flavour);
    False: PX4's rule — with an attitude only the yaw rate is a feed-forward, and roll and pitch
    rates sent beside it are what PX4 v1.16 publishes as a second, conflicting rate setpoint
    (counted, warned once, not flown)"""
    hold_controller: str = "ism_do"
    """position controller of the firmware's own hold, take-off and landing"""
    flavour: str = "px4"
    """"px4" or "ardupilot" (modes, take-off in GUIDED, no offboard-loss failsafe, ANGLE_MAX, ...)"""
    guided_timeout_s: float = 3.0
    """ArduPilot GUID_TIMEOUT: attitude targets older than this are no longer flown; it holds"""
    angle_max_deg: float = 30.0
    """ArduPilot ATC_ANGLE_MAX [deg] (ANGLE_MAX in cdeg before 4.7): the lean limit of its own modes;
    GUIDED attitude targets are not clipped to it (seen on ArduCopter SITL)"""
    rate_ff_enabled: bool = True
    """ArduPilot ATC_RATE_FF_ENAB: attitude targets are shaped, approached with the time constant
    ``input_tc_s`` instead of flown as sent (ArduPilot's default; the companion turns it off)"""
    input_tc_s: float = 0.15
    """ArduPilot ATC_INPUT_TC: the time constant of that shaping [s]"""
    input_accel_max_rad_s2: float = math.radians(1100.0)
    """ArduPilot ATC_ACCEL_R_MAX / ATC_ACCEL_P_MAX (default 110000 cdeg/s^2): how fast the shaped
    target's rate may change [rad/s^2]"""
    angle_boost: bool = True
    """ArduPilot ATC_ANGLE_BOOST: throttle divided by the cosine of the vehicle's tilt (ArduPilot's
    default; a companion that already sends the thrust magnitude then climbs in every lean)"""
    position_after_s: float | None = None
    """vehicle seconds after boot before the estimator has an origin (no LOCAL_POSITION_NED, no arming);
    None: the flavour's own (ArduCopter ~40 s, seen on its SITL; PX4 SIH about 1 s)"""
    offboard_loss_hold: bool = False
    """offboard loss: hold for ``failsafe_hold_s``, then land (PX4 with RC and COM_OBL_RC_ACT hold);
    False: descend and land at once (PX4 v1.16 without RC, the default)"""
    guided_thrust_is_throttle: bool = False
    """ArduPilot GUID_OPTIONS bit 3: thrust is throttle (else a climb rate, 0.5 = hold altitude)"""
    shaping: ShapingLimits = ShapingLimits()
    """speeds, accelerations and gains of trajectory setpoints in OFFBOARD and of braking"""


HOVER_STALE = 0.95
"""ArduCopter's MOT_THST_HOVER at boot over the throttle that really hovers: its SITL boots with the
saved 0.35 and learns about 0.367 in a GUIDED hover (tests/contract)"""
HOVER_LEARN_TC_S = 10.0
"""the time constant of ArduCopter's hover-throttle learning (AP_MOTORS_THST_HOVER_TC)"""


class CommandResult(NamedTuple):
    result: MavResult
    reason: str = ""


FORCE_DISARM = float(FORCE_ARM_DISARM)

class Failsafe(enum.StrEnum):
    """The failsafe in progress; its value is what reports and STATUSTEXTs say."""

    OFFBOARD_LOST = "offboard lost"
    """no setpoint for the timeout: holding (PX4 with RC, COM_OBL_RC_ACT hold)"""
    OFFBOARD_LOST_LANDING = "offboard lost, landing"
    """still none after the hold: landing"""
    OFFBOARD_LOST_DESCENDING = "offboard lost, descending"
    """PX4 v1.16 without RC: descending at once (the heartbeat shows POSCTL)"""
    IMU_FAILED = "IMU failed"
    POSITION_LOST = "position lost"
    """no tracking in the air: descending blind"""
    POSITION_LOST_LANDING = "position lost, landing"
    """tracking back during the blind descent: landing on it"""

_POSITION_MODES = (Mode.HOLD, Mode.TAKEOFF, Mode.LAND, Mode.RTL, Mode.GUIDED)


class Autopilot:
    """Modes, arming and setpoints around one :class:`SimVehicle`: :meth:`decide` before each plant
    step, :meth:`observe` after it (:func:`sitl.autopilot.world.step`)."""

    POSITION_TIMEOUT_S = 0.5
    """no tracking sample for this long in the air: position lost (PX4's COM_POS_FS_DELAY is 1 s)"""
    SENSOR_FAILSAFES = (Failsafe.IMU_FAILED, Failsafe.POSITION_LOST, Failsafe.POSITION_LOST_LANDING)

    def __init__(self, vehicle: SimVehicle, params: AutopilotParams | None = None) -> None:
        self.vehicle = vehicle
        vehicle.enable_fault_checks()
        self.sensed = Sensed.of(vehicle)
        """the vehicle's readings at the newest :meth:`decide` or :meth:`observe`"""
        self.params = params or AutopilotParams()
        self.accel_bias_z_m_s2 = 0.0
        """vertical accelerometer bias (NED), learnt against the tracking system (sitl.autopilot.blind)"""
        self.blind: BlindDescent | None = None
        """the descent on the accelerometer alone, while position is lost"""
        sc = vehicle.scenario
        self.dt = vehicle.dt
        self.pos_div = int(round(sc.plant_rate_hz / sc.position_rate_hz))
        self.pos_dt = self.pos_div * self.dt
        self.ground_z = sc.airframe.ground_z_m
        self.rules: FlavourRules = rules_for(self.params.flavour)
        """what differs between PX4 and ArduCopter (sitl.autopilot.flavours)"""
        self.mode = self.rules.initial_mode
        """ArduCopter boots in STABILIZE, PX4 in HOLD"""
        self.user_mode = Mode.HOLD
        """the last mode a command chose (PX4 returns to it after a disarm)"""
        self.armed = False
        self.landed = True
        self.arm_time = 0.0
        self.home: Vec3 = vehicle.state.pos_ned_m
        self.lifted_off = False
        self.touchdown_time: float | None = None
        self.failsafe: Failsafe | None = None
        self.failsafe_time = 0.0
        self.messages: deque[tuple[Severity, str]] = deque(maxlen=32)
        self.events: deque[tuple[float, str]] = deque(maxlen=64)
        """(time, text) of warnings and worse: failsafes, faults, refusals (for reports)"""
        self.rejected: dict[str, int] = {}
        """counts of rejected inputs by reason (setpoints, commands), for tests and reports"""

        self.setpoint_time_by_sender: dict[int, float] = {}
        """when each system's newest accepted setpoint arrived (system ids: at most 256 entries)"""
        self.setpoints_accepted = 0
        self.last_setpoint_time = -math.inf
        self.setpoint_sender: int | None = None
        """the system whose setpoint is stored (before offboard anyone may stream one)"""
        self.offboard_owner: int | None = None
        self.offboard_attitude: AttitudeSetpoint | None = None
        self.offboard_uses_attitude = True
        self.offboard_target: TrajectoryTarget | None = None
        """the newest trajectory setpoint (None: the newest setpoint is an attitude)"""
        self.shaped: ShapedReference | None = None
        """the reference the position loop tracks while flying a trajectory setpoint or braking"""
        self.braking = False

        self.position_loop = PositionLoop.create(self.params.hold_controller, sc.vehicle, sc.position, sc.reference)
        self.ref_filter = ReferenceFilter(sc.trajectory, vehicle.state.pos_ned_m)
        self.target: Vec3 = vehicle.state.pos_ned_m
        self.target_yaw = 0.0
        self.setpoint = self._idle_setpoint()
        self._k = 0
        """plant steps so far"""
        self._position_due_k = 0
        """the plant step at which the position loop next runs (every pos_div steps)"""
        self.step_dt = self.dt
        """the time the rules' newest decision covers (a chunk of plant steps)"""
        self._land_phase_home = False
        vehicle.motors_on = False

    @property
    def ardupilot(self) -> bool:
        """ArduCopter's rules (the server's wire-level choices still ask this)."""
        return self.rules.name == "ardupilot"

    @property
    def has_position(self) -> bool:
        after = self.params.position_after_s
        if after is None:
            after = self.rules.position_after_s
        return self.t >= after

    @property
    def follows_stream(self) -> bool:
        """Flying a companion's setpoint stream: armed, in OFFBOARD, or in GUIDED flying attitude
        targets. (Disarmed after a landing, PX4 is back in OFFBOARD with no one streaming: a world
        in lockstep must not wait for setpoints there.)"""
        return self.armed and (self.mode == Mode.OFFBOARD or (self.mode == Mode.GUIDED and self._guided_flying))

    # --- events --------------------------------------------------------------------------

    def _say(self, severity: Severity, text: str) -> None:
        self.messages.append((severity, text[:50]))
        if severity <= Severity.WARNING:
            self.events.append((round(self.t, 3), text))

    def say(self, severity: Severity, text: str) -> None:
        """A STATUSTEXT from outside the autopilot (e.g. a fault being injected)."""
        self._say(severity, text)

    def _reject(self, reason: str) -> None:
        self.rejected[reason] = self.rejected.get(reason, 0) + 1

    @property
    def t(self) -> float:
        return self.sensed.t

    # --- commands ------------------------------------------------------------------------

    def command(self, command: int, params: tuple[float, ...], sender: int = 255) -> CommandResult:
        """COMMAND_LONG semantics; every call is idempotent (MAVSDK retries)."""
        p = tuple(params) + (math.nan,) * (7 - len(params))
        if command == MAV_CMD_COMPONENT_ARM_DISARM:
            return self._arm_disarm(p[0], p[1])
        if command == MAV_CMD_NAV_TAKEOFF:
            return self._takeoff(p[6])
        if command == MAV_CMD_NAV_LAND:
            return self.set_mode(Mode.LAND, sender)
        if command == MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return self.set_mode(Mode.RTL, sender)
        if command == MAV_CMD_NAV_LOITER_UNLIM:
            return self.set_mode(Mode.HOLD, sender)
        if command == MAV_CMD_DO_SET_MODE:
            if not (math.isfinite(p[0]) and math.isfinite(p[1]) and math.isfinite(p[2])):
                return self._deny("mode change: non-finite parameters")
            if not int(p[0]) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
                return self._deny("mode change: base mode lacks the custom flag")
            mode = mode_from_command(self.params.flavour, int(p[1]), int(p[2]))
            if mode is None:
                return self._deny(f"mode change: unknown mode {int(p[1])}/{int(p[2])}")
            return self.set_mode(mode, sender)
        self._reject("unsupported command")
        return CommandResult(MavResult.UNSUPPORTED, f"command {command} not supported")

    def _deny(self, reason: str, result: MavResult = MavResult.DENIED) -> CommandResult:
        self._reject(reason.split(":")[0])
        self._say(Severity.WARNING, reason)
        return CommandResult(result, reason)

    def _arm_disarm(self, arm: float, force: float) -> CommandResult:
        if arm == 1.0 and self.terminated:
            return self._deny(f"Arming denied: flight terminated (restart): {self.terminated}")
        if arm == 1.0 and self.sensed.imu_failed:
            return self._deny(f"Arming denied: IMU failed ({self.sensed.imu_failed})")
        if arm == 1.0:
            if self.armed:
                return CommandResult(MavResult.ACCEPTED)
            if not self.landed:
                return self._deny("Arming denied: not on the ground")
            if self.t < 1.0 or not self.has_position:
                return self._deny("Arming denied: estimator settling", MavResult.TEMPORARILY_REJECTED)
            if self.mode == Mode.OFFBOARD and not self.setpoint_fresh(None):
                return self._deny("Arming denied: No offboard signal", MavResult.TEMPORARILY_REJECTED)
            self.armed = True
            self.arm_time = self.t
            self.lifted_off = False
            self.home = self.sensed.tracked.pos_ned_m
            self.vehicle.motors_on = True
            self._reset_controllers()
            self._say(Severity.INFO, "Armed")
            return CommandResult(MavResult.ACCEPTED)
        if arm == 0.0:
            if not self.armed:
                return CommandResult(MavResult.ACCEPTED)
            if not self.landed and force != FORCE_DISARM:
                return self._deny("Disarming denied: in the air")
            self._disarm("Disarmed" if self.landed else "Disarmed in the air (forced)")
            return CommandResult(MavResult.ACCEPTED)
        return self._deny(f"Arm/disarm: invalid param1 {arm!r}")

    terminated: str | None = None
    """why the flight was terminated (latched: arming is refused until restart)"""

    def terminate(self, reason: str) -> None:
        """Flight termination, PX4's answer to a failure it cannot fly through (its failure
        detector) and ours to a numerical fault (sitl.autopilot.guard): motors off where it is, disarmed,
        the reason latched."""
        self.terminated = reason
        self._say(Severity.CRITICAL, f"{reason}: motors off")
        self.armed = self.vehicle.motors_on = False
        self.failsafe = None
        if self.mode in (Mode.LAND, Mode.TAKEOFF, Mode.RTL, Mode.OFFBOARD):
            self.mode = Mode.HOLD
        self.setpoint = self._idle_setpoint()

    def _disarm(self, text: str) -> None:
        self.armed = False
        self.vehicle.motors_on = False
        self.failsafe = None
        if self.mode in (Mode.LAND, Mode.TAKEOFF, Mode.RTL):
            # PX4 returns to the last mode the user chose (OFFBOARD after an offboard flight, where it
            # then refuses to arm without a stream); ArduCopter to GUIDED after a GUIDED take-off
            self.mode = self.rules.mode_after_disarm(self.user_mode)
        self._say(Severity.INFO, text)

    @property
    def reported_mode(self) -> Mode:
        """The mode the heartbeat shows: PX4 v1.16 shows POSCTL while its offboard-loss failsafe
        descends without RC."""
        return self.rules.reported_mode(self.mode, self.failsafe == Failsafe.OFFBOARD_LOST_DESCENDING)

    def _takeoff(self, altitude_param: float) -> CommandResult:
        """MAV_CMD_NAV_TAKEOFF (or PX4's TAKEOFF mode, NaN: its default height); the flavour reads
        param7 and says where take-off may start."""
        if not self.armed:
            return self._deny("Takeoff denied: disarmed")
        height = self.rules.takeoff_height(self.mode, altitude_param, self.origin_alt_m, self.params.takeoff_alt_m)
        if isinstance(height, str):
            return self._deny(height)
        if self.mode == Mode.TAKEOFF:
            return CommandResult(MavResult.ACCEPTED)
        self.takeoff_alt_m = height
        self._enter(Mode.TAKEOFF)
        return CommandResult(MavResult.ACCEPTED)

    guided_climb_rate_m_s = 0.0
    """ArduPilot, thrust as climb rate (sitl.autopilot.guided): the newest target's"""
    _shaped: ShapedAttitude | None = None
    """ArduPilot, ATC_RATE_FF_ENAB: the shaped target flown (None: none yet, or not shaping)"""
    _guided_flying = False

    origin_alt_m = 488.0
    """AMSL altitude of the local origin (set by the server from its geodetic origin)"""
    takeoff_alt_m = AutopilotParams.takeoff_alt_m

    def set_mode(self, mode: Mode, sender: int = 255) -> CommandResult:
        if self.failsafe in self.SENSOR_FAILSAFES and mode != Mode.LAND:
            return self._deny(f"{mode.name} denied: {self.failsafe}, landing")
        if mode == self.mode and self.failsafe is None:
            if mode == Mode.OFFBOARD and sender != self.offboard_owner:
                return self._deny("Offboard denied: another system has control")
            return CommandResult(MavResult.ACCEPTED)
        if mode in (Mode.MANUAL, Mode.ALTCTL, Mode.POSCTL):
            return self._deny(f"{mode.name} denied: no RC in this simulation")
        if mode == Mode.MISSION:
            return self._deny("Mission denied: no mission loaded")
        if not self.rules.has_mode(mode):
            return self._deny(f"{mode.name} denied: not a mode of this autopilot")
        if mode == Mode.OFFBOARD and not self.armed and self.rules.disarmed_offboard_is_intention:
            # PX4 takes a mode while disarmed as the user's intention (arming then needs a stream)
            self.mode = self.user_mode = Mode.OFFBOARD
            return CommandResult(MavResult.ACCEPTED)
        if mode == Mode.OFFBOARD:
            if not self.setpoint_fresh(sender):  # PX4: a mode whose requirement fails is temporarily rejected
                return self._deny("Offboard denied: No offboard signal", MavResult.TEMPORARILY_REJECTED)
            self.offboard_owner = sender
            if self.setpoint_sender != sender:  # the newest setpoint is another system's: not the owner's
                self.offboard_attitude = AttitudeSetpoint(self.sensed.q_est, (0.0, 0.0, 0.0),
                                                          self.vehicle.hover_thrust_n)
                self.offboard_uses_attitude, self.offboard_target = True, None
                self.setpoint_sender = sender
        if mode == Mode.TAKEOFF and self.rules.takeoff_is_a_mode:
            return self._takeoff(math.nan)
        if mode in (Mode.RTL, Mode.LAND) and (not self.armed or self.landed):
            if mode == Mode.LAND:
                return CommandResult(MavResult.ACCEPTED)  # already down: nothing to do
            return self._deny("RTL denied: not flying")
        if self.failsafe is not None:
            self._say(Severity.WARNING, "Failsafe cleared by mode change")
            self.failsafe = None
        if mode not in (Mode.TAKEOFF, Mode.LAND, Mode.RTL):
            self.user_mode = mode
        self._enter(mode)
        return CommandResult(MavResult.ACCEPTED)

    def _enter(self, mode: Mode) -> None:
        prev = self.mode
        self.mode = mode
        pos = self.sensed.tracked.pos_ned_m
        yaw = float(quat.to_euler(self.sensed.q_est)[2])
        traj = self.vehicle.scenario.trajectory
        was_braking, self.braking = self.braking, False
        if mode in _POSITION_MODES and prev not in _POSITION_MODES:
            # start the reference where the vehicle is, moving as it moves, and brake it to rest first:
            # the mode's own reference (at most 2 m/s) cannot start faster than that
            flying_trajectory = prev == Mode.OFFBOARD and self.offboard_target is not None and self.shaped is not None
            if not flying_trajectory:
                self.shaped = self._vehicle_reference()
                self.position_loop.reset()
                self.position_loop.thrust_n = self.setpoint.thrust_n
            self.braking = not self.landed
            self.ref_filter = ReferenceFilter(traj, pos, yaw, self.sensed.tracked.vel_ned_m_s)
        elif mode == Mode.OFFBOARD and self.offboard_target is not None and not was_braking:
            self._start_trajectory(from_mode_reference=prev in _POSITION_MODES)  # (braking: go on from its reference)
        if mode in (Mode.HOLD, Mode.GUIDED):
            self.ref_filter.params = traj
            self.target, self.target_yaw = pos, yaw
            self._guided_flying = False
        elif mode == Mode.TAKEOFF:
            self.ref_filter.params = dataclasses.replace(traj, max_speed_m_s=self.params.takeoff_speed_m_s)
            z = self.home[2] - self.takeoff_alt_m
            self.target = (pos[0], pos[1], z if self.landed else min(pos[2], z))  # never descend
            self.target_yaw = yaw
        elif mode == Mode.LAND:
            self.ref_filter.params = dataclasses.replace(traj, max_speed_m_s=self.land_speed_m_s())
            self.target = (pos[0], pos[1], self.ground_z + 1.0)  # below the ground: keep descending
            self.target_yaw = yaw
            self.touchdown_time = None
        elif mode == Mode.RTL:
            self.ref_filter.params = traj
            self.target = (self.home[0], self.home[1], min(pos[2], self.home[2] - self.takeoff_alt_m))
            self.target_yaw = yaw
            self._land_phase_home = False
        elif mode == Mode.OFFBOARD:
            self.failsafe = None
        self._say(Severity.INFO, f"Mode {mode.name}")

    # --- offboard setpoints ------------------------------------------------------------

    def setpoint_fresh(self, sender: int | None = None) -> bool:
        """A setpoint (from ``sender``, if given) arrived within the offboard loss timeout: PX4 v1.16's
        offboard check, which asks for one fresh offboard_control_mode and no rate
        (commander/HealthAndArmingChecks/checks/offboardCheck.cpp)."""
        last = self.last_setpoint_time if sender is None else self.setpoint_time_by_sender.get(sender, -math.inf)
        return self.t - last <= self.params.offboard_loss_timeout_s

    def attitude_target(
        self, sender: int, type_mask: int, q: tuple[float, float, float, float], body_rates_rad_s: Vec3,
        thrust: float,
    ) -> str | None:
        """A SET_ATTITUDE_TARGET; returns the reason it was rejected, or None.

        ``thrust`` is normalised (0..1, T = thrust * T_max). Rejected: non-finite numbers, a
        quaternion whose norm is off by more than 1e-3, thrust outside [0, 1], rates beyond
        ``max_rate_setpoint_rad_s``, and any setpoint from a system other than the one that
        took offboard control while in OFFBOARD.
        """
        use_rates = (not type_mask & mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE,
                     not type_mask & mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE,
                     not type_mask & mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE)
        use_thrust = not type_mask & mavlink.ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE
        use_att = not type_mask & mavlink.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
        reason = None
        n = math.nan
        if use_att:
            q0, q1, q2, q3 = q
            n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)  # not finite if any part is not
            if not math.isfinite(n):
                reason = "non-finite quaternion"
            elif abs(n - 1.0) > 1e-3:
                reason = "non-unit quaternion"
        used = [w for w, u in zip(body_rates_rad_s, use_rates) if u]
        if reason is None and not all(map(math.isfinite, used)):
            reason = "non-finite body rate"
        if reason is None and used and max(map(abs, used)) > self.params.max_rate_setpoint_rad_s:
            reason = "body rate out of range"
        if reason is None and use_thrust and not (math.isfinite(thrust) and 0.0 <= thrust <= 1.0):
            reason = "thrust outside [0, 1]"
        if reason is None and self.mode == Mode.OFFBOARD and self.offboard_owner not in (None, sender):
            reason = "setpoint from a system without offboard control"
        if reason is not None:
            self._reject(reason)
            return reason
        self._note_setpoint(sender)
        prev = self.offboard_attitude
        t_max = self.vehicle.scenario.vehicle.thrust_max_n
        thrust_n = thrust * t_max if use_thrust else (prev.thrust_n if prev else 0.0)
        self.guided_climb_rate_m_s = climb_rate_m_s(thrust) if use_thrust else 0.0
        rates = tuple(w if u else 0.0 for w, u in zip(body_rates_rad_s, use_rates))
        if use_att:
            q_d = (q[0] / n, q[1] / n, q[2] / n, q[3] / n)
            if not self.params.paper_inner_loop and not self.rules.attitude_with_rates:
                if use_rates[0] and use_rates[1]:
                    self._reject("attitude and body rates together")
                    if self.rejected["attitude and body rates together"] == 1:
                        self._say(Severity.WARNING, "Attitude and body rates both set: rates not flown")
                rates = (0.0, 0.0, rates[2])
        else:
            q_d = prev.q_d if prev else self.sensed.q_est
        self.offboard_attitude = AttitudeSetpoint(q_d, rates, thrust_n)  # type: ignore[arg-type]
        if use_att != self.offboard_uses_attitude:  # attitude <-> rates: the old integral is meaningless
            self.vehicle.onboard.controller.reset_integral()
            self._rate_q = None
        self.offboard_uses_attitude = use_att
        self.offboard_target = None
        return None

    TARGET_LIMITS = (1e5, 1e3, 1e3)
    """the largest position [m], velocity [m/s] and acceleration [m/s^2] a trajectory setpoint may carry"""

    def position_target(self, sender: int, target: TrajectoryTarget) -> str | None:
        """A trajectory setpoint (SET_POSITION_TARGET_LOCAL_NED, already in NED); returns a rejection
        reason or None. Rejected: no position, velocity or acceleration at all (PX4: "invalid"), an
        infinite or absurd value, and a setpoint from a system without offboard control in OFFBOARD."""
        parts = (target.pos_ned_m, target.vel_ned_m_s, target.accel_ned_m_s2)
        reason = None
        if all(math.isnan(c) for part in parts for c in part):
            reason = "no pos, vel or accel"
        elif any(abs(c) > limit for part, limit in zip(parts, self.TARGET_LIMITS) for c in part if not math.isnan(c)):
            reason = "out of range"
        elif not all(abs(c) < 1e3 for c in (target.yaw_rad, target.yaw_rate_rad_s) if not math.isnan(c)):
            reason = "out of range"
        elif self.mode == Mode.OFFBOARD and self.offboard_owner not in (None, sender):
            reason = "setpoint from a system without offboard control"
        if reason is not None:
            self._reject(reason)
            return reason
        self._note_setpoint(sender)
        o = self.vehicle.estimate_offset_ned_m  # sent in the reported estimate's frame
        if any(o) and not all(math.isnan(c) for c in target.pos_ned_m):
            target = dataclasses.replace(target, pos_ned_m=tuple(c - oc for c, oc in zip(target.pos_ned_m, o)))
        if self.offboard_target is None and self.mode == Mode.OFFBOARD:
            self._start_trajectory(from_mode_reference=False)
        self.offboard_target = target
        return None

    def _note_setpoint(self, sender: int) -> None:
        self.last_setpoint_time = self.t
        self.setpoint_time_by_sender[sender] = self.t
        self.setpoints_accepted += 1
        self.setpoint_sender = sender

    def _vehicle_reference(self) -> ShapedReference:
        """A reference where the vehicle is, moving as it moves."""
        ms = self.sensed.tracked
        return ShapedReference(ms.pos_ned_m, ms.vel_ned_m_s, ZERO3, float(quat.to_euler(self.sensed.q_est)[2]))

    def _start_trajectory(self, from_mode_reference: bool) -> None:
        """OFFBOARD begins to fly trajectory setpoints: from the position mode's own reference if one was
        flying (no jump), else from the vehicle's state with the position loop started afresh."""
        if from_mode_reference:
            f = self.ref_filter
            self.shaped = ShapedReference(f.pos_ned_m, f.vel_ned_m_s, f.accel_ned_m_s2, float(f.yaw_rad))
            return
        self.shaped = self._vehicle_reference()
        self.position_loop.reset()
        self.position_loop.thrust_n = self.setpoint.thrust_n

    # --- stepping ----------------------------------------------------------------------

    def decide(self, sensed: Sensed, steps: int = 1) -> AttitudeSetpoint:
        """Before ``steps`` plant steps, on what the vehicle sensed: the failsafes, then the setpoint
        the onboard attitude loop is to track through them (the mode's, while armed)."""
        self.sensed = sensed
        self.step_dt = steps * self.dt
        self._failsafes()
        if self.armed:
            self.setpoint = self._mode_setpoint()
        return self.setpoint

    def observe(self, sensed: Sensed, steps: int = 1) -> None:
        """After ``steps`` plant steps, on what the vehicle sensed: landing detection and the time flown."""
        self.sensed = sensed
        self._update_landed()
        if self.armed and not self.landed:
            self.airborne_s += steps * self.dt
        self._k += steps

    def stand_still(self, sensed: Sensed) -> None:
        """A step in which nothing flies (a halted world, :mod:`sitl.autopilot.guard`): the reading
        follows the clock, no rule runs."""
        self.sensed = sensed

    airborne_s = 0.0
    """vehicle seconds flown (armed, off the ground) since boot"""

    def reported_hover_throttle(self) -> float:
        """MPC_THR_HOVER / MOT_THST_HOVER as the autopilot reports it. PX4's is the model's. ArduCopter's
        is a learnt value (MOT_HOVER_LEARN 2): at boot the saved one, 5 % low on its SITL
        (HOVER_STALE), converging to the truth with a 10 s time constant of flight (HOVER_LEARN_TC_S)."""
        m = self.vehicle.scenario.vehicle
        true = m.weight_n / m.thrust_max_n
        if not self.rules.learns_hover_throttle:
            return true
        return true * (1.0 + (HOVER_STALE - 1.0) * math.exp(-self.airborne_s / HOVER_LEARN_TC_S))

    def _sensor_failsafes(self) -> None:
        """A failed IMU or lost position in the air: say why once, and land (blind if need be)."""
        v = self.sensed
        if self.failsafe != Failsafe.POSITION_LOST and v.position_age_s < 0.05:  # fresh tracking only
            g = self.vehicle.scenario.vehicle.gravity_m_s2
            self.accel_bias_z_m_s2 = learn_bias(self.accel_bias_z_m_s2, v, g, self.step_dt)
        if not self.armed or self.landed:
            return
        if v.imu_failed and v.position_age_s > self.POSITION_TIMEOUT_S:
            # no attitude source is left (the gyro-less loop flies on tracking, the blind descent on
            # the IMU): nothing can keep the vehicle upright, so the flight ends where it is
            self.terminate(f"No attitude: IMU failed ({v.imu_failed}) and tracking lost")
            return
        if v.imu_failed and self.failsafe != Failsafe.IMU_FAILED and self.failsafe != Failsafe.POSITION_LOST:
            self._say(Severity.CRITICAL, f"IMU failed ({v.imu_failed}): landing")
            self._enter(Mode.LAND)
            self.failsafe, self.failsafe_time = Failsafe.IMU_FAILED, self.t
        if v.position_age_s > self.POSITION_TIMEOUT_S and self.failsafe != Failsafe.POSITION_LOST:
            self._say(Severity.CRITICAL, "Position lost: descending")
            if self.mode != Mode.LAND:
                self._enter(Mode.LAND)
            self.failsafe, self.failsafe_time = Failsafe.POSITION_LOST, self.t
            self.blind = blind_start(v, self.ground_z)
        elif self.failsafe == Failsafe.POSITION_LOST and v.position_age_s < 0.05:
            self._say(Severity.WARNING, "Position back: landing")  # land where it is, with position
            self.failsafe = Failsafe.POSITION_LOST_LANDING
            self._enter(Mode.LAND)

    def _failsafes(self) -> None:
        p, t = self.params, self.t
        self._sensor_failsafes()
        if self.mode == Mode.OFFBOARD and self.armed and t - self.last_setpoint_time > p.offboard_loss_timeout_s:
            self.failsafe_time = t
            if self.params.offboard_loss_hold:
                self.failsafe = Failsafe.OFFBOARD_LOST
                self._say(Severity.CRITICAL, "Failsafe: offboard lost, holding")
                self._enter(Mode.HOLD)
            else:  # PX4 v1.16 without RC: descend at once (its heartbeat says POSCTL meanwhile)
                self.failsafe = Failsafe.OFFBOARD_LOST_DESCENDING
                self._say(Severity.CRITICAL, "Failsafe: offboard lost, descending")
                self._enter(Mode.LAND)
        elif (self.failsafe == Failsafe.OFFBOARD_LOST and self.mode == Mode.HOLD
              and t - self.failsafe_time > p.failsafe_hold_s):
            self._say(Severity.CRITICAL, "Failsafe: landing")
            self._enter(Mode.LAND)
            self.failsafe = Failsafe.OFFBOARD_LOST_LANDING
        if self.armed and self.landed:
            if not self.lifted_off and t - self.arm_time > p.disarm_preflight_s and self.mode != Mode.TAKEOFF:
                self._disarm("Disarmed: no take-off")
            elif self.lifted_off and self.touchdown_time is not None and t - self.touchdown_time > p.disarm_land_s:
                self._disarm("Landed, disarmed")

    def _idle_setpoint(self) -> AttitudeSetpoint:
        yaw = quat.to_euler(self.sensed.q_est)[2]
        return AttitudeSetpoint(quat.from_yaw(yaw), ZERO3, 0.0)

    def _reset_controllers(self) -> None:
        self.vehicle.onboard.reset()
        self.position_loop.reset()

    def _mode_setpoint(self) -> AttitudeSetpoint:
        mode = self.mode
        if mode == Mode.OFFBOARD and self.offboard_target is None:
            sp = self.offboard_attitude
            if sp is None:
                return self._idle_setpoint()
            if not self.offboard_uses_attitude:
                sp = AttitudeSetpoint(self._rate_reference(sp.omega_d_rad_s), sp.omega_d_rad_s, sp.thrust_n)
            if self.landed and sp.thrust_n < self.vehicle.hover_thrust_n:
                self.vehicle.onboard.reset()  # on the ground: no integrator wind-up
            return sp
        if mode == Mode.GUIDED:
            sp = self.offboard_attitude
            fresh = sp is not None and self.t - self.last_setpoint_time <= self.params.guided_timeout_s
            if fresh:
                assert sp is not None
                self._guided_flying = True
                if not self.offboard_uses_attitude:
                    sp = AttitudeSetpoint(self._rate_reference(sp.omega_d_rad_s), sp.omega_d_rad_s, sp.thrust_n)
                elif any(sp.omega_d_rad_s):
                    # ArduCopter keeps turning the last target by the body rates sent with it
                    age = self.t - self.last_setpoint_time
                    sp = AttitudeSetpoint(quat.integrate(sp.q_d, sp.omega_d_rad_s, age), sp.omega_d_rad_s,
                                          sp.thrust_n)
                sp, self._shaped = guided_target(sp, self._shaped, self.sensed, self.params,
                                                 self.vehicle.scenario.vehicle, self.guided_climb_rate_m_s,
                                                 self.step_dt)
                return sp
            self._shaped = None
            if self._guided_flying:  # GUID_TIMEOUT: level out and keep the altitude; position is not held
                self._guided_flying = False
                self._say(Severity.WARNING, "Guided: attitude target timed out, levelling")
            if self.landed:
                self._reset_controllers()
                return self._idle_setpoint()
            if sp is not None:
                return level_keeping_altitude(self.sensed, self.vehicle.scenario.vehicle)
        if self.landed and mode not in (Mode.TAKEOFF, Mode.OFFBOARD, Mode.GUIDED):
            self._reset_controllers()
            return self._idle_setpoint()
        if self.failsafe == Failsafe.POSITION_LOST:
            return self._blind_descent()
        if self._k < self._position_due_k:
            return self.setpoint
        self._position_due_k = (self._k // self.pos_div + 1) * self.pos_div  # the position loop's grid
        if mode == Mode.RTL:
            pos = self.sensed.tracked.pos_ned_m
            if not self._land_phase_home and math.hypot(pos[0] - self.home[0], pos[1] - self.home[1]) < 0.3:
                self._land_phase_home = True
                self._enter(Mode.LAND)
                self.target = (self.home[0], self.home[1], self.target[2])  # land at home, not near it
        if self.landed:
            self.position_loop.reset()  # the ground reaction is not a disturbance to learn
        if mode == Mode.LAND:
            self.ref_filter.params = dataclasses.replace(self.ref_filter.params, max_speed_m_s=self.land_speed_m_s())
        ms, q = self.sensed.tracked, self.sensed.q_est
        sf_ned = quat.rotate(q, self.vehicle.mean_specific_force_body())  # the IMU's mean since the last position step
        ref = self._reference()
        meas = PositionMeasurement(ms.pos_ned_m, ms.vel_ned_m_s, q, sf_ned)
        return self.position_loop.update(meas, ref, self.pos_dt)

    def _reference(self) -> PositionReference:
        """This position step's reference: the shaped one while braking or flying a trajectory setpoint in
        OFFBOARD, else the mode's filter towards its target."""
        if not (self.braking or self.mode == Mode.OFFBOARD):
            return self.ref_filter.update(self.target, self.target_yaw, self.pos_dt)
        target = self._brake_target() if self.braking else self.offboard_target
        assert target is not None
        if self.shaped is None:
            self.shaped = self._vehicle_reference()
        self.shaped = s = shape_step(self.params.shaping, self.shaped, target, self.pos_dt,
                                     self.sensed.tracked.pos_ned_m, self.braking)
        if self.braking and at_rest(s._replace(vel_ned_m_s=sub(s.vel_ned_m_s, target.vel_ned_m_s))):
            self._stop_braking(s)
        return PositionReference(s.pos_ned_m, s.vel_ned_m_s, s.accel_ned_m_s2, s.yaw_rad)

    def _brake_target(self) -> TrajectoryTarget:
        """What braking steers to: rest, or for PX4's offboard-loss Descend (no RC), which commands its
        descent speed at once, that speed (a climb turns into the descent under the same limits)."""
        if self.failsafe == Failsafe.OFFBOARD_LOST_DESCENDING and self.mode == Mode.LAND:
            return TrajectoryTarget(vel_ned_m_s=(0.0, 0.0, self.land_speed_m_s()))
        return BRAKE

    def _stop_braking(self, s: ShapedReference) -> None:
        """At rest: the mode's own reference takes over from there (HOLD holds there, LAND descends from
        there, RTL flies home from there)."""
        self.braking = False
        self.ref_filter = ReferenceFilter(self.ref_filter.params, s.pos_ned_m, s.yaw_rad, s.vel_ned_m_s,
                                          s.accel_ned_m_s2)
        x, y, z = s.pos_ned_m
        if self.mode in (Mode.HOLD, Mode.GUIDED):
            self.target, self.target_yaw = s.pos_ned_m, s.yaw_rad
        elif self.mode in (Mode.LAND, Mode.TAKEOFF):
            self.target = (x, y, self.target[2])
            self.target_yaw = s.yaw_rad
        elif self.mode == Mode.RTL:  # home at the height it stopped at, or the take-off height if higher
            self.target = (self.target[0], self.target[1], min(z, self.home[2] - self.takeoff_alt_m))

    LAND_ALT1_M = 10.0
    """MPC_LAND_ALT1: above this height LAND descends at MPC_Z_VEL_MAX_DN"""
    LAND_ALT2_M = 5.0
    """MPC_LAND_ALT2: below this height at MPC_LAND_SPEED; in between, interpolated"""

    def land_speed_m_s(self) -> float:
        """PX4's descent speed in LAND at the vehicle's height above home (FlightTaskAuto's
        _prepareLandSetpoints): MPC_LAND_SPEED below MPC_LAND_ALT2, MPC_Z_VEL_MAX_DN above MPC_LAND_ALT1;
        never below MPC_LAND_SPEED (a faster MPC_LAND_SPEED is flown as set)."""
        height = self.home[2] - float(self.sensed.tracked.pos_ned_m[2])
        slow, fast = self.params.land_speed_m_s, max(self.params.shaping.speed_down_m_s, self.params.land_speed_m_s)
        k = min(max((height - self.LAND_ALT2_M) / (self.LAND_ALT1_M - self.LAND_ALT2_M), 0.0), 1.0)
        return slow + k * (fast - slow)

    def _blind_descent(self) -> AttitudeSetpoint:
        """Level, descending at BLIND_DESCENT_M_S by the accelerometer alone (no position), until it
        counts itself down (:mod:`sitl.autopilot.blind`)."""
        m = self.vehicle.scenario.vehicle
        assert self.blind is not None
        self.blind = d = blind_step(self.blind, self.sensed, self.accel_bias_z_m_s2, m.gravity_m_s2, self.step_dt)
        if counted_down(d):
            self.landed, self.touchdown_time = True, self.t
            self._say(Severity.INFO, "Landed (counted down without position)")
            return self._idle_setpoint()
        yaw = float(quat.to_euler(self.sensed.q_est)[2])
        return AttitudeSetpoint(quat.from_yaw(yaw), ZERO3,
                                blind_thrust_n(d, m.mass_kg, m.gravity_m_s2, m.weight_n, m.thrust_max_n))

    def _rate_reference(self, omega_d: Vec3) -> tuple:
        """Rates-only setpoints are flown as an attitude reference integrated from the commanded
        rates, so the attitude loop's integral keeps its meaning; re-anchored to the estimate if
        the vehicle falls more than 30 deg behind (saturation), so it cannot run away."""
        q_est = self.sensed.q_est
        q_ref = self._rate_q
        if q_ref is None or quat.angle_between(q_ref, q_est) > math.radians(30.0):
            q_ref = q_est
        self._rate_q = quat.integrate(q_ref, omega_d, self.step_dt)
        return self._rate_q

    _rate_q: tuple | None = None

    def _update_landed(self) -> None:
        if self.failsafe == Failsafe.POSITION_LOST:
            return  # the tracked position is frozen: the blind descent decides
        ms = self.sensed.tracked
        height = self.ground_z - ms.pos_ned_m[2]
        speed = math.sqrt(sum(v * v for v in ms.vel_ned_m_s))
        if self.landed:
            if height > 0.1:
                self.landed = False
                self.lifted_off = True
                self.touchdown_time = None
                if self.mode == Mode.TAKEOFF:
                    self.position_loop.thrust_n = self.setpoint.thrust_n
        elif height < 0.03 and speed < 0.2:
            self.landed = True
            self.touchdown_time = self.t
        if self.mode == Mode.TAKEOFF and not self.landed:
            if abs(ms.pos_ned_m[2] - self.target[2]) < 0.1 and speed < 0.3:
                self._say(Severity.INFO, "Takeoff complete")
                target = self.target
                self._enter(self.rules.after_takeoff)
                self.target = target  # hold the take-off altitude, not where the check fired

    @property
    def landed_state(self) -> LandedState:
        if not self.armed or (self.landed and self.mode != Mode.TAKEOFF):
            return LandedState.ON_GROUND
        if self.mode == Mode.TAKEOFF:
            return LandedState.TAKEOFF
        if self.mode == Mode.LAND:
            return LandedState.LANDING
        return LandedState.IN_AIR
