"""MAVSDK-Python's official offboard examples (offboard_attitude, offboard_velocity_ned,
offboard_velocity_body, offboard_position_velocity_ned), each flown as its script flies it by the real
MAVSDK core, on the bundled vehicle and on PX4 v1.16 SIH (skipped where no build is found), and judged
by the same assertions: what the firmware does with them is what the bundled vehicle must do.

The client code is ours, in the examples' shape (connect with ``udpin://`` where the vehicle sends, as
PX4 SITL does; wait for health; arm; one setpoint; ``offboard.start()``; the steps; ``offboard.stop()``),
written for MAVSDK 4's asyncio API. The examples' pauses are wall seconds at real time; here they are
the vehicle's seconds (its attitude stamps), so each step lasts the example's time however fast the
vehicle runs. Figures
come from PX4's parameters, which the bundled vehicle shares (sitl/autopilot/shaping.py): MPC_Z_P = 1
and MPC_XY_P = 0.95 [1/s] put a position setpoint sent with a velocity feed-forward v at v / P past
the point; MPC_Z_VEL_MAX_UP = 3 m/s; a commanded velocity is reached within 0.3 m/s in a 4 s step.
Where the airframes differ (the bundled vehicle hovers at 0.33 of full thrust, PX4's SIH at 0.5; its
speed limit is 5 m/s, PX4's 12), the assertions hold for both.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import pytest
from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.offboard import OffboardAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.offboard import Attitude, PositionNedYaw, VelocityBodyYawspeed, VelocityNedYaw
from mavsdk.plugins.telemetry import FlightMode

from companion.control.vector import Vec3
from companion.vehicle_process import VehicleProcess
from helpers.firmware import Px4Sih, find_px4
from helpers.processes import ROOT, child_env, free_udp_port

pytestmark = [pytest.mark.integration, pytest.mark.contract]

SPEED = {"bundled": 4.0, "firmware": 2.0}
"""vehicle seconds per wall second: MAVSDK resends the last setpoint at 20 Hz of wall time, 5-10 Hz of
the vehicle's, well inside the offboard loss timeout (1 s). On PX4 SIH they run one at a time
(tests/run_tiers.sh): the examples' client reads telemetry without stamps, and beside other tests
one read a velocity 1.3 m/s off the one PX4 had reached by the end of its step. And at 2x: at 4x,
alone, two of the four ended a hold 0.02 m/s past their bound (0.32 m/s of 0.3, 0.52 m of 0.5)"""
FIRMWARE_SPEED_OF = {"test_offboard_velocity_body_example_turns_climbs_and_flies_its_circles": 1.0}
"""examples flown slower on PX4 SIH: at 2x the body-velocity example's stops ended at 0.32-0.39 m/s
(bound 0.3) in four runs of 2026-12-06 on an idle host, at b274780 too, and its circle once at 2.75 m/s
(3.5 expected); at 1x it passed"""


@dataclass(frozen=True)
class VelocityLoop:
    """How a vehicle follows a velocity setpoint, per axis: ``a = P e + I \u222be - D dv/dt - k v``
    (PX4's velocity PID, its D on the measured acceleration, and the airframe's linear drag ``k``
    [1/s]); a takeoff ramp of ``takeoff_ramp_s`` on the first climb from the ground (PX4's
    MPC_TKO_RAMP_T). The bundled vehicle's shaped reference is a first-order lag of ``P``, its position
    loop cancelling the drag: P alone, no I, no drag, no ramp."""

    p_xy: float
    i_xy: float = 0.0
    d_xy: float = 0.0
    p_z: float = 2.0
    i_z: float = 0.0
    drag_per_s: float = 0.0
    takeoff_ramp_s: float = 0.0

    def circle_speed_m_s(self, speed_m_s: float, turn_rad_s: float) -> float:
        """The steady speed following a setpoint of ``speed_m_s`` that turns at ``turn_rad_s``:
        |G(i w)| of the loop, G(s) = (P s + I) / ((1 + D) s^2 + (P + k) s + I)."""
        s = 1j * turn_rad_s
        g = (self.p_xy * s + self.i_xy) / ((1.0 + self.d_xy) * s * s + (self.p_xy + self.drag_per_s) * s + self.i_xy)
        return speed_m_s * abs(g)

    def follow(self, steps: list[tuple[Vec3, float]], dt: float = 1e-3) -> list[tuple[float, ...]]:
        """The NED velocity at the end of each (setpoint, seconds) step, from rest on the ground (the
        climb ramped in over ``takeoff_ramp_s``), integrated at ``dt``."""
        gains = [(self.p_xy, self.i_xy, self.d_xy)] * 2 + [(self.p_z, self.i_z, 0.0)]
        v, integral, t, ends = [0.0] * 3, [0.0] * 3, 0.0, []
        for setpoint, seconds in steps:
            for _ in range(round(seconds / dt)):
                ramp = min(t / self.takeoff_ramp_s, 1.0) if self.takeoff_ramp_s else 1.0
                for ax, (p, i, d) in enumerate(gains):
                    e = setpoint[ax] * (ramp if ax == 2 else 1.0) - v[ax]
                    integral[ax] += e * dt
                    v[ax] += (p * e + i * integral[ax] - self.drag_per_s * v[ax]) / (1.0 + d) * dt
                t += dt
            ends.append(tuple(v))
        return ends


BUNDLED_LOOP = VelocityLoop(p_xy=2.0, p_z=2.0)
"""sitl/autopilot/shaping.py: ShapingLimits.vel_gain"""
PX4_SIH_LOOP = VelocityLoop(p_xy=1.8, i_xy=0.4, d_xy=0.2, p_z=4.0, i_z=2.0, drag_per_s=1.0, takeoff_ramp_s=3.0)
"""PX4 v1.16 SIH's parameters as it reports them: MPC_XY_VEL_P_ACC 1.8, _I_ACC 0.4, _D_ACC 0.2,
MPC_Z_VEL_P_ACC 4, _I_ACC 2, SIH_KDV 1 N s/m on SIH_MASS 1 kg, MPC_TKO_RAMP_T 3 s"""


@dataclass
class Vehicle:
    name: str
    url: str
    """where MAVSDK listens (the vehicle sends first, as PX4 SITL does)"""
    speed: float
    loop: VelocityLoop


@pytest.fixture(params=["bundled", "firmware"])
def vehicle(request) -> Iterator[Vehicle]:  # type: ignore[no-untyped-def]
    if request.param == "bundled":
        port = free_udp_port()
        speed = SPEED["bundled"]
        v = VehicleProcess("--flavour", "px4", "--peer", f"127.0.0.1:{port}", speedup=speed, env=child_env(), cwd=ROOT)
        yield Vehicle("bundled px4", f"udpin://127.0.0.1:{port}", speed, BUNDLED_LOOP)
        report = v.stop()
        assert report["terminated"] is None, report["events"]
        return
    build, why = find_px4()
    if build is None:
        pytest.skip(why)
    speed = FIRMWARE_SPEED_OF.get(request.node.originalname, SPEED["firmware"])
    with Px4Sih(build, speed=speed) as p:
        yield Vehicle("PX4 v1.16 SIH", p.url, speed, PX4_SIH_LOOP)


@dataclass
class Seen:
    """The newest telemetry, kept by background subscriptions."""

    north_m: float = math.nan
    east_m: float = math.nan
    down_m: float = math.nan
    v_ned_m_s: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    roll_deg: float = math.nan
    yaw_deg: float = math.nan
    mode: FlightMode = FlightMode.UNKNOWN
    armed: bool = False
    yaws: list[tuple[float, float]] = field(default_factory=list)
    """(wall time, yaw) of every attitude, for yaw rates"""

    @property
    def speed_h_m_s(self) -> float:
        return math.hypot(self.v_ned_m_s[0], self.v_ned_m_s[1])

    @property
    def course_deg(self) -> float:
        return math.degrees(math.atan2(self.v_ned_m_s[1], self.v_ned_m_s[0]))

    def yaw_rate_deg_s(self, speed: float, over_s: float = 1.0, until_s: float | None = None) -> float:
        """The mean yaw rate over the ``over_s`` vehicle seconds before ``until_s`` (default: the
        newest attitude), unwrapped, timed by the attitude's own stamps (a loaded host runs the
        vehicle slower than ``speed``: timed by the wall clock, 30 deg/s read 15). ``speed`` is kept
        for the callers; the stamps need none."""
        end = self.yaws[-1][0] if until_s is None else until_s
        recent = [(t, y) for t, y in self.yaws if end - over_s <= t <= end]
        turned = sum(_wrap(b[1] - a[1]) for a, b in zip(recent, recent[1:]))
        return turned / (recent[-1][0] - recent[0][0])


def _wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


async def _watch(tel: TelemetryAsync, seen: Seen) -> None:
    async def position() -> None:
        async for pv in tel.subscribe_position_velocity_ned():
            p, v = pv.position, pv.velocity
            seen.north_m, seen.east_m, seen.down_m = p.north_m, p.east_m, p.down_m
            seen.v_ned_m_s = (v.north_m_s, v.east_m_s, v.down_m_s)

    async def attitude() -> None:
        async for e in tel.subscribe_attitude_euler():
            seen.roll_deg, seen.yaw_deg = e.roll_deg, e.yaw_deg
            seen.yaws.append((e.timestamp_us * 1e-6, e.yaw_deg))  # vehicle time
            del seen.yaws[:-400]

    async def mode() -> None:
        async for m in tel.subscribe_flight_mode():
            seen.mode = m

    async def armed() -> None:
        async for a in tel.subscribe_armed():
            seen.armed = a

    await asyncio.gather(position(), attitude(), mode(), armed())


async def _until(cond, timeout_s: float) -> None:  # type: ignore[no-untyped-def]
    end = asyncio.get_running_loop().time() + timeout_s
    while not cond():
        assert asyncio.get_running_loop().time() < end, "timed out"
        await asyncio.sleep(0.02)


def fly(vehicle: Vehicle, example) -> dict:  # type: ignore[no-untyped-def]
    """Connect as the examples do, wait for a position and home, arm, run ``example``; what it noted."""
    notes: dict = {}
    seen = Seen()

    async def pause(seconds: float) -> None:
        """``seconds`` of the vehicle's time, by its attitude stamps (a loaded host runs the firmware
        slower than its speed factor: timed by the wall clock, a 4 s step was 2.5 s of PX4's)."""
        await _until(lambda: bool(seen.yaws), 10.0)
        start = seen.yaws[-1][0]
        await _until(lambda: seen.yaws[-1][0] - start >= seconds, 10.0 + 4.0 * seconds / vehicle.speed)

    async def run() -> None:
        async with Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION)) as sdk:
            await sdk.add_any_connection(vehicle.url)
            system = await sdk.first_autopilot(timeout_s=30.0)
            assert system is not None
            tel, action, offboard = TelemetryAsync(system), ActionAsync(system), OffboardAsync(system)
            watcher = asyncio.create_task(_watch(tel, seen))
            try:
                async for health in tel.subscribe_health():
                    if health.is_global_position_ok and health.is_home_position_ok and health.is_armable:
                        break
                await action.arm()
                await _until(lambda: seen.armed and math.isfinite(seen.down_m), 10.0)
                notes["speed"], notes["ground_down_m"] = vehicle.speed, seen.down_m
                await example(offboard, action, seen, pause, notes)
            finally:
                watcher.cancel()
                await asyncio.gather(watcher, return_exceptions=True)
            del tel, action, offboard, system

    asyncio.run(asyncio.wait_for(run(), 240.0))
    return notes


async def _start(offboard: OffboardAsync, seen: Seen, notes: dict) -> None:
    await offboard.start()  # raises OffboardError (COMMAND_DENIED on the old bundled vehicle)
    await _until(lambda: seen.mode == FlightMode.OFFBOARD, 10.0)
    notes["started"] = True


async def _stop_and_settle(offboard: OffboardAsync, seen: Seen, pause, notes: dict) -> None:  # type: ignore[no-untyped-def]
    await offboard.stop()
    await _until(lambda: seen.mode == FlightMode.HOLD, 10.0)
    await pause(10.0)
    notes["after_stop"] = (seen.mode, seen.armed, math.sqrt(sum(c * c for c in seen.v_ned_m_s)), seen.down_m)


# --- offboard_attitude ------------------------------------------------------------------------


async def offboard_attitude(offboard, action, seen, pause, notes) -> None:  # type: ignore[no-untyped-def]
    await offboard.set_attitude(Attitude(0.0, 0.0, 0.0, 0.0))
    await _start(offboard, seen, notes)
    down0 = seen.down_m
    await offboard.set_attitude(Attitude(0.0, 0.0, 0.0, 0.7))  # "Go up at 70% thrust"
    await pause(2.0)
    notes["climbed_m"] = down0 - seen.down_m
    await offboard.set_attitude(Attitude(30.0, 0.0, 0.0, 0.6))  # "Roll 30 at 60% thrust"
    await pause(2.0)
    notes["roll_30"] = seen.roll_deg
    await offboard.set_attitude(Attitude(-30.0, 0.0, 0.0, 0.6))  # "Roll -30 at 60% thrust"
    await pause(2.0)
    notes["roll_-30"] = seen.roll_deg
    await offboard.set_attitude(Attitude(0.0, 0.0, 0.0, 0.6))  # "Hover at 60% thrust"
    await pause(2.0)
    await _stop_and_settle(offboard, seen, pause, notes)
    await action.land()
    await _until(lambda: seen.mode == FlightMode.LAND, 10.0)
    down = seen.down_m
    await pause(3.0)
    notes["land_descent_m"] = seen.down_m - down


def test_offboard_attitude_example_climbs_rolls_and_holds_when_offboard_stops(vehicle):
    """One set_attitude, then offboard.start() is accepted; 70 % thrust climbs (both hover below it); the
    +-30 deg rolls are flown within 5 deg; offboard.stop() (HOLD) brakes whatever the climb rate (the
    bundled vehicle: some 8 m/s) to under 0.5 m/s within 10 s, armed; land() descends (0.5 m in 3 s)."""
    notes = fly(vehicle, offboard_attitude)
    assert notes["started"] and notes["climbed_m"] > 1.0
    assert abs(notes["roll_30"] - 30.0) < 5.0 and abs(notes["roll_-30"] + 30.0) < 5.0
    mode, armed, speed, _ = notes["after_stop"]
    assert mode == FlightMode.HOLD and armed and speed < 0.5, notes
    assert notes["land_descent_m"] > 0.5, notes


# --- offboard_velocity_ned --------------------------------------------------------------------


async def offboard_velocity_ned(offboard, action, seen, pause, notes) -> None:  # type: ignore[no-untyped-def]
    await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))
    await _start(offboard, seen, notes)
    steps = [("up", VelocityNedYaw(0.0, 0.0, -2.0, 0.0), 4.0),
             ("north, face east", VelocityNedYaw(2.0, 0.0, 0.0, 90.0), 4.0),
             ("south, face west", VelocityNedYaw(-2.0, 0.0, 0.0, 270.0), 4.0),
             ("west, face east", VelocityNedYaw(0.0, -2.0, 0.0, 90.0), 4.0),
             ("east", VelocityNedYaw(0.0, 2.0, 0.0, 90.0), 4.0),
             ("face south", VelocityNedYaw(0.0, 0.0, 0.0, 180.0), 2.0),
             ("down, face north", VelocityNedYaw(0.0, 0.0, 1.0, 0.0), 4.0)]
    for name, setpoint, seconds in steps:
        await offboard.set_velocity_ned(setpoint)
        await pause(seconds)
        notes[name] = (seen.v_ned_m_s, seen.yaw_deg, (setpoint.north_m_s, setpoint.east_m_s, setpoint.down_m_s),
                       setpoint.yaw_deg, seconds, notes["ground_down_m"] - seen.down_m)
    await _stop_and_settle(offboard, seen, pause, notes)


def test_offboard_velocity_ned_example_flies_each_velocity_and_heading(vehicle):
    """Started on the ground after one set_velocity_ned; at the end of each step the velocity is what
    the vehicle's velocity loop reaches of the commanded one (:class:`VelocityLoop`) within 0.35 m/s on
    every axis, and the heading the commanded one within 10 deg; stop() holds (under 0.5 m/s 10 s
    later: PX4 SIH's GPS-fed estimate still reads 0.31 m/s in HOLD). The bundled vehicle reaches each
    velocity within 1 %; PX4 against SIH's drag 1.90 of the first 2 m/s climb (its takeoff ramp; 1.69
    flown) and 1.64 of 2 m/s north (1.59 flown). PX4 climbs some 4 m in the first step, so the last
    (4 s down at 1 m/s) ends on the ground: there, under 1 m high, it may only not sink faster."""
    notes = fly(vehicle, offboard_velocity_ned)
    assert notes["started"]
    names = ("up", "north, face east", "south, face west", "west, face east", "east", "face south", "down, face north")
    model = vehicle.loop.follow([(notes[name][2], notes[name][4]) for name in names])
    heights = {name: round(notes[name][5], 2) for name in names}  # the estimate's, at each step's end [m]
    for name, modelled in zip(names, model):
        vel, yaw, want, want_yaw, _, height_m = notes[name]
        if name == "down, face north" and height_m < 1.0:  # back on the ground: it climbed less than it sinks
            assert vel[2] < 1.2, (name, vel, height_m)
            continue
        assert max(abs(a - b) for a, b in zip(vel, modelled)) < 0.35, (name, vel, want, modelled, heights)
        assert abs(_wrap(yaw - want_yaw)) < 10.0, (name, yaw, want_yaw)
    mode, armed, speed, down_m = notes["after_stop"]
    # as after offboard_attitude, but a last step that ended on the ground may end disarmed there: PX4's
    # land detector disarms a landed vehicle in any mode (COM_DISARM_LAND, 2 s; "Landing detected",
    # "Disarmed by landing" in one flight beside the rest of the suite, 0.05 m from the ground)
    on_ground = notes["down, face north"][5] < 1.0 and notes["ground_down_m"] - down_m < 0.5
    assert mode == FlightMode.HOLD and (armed or on_ground) and speed < 0.5, notes["after_stop"]


# --- offboard_velocity_body -------------------------------------------------------------------


async def offboard_velocity_body(offboard, action, seen, pause, notes) -> None:  # type: ignore[no-untyped-def]
    await offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))
    await _start(offboard, seen, notes)
    steps = [("turn clockwise and climb", VelocityBodyYawspeed(0.0, 0.0, -1.0, 60.0), 5.0),
             ("turn back anti-clockwise", VelocityBodyYawspeed(0.0, 0.0, 0.0, -60.0), 5.0),
             ("wait", VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0), 2.0),
             ("circle", VelocityBodyYawspeed(5.0, 0.0, 0.0, 30.0), 15.0),
             ("wait again", VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0), 5.0),
             ("circle sideways", VelocityBodyYawspeed(0.0, -5.0, 0.0, 30.0), 15.0),
             ("wait at the end", VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0), 8.0)]
    for name, setpoint, seconds in steps:
        await offboard.set_velocity_body(setpoint)
        begun = seen.yaws[-1][0]
        await pause(seconds)
        # the rate over the step's second before its last half second, fixed in vehicle time: read at
        # whatever moment this task wakes, PX4 SIH's yaw-rate dip 5 s into the climb (~0.5 s at
        # 11-14 deg/s, in every flight) fell partly inside and read 29 and 44 deg/s for 60
        rate = seen.yaw_rate_deg_s(notes["speed"], until_s=begun + seconds - 0.5)
        notes[name] = (seen.v_ned_m_s, seen.speed_h_m_s, seen.course_deg, seen.yaw_deg, rate)
    await _stop_and_settle(offboard, seen, pause, notes)


def test_offboard_velocity_body_example_turns_climbs_and_flies_its_circles(vehicle):
    """At the end of each step: the yaw rate is the commanded +-60 deg/s within 10 deg/s and the climb
    1 m/s within 0.3; on the circles the speed is what the vehicle's velocity loop keeps of 5 m/s turning
    at 30 deg/s, within 0.6 (the bundled vehicle's first-order reference: 4.84 m/s; PX4's PID against
    SIH's drag of 1 /s: 3.49, 3.58 flown) and the course is forward (left, sideways) of the heading
    within 25 deg (it lags the turn by atan(0.52 / 2) = 15 deg); still within 0.3 m/s after each wait;
    stop() holds."""
    notes = fly(vehicle, offboard_velocity_body)
    vel, _, _, _, rate = notes["turn clockwise and climb"]
    assert abs(rate - 60.0) < 10.0 and abs(vel[2] + 1.0) < 0.3, notes["turn clockwise and climb"]
    assert abs(notes["turn back anti-clockwise"][4] + 60.0) < 10.0
    circle_m_s = vehicle.loop.circle_speed_m_s(5.0, math.radians(30.0))
    for name, offset in (("circle", 0.0), ("circle sideways", -90.0)):
        _, speed, course, yaw, rate = notes[name]
        assert abs(speed - circle_m_s) < 0.6 and abs(rate - 30.0) < 10.0, (name, notes[name], circle_m_s)
        assert abs(_wrap(course - (yaw + offset))) < 25.0, (name, notes[name])
    for name in ("wait again", "wait at the end"):
        assert notes[name][1] < 0.3, (name, notes[name])
    mode, armed, _, _ = notes["after_stop"]
    assert mode == FlightMode.HOLD and armed


# --- offboard_position_velocity_ned -----------------------------------------------------------


async def offboard_position_velocity_ned(offboard, action, seen, pause, notes) -> None:  # type: ignore[no-untyped-def]
    await offboard.set_position_ned(PositionNedYaw(0.0, 0.0, 0.0, 0.0))
    await _start(offboard, seen, notes)
    peak = 0.0
    await offboard.set_position_velocity_ned(PositionNedYaw(0.0, 0.0, -10.0, 0.0),
                                             VelocityNedYaw(0.0, 0.0, -1.0, 0.0))
    for _ in range(20):
        await pause(0.5)
        peak = max(peak, -seen.v_ned_m_s[2])
    notes["up"] = (seen.north_m, seen.east_m, seen.down_m, peak)
    peak = 0.0
    await offboard.set_position_velocity_ned(PositionNedYaw(50.0, 0.0, -10.0, 0.0),
                                             VelocityNedYaw(1.0, 0.0, 0.0, 0.0))
    for _ in range(40):
        await pause(0.5)
        peak = max(peak, seen.v_ned_m_s[0])
    notes["north"] = (seen.north_m, seen.east_m, seen.down_m, peak)
    await action.land()
    await _until(lambda: seen.mode == FlightMode.LAND, 10.0)
    await offboard.stop()  # the example stops offboard after land(): HOLD, in the air, on PX4 too
    await _until(lambda: seen.mode == FlightMode.HOLD, 10.0)
    notes["after_stop"] = (seen.mode, seen.armed)


def test_offboard_position_velocity_ned_example_adds_the_feed_forward_as_px4_does(vehicle):
    """Position (0, 0, -10) with 1 m/s up: climbs at the 3 m/s limit (MPC_Z_VEL_MAX_UP, at least 2.5 seen)
    and settles where feed-forward and P term cancel, 1 / MPC_Z_P = 1 m above the point: 11 +- 0.5 m up
    after 10 s. Then (50, 0, -10) with 1 m/s north: 50 + 1 / MPC_XY_P = 51.05 +- 0.5 m north and 10 +- 0.5 m
    up after 20 s, faster than 3 m/s on the way (the 2 m/s of a position-only reference would not get
    there). land() lands until stop() switches to HOLD, where it stays armed."""
    notes = fly(vehicle, offboard_position_velocity_ned)
    north, east, down, peak = notes["up"]
    assert abs(down + 11.0) < 0.5 and abs(north) < 0.5 and abs(east) < 0.5 and peak > 2.5, notes["up"]
    north, east, down, peak = notes["north"]
    assert abs(north - (50.0 + 1.0 / 0.95)) < 0.5 and abs(down + 10.0) < 0.5 and peak > 3.0, notes["north"]
    assert notes["after_stop"] == (FlightMode.HOLD, True)
