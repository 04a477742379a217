"""The one interface the companion uses to talk to an autopilot, whatever the backend."""

from __future__ import annotations

import abc
import asyncio
import math
import time
from collections import Counter
from dataclasses import dataclass
from typing import Callable

from companion.link.clock import VehicleClock
from companion.control.quaternion import Quat
from companion.control.vector import Vec3
from companion.link.stamps import Admitted, StampGate
from companion.link.state import VehicleState
from companion.mavlink.boot_time import boot_ms
from companion.mavlink.identity import VehicleTarget

from .flavour import Flavour

__all__ = ["LinkError", "VehicleLink", "TrafficHook", "ConnectWait", "PROGRESS_EVERY_S"]

TrafficHook = Callable[[bytes], None]
"""called with every raw datagram sent or received (for the .tlog)"""


REASON_WAIT_S = 0.3
"""wall seconds to wait for the text that explains a refused command"""


PROGRESS_EVERY_S = 5.0
"""wall seconds between progress lines while waiting for a vehicle's telemetry"""


class LinkError(RuntimeError):
    """The vehicle did not answer, refused, or went away."""


@dataclass(frozen=True)
class ConnectWait:
    """How long connecting may take, in wall seconds from its start: an autopilot's heartbeat
    *and* its navigation telemetry (attitude and position) within ``timeout_s``
    (``--connect-timeout``), whatever the peer sends meanwhile. Only a vehicle that already sends
    attitude but has no position yet (its estimator has no origin: ArduCopter ~40 s after boot)
    may be waited for longer, ``position_wait_s`` more (``--position-wait``, 0 by default), and
    every :data:`PROGRESS_EVERY_S` the wait says so."""

    timeout_s: float
    position_wait_s: float = 0.0

    def deadline_s(self, has_attitude: bool) -> float:
        """Seconds after the start of connecting by which position and attitude must flow."""
        return self.timeout_s + (self.position_wait_s if has_attitude else 0.0)

    def progress(self, elapsed_s: float, has_attitude: bool) -> str:
        """The progress line while waiting ``elapsed_s`` into connecting."""
        if not has_attitude:
            return (f"vehicle found, waiting for its telemetry (ATTITUDE_QUATERNION, LOCAL_POSITION_NED): "
                    f"{elapsed_s:.0f} s of --connect-timeout {self.timeout_s:g} s")
        if elapsed_s <= self.timeout_s:
            extra = f", then up to {self.position_wait_s:g} s more (--position-wait)" if self.position_wait_s else ""
            return (f"vehicle found, waiting for its position (LOCAL_POSITION_NED; attitude flows): "
                    f"{elapsed_s:.0f} s of --connect-timeout {self.timeout_s:g} s{extra}")
        return (f"still no position (LOCAL_POSITION_NED) after {elapsed_s:.0f} s: waiting up to "
                f"{self.deadline_s(True) - elapsed_s:.0f} s more (--position-wait {self.position_wait_s:g})")

    def failure(self, elapsed_s: float, has_attitude: bool) -> str:
        """Why connecting gave up, and what to try."""
        if not has_attitude:
            return (f"the autopilot answers (heartbeat) but sent no attitude and no position within "
                    f"{elapsed_s:.0f} s (--connect-timeout {self.timeout_s:g}): does it stream telemetry to "
                    f"this link (ATTITUDE_QUATERNION, LOCAL_POSITION_NED)?")
        longer = ("; a vehicle whose estimator needs longer can be waited for with --position-wait S "
                  "(ArduCopter SITL: about 40 s after boot)" if not self.position_wait_s else "")
        return (f"the autopilot sends attitude but no position (LOCAL_POSITION_NED) after {elapsed_s:.0f} s "
                f"(--connect-timeout {self.timeout_s:g}, --position-wait {self.position_wait_s:g}): GPS or "
                f"position source, EKF origin?{longer}")


class VehicleLink(abc.ABC):
    """A connection to one autopilot. ``state`` and ``clock`` are kept up to date by :meth:`run`."""

    state: VehicleState
    clock: VehicleClock
    flavour: Flavour | None
    stats: Counter[str]
    target: VehicleTarget
    """which autopilot on the link to fly (--target-system/--target-component)"""
    traffic: TrafficHook | None

    gate: StampGate
    """which telemetry stamps are believed (companion/link/stamps.py); counts into ``stats``"""

    def __init__(self, target: VehicleTarget | None, traffic: TrafficHook | None) -> None:
        """What every backend keeps: the vehicle's state and clock, the stamp gate and the counts."""
        self.target = target or VehicleTarget()
        self.traffic = traffic
        self.state = VehicleState()
        self.clock = VehicleClock()
        self.flavour = None
        self.stats = Counter()
        self.gate = StampGate(counts=self.stats)
        self.on_telemetry: Callable[[], None] | None = None

    def _sample(self, stamp_s: float, wall: float, store: Callable[..., bool], *values: object,
                wraps: bool = False) -> bool:
        """One telemetry sample, the one way in: its stamp through the gate (:meth:`_admit`), the
        state set by ``store(*values, t_s, wall)`` at the admitted time (a ``VehicleState.set_*``:
        it says whether the values were valid), then the clock and the control loop told
        (:meth:`_observe`). False: not believed or not valid."""
        a = self._admit(stamp_s, wall, wraps)
        if a is None or not self._valid(store(*values, a.t_s, wall)):
            return False
        self._observe(a, wall)
        return True

    def _setpoint_ms(self, stamp_s: float | None) -> int:
        """A setpoint's ``time_boot_ms``: the telemetry stamp it was computed from (None: the newest)."""
        return boot_ms(self.state.t if stamp_s is None else stamp_s)

    def _admit(self, stamp_s: float, wall: float, wraps: bool = False) -> Admitted | None:
        """A sample's stamp through the gate (``wraps``: a ``time_boot_ms``, unwrapped there); on a
        change of the vehicle's time base the clock and the held stamps start over."""
        before = self.gate.rebases
        admitted = self.gate.admit(stamp_s, wall, self.clock.rate if self.clock.ready else 1.0, wraps)
        if self.gate.rebases != before:
            self.clock.reset()
            self.state.restart_time()
        return admitted

    on_telemetry: Callable[[], None] | None
    """called when a believed stamp has come in, once the state holds everything that came with it
    (the control loop's tick for that sample runs in it: lockstep)"""

    def _observe(self, admitted: Admitted, wall: float) -> None:
        if admitted.feeds_clock:
            self.clock.observe(admitted.t_s, wall)
            self._telemetry_in()

    _fresh = False
    """a believed stamp came in since the control loop was last told"""

    def _telemetry_in(self) -> None:
        """A believed stamp came in: tell the control loop once the samples that are ready with
        it have been stored too (the event loop's next round; the pymavlink backend tells it
        itself when it has read its queue)."""
        if self._fresh or self.on_telemetry is None:
            return
        self._fresh = True
        asyncio.get_running_loop().call_soon(self._tell)

    def _tell(self) -> None:
        self._fresh = False
        if self.on_telemetry is not None:
            self.on_telemetry()

    params_complete: bool = False
    """the autopilot's whole parameter list has arrived (PARAM_VALUE's count reached)"""
    progress: Callable[[str], None] | None = None
    """where connection progress is reported (the flight's log)"""

    async def _wait_navigation(self, wait: ConnectWait, start: float) -> float:
        """After the heartbeat: until position and attitude flow, by ``wait``'s deadline counted
        from ``start`` (wall, monotonic), with a progress line every :data:`PROGRESS_EVERY_S`.
        Returns the deadline that applied (wall)."""
        st = self.state
        said, extra = -math.inf, False
        while not st.has_navigation:
            now = time.monotonic()
            has_attitude = math.isfinite(st.t_att)
            if now - start >= wait.deadline_s(has_attitude):
                raise LinkError(wait.failure(now - start, has_attitude))
            past_timeout = now - start > wait.timeout_s  # the --position-wait has begun: say so at once
            if self.progress is not None and (now - said >= PROGRESS_EVERY_S or past_timeout != extra):
                said, extra = now, past_timeout
                self.progress(wait.progress(now - start, has_attitude))
            await asyncio.sleep(0.05)
        return start + wait.deadline_s(True)

    async def _refusal_reason(self, before: int) -> str:
        """What the autopilot said after a refusal (texts since index ``before``), the most severe
        first. The reason (STATUSTEXT, or an EVENT on PX4) follows the answer: give it a moment."""
        st = self.state
        end = time.monotonic() + REASON_WAIT_S
        while st.texts_seen == before and time.monotonic() < end:
            await asyncio.sleep(0.01)
        new = st.texts_since(before)
        ranked = sorted(enumerate(new), key=lambda it: (it[1][0], -it[0]))[:4]  # MAV_SEVERITY: lower is worse
        return "; ".join(text for _, (_, text) in ranked)

    def _valid(self, accepted: bool) -> bool:
        """Pass through a ``VehicleState.set_*`` result, counting a refused sample."""
        if not accepted:
            self.stats["invalid_telemetry"] += 1  # NaN, inf or impossible: the sample is ignored
        return accepted

    @abc.abstractmethod
    async def open(self) -> None: ...

    @abc.abstractmethod
    async def close(self) -> None: ...

    @abc.abstractmethod
    async def run(self, stop: asyncio.Event) -> None:
        """Read telemetry and keep the link alive (heartbeats) until ``stop`` is set."""

    @abc.abstractmethod
    async def wait_connected(self, timeout_s: float, position_wait_s: float = 0.0) -> None:
        """Until an autopilot's heartbeat and navigation telemetry arrive, within ``timeout_s`` of
        wall time in all (:class:`ConnectWait`); LinkError when they do not."""

    @abc.abstractmethod
    async def set_arming_mode(self) -> None:
        """Switch to the mode the autopilot arms and takes off in: GUIDED on ArduPilot; HOLD on PX4,
        which after a disarm restores the last mode the user chose (OFFBOARD after our own previous
        flight), fails its pre-arm checks there and refuses to arm."""

    @abc.abstractmethod
    async def arm(self) -> None: ...

    @abc.abstractmethod
    async def disarm(self, force: bool = False) -> None: ...

    @abc.abstractmethod
    async def takeoff(self, altitude_m: float) -> None: ...

    @abc.abstractmethod
    async def start_offboard(self) -> None:
        """Switch to the mode that flies attitude setpoints (PX4 OFFBOARD, ArduPilot GUIDED)."""

    @abc.abstractmethod
    async def hold(self, attempts: int | None = None) -> None:
        """Switch to the autopilot's position hold (PX4 HOLD, ArduPilot BRAKE); ``attempts``: send
        the command at most that many times (default: the link's retries)."""

    @abc.abstractmethod
    async def land(self) -> None: ...

    @abc.abstractmethod
    def send_attitude_target(self, q: Quat, body_rates_rad_s: Vec3, thrust: float, type_mask: int = 0,
                             stamp_s: float | None = None) -> None:
        """SET_ATTITUDE_TARGET with quaternion, body rates, normalised thrust and the ignore bits,
        now (no await). ``time_boot_ms`` is ``stamp_s``, the vehicle time of the telemetry the
        setpoint was computed from (None: the newest), which the bundled vehicle's lockstep and
        the firmware bridge's wait on."""

    @abc.abstractmethod
    def send_position_target(self, pos_ned_m: Vec3, vel_ned_m_s: Vec3, accel_ned_m_s2: Vec3, yaw_rad: float,
                             stamp_s: float | None = None) -> None:
        """SET_POSITION_TARGET_LOCAL_NED with position, velocity, acceleration and yaw, now: the
        autopilot's own position control flies it (``stamp_s`` as for attitude targets)."""

    @abc.abstractmethod
    def send_debug(self, t_s: float, vectors: dict[str, Vec3], values: dict[str, float]) -> None:
        """Controller state for the ground station: DEBUG_VECT per vector, NAMED_VALUE_FLOAT per value
        (names of at most 10 characters; MAVProxy and QGroundControl show both)."""

    @abc.abstractmethod
    async def get_param(self, name: str, timeout_s: float = 1.0, retries: int = 3) -> float | None:
        """The parameter's value, or None if the vehicle has no such parameter (no answer after
        ``retries`` tries of ``timeout_s``: autopilots do not answer for unknown names)."""

    @abc.abstractmethod
    async def set_param(self, name: str, value: float) -> float:
        """Write and return the value the vehicle echoes (LinkError if it never answers)."""

    async def __aenter__(self) -> VehicleLink:
        await self.open()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    rx_lag_s: float = 0.0
    """wall seconds the last parsed datagram waited in our own queue (0 without one)"""
    rx_lag_max_s: float = 0.0
    """the longest such wait since :meth:`take_rx_lag_max` was last called"""

    def take_rx_lag_max(self) -> float:
        lag, self.rx_lag_max_s = self.rx_lag_max_s, 0.0
        return lag

    @property
    def rx_queue_depth(self) -> int:
        """Datagrams received but not yet parsed (0 where the backend keeps no queue of ours)."""
        return 0

    @property
    def in_offboard(self) -> bool:
        return self.state.offboard

    def telemetry_age(self, wall_t: float) -> float:
        """Vehicle seconds since the older of position and attitude (inf before any)."""
        t = min(self.state.t_pos, self.state.t_att)
        return math.inf if not math.isfinite(t) else self.clock.age(t, wall_t)
