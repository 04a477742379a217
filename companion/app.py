"""A flight: link, control loop, streamer, watchdog and mission runner under one TaskGroup.

- **reader** (``link.run``): telemetry into :class:`~companion.state.VehicleState`, heartbeats out;
- **control loop**: a fixed rate *in vehicle time* (sleeps until the vehicle clock reaches the next
  tick, so it follows the simulated vehicle's speed-up); computes a checked setpoint while the
  controller is engaged and records a row every tick;
- **streamer**: sends each new setpoint the moment it exists (and nothing stale);
- **watchdog**: position or attitude older than ``telemetry_timeout_s`` (vehicle time) -> stop
  setpoints and tell the autopilot to hold; nothing at all for ``link_lost_s`` (wall) -> the flight
  ends with :class:`LinkLost`; the autopilot leaving offboard while we fly it -> abort;
- **mission runner**: the steps; on an interrupt (SIGINT) or an abort it stops streaming, commands
  hold, then land, and waits for the vehicle to disarm — it never just goes silent in the air.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import datetime
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Awaitable

from companion.control.params import PositionGains

from .health import HealthMonitor
from .link import LinkError, VehicleLink, open_link
from .link.signing import fingerprint
from .mission import Mission, Step
from .offboard import OffboardController, Setpoint
from .recorder import FlightRecorder
from .safety import SetpointGuard
from .silence import AwakeSilence
from .thrust_scale import ThrustScaleEstimator

__all__ = ["FlightOptions", "FlightResult", "Flight", "LinkLost", "MissionAbort", "EXIT_CODES"]

EXIT_CODES = {"completed": 0, "aborted": 1, "link lost": 3, "interrupted": 130}


class LinkLost(RuntimeError):
    """No telemetry from the vehicle for longer than the link-lost bound."""


class MissionAbort(RuntimeError):
    """The mission cannot go on (refused command, offboard left, timeout)."""


class _Interrupted(Exception):
    pass


@dataclass
class FlightOptions:
    connect: str = "udp://127.0.0.1:14540"
    backend: str = "pymavlink"
    controller: str | None = None
    """overrides the mission's position controller"""
    rate_hz: float | None = None
    out_dir: Path = Path("flights")
    connect_timeout_s: float = 20.0
    thrust_max_n: float | None = None
    quiet: bool = False
    signing_key: bytes | None = field(default=None, repr=False)
    """MAVLink 2 signing key (pymavlink backend): sign what we send, believe only signed frames"""


@dataclass
class FlightResult:
    result: str
    message: str
    folder: Path
    summary: dict = field(default_factory=dict)

    @property
    def exit_code(self) -> int:
        return EXIT_CODES.get(self.result, 1)


PRECISE_SLEEP_S = 0.0015
RESYNC_TICKS = 5
"""the control loop resyncs to the vehicle's clock when it is this many ticks off it"""
WATCHDOG_S = 0.02
"""wall seconds between the watchdog's checks"""
STALLED_S = 0.05
"""wall seconds a periodic task woke late by that mean this process was stalled"""
MIN_SILENCE_S = 0.15
"""wall seconds of silence below which telemetry is never called stale (sped-up simulations)"""
MIN_HOLD_SILENCE_S = 0.5
"""wall seconds of silence below which we never command hold: sped up, a host stall freezes the
simulated vehicle for a few hundred ms of wall time, which the clock line reads as seconds of
vehicle time (a real vehicle, at rate 1, reaches ``stale_hold_s`` first)"""


def wall_timeout_s(timeout_v_s: float, rate: float) -> float:
    """The wall-clock bound on a mission timeout of ``timeout_v_s`` vehicle seconds: twice what the
    vehicle's rate (bounded to 0.25..1) makes it, plus 2 s. Timeouts count vehicle time, which
    only telemetry stamps move; this bound fires even if those stamps stop or lie, so no stamp
    can keep a mission waiting for ever (a simulated vehicle slower than 0.5x may meet it first)."""
    return 2.0 * timeout_v_s / min(max(rate, 0.25), 1.0) + 2.0


async def _sleep_until(wall_t: float, precise_s: float = PRECISE_SLEEP_S) -> None:
    """asyncio.sleep rounds its wake-up up to whole milliseconds (epoll); for the last
    ``precise_s`` a blocking nanosleep lands the tick within ~0.1 ms. The loop is blocked only for
    time it would have spent idle; datagrams wait in the socket buffer (stamped on arrival)."""
    remaining = wall_t - time.monotonic()
    if remaining > precise_s:
        await asyncio.sleep(remaining - precise_s)
    remaining = wall_t - time.monotonic()
    if remaining > 0:
        time.sleep(remaining)


class Flight:
    def __init__(self, mission: Mission, options: FlightOptions | None = None) -> None:
        self.mission = mission
        self.opt = opt = options or FlightOptions()
        self.controller_name = opt.controller or mission.controller.position
        self.rate_hz = opt.rate_hz or mission.controller.rate_hz
        stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
        self.folder = opt.out_dir / f"{stamp}_{mission.name}_{self.controller_name}"
        n = 1
        while self.folder.exists():
            n += 1
            self.folder = opt.out_dir / f"{stamp}_{mission.name}_{self.controller_name}_{n}"
        self.recorder = FlightRecorder(self.folder)
        link_options = {} if opt.signing_key is None else {"signing_key": opt.signing_key}
        self.link: VehicleLink = open_link(opt.connect, opt.backend, traffic=self.recorder.traffic, **link_options)
        safety = mission.safety
        self.guard = SetpointGuard(math.radians(safety.max_tilt_deg), math.radians(safety.max_rate_deg_s))
        self.control: OffboardController | None = None
        self.engaged = False
        """the controller computes setpoints (streaming before and during offboard)"""
        self.expect_offboard = False
        self.stale = False
        self.outages = 0
        """episodes of stale telemetry"""
        self.stale_for_s = 0.0
        self.longest_outage_s = 0.0
        self.stale_until_wall = -math.inf
        self._background: set[asyncio.Task[None]] = set()
        self.finished = asyncio.Event()
        self.interrupted = asyncio.Event()
        self._new_setpoint = asyncio.Event()
        self._setpoint: Setpoint | None = None
        self.sent = 0
        self.rejected = 0
        self.late_ticks = 0
        self.health = HealthMonitor()
        self.tick_periods: list[float] = []
        """wall-clock spacing of sent setpoints (bounded), for the jitter benchmark"""
        self._last_sent_wall = math.nan
        self.failure: str | None = None

    def log(self, text: str) -> None:
        if not self.opt.quiet:
            t = self.link.state.t
            stamp = f"{t:8.2f}" if math.isfinite(t) else "      --"  # vehicle time, once it is known
            print(f"[{stamp}] {text}", flush=True)

    def interrupt(self) -> None:
        """SIGINT: the runner holds, lands and disarms; a second one gives up waiting."""
        if self.interrupted.is_set():
            self.finished.set()
        self.interrupted.set()

    # --- running -------------------------------------------------------------------------

    async def run(self) -> FlightResult:
        result, message = "completed", ""
        self._cpu0, self._wall0 = time.process_time(), time.monotonic()
        try:
            async with self.link:
                try:
                    async with asyncio.TaskGroup() as tg:
                        tg.create_task(self.link.run(self.finished))
                        tg.create_task(self._watchdog())
                        tg.create_task(self._control_loop())
                        tg.create_task(self._streamer())
                        runner = tg.create_task(self._mission())
                    result, message = runner.result()
                except* LinkLost as eg:
                    result, message = "link lost", str(eg.exceptions[0])
                except* LinkError as eg:
                    result, message = "aborted", str(eg.exceptions[0])
        finally:
            summary = self._summary(result, message)
            self.recorder.close(summary)
        return FlightResult(result, message, self.folder, summary)

    async def _watchdog(self) -> None:
        safety = self.mission.safety
        hold_requested = False
        woke = time.monotonic()
        # silence counted only while this process was awake to hear it (companion/silence.py)
        heard_nothing, heard_no_navigation = AwakeSilence(2 * WATCHDOG_S), AwakeSilence(2 * WATCHDOG_S)
        while not self.finished.is_set():
            await asyncio.sleep(WATCHDOG_S)
            st = self.link.state
            now, due = time.monotonic(), woke + WATCHDOG_S
            woke = now
            if now - due > STALLED_S:
                # this process was stalled: what arrived meanwhile is still unread in the socket,
                # so nothing can be judged old yet; the reader drains it before the next check
                continue
            silent_link = heard_nothing.check(st.wall_last, now)
            silent_nav = heard_no_navigation.check(min(st.wall_pos, st.wall_att), now)
            # from the first message on (wait_connected bounds the wait for the first one)
            if st.sysid and math.isfinite(st.wall_last) and silent_link > safety.link_lost_s:
                raise LinkLost(f"vehicle link lost: no telemetry for {silent_link:.1f} s "
                               f"(bound {safety.link_lost_s:g} s)")
            if not self.engaged:
                self.stale = False
                continue
            age = self.link.telemetry_age(now)
            # stale: too old in vehicle time AND really silent on the wire; sped up, a short pause
            # of the (simulated) vehicle itself would otherwise look like seconds of vehicle time
            stale = age > safety.telemetry_timeout_s and silent_nav > max(
                safety.telemetry_timeout_s / max(self.link.clock.rate, 1e-3), MIN_SILENCE_S)
            # behind: datagrams keep coming but wait in our own queue (this process starved of CPU);
            # measured on our side of the socket, so a pausing vehicle cannot fake it
            behind_s = self.link.rx_lag_s * self.link.clock.rate
            behind = behind_s > safety.telemetry_timeout_s
            if behind:
                stale, age = True, max(age, behind_s)
            if stale and not self.stale:
                self.outages += 1
                why = "queued here" if behind else "stale"
                self.log(f"telemetry {why} ({age:.2f} s): setpoints paused")
            elif self.stale and not stale:
                self.stale_until_wall = now
                self.log(f"telemetry back after {self.stale_for_s:.2f} s")
            if stale:
                self.stale_for_s = age
                self.longest_outage_s = max(self.longest_outage_s, age)
                # hold only for real silence: not for a backlog in our own queue (it clears in one
                # pass of the reader) nor for a stall of this host (not counted, above)
                if (age > safety.stale_hold_s and not hold_requested and silent_nav > max(
                        safety.stale_hold_s / max(self.link.clock.rate, 1e-3), MIN_HOLD_SILENCE_S)):
                    hold_requested = True
                    self.log(f"telemetry stale for {age:.2f} s: commanding hold")
                    # in the background: the command retries while the link is down
                    task = asyncio.get_running_loop().create_task(self._best_effort(self.link.hold()))
                    self._background.add(task)
                    task.add_done_callback(self._background.discard)
            self.stale = stale

    async def _best_effort(self, command: Awaitable[None]) -> None:
        with contextlib.suppress(LinkError):
            await command

    def _outage_recent(self, within_s: float = 2.0) -> bool:
        """True while telemetry is stale and for ``within_s`` wall seconds after it came back: a mode
        change seen then is the autopilot's reaction to the outage, not a pilot's decision."""
        return self.stale or time.monotonic() - self.stale_until_wall < within_s

    async def _control_loop(self) -> None:
        clock, state = self.link.clock, self.link.state
        period = 1.0 / self.rate_hz
        while not clock.ready and not self.finished.is_set():
            await asyncio.sleep(0.01)
        t_next = clock.now(time.monotonic())
        while not self.finished.is_set():
            t_next += period
            wake, now = clock.wall_at(t_next), time.monotonic()
            if wake - now > RESYNC_TICKS * period / clock.rate:
                # the clock line moved back under us (re-anchored on a vehicle that paused)
                t_next = clock.now(now) + period
                wake = clock.wall_at(t_next)
            # block at most a quarter of a tick: sped up, a tick is only a few ms of wall time
            await _sleep_until(wake, min(PRECISE_SLEEP_S, 0.25 * period / clock.rate))
            now_v = clock.now(time.monotonic())
            if now_v - t_next > RESYNC_TICKS * period:  # fell behind (a stalled vehicle or machine)
                self.late_ticks += 1
                t_next = now_v
            tick, sent = None, False
            if self.engaged and self.control is not None and state.has_navigation and not self.stale:
                self.health.observe_age(t_next - min(state.t_pos, state.t_att))
                # the controller's own time follows the telemetry's stamps, not just this line:
                # a tick with no new vehicle time to step re-sends the last setpoint
                tick, moved = self.control.update(state, t_next)
                if tick is not None and tick.rejected is None:
                    self._setpoint = tick.setpoint
                    self._new_setpoint.set()
                    sent = True
                elif tick is not None and moved:
                    self.rejected += 1
                    self.log(f"setpoint rejected: {tick.rejected}")
            thrust = self.control.thrust if self.control else None
            self.recorder.row(state, tick, sent,
                              thrust.thrust_max_n if thrust else math.nan,
                              thrust.estimated_thrust_max_n if thrust else math.nan)
            health = self.health.sample(t_next, self.link.stats["received"], self.sent, self.link.rx_queue_depth,
                                        self.late_ticks, self.link.rx_lag_max_s)
            if health is not None:
                self.link.take_rx_lag_max()
                self.recorder.health(health)

    async def _streamer(self) -> None:
        while not self.finished.is_set():
            try:
                await asyncio.wait_for(self._new_setpoint.wait(), 0.1)
            except TimeoutError:
                continue
            self._new_setpoint.clear()
            sp = self._setpoint
            if sp is None or not self.engaged or self.stale:
                continue
            self.link.send_attitude_target(sp.q, sp.body_rates_rad_s, sp.thrust)
            self.sent += 1
            now = time.monotonic()
            if math.isfinite(self._last_sent_wall):
                self.tick_periods.append(now - self._last_sent_wall)
                if len(self.tick_periods) > 100_000:
                    del self.tick_periods[:50_000]
            self._last_sent_wall = now

    # --- mission -------------------------------------------------------------------------

    async def _until(self, cond, timeout_v: float, what: str) -> None:  # type: ignore[no-untyped-def]
        """Wait until ``cond()`` (checked every 10 ms wall), at most ``timeout_v`` vehicle seconds.
        Raises on interrupt, on leaving offboard while expected, and on timeout."""
        clock = self.link.clock
        wall_start = time.monotonic()
        start = clock.now(wall_start)
        wall_limit = wall_timeout_s(timeout_v, clock.rate)
        while True:
            if self.interrupted.is_set():
                raise _Interrupted()
            if self.expect_offboard and not self.link.state.offboard:
                during = f" after a {self.stale_for_s:.1f} s telemetry outage" if self._outage_recent() else ""
                raise MissionAbort(f"the autopilot left offboard (mode {self.link.state.mode}){during}")
            if cond():
                return
            now = time.monotonic()
            if clock.now(now) - start > timeout_v or now - wall_start > wall_limit:
                raise MissionAbort(f"timeout: {what} not within {timeout_v:g} s")
            await asyncio.sleep(0.01)

    async def _sleep_v(self, seconds: float) -> None:
        clock = self.link.clock
        end = clock.now(time.monotonic()) + seconds
        await self._until(lambda: clock.now(time.monotonic()) >= end, seconds + 5.0, "wait")

    async def _mission(self) -> tuple[str, str]:
        link, m = self.link, self.mission
        try:
            self.log(f"connecting to {self.opt.connect} ({self.opt.backend})")
            await link.wait_connected(self.opt.connect_timeout_s)
            self.log(f"connected: {link.state.autopilot} system {link.state.sysid}, mode {link.state.mode}")
            await self._make_controller()
            for i, step in enumerate(m.steps):
                self.recorder.begin(i, step.name, step.action, link.state.t)
                self.log(f"step {step.name}")
                await self._step(step)
            self.recorder.end(link.state.t)
            return "completed", f"mission {m.name} completed"
        except _Interrupted:
            self.recorder.end(link.state.t, False, "interrupted")
            self.log("interrupted: holding, then landing")
            await self._recover()
            return "interrupted", "interrupted by the operator; landed and disarmed" if not link.state.armed else \
                "interrupted by the operator"
        except (MissionAbort, LinkError) as exc:
            self.recorder.end(link.state.t, False, str(exc))
            self.log(f"aborted: {exc}")
            self.failure = str(exc)
            if link.state.sysid and time.monotonic() - link.state.wall_last < m.safety.link_lost_s:
                # a pilot who took over keeps control; after an outage the companion lands the vehicle
                # itself (the autopilot's failsafe would too, later)
                pilot = not link.state.offboard and self.expect_offboard and not self._outage_recent()
                await self._recover(leave_to_autopilot=pilot)
            return "aborted", str(exc)
        finally:
            self.engaged = False
            self.finished.set()

    async def _recover(self, leave_to_autopilot: bool = False) -> None:
        """Stop streaming; hold; land; wait until disarmed. If the autopilot left offboard by itself
        (a failsafe, or a pilot), it is in charge: stop without fighting it."""
        self.engaged = False
        self.expect_offboard = False
        for task in list(self._background):  # e.g. a hold still being retried after an outage
            task.cancel()
        link = self.link
        if not link.state.armed:
            return
        if leave_to_autopilot:
            self.log(f"the autopilot (mode {link.state.mode}) has control: the companion stops here")
            return
        self.log("holding, then landing")
        with contextlib.suppress(LinkError):
            await link.hold()
            await asyncio.sleep(0.5 / max(link.clock.rate, 1e-3))
            await link.land()
        self.interrupted.clear()
        with contextlib.suppress(MissionAbort, _Interrupted):
            await self._until(lambda: not link.state.armed, 120.0, "disarm after landing")

    async def _make_controller(self) -> None:
        m, link = self.mission, self.link
        t_max = self.opt.thrust_max_n or m.thrust.thrust_max_n
        source = "configuration"
        # optional look-ups: a parameter an autopilot does not have simply gets no answer
        if not t_max:
            sim = await link.get_param("SIM_THRUST_MAX", 0.3, 2)
            if sim:
                t_max, source = sim, "vehicle SIM_THRUST_MAX"
        if not t_max:
            names = ("MOT_THST_HOVER", "MPC_THR_HOVER") if link.state.autopilot == "ardupilot" else (
                "MPC_THR_HOVER", "MOT_THST_HOVER")
            for name in names:
                hover = await link.get_param(name, 0.3, 2)
                if hover:
                    t_max, source = m.vehicle.weight_n / hover, f"vehicle {name} = {hover:.3f}"
                    break
        if not t_max and m.thrust.hover_throttle:
            t_max, source = m.vehicle.weight_n / m.thrust.hover_throttle, "mission hover_throttle"
        if not t_max:
            raise MissionAbort("no thrust scale: set [thrust] thrust_max_n or hover_throttle in the mission")
        self.log(f"thrust scale {t_max:.2f} N at full throttle ({source})")
        if link.state.autopilot == "ardupilot":
            await self._ardupilot_lean_angle()
        gains = m.gains
        if self.link.state.specific_force_body_m_s2 is None:
            gains = dataclasses.replace(gains, observer_uses_imu=False)
            self.log("no HIGHRES_IMU: the force observer falls back to differentiated velocity")
        # the controller clamps to the safety limits itself (the guard is the last line, and a
        # rejected setpoint is a missing one): tilt 1 deg and rate 1% inside the guard's bounds
        reference = dataclasses.replace(
            m.reference,
            tilt_max_rad=min(m.reference.tilt_max_rad, math.radians(m.safety.max_tilt_deg - 1.0)),
            rate_limit_rad_s=min(m.reference.rate_limit_rad_s, 0.99 * math.radians(m.safety.max_rate_deg_s)),
        )
        self.control = OffboardController(
            self.controller_name, m.vehicle, gains if isinstance(gains, PositionGains) else PositionGains(),
            reference, m.trajectory, ThrustScaleEstimator(t_max, adapt=m.thrust.adapt),
            self.guard, estimate_thrust=m.thrust.estimate, period_s=1.0 / self.rate_hz,
        )

    async def _arm(self, timeout_s: float) -> None:
        """Arm once the autopilot says its pre-arm checks pass (an estimator still converging is
        normal just after boot), retrying a refusal a few times before giving up."""
        st = self.link.state
        await self._until(lambda: st.armable is not False, timeout_s, "pre-arm checks to pass")
        for attempt in range(4):
            try:
                await self.link.arm()
                return
            except LinkError as exc:
                if attempt == 3:
                    raise
                self.log(f"{exc}; retrying")
                await self._sleep_v(1.0)

    async def _ardupilot_lean_angle(self) -> None:
        """ArduCopter clips attitude targets to ANGLE_MAX (30 deg by default): raise it to the
        mission's tilt bound, or the 45 deg hover could never be flown."""
        want = 100.0 * self.mission.safety.max_tilt_deg
        have = await self.link.get_param("ANGLE_MAX")
        if have is not None and have < want:
            got = await self.link.set_param("ANGLE_MAX", want)
            if got < want:
                raise MissionAbort(f"ANGLE_MAX is {got / 100:g} deg and could not be raised to {want / 100:g}")
            self.log(f"ANGLE_MAX raised from {have / 100:g} to {want / 100:g} deg (mission tilt bound)")

    async def _step(self, s: Step) -> None:
        link, st = self.link, self.link.state
        c = self.control
        assert c is not None
        if s.action == "takeoff":
            if not st.armed:
                await self._arm(s.timeout_s)
            ground = st.pos_ned_m[2]
            await link.takeoff(s.altitude_m)
            target = ground - s.altitude_m
            await self._until(lambda: abs(st.pos_ned_m[2] - target) < 0.15 and st.mode not in ("TAKEOFF",),
                              s.timeout_s, f"take-off to {s.altitude_m:g} m")
        elif s.action == "offboard":
            c.start(st)
            self.engaged = True
            await self._sleep_v(1.2)  # setpoints flow for > 1 s at > 2 Hz before the switch (PX4)
            await link.start_offboard()
            await self._until(lambda: st.offboard, s.timeout_s, "offboard mode")
            self.expect_offboard = True
        elif s.action == "hold":
            if s.position_ned_m is not None:
                c.set_target(s.position_ned_m, math.radians(s.yaw_deg) if s.yaw_deg is not None else None)
            elif s.yaw_deg is not None:
                c.set_target(c.target, math.radians(s.yaw_deg))
            await self._sleep_v(s.duration_s)
        elif s.action == "goto":
            for wp in s.waypoints:
                c.set_target(wp, speed_m_s=s.speed_m_s)
                await self._until(lambda wp=wp: c.reference_at_target and math.dist(st.pos_ned_m, wp) < s.tolerance_m,
                                  s.timeout_s, f"waypoint {wp}")
                if s.hold_s > 0:
                    await self._sleep_v(s.hold_s)
        elif s.action == "set_param":
            if s.sim_only and await link.get_param(s.param) is None:
                self.log(f"{s.param}: no such parameter on this vehicle (sim_only step skipped)")
                return
            echoed = await link.set_param(s.param, s.value)
            if abs(echoed - s.value) > 1e-6 * max(1.0, abs(s.value)):
                raise MissionAbort(f"{s.param} = {s.value:g} refused (vehicle keeps {echoed:g})")
        elif s.action == "wait":
            await self._sleep_v(s.duration_s)
        elif s.action == "land":
            self.expect_offboard = False
            if st.armed:
                await link.land()
                self.engaged = False
                await self._until(lambda: not st.armed, s.timeout_s, "landing and disarm")

    # --- summary -------------------------------------------------------------------------

    def _summary(self, result: str, message: str) -> dict:
        thrust = self.control.thrust if self.control else None
        periods = sorted(self.tick_periods)
        jitter = {}
        if len(periods) > 10:
            med = periods[len(periods) // 2]
            jitter = {"median_period_ms": 1000 * med,
                      "p99_abs_jitter_ms": 1000 * sorted(abs(p - med) for p in periods)[int(0.99 * len(periods))]}
        ct = self.control.time if self.control else None
        return {
            "mission": self.mission.name, "result": result, "message": message,
            "controller": self.controller_name, "rate_hz": self.rate_hz, "backend": self.opt.backend,
            "autopilot": self.link.state.autopilot, "setpoints_sent": self.sent,
            "setpoints_rejected": self.rejected, "late_ticks": self.late_ticks,
            "telemetry_outages": self.outages, "longest_outage_s": self.longest_outage_s,
            "thrust_max_n": thrust.thrust_max_n if thrust else None,
            "thrust_max_est_n": thrust.estimated_thrust_max_n if thrust else None,
            "vehicle_clock_rate": self.link.clock.rate, "setpoint_timing": jitter,
            # how often the controller's time waited for telemetry or replayed a gap (control_time.py)
            "controller_time": {"held_ticks": ct.held_ticks, "sub_steps": ct.sub_steps,
                                "dropped_s": round(ct.dropped_s, 3)} if ct else None,
            "cpu_s": time.process_time() - self._cpu0, "wall_s": time.monotonic() - self._wall0,
            "link_stats": dict(getattr(self.link, "stats", {})),
            "older_samples": self.link.state.older_samples,
            "signing": fingerprint(self.opt.signing_key) if self.opt.signing_key else "off",
            "signing_rejections": dict(getattr(self.link, "signing_rejections", {})),
        }

