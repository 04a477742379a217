"""The frozen dataclasses a mission is made of; loading and checking live in the sibling modules."""

from __future__ import annotations

from dataclasses import dataclass, field

from companion.control.params import PositionGains, ReferenceParams, TrajectoryParams, VehicleParams
from companion.control.vector import Vec3
from companion.mavlink.identity import VehicleTarget

from .safety import SafetyVolume

__all__ = ["ACTIONS", "REQUIRED", "ALLOWED", "Step", "ControllerConfig", "ThrustConfig", "SafetyConfig", "Mission"]

ACTIONS = ("takeoff", "offboard", "hold", "goto", "set_param", "wait", "land")

# which keys each action needs and accepts
REQUIRED = {
    "takeoff": ("altitude_m",),
    "offboard": (),
    "hold": ("duration_s",),
    "goto": ("waypoints",),
    "set_param": ("param", "value"),
    "wait": ("duration_s",),
    "land": (),
}
ALLOWED = {
    "takeoff": ("altitude_m", "timeout_s"),
    "offboard": ("timeout_s",),
    "hold": ("duration_s", "position_ned_m", "yaw_deg"),
    "goto": ("waypoints", "speed_m_s", "tolerance_m", "hold_s", "timeout_s"),
    "set_param": ("param", "value", "sim_only", "keep"),
    "wait": ("duration_s",),
    "land": ("timeout_s",),
}


@dataclass(frozen=True)
class Step:
    action: str
    name: str = ""
    """shown in the summary; defaults to the action and its index"""
    altitude_m: float = 0.0
    duration_s: float = 0.0
    position_ned_m: Vec3 | None = None
    """hold here (None: where the previous step left the reference)"""
    yaw_deg: float | None = None
    waypoints: tuple[Vec3, ...] = ()
    speed_m_s: float | None = None
    tolerance_m: float = 0.15
    hold_s: float = 0.0
    """how long to stay at each waypoint once reached"""
    param: str = ""
    value: float = 0.0
    sim_only: bool = False
    """skip (with a warning) if the vehicle has no such parameter, e.g. a real vehicle"""
    keep: bool = False
    """leave the value set after the flight (by default every parameter the companion wrote is put back)"""
    timeout_s: float = 60.0


@dataclass(frozen=True)
class ControllerConfig:
    position: str = "ism_do"
    """pid | aibc | pd_do | ism_do"""
    rate_hz: float = 100.0
    ardupilot_shaping: bool = False
    """ArduCopter only: keep its attitude input shaping (ATC_RATE_FF_ENAB 1, ATC_INPUT_TC) while the
    companion flies. By default the companion turns it off and puts it back when the flight ends,
    on every path: shaped, each attitude target lags by the input time constant (0.15 s)"""


@dataclass(frozen=True)
class ThrustConfig:
    """Newtons to normalised thrust: ``u = T / thrust_max_n``.

    ``thrust_max_n = 0`` takes it from the vehicle: the simulated vehicle's SIM_THRUST_MAX, else
    ``m g / MPC_THR_HOVER`` (PX4) or ``m g / MOT_THST_HOVER`` (ArduPilot), else ``hover_throttle``.
    The scale is also estimated online from the force observer's vertical estimate.
    """

    thrust_max_n: float = 0.0
    hover_throttle: float = 0.0
    estimate: bool = True
    adapt: bool = True
    """let the online estimate correct the scale (slowly, within +-40%)"""


@dataclass(frozen=True)
class SafetyConfig:
    telemetry_timeout_s: float = 0.3
    """vehicle-clock age of position/attitude beyond which setpoints stop (at a speed-up, the streams
    must also have been silent for at least 0.15 s of wall time); they resume when it is fresh again"""
    stale_hold_s: float = 1.0
    """vehicle seconds of stale telemetry after which the companion also commands hold (PX4's
    COM_OF_LOSS_T default); a shorter outage only pauses the setpoints and the flight goes on"""
    link_lost_s: float = 3.0
    """wall seconds without any telemetry after which the companion gives up and exits with an error"""
    max_tilt_deg: float = 60.0
    max_rate_deg_s: float = 250.0
    volume: SafetyVolume = field(default_factory=SafetyVolume)
    """where the mission may fly, around home (``[safety.volume]``); the runtime enforces it in
    flight with :meth:`SafetyVolume.breach`"""


@dataclass(frozen=True)
class Mission:
    """A mission as the flight runtime gets it: only ever from a loader, which has checked it all."""

    name: str
    """letters, digits, '-', '_', '.': it becomes part of the flight record's folder name"""
    description: str = ""
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    gains: PositionGains = field(default_factory=PositionGains)
    reference: ReferenceParams = field(default_factory=ReferenceParams)
    trajectory: TrajectoryParams = field(default_factory=TrajectoryParams)
    thrust: ThrustConfig = field(default_factory=ThrustConfig)
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    target: VehicleTarget = field(default_factory=VehicleTarget)
    """which vehicle on the link to fly (``[target] system_id``, ``component_id``); ``fly
    --target-system`` overrides it"""
    steps: tuple[Step, ...] = ()

