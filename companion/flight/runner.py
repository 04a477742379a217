"""A flight: link, control loop, watchdog and mission under one TaskGroup.

- **reader** (``link.run``): telemetry into :class:`~companion.link.state.VehicleState`, heartbeats out;
- **control loop**: a fixed rate in vehicle time, ticked by the telemetry's samples
  (:mod:`.pacing`); computes a checked setpoint while the controller is engaged, sends it the
  moment it exists (and nothing stale), and records a row every tick;
- **watchdog**: samples the link every 20 ms and carries out what the judge
  (:mod:`.supervisor`) decides: pause setpoints on stale telemetry, command hold, end the flight
  when the link is lost or the vehicle leaves its safety volume;
- **mission**: the steps (:mod:`.steps`); on an interrupt (SIGINT) or an abort it stops streaming,
  commands hold, then land, and waits for the vehicle to disarm — it never just goes silent in the
  air — and puts back every autopilot parameter it changed (:mod:`.prepare`).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import datetime
import math
import re
import shutil
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control.params import PositionGains
from companion.link import LinkError, VehicleLink, open_link
from companion.link.resets import ResetBound, ResetsTold, unstable_reason
from companion.mavlink.identity import VehicleTarget, resolve_target
from companion.mavlink.signing import fingerprint
from companion.mission import Mission

from . import preflight, supervisor
from .errors import EXIT_CODES, Interrupted, LinkLost, MissionAbort
from .guard import SetpointGuard
from .health import HealthMonitor
from .offboard import OffboardController, PositionTarget, Setpoint, Tick
from .output import choose_output
from .pacing import TickGrid
from .ticker import Ticker
from .prepare import RESTORE_WITHIN_S, ParamChanges, prepare_ardupilot, thrust_scale
from .recorder import FlightRecorder, strict_json
from .sent import SentSetpoints
from .silence import AwakeSilence
from .steps import run_step
from .thrust_scale import ThrustScaleEstimator

__all__ = ["FlightOptions", "FlightResult", "Flight", "wall_timeout_s"]

DEBUG_PERIOD_S = 0.1
"""vehicle seconds between the controller-state messages for the ground station (10 Hz)"""
WATCHDOG_S = 0.02
"""wall seconds between the watchdog's checks"""
STALLED_S = 0.05
"""wall seconds a periodic task woke late by that mean this process was stalled"""


@dataclass
class FlightOptions:
    connect: str = "udpin://0.0.0.0:14540"
    """where PX4 SITL, and the bundled ``sitl`` with its default ports, send their API link"""
    backend: str = "pymavlink"
    controller: str | None = None
    """overrides the mission's position controller"""
    rate_hz: float | None = None
    out_dir: Path = Path("flights")
    connect_timeout_s: float = 20.0
    """wall seconds for an autopilot's heartbeat and its navigation telemetry, all told"""
    position_wait_s: float = 0.0
    """wall seconds more for a position, for a vehicle that sends attitude but has none yet"""
    thrust_max_n: float | None = None
    quiet: bool = False
    signing_key: bytes | None = field(default=None, repr=False)
    """MAVLink 2 signing key (pymavlink backend): sign what we send, believe only signed frames"""
    output: str = "auto"
    """what SET_ATTITUDE_TARGET carries: auto | attitude | rates | attitude_rates (output.py)"""
    mission_file: Path | None = None
    """copied into the flight record"""
    take_over: bool = False
    """fly a vehicle that is already armed or flying, from where it is (its take-off steps skipped)"""
    ardupilot_shaping: bool | None = None
    """overrides the mission's [controller] ardupilot_shaping"""
    target: VehicleTarget | None = None
    """the vehicle to fly on the link (``--target-system``); overrides the mission's [target]"""


@dataclass
class FlightResult:
    result: str
    message: str
    folder: Path
    summary: dict = field(default_factory=dict)

    @property
    def exit_code(self) -> int:
        return EXIT_CODES.get(self.result, 1)


def flight_folder(out_dir: Path, mission_name: str, controller: str) -> Path:
    """``<out>/<time>_<mission>_<controller>[_n]``, always inside ``out``: the names are reduced to
    a safe set of characters (a mission is checked when loaded, but a file name, a plan's stem or
    a program can still carry ``/`` or ``..``)."""
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    base = f"{stamp}_{_safe(mission_name)}_{_safe(controller)}"
    folder, n = out_dir / base, 1
    while folder.exists():
        n += 1
        folder = out_dir / f"{base}_{n}"
    if folder.resolve().parent != out_dir.resolve():
        raise ValueError(f"flight folder {folder} is not inside {out_dir}")
    return folder


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name).lstrip(".")[:64] or "flight"


def wall_timeout_s(timeout_v_s: float, rate: float) -> float:
    """The wall-clock bound on a mission timeout of ``timeout_v_s`` vehicle seconds: twice what the
    vehicle's rate (bounded to 0.25..1) makes it, plus 2 s. Timeouts count vehicle time, which
    only telemetry stamps move; this bound fires even if those stamps stop or lie, so no stamp
    can keep a mission waiting for ever (a simulated vehicle slower than 0.5x may meet it first)."""
    return 2.0 * timeout_v_s / min(max(rate, 0.25), 1.0) + 2.0


class Flight:
    def __init__(self, mission: Mission, options: FlightOptions | None = None) -> None:
        self.mission = mission
        self.opt = opt = options or FlightOptions()
        self.controller_name = opt.controller or mission.controller.position
        self.rate_hz = opt.rate_hz or mission.controller.rate_hz
        self.folder = flight_folder(opt.out_dir, mission.name, self.controller_name)
        self.recorder = FlightRecorder(self.folder, warn=self.log)
        self.target, self.target_note = resolve_target(opt.target, mission.target)
        link_options: dict[str, object] = {"target": self.target}
        if opt.signing_key is not None:
            link_options["signing_key"] = opt.signing_key
        self.link: VehicleLink = open_link(opt.connect, opt.backend, traffic=self.recorder.traffic, **link_options)
        safety = mission.safety
        self.guard = SetpointGuard(math.radians(safety.max_tilt_deg), math.radians(safety.max_rate_deg_s))
        self.limits = supervisor.Limits(safety.telemetry_timeout_s, safety.stale_hold_s, safety.link_lost_s)
        self.watch = supervisor.Watchdog()
        self.params = ParamChanges(self.link, self.log)
        self.control: OffboardController | None = None
        self.engaged = False
        """the controller computes setpoints (streaming before and during offboard)"""
        self.expect_offboard = False
        self.skipped: list[str] = []
        """mission steps that could not be flown on this vehicle (e.g. a simulated force on a real one)"""
        self._background: set[asyncio.Task[None]] = set()
        self.finished = asyncio.Event()
        self.interrupted = asyncio.Event()
        self._setpoint: tuple[Setpoint | PositionTarget, float] | None = None
        """the newest setpoint to stream, and the vehicle time of the telemetry it was computed from [s]"""
        self.setpoints = SentSetpoints()
        self.rejected = 0
        self.grid = TickGrid(1.0 / self.rate_hz)
        self.ticker = Ticker(self.grid, self._tick)
        """ticks fired by the clock line because the sample for them had not arrived"""
        self.output = choose_output(opt.output, "px4")
        """what SET_ATTITUDE_TARGET carries (output.py); chosen again once the autopilot is known"""
        self.health = HealthMonitor()
        self._debug_due = -math.inf
        self.taking_over = False
        self.ours = False
        """the companion armed the vehicle or was told to take it over: only then does it recover it"""
        self.preflight: dict = {}
        self.failure: str | None = None
        self._breach: str | None = None
        self.resets_told = ResetsTold()

    @property
    def stale(self) -> bool:
        return self.watch.stale

    @property
    def controller(self) -> OffboardController:
        assert self.control is not None, "the controller is made before the first step"
        return self.control

    def log(self, text: str) -> None:
        if not self.opt.quiet:
            t = self.link.state.t
            stamp = f"{t:8.2f}" if math.isfinite(t) else "      --"  # vehicle time, once it is known
            print(f"[{stamp}] {text}", flush=True)

    def interrupt(self) -> None:
        """SIGINT: the mission holds, lands and disarms; a second one gives up waiting."""
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
                        mission = tg.create_task(self._mission())
                    result, message = mission.result()
                except* LinkLost as eg:
                    result, message = "link lost", str(eg.exceptions[0])
                except* LinkError as eg:
                    result, message = "aborted", str(eg.exceptions[0])
                if self.params.pending:  # the mission ended before it could put them back (a lost link)
                    await self._restore_with_reader()
        except LinkError as exc:  # opening the link: the port is taken, the device missing; nothing flew
            result, message = "aborted", str(exc)
        finally:
            summary = self._summary(result, message)
            self.recorder.close(summary)
            params = self.link.state.params
            if params and self.recorder.failed is None:  # the autopilot's parameter snapshot
                with contextlib.suppress(OSError):
                    (self.folder / "parameters.json").write_text(strict_json(dict(sorted(params.items()))))
            if not self.link.state.sysid:  # never reached a vehicle: no flight, no folder
                shutil.rmtree(self.folder, ignore_errors=True)
        return FlightResult(result, message, self.folder, summary)

    async def _restore_params(self) -> None:
        with contextlib.suppress(Exception):
            await asyncio.wait_for(self.params.restore(RESTORE_WITHIN_S), RESTORE_WITHIN_S + 5.0)
        self.params.give_up()

    async def _restore_with_reader(self) -> None:
        """Put the parameters back after the flight's tasks ended (the link was lost): the answers
        need a reader, and a link that comes back within RESTORE_WITHIN_S gets them back."""
        stop = asyncio.Event()

        async def restore_then_stop() -> None:
            try:
                await self._restore_params()
            finally:
                stop.set()

        with contextlib.suppress(Exception):
            async with asyncio.TaskGroup() as tg:
                tg.create_task(self.link.run(stop))
                tg.create_task(restore_then_stop())
        self.params.give_up()

    def _in_background(self, command: Awaitable[None]) -> None:
        async def best_effort() -> None:
            with contextlib.suppress(LinkError):
                await command

        task = asyncio.get_running_loop().create_task(best_effort())
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    async def _watchdog(self) -> None:
        woke = time.monotonic()
        # silence counted only while this process was awake to hear it (silence.py)
        heard_nothing, heard_no_navigation = AwakeSilence(2 * WATCHDOG_S), AwakeSilence(2 * WATCHDOG_S)
        while not self.finished.is_set():
            await asyncio.sleep(WATCHDOG_S)
            st, link = self.link.state, self.link
            now, due = time.monotonic(), woke + WATCHDOG_S
            woke = now
            if now - due > STALLED_S:
                # this process was stalled: what arrived meanwhile is still unread in the socket,
                # so nothing can be judged old yet; the reader drains it before the next check
                continue
            w = supervisor.Watch(
                wall_s=now, connected=bool(st.sysid) and math.isfinite(st.wall_last),
                silent_link_s=heard_nothing.check(st.wall_last, now),
                silent_nav_s=heard_no_navigation.check(min(st.wall_pos, st.wall_att), now),
                telemetry_age_s=link.telemetry_age(now), behind_s=link.rx_lag_s * link.clock.rate,
                rate=link.clock.rate, engaged=self.engaged)
            verdict = supervisor.judge(self.watch, w, self.limits)
            self.watch = verdict.state
            for text in verdict.log:
                self.log(text)
            if verdict.link_lost:
                raise LinkLost(verdict.link_lost)
            if verdict.hold:
                self._in_background(self._hold_while_ours())

    async def _hold_while_ours(self) -> None:
        """Command hold once a heartbeat heard after the request says the vehicle still flies our
        setpoints (retried while the link is down): a hold that lands after the autopilot's own
        failsafe began would cancel it, and the mode known before the outage is stale."""
        st = self.link.state
        for _ in range(10):
            asked = st.wall_heartbeat
            end = time.monotonic() + self.mission.safety.link_lost_s
            while st.wall_heartbeat <= asked and time.monotonic() < end:
                await asyncio.sleep(0.02)
            heard = st.wall_heartbeat > asked
            if not supervisor.may_command_hold(self.expect_offboard, st.offboard, heard):
                self.log(f"the autopilot left offboard by itself (mode {st.mode}): no hold sent" if heard else
                         "no heartbeat since the outage began: no hold sent (the autopilot's failsafe decides)")
                return
            try:
                await self.link.hold(attempts=1)
                return
            except LinkError:
                continue

    def _volume_breach(self) -> str | None:
        volume = getattr(self.mission.safety, "volume", None)
        if volume is None or not self.link.state.has_navigation:
            return None
        return volume.breach(self.link.state.pos_ned_m)  # type: ignore[no-any-return]

    async def _control_loop(self) -> None:
        await self.ticker.run(self.link, self.finished)

    def _tick(self) -> None:
        """One tick: the supervisor's judgement, the controller's step, the setpoint sent, the
        flight's row, the debug values and the health sample."""
        state, grid = self.link.state, self.grid
        t_next = grid.t_next
        tick, sent = None, False
        self._note_resets()
        if self.engaged and self.expect_offboard and self._breach is None and not self.stale:
            self.watch, breach = supervisor.judge_breach(self.watch, self._volume_breach())
            if breach:  # no setpoint after it: the mission ends, hold then land (until())
                self._breach = breach
                self.log(f"{breach}: holding, then landing")
        if (self.engaged and self.control is not None and state.has_navigation and not self.stale
                and self._breach is None):
            self.health.observe_age(t_next - min(state.t_pos, state.t_att))
            # the controller's own time follows the telemetry's stamps, not just this line:
            # a tick with no new vehicle time to step re-sends the last setpoint
            tick, moved = self.control.update(state, t_next)
            if tick is not None and tick.rejected is None:
                # stamped with the telemetry this tick flew on (lockstep lets the world run
                # one period past it), not whatever is newest when it is sent
                self._setpoint = (tick.setpoint, state.t)
                self._stream()
                sent = True
            elif tick is not None and moved:
                self.rejected += 1
                self.log(f"setpoint rejected: {tick.rejected}")
        thrust = self.control.thrust if self.control else None
        self.recorder.row(state, tick, sent,
                          thrust.thrust_max_n if thrust else math.nan,
                          thrust.estimated_thrust_max_n if thrust else math.nan)
        if tick is not None and t_next >= self._debug_due:
            self._debug_due = t_next + DEBUG_PERIOD_S
            self._send_debug(tick, t_next)
        health = self.health.sample(t_next, self.link.stats["received"], self.sent, self.link.rx_queue_depth,
                                    grid.late_ticks, self.link.rx_lag_max_s)
        if health is not None:
            self.link.take_rx_lag_max()
            self.recorder.health(health)

    def _note_resets(self) -> None:
        """Log each estimator reset the link found (link/resets.py), count it in its segment, and
        judge whether the estimate still is one to fly on."""
        det, told = self.link.state.resets, self.resets_told
        for reset in det.resets[told.resets:]:
            n, e, d = reset.shift_ned_m
            self.log(f"estimator reset{' (announced)' if reset.announced else ''}: the position "
                     f"estimate jumped {reset.size_m:.2f} m (N {n:+.2f}, E {e:+.2f}, D {d:+.2f}) at "
                     f"t={reset.t_s:.2f} s: re-anchored, the vehicle holds where it was")
            if self.recorder.segments:
                self.recorder.segments[-1].position_resets += 1
        if det.announcements > told.announcements:
            self.log(f"the autopilot announced an estimator reset (ODOMETRY reset_counter {det.counter})")
        unstable = told.unstable
        if unstable is None and det.unstable(self.link.state.t):
            unstable = unstable_reason()
        # an announced reset found after it was taken as unannounced is relabelled, not added
        self.resets_told = ResetsTold(len(det.resets), max(det.announcements, told.announcements), unstable)

    def _send_debug(self, tick: Tick, t: float) -> None:
        """The force estimate, the commanded force and the tracking error to the ground station
        (through the autopilot, which routes them), at most 10 times a vehicle second."""
        ref = tick.reference.pos_ned_m
        err = math.dist(self.link.state.pos_ned_m, ref)
        vectors = {"F_est": tick.estimate_n, "F_cmd": tick.force_n}
        values = {"err_m": err, "thr_scale": self.control.thrust.thrust_max_n if self.control else math.nan}
        self.link.send_debug(t, {k: v for k, v in vectors.items() if all(math.isfinite(c) for c in v)},
                             {k: v for k, v in values.items() if math.isfinite(v)})

    def _stream(self) -> None:
        """The new setpoint to the vehicle, as soon as the tick has it."""
        if self._setpoint is None or not self.engaged or self.stale:
            return
        sp, stamp_s = self._setpoint
        if isinstance(sp, PositionTarget):  # in the autopilot's frame: its estimate, resets and all
            o = self.link.state.resets.offset_ned_m
            pos = (sp.pos_ned_m[0] + o[0], sp.pos_ned_m[1] + o[1], sp.pos_ned_m[2] + o[2])
            self.link.send_position_target(pos, sp.vel_ned_m_s, sp.accel_ned_m_s2, sp.yaw_rad, stamp_s=stamp_s)
        else:
            self.link.send_attitude_target(sp.q, sp.body_rates_rad_s, sp.thrust, self.output.type_mask,
                                           stamp_s=stamp_s)
        self.setpoints.sent(self.link.state.t, time.monotonic())

    # --- waiting (used by the steps) -------------------------------------------------------

    async def until(self, cond: Callable[[], bool], timeout_v: float, what: str, taking_off: bool = False) -> None:
        """Wait until ``cond()`` (checked every 10 ms wall), at most ``timeout_v`` vehicle seconds as
        the believed telemetry stamps show them (and a wall-clock bound no stamp can hold up). Ends
        early with an abort when the judge says so (supervisor.judge_wait), or when the vehicle has
        left its safety volume."""
        clock, st = self.link.clock, self.link.state
        wall_start = time.monotonic()
        start = st.t  # vehicle time seen to pass: believed stamps only (link/stamps.py), never the line
        wall_limit = wall_timeout_s(timeout_v, clock.rate)
        armed_seen, mode_at_start = st.armed, st.mode
        while True:
            now = time.monotonic()
            armed_seen = armed_seen or st.armed
            why = supervisor.judge_wait(supervisor.StepWatch(
                interrupted=self.interrupted.is_set(), expect_offboard=self.expect_offboard, offboard=st.offboard,
                mode=st.mode, armed=st.armed, taking_off=taking_off, armed_seen=armed_seen,
                mode_at_start=mode_at_start, outage=supervisor.outage_recent(self.watch, now),
                stale_for_s=self.watch.stale_for_s))
            if why == "interrupted":
                raise Interrupted()
            if why is not None:
                raise MissionAbort(why)
            if self._breach is not None:
                raise MissionAbort(self._breach)
            if self.resets_told.unstable is not None and self.expect_offboard:
                raise MissionAbort(self.resets_told.unstable)
            if cond():
                return
            if st.t - start > timeout_v or now - wall_start > wall_limit:
                raise MissionAbort(f"timeout: {what} not within {timeout_v:g} s")
            await asyncio.sleep(0.01)

    @property
    def sent(self) -> int:
        """setpoints sent so far"""
        return self.setpoints.count

    @property
    def last_sent_t(self) -> float:
        """vehicle time [s] of the newest setpoint sent"""
        return self.setpoints.last_t

    async def sleep_v(self, seconds: float) -> None:
        """``seconds`` of vehicle time as the telemetry's stamps show it passing."""
        st = self.link.state
        end = st.t + seconds
        await self.until(lambda: st.t >= end, seconds + 5.0, "wait")

    # --- mission -------------------------------------------------------------------------

    async def _mission(self) -> tuple[str, str]:
        link, m = self.link, self.mission
        try:
            self.log(f"connecting to {self.opt.connect} ({self.opt.backend}), to fly {self.target.describe()}")
            if self.target_note:
                self.log(self.target_note)
            link.progress = self.log
            await link.wait_connected(self.opt.connect_timeout_s, self.opt.position_wait_s)
            self.log(f"connected: {link.state.autopilot} system {link.state.sysid}, mode {link.state.mode}")
            self.output = choose_output(self.opt.output, link.state.autopilot)
            self.log(f"setpoints: {self.output.mode} (type_mask {self.output.type_mask})")
            await self._check_not_someone_elses()
            await self._make_controller()
            self.preflight = await self._preflight()
            self.recorder.metadata(self._metadata(), self.opt.mission_file)
            for i, step in enumerate(m.steps):
                self.recorder.begin(i, step.name, step.action, link.state.t)
                if self.taking_over and step.action == "takeoff":
                    self.skipped.append(f"{step.name}: taken over in the air")
                    self.log(f"step {step.name}: skipped (taken over in the air)")
                    continue
                self.log(f"step {step.name}")
                await run_step(self, step)
            self.recorder.end(link.state.t)
            result = ("completed", f"mission {m.name} completed")
        except Interrupted:
            self.recorder.end(link.state.t, False, "interrupted")
            if not self.ours:
                self.log("interrupted before the companion flew the vehicle")
                self.engaged = False
                await self._restore_params()
                self.finished.set()
                return ("interrupted", "interrupted by the operator before the flight")
            self.log("interrupted: holding, then landing")
            await self._recover(supervisor.recovery(self.expect_offboard, link.state.offboard, False, link.state.mode,
                                                    link.state.autopilot) if self.expect_offboard else "hold_then_land")
            result = ("interrupted", "interrupted by the operator; landed and disarmed" if not link.state.armed else
                      "interrupted by the operator")
        except (MissionAbort, LinkError) as exc:
            self.recorder.end(link.state.t, False, str(exc))
            self.log(f"aborted: {exc}")
            self.failure = str(exc)
            if not self.ours:
                self.log("the companion never flew this vehicle: it leaves it as it is")
            elif link.state.sysid and time.monotonic() - link.state.wall_last < m.safety.link_lost_s:
                await self._recover(supervisor.recovery(
                    self.expect_offboard, link.state.offboard, supervisor.outage_recent(self.watch, time.monotonic()),
                    link.state.mode, link.state.autopilot, link.state.on_ground))
            result = ("aborted", str(exc))
        finally:
            self.engaged = False
        await self._restore_params()
        self.finished.set()
        return result

    async def _recover(self, how: str = "hold_then_land") -> None:
        """Stop streaming, then as :func:`supervisor.recovery` decided: hold and land, land, or leave
        the vehicle to the autopilot that took it (a pilot, or its failsafe: never fought, never
        cancelled); wait until disarmed."""
        self.engaged = False
        self.expect_offboard = False
        self._breach = None
        for task in list(self._background):  # e.g. a hold still being retried after an outage
            task.cancel()
        link = self.link
        if not link.state.armed:
            return
        if how == "leave":
            self.log(f"the autopilot (mode {link.state.mode}) has control: the companion stops here")
            return
        self.log("holding, then landing" if how == "hold_then_land" else f"the vehicle holds ({link.state.mode}): "
                 "landing it")
        with contextlib.suppress(LinkError):
            if how == "hold_then_land":
                await link.hold()
                await asyncio.sleep(0.5 / max(link.clock.rate, 1e-3))
            await link.land()
        self.interrupted.clear()
        with contextlib.suppress(MissionAbort, Interrupted):
            await self.until(lambda: not link.state.armed, 120.0, "disarm after landing")

    async def _make_controller(self) -> None:
        m, link = self.mission, self.link
        found = await thrust_scale(link, m.vehicle.weight_n, self.opt.thrust_max_n or m.thrust.thrust_max_n,
                                   m.thrust.hover_throttle)
        if found is None:
            raise MissionAbort("no thrust scale: set [thrust] thrust_max_n or hover_throttle in the mission")
        t_max, source = found
        self.log(f"thrust scale {t_max:.2f} N at full throttle ({source})")
        link.state.resets.bound = ResetBound.for_vehicle(t_max, m.vehicle.mass_kg, m.vehicle.gravity_m_s2)
        if link.state.autopilot == "ardupilot":
            keep = self.opt.ardupilot_shaping
            await prepare_ardupilot(self.params, self.log,
                                    keep_shaping=m.controller.ardupilot_shaping if keep is None else keep)
        gains = m.gains
        if self.link.state.specific_force_body_m_s2 is None:
            gains = dataclasses.replace(gains, observer_uses_imu=False)
            self.log("no IMU (HIGHRES_IMU or SCALED_IMU): the force observer uses differentiated velocity")
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
            self.guard, output=self.output, estimate_thrust=m.thrust.estimate, period_s=1.0 / self.rate_hz,
        )

    async def arm(self, timeout_s: float) -> None:
        """Arm once the autopilot says its pre-arm checks pass (an estimator still converging is
        normal just after boot), retrying a refusal a few times before giving up."""
        st = self.link.state
        await self.link.set_arming_mode()
        await self.until(lambda: st.armable is not False, timeout_s, "pre-arm checks to pass")
        self.ours = True  # from the arming mode on, this flight answers for the vehicle
        for attempt in range(4):
            try:
                await self.link.arm()
                return
            except LinkError as exc:
                if attempt == 3:
                    raise
                self.log(f"{exc}; retrying")
                await self.sleep_v(1.0)

    async def _check_not_someone_elses(self) -> None:
        """An armed or flying vehicle is someone's: the companion does not take it without being told."""
        st = self.link.state
        flying = st.armed or st.landed_state == mavlink.MAV_LANDED_STATE_IN_AIR
        if flying and not self.opt.take_over:
            raise MissionAbort(f"the vehicle is already {'armed' if st.armed else 'flying'} (mode {st.mode}): "
                               "another operator may be flying it. To fly it from where it is, start again with "
                               "--take-over")
        if flying:
            why = self.take_over_refusal()
            if why is not None:
                raise MissionAbort(f"not taken over: {why}")
            self.taking_over = True  # ours only once the autopilot accepts the switch (steps.offboard)
            self.log(f"taking over an armed vehicle in {st.mode}: its take-off steps are skipped")
        volume = getattr(self.mission.safety, "volume", None)
        where = volume.breach(st.pos_ned_m) if volume is not None else None
        if where is not None and not flying:
            raise MissionAbort(f"the vehicle is outside its safety volume before take-off ({where}): the "
                               "autopilot's local origin is not where it stands (moved after boot?)")

    def take_over_refusal(self) -> str | None:
        """Why ``--take-over`` must leave this vehicle alone now (supervisor.take_over_refusal)."""
        st = self.link.state
        return supervisor.take_over_refusal(supervisor.TakeOverView(
            armed=st.armed, in_air=st.landed_state == mavlink.MAV_LANDED_STATE_IN_AIR, on_ground=st.on_ground,
            landed_known=st.landed_state != mavlink.MAV_LANDED_STATE_UNDEFINED, mode=st.mode, autopilot=st.autopilot,
            failsafe=st.failsafe,
            has_navigation=st.has_navigation, vel_ned_m_s=st.vel_ned_m_s))

    async def _preflight(self) -> dict:
        """Read the autopilot's failsafe settings and print them, with warnings (preflight.py)."""
        st = self.link.state
        values: dict[str, float | None] = {}
        await asyncio.sleep(0.2 / max(self.link.clock.rate, 1e-3))  # the parameter list asked for at connection
        for check in preflight.checks_for(st.autopilot):
            if check.name in st.params:
                values[check.name] = st.params[check.name]
            elif self.link.params_complete:
                values[check.name] = None  # the whole list came, without it
            else:
                values[check.name] = await self.link.get_param(check.name, 0.3, 2)
        lines, warnings = preflight.report(st.autopilot, values)
        self.log(f"pre-flight: {st.autopilot} failsafe settings")
        for line in lines:
            self.log(line)
        for w in warnings:
            self.log(f"WARNING: {w}")
        return {"values": values, "warnings": warnings}

    def _metadata(self) -> dict:
        from .metadata import flight_metadata

        return flight_metadata(self.mission, self.controller_name, self.output.mode, self.rate_hz, self.link,
                               self.opt.backend, self.opt.connect) | {"preflight": self.preflight}

    # --- summary -------------------------------------------------------------------------

    def _summary(self, result: str, message: str) -> dict:
        thrust = self.control.thrust if self.control else None
        ct = self.control.time if self.control else None
        w = self.watch
        params = self.params.record.summary()
        return {
            "mission": self.mission.name, "result": result, "message": message,
            "controller": self.controller_name, "rate_hz": self.rate_hz, "backend": self.opt.backend,
            "output": self.output.mode, "type_mask": self.output.type_mask,
            "autopilot": self.link.state.autopilot, "setpoints_sent": self.sent,
            "setpoint_rate_hz": self.setpoints.rate_hz(),
            "setpoints_rejected": self.rejected, "late_ticks": self.grid.late_ticks,
            "ticks_on_clock": self.ticker.ticks_on_clock,
            "telemetry_outages": w.outages, "longest_outage_s": w.longest_outage_s,
            "thrust_max_n": thrust.thrust_max_n if thrust else None,
            "thrust_max_est_n": thrust.estimated_thrust_max_n if thrust else None,
            "vehicle_clock_rate": self.link.clock.rate, "setpoint_timing": self.setpoints.timing(),
            # how often the controller's time waited for telemetry or replayed a gap (control_time.py)
            "controller_time": {"held_ticks": ct.held_ticks, "sub_steps": ct.sub_steps,
                                "dropped_s": round(ct.dropped_s, 3)} if ct else None,
            "cpu_s": time.process_time() - self._cpu0, "wall_s": time.monotonic() - self._wall0,
            "link_stats": dict(getattr(self.link, "stats", {})),
            "older_samples": self.link.state.older_samples,
            "position_resets": [{"t": r.t_s, "shift_ned_m": r.shift_ned_m, "announced": r.announced}
                                for r in self.link.state.resets.resets],
            "reset_announcements": self.link.state.resets.announcements,
            "position_offset_ned_m": self.link.state.resets.offset_ned_m,
            "acceleration_source": self.control.acceleration_source if self.control else None,
            "skipped_steps": list(self.skipped),
            "params_not_restored": params["not_restored"], "params_restored": params["restored"],
            "params_kept": params["kept"],
            "record": "complete" if self.recorder.failed is None else f"stopped: {self.recorder.failed}",
            "signing": fingerprint(self.opt.signing_key) if self.opt.signing_key else "off",
            "signing_rejections": dict(getattr(self.link, "signing_rejections", {})),
        }
