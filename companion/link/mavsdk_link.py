"""MAVSDK 4 (in-process C++ core) as the link, for PX4.

MAVSDK does what it is best at: discovery, arming, take-off, hold and land (Action), telemetry
subscriptions (Telemetry) and parameters (Param). Two things it cannot do are done through its
MavlinkDirect plugin: the SET_ATTITUDE_TARGET with quaternion *and* body rates that our
controller produces, and DO_SET_MODE to OFFBOARD (MAVSDK's Offboard plugin insists on owning
the setpoint stream).

The flight's ``.tlog``: MAVSDK forwards what it receives to a second, local connection (a tap
socket of ours), and sends its own messages on every connection; both are recorded. Messages
addressed only to MAVSDK itself (COMMAND_ACK) are not forwarded, so they are missing from this
backend's log; what we send through MavlinkDirect (the setpoints) does not reach the tap either,
so it is encoded again with pymavlink for the log (same content, its own sequence numbers).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import time
from typing import Any

from mavsdk.asyncio import ComponentType, Configuration, ForwardingOption, Mavsdk
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.events import EventsAsync
from mavsdk.asyncio.plugins.mavlink_direct import MavlinkDirectAsync
from mavsdk.asyncio.plugins.param import ParamAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk.plugins.mavlink_direct import MavlinkMessage
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.mavlink.boot_time import boot_ms
from companion.mavlink.identity import SURVEY_S, VehicleTarget
from companion.mavlink.setpoints import POSITION_TARGET_MASK
from companion.mavlink.params import MAV_PARAM_TYPE_REAL32, PLANT_COMPID
from companion.control.quaternion import Quat
from companion.control.vector import Vec3

from .base import ConnectWait, LinkError, TrafficHook, VehicleLink
from .url import parse_endpoint
from .flavour import PX4

__all__ = ["MavsdkLink"]

LANDED_STATES = {"ON_GROUND": mavlink.MAV_LANDED_STATE_ON_GROUND, "IN_AIR": mavlink.MAV_LANDED_STATE_IN_AIR,
                 "TAKING_OFF": mavlink.MAV_LANDED_STATE_TAKEOFF, "LANDING": mavlink.MAV_LANDED_STATE_LANDING}
"""MAVSDK's LandedState names -> MAV_LANDED_STATE (anything else: UNDEFINED)"""


class _Stop(Exception):
    pass


class _Tap(asyncio.DatagramProtocol):
    def __init__(self, hook: TrafficHook | None) -> None:
        self.hook = hook

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        if self.hook is not None:
            self.hook(data)


def _mavsdk_url(url: str) -> str:
    """Our connection string in MAVSDK's words (it calls a TCP client tcpout://)."""
    e = parse_endpoint(url)
    if e.kind == "tcp":
        return f"tcpout://{e.host}:{e.port}"
    return e.url


class MavsdkLink(VehicleLink):
    def __init__(self, url: str, traffic: TrafficHook | None = None, signing_key: bytes | None = None,
                 target: VehicleTarget | None = None) -> None:
        if signing_key is not None:
            raise LinkError("MAVLink signing needs --backend pymavlink: MAVSDK 4.1's Python API takes no signing key")
        super().__init__(target, traffic)
        if self.target.component_id not in (0, 1):
            raise LinkError("the MAVSDK backend flies an autopilot's component 1 only: drop --target-component or "
                            "use --backend pymavlink")
        self.url = url
        self._sdk: Mavsdk | None = None
        self._tap: asyncio.DatagramTransport | None = None
        self._system: Any = None
        self._plant_waiting: dict[str, asyncio.Future[float]] = {}
        self._plant_params: set[str] = set()
        self._plant_heard = False
        """parameters the simulated plant's component serves (``sitl --firmware``)"""
        self._outbox: asyncio.Queue[MavlinkMessage] = asyncio.Queue(maxsize=4)
        # what we send through MavlinkDirect never reaches the tap: encode it for the log ourselves
        self._log_mav = mavlink.MAVLink(None, srcSystem=245, srcComponent=190)

    async def open(self) -> None:
        loop = asyncio.get_running_loop()
        tap, _ = await loop.create_datagram_endpoint(lambda: _Tap(self.traffic), local_addr=("127.0.0.1", 0))
        self._tap = tap  # type: ignore[assignment]
        tap_port = tap.get_extra_info("sockname")[1]
        self._sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        try:
            await self._sdk.add_any_connection(_mavsdk_url(self.url))
            await self._sdk.add_any_connection(f"udpout://127.0.0.1:{tap_port}", ForwardingOption.ON)
        except Exception as exc:  # MavsdkConnectionError and friends
            raise LinkError(f"MAVSDK cannot open {self.url}: {exc}") from None

    async def close(self) -> None:
        if self._sdk is not None:
            self._sdk.destroy()
            self._sdk = None
        if self._tap is not None:
            self._tap.close()
            self._tap = None

    async def wait_connected(self, timeout_s: float, position_wait_s: float = 0.0) -> None:
        """An autopilot, then its navigation telemetry, within ``timeout_s`` of wall time in all
        (:class:`~companion.link.base.ConnectWait`)."""
        assert self._sdk is not None
        start = time.monotonic()
        system = await self._choose_system(timeout_s)
        if getattr(await system.autopilot_type(), "name", "") != "PX4":
            raise LinkError("the MAVSDK backend flies PX4; use --backend pymavlink for ArduPilot")
        self._system = system
        self.flavour = PX4
        st = self.state
        st.autopilot, st.sysid, st.compid = "px4", await system.get_system_id(), 1
        self.telemetry = TelemetryAsync(system)
        self.action = ActionAsync(system)
        self.direct = MavlinkDirectAsync(system)
        self.param = ParamAsync(system)
        for setter, hz in ((self.telemetry.set_rate_attitude_quaternion, 100.0),
                           (self.telemetry.set_rate_position_velocity_ned, 60.0),
                           (self.telemetry.set_rate_imu, 100.0)):
            try:
                async with asyncio.timeout(max(start + timeout_s - time.monotonic(), 0.0)):
                    await setter(hz)
            except Exception:  # refused, or the time to connect has run out (the wait below says so)
                self.stats["rate_requests_refused"] += 1
        # run() fills the state; it must already be running
        await self._wait_navigation(ConnectWait(timeout_s, position_wait_s), start)

    async def _autopilots(self) -> dict[int, Any]:
        """The systems MAVSDK has discovered that have an autopilot, by system id."""
        assert self._sdk is not None
        found: dict[int, Any] = {}
        for system in await self._sdk.get_systems():
            if await system.has_autopilot():
                found[await system.get_system_id()] = system
        return found

    async def _choose_system(self, timeout_s: float) -> Any:
        """The target system (or, with none chosen, the only autopilot), after listening
        :data:`SURVEY_S` for every autopilot on the link; LinkError naming the systems heard when
        the target is absent or, without a target, when there are several. MAVSDK merges two
        senders of one system id into one system: that conflict shows only with the pymavlink
        backend."""
        end = time.monotonic() + timeout_s
        first = math.nan
        while True:
            found = await self._autopilots()
            now = time.monotonic()
            if found and math.isnan(first):
                first = now
            ours = found.get(self.target.system_id) if self.target.chosen else None
            if (ours is not None or (not self.target.chosen and found)) and now >= min(first + SURVEY_S, end):
                break
            if now >= end:
                heard = ", ".join(map(str, sorted(found))) or "none"
                if self.target.chosen:
                    raise LinkError(f"no heartbeat from {self.target.describe()}; heard systems {heard} (within "
                                    f"--connect-timeout {timeout_s:g} s at {self.url})")
                raise LinkError(f"no autopilot found at {self.url} within {timeout_s:g} s")
            await asyncio.sleep(0.1)
        if not self.target.chosen and len(found) > 1:
            raise LinkError(f"more than one autopilot on this link: systems {', '.join(map(str, sorted(found)))}; "
                            f"choose one with --target-system N (or [target] system_id = N in the mission)")
        return ours if ours is not None else next(iter(found.values()))

    # --- telemetry -------------------------------------------------------------------------

    async def run(self, stop: asyncio.Event) -> None:
        while self._system is None and not stop.is_set():
            await asyncio.sleep(0.02)
        if stop.is_set():
            return
        try:
            async with asyncio.TaskGroup() as tg:
                for coro in (self._attitude(), self._rates(), self._position(), self._imu(), self._mode(),
                             self._armed(), self._landed(), self._texts(), self._events(), self._health(),
                             self._sender(), self._plant_values(), self._plant_heartbeats()):
                    tg.create_task(coro)
                await stop.wait()
                raise _Stop()
        except* _Stop:
            pass

    def _seen(self) -> float:
        now = time.monotonic()
        self.state.wall_last = now
        return now

    async def _attitude(self) -> None:
        async for q in self.telemetry.subscribe_attitude_quaternion():
            now = self._seen()
            self._sample(q.timestamp_us * 1e-6, now, self.state.set_attitude, (q.w, q.x, q.y, q.z), None,
                         wraps=True)  # from time_boot_ms

    async def _rates(self) -> None:
        async for w in self.telemetry.subscribe_attitude_angular_velocity_body():
            self._valid(self.state.set_rates((w.roll_rad_s, w.pitch_rad_s, w.yaw_rad_s)))

    async def _position(self) -> None:
        # PositionVelocityNed carries no timestamp: stamp it with the newest stamp seen (attitude
        # and IMU come at 100 Hz), not with the clock line, which runs on while a simulated
        # vehicle pauses and would make a repeated position look new (companion/flight/control_time.py)
        async for pv in self.telemetry.subscribe_position_velocity_ned():
            now = self._seen()
            p, v = pv.position, pv.velocity
            newest = max(self.state.t_att, self.state.t_imu)
            t = newest if math.isfinite(newest) else (self.clock.now(now) if self.clock.ready else 0.0)
            if t <= self.state.t_pos:  # two positions between attitude stamps: the second is newer
                t = self.state.t_pos + 1e-6
            self._valid(self.state.set_position((p.north_m, p.east_m, p.down_m),
                                                (v.north_m_s, v.east_m_s, v.down_m_s), t, now))

    async def _imu(self) -> None:
        async for imu in self.telemetry.subscribe_imu():
            now = self._seen()
            a = imu.acceleration_frd
            self._sample(imu.timestamp_us * 1e-6, now, self.state.set_imu, (a.forward_m_s2, a.right_m_s2, a.down_m_s2))

    async def _mode(self) -> None:
        async for mode in self.telemetry.subscribe_flight_mode():
            self.state.mode = mode.name
            self.state.offboard = mode.name == "OFFBOARD"
            self.state.wall_heartbeat = self._seen()

    async def _armed(self) -> None:
        async for armed in self.telemetry.subscribe_armed():
            self.state.armed = bool(armed)

    async def _landed(self) -> None:
        async for landed in self.telemetry.subscribe_landed_state():
            self.state.landed_state = LANDED_STATES.get(landed.name, mavlink.MAV_LANDED_STATE_UNDEFINED)

    async def _health(self) -> None:
        async for h in self.telemetry.subscribe_health():
            self.state.armable = bool(h.is_armable)

    async def _texts(self) -> None:
        async for text in self.telemetry.subscribe_status_text():
            self.state.add_text(6, text.text)

    async def _events(self) -> None:
        """PX4's EVENTs (refusal reasons, failsafes): MAVSDK fetches their texts from the vehicle."""
        try:
            async for event in EventsAsync(self._system).subscribe_events():
                self.state.add_text(int(event.log_level), event.message)
                self.stats["events"] += 1
        except Exception:  # an autopilot without events (ArduPilot) or an older MAVSDK
            self.stats["events_unavailable"] += 1

    async def _sender(self) -> None:
        while True:
            msg = await self._outbox.get()
            try:
                await self.direct.send_message(msg)
                self.stats["setpoints"] += 1
            except Exception:
                self.stats["send_errors"] += 1

    # --- commands --------------------------------------------------------------------------

    async def _do(self, what: str, coro: Any) -> None:
        before = self.state.texts_seen
        try:
            await coro
        except Exception as exc:  # ActionError etc. carry the autopilot's refusal
            reason = await self._refusal_reason(before)
            raise LinkError(f"{what} refused: {exc}{' (' + reason + ')' if reason else ''}") from None

    async def set_arming_mode(self) -> None:
        await self._do("the arming mode (HOLD)", self.action.hold())

    async def arm(self) -> None:
        await self._do("arming", self.action.arm())

    async def disarm(self, force: bool = False) -> None:
        await self._do("disarming", self.action.kill() if force else self.action.disarm())

    async def takeoff(self, altitude_m: float) -> None:
        await self._do("take-off altitude", self.action.set_takeoff_altitude(altitude_m))
        await self._do("take-off", self.action.takeoff())

    async def start_offboard(self) -> None:
        main, sub = PX4.offboard_mode
        fields = {"target_system": self.state.sysid, "target_component": 1, "command": mavlink.MAV_CMD_DO_SET_MODE,
                  "confirmation": 0, "param1": float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED),
                  "param2": float(main), "param3": float(sub), "param4": 0.0, "param5": 0.0, "param6": 0.0,
                  "param7": 0.0}
        cmd = MavlinkMessage(message_name="COMMAND_LONG", system_id=245, component_id=190,
                             target_system_id=self.state.sysid, target_component_id=1, fields_json=json.dumps(fields))
        before = self.state.texts_seen
        try:
            ack = await self.direct.send_command(cmd)
            result = json.loads(ack.fields_json).get("result", -1) if ack.fields_json else -1
        except Exception as exc:
            raise LinkError(f"offboard mode: {exc}") from None
        if result != mavlink.MAV_RESULT_ACCEPTED:
            reason = await self._refusal_reason(before)
            raise LinkError(f"offboard mode refused (MAV_RESULT {result}){': ' + reason if reason else ''}")

    async def hold(self, attempts: int | None = None) -> None:
        await self._do("hold", self.action.hold())

    async def land(self) -> None:
        await self._do("land", self.action.land())

    # --- setpoints and parameters ----------------------------------------------------------

    def send_attitude_target(self, q: Quat, body_rates_rad_s: Vec3, thrust: float, type_mask: int = 0,
                             stamp_s: float | None = None) -> None:
        fields = {"time_boot_ms": self._setpoint_ms(stamp_s),
                  "target_system": self.state.sysid, "target_component": 1, "type_mask": type_mask,
                  "q": [float(c) for c in q], "body_roll_rate": float(body_rates_rad_s[0]),
                  "body_pitch_rate": float(body_rates_rad_s[1]), "body_yaw_rate": float(body_rates_rad_s[2]),
                  "thrust": float(thrust)}
        msg = MavlinkMessage(message_name="SET_ATTITUDE_TARGET", system_id=245, component_id=190,
                             target_system_id=self.state.sysid, target_component_id=1, fields_json=json.dumps(fields))
        self._queue_direct(msg)
        if self.traffic is not None:
            self.traffic(self._log_mav.set_attitude_target_encode(
                fields["time_boot_ms"], self.state.sysid, 1, type_mask, fields["q"], fields["body_roll_rate"],
                fields["body_pitch_rate"], fields["body_yaw_rate"], fields["thrust"]).pack(self._log_mav))

    def send_position_target(self, pos_ned_m: Vec3, vel_ned_m_s: Vec3, accel_ned_m_s2: Vec3, yaw_rad: float,
                             stamp_s: float | None = None) -> None:
        x, y, z = (float(c) for c in pos_ned_m)
        vx, vy, vz = (float(c) for c in vel_ned_m_s)
        ax, ay, az = (float(c) for c in accel_ned_m_s2)
        fields = {"time_boot_ms": self._setpoint_ms(stamp_s),
                  "target_system": self.state.sysid, "target_component": 1,
                  "coordinate_frame": mavlink.MAV_FRAME_LOCAL_NED, "type_mask": POSITION_TARGET_MASK,
                  "x": x, "y": y, "z": z, "vx": vx, "vy": vy, "vz": vz, "afx": ax, "afy": ay, "afz": az,
                  "yaw": float(yaw_rad), "yaw_rate": 0.0}
        self._queue_direct(MavlinkMessage(message_name="SET_POSITION_TARGET_LOCAL_NED", system_id=245,
                                          component_id=190, target_system_id=self.state.sysid, target_component_id=1,
                                          fields_json=json.dumps(fields)))
        if self.traffic is not None:
            self.traffic(self._log_mav.set_position_target_local_ned_encode(
                fields["time_boot_ms"], self.state.sysid, 1, mavlink.MAV_FRAME_LOCAL_NED, POSITION_TARGET_MASK,
                x, y, z, vx, vy, vz, ax, ay, az, float(yaw_rad), 0.0).pack(self._log_mav))

    def send_debug(self, t_s: float, vectors: dict[str, Vec3], values: dict[str, float]) -> None:
        t_us, t_ms = int(max(t_s, 0.0) * 1e6), boot_ms(t_s)
        messages = [("DEBUG_VECT", {"name": name[:10], "time_usec": t_us, "x": float(v[0]), "y": float(v[1]),
                                    "z": float(v[2])}) for name, v in vectors.items()]
        messages += [("NAMED_VALUE_FLOAT", {"time_boot_ms": t_ms, "name": name[:10], "value": float(x)})
                     for name, x in values.items()]
        for kind, fields in messages:
            msg = MavlinkMessage(message_name=kind, system_id=245, component_id=190, target_system_id=0,
                                 target_component_id=0, fields_json=json.dumps(fields))
            asyncio.get_running_loop().create_task(self._direct_best_effort(msg))

    async def _direct_best_effort(self, msg: MavlinkMessage) -> None:
        with contextlib.suppress(Exception):
            await self.direct.send_message(msg)

    def _queue_direct(self, msg: MavlinkMessage) -> None:
        if self._outbox.full():  # never queue stale setpoints: the newest one wins
            self._outbox.get_nowait()
            self.stats["setpoints_superseded"] += 1
        self._outbox.put_nowait(msg)

    async def get_param(self, name: str, timeout_s: float = 1.0, retries: int = 3) -> float | None:
        """From the autopilot or, once a simulated plant's own component (PLANT_COMPID, ``sitl
        --firmware``) has been heard, from the plant first: it never serves the autopilot's names
        (MAVSDK's parameter plugin may take the plant's PARAM_VALUE, which the firmware forwards,
        for the autopilot's)."""
        if self._plant_heard:
            value = await self._plant_param(name, None, 0.5, 2)
            if value is not None:
                self._plant_params.add(name)
                return value
        try:
            return float(await self.param.get_param_float(name))
        except Exception:
            return None

    async def _plant_param(self, name: str, value: float | None, timeout_s: float = 1.0,
                           retries: int = 3) -> float | None:
        """PARAM_REQUEST_READ (``value`` None) or PARAM_SET of the plant's component, through
        MavlinkDirect (MAVSDK's parameter plugin serves the autopilot); its PARAM_VALUE."""
        sysid = self.state.sysid  # set once the target system was chosen (wait_connected)
        fields = {"target_system": sysid, "target_component": PLANT_COMPID, "param_id": name}
        if value is None:
            kind, fields = "PARAM_REQUEST_READ", fields | {"param_index": -1}
        else:
            kind, fields = "PARAM_SET", fields | {"param_value": float(value), "param_type": MAV_PARAM_TYPE_REAL32}
        msg = MavlinkMessage(message_name=kind, system_id=245, component_id=190, target_system_id=sysid,
                             target_component_id=PLANT_COMPID, fields_json=json.dumps(fields))
        fut: asyncio.Future[float] = asyncio.get_running_loop().create_future()
        self._plant_waiting[name] = fut
        try:
            for _ in range(retries):
                try:
                    await self.direct.send_message(msg)
                except Exception:
                    return None
                try:
                    return await asyncio.wait_for(asyncio.shield(fut), timeout_s)
                except TimeoutError:
                    continue
            return None
        finally:
            self._plant_waiting.pop(name, None)

    async def _plant_heartbeats(self) -> None:
        async for m in self.direct.subscribe_message("HEARTBEAT"):
            if m.component_id == PLANT_COMPID and m.system_id == self.state.sysid:
                self._plant_heard = True
                return

    async def _plant_values(self) -> None:
        """PARAM_VALUE from the plant's component, for :meth:`_plant_param`."""
        async for m in self.direct.subscribe_message("PARAM_VALUE"):
            if m.component_id != PLANT_COMPID or m.system_id != self.state.sysid:
                continue
            try:
                fields = json.loads(m.fields_json)
                name, value = str(fields["param_id"]), float(fields["param_value"])
            except (ValueError, KeyError, TypeError):
                self.stats["bad_plant_params"] += 1
                continue
            fut = self._plant_waiting.get(name)
            if fut is not None and not fut.done():
                fut.set_result(value)

    async def set_param(self, name: str, value: float) -> float:
        if name not in self._plant_params and await self.get_param(name) is None:
            raise LinkError(f"parameter {name}: the autopilot has no such parameter")
        if name in self._plant_params:
            echoed = await self._plant_param(name, value)
            if echoed is None:
                raise LinkError(f"parameter {name} was not acknowledged")
            return echoed
        try:
            await self.param.set_param_float(name, float(value))
        except Exception as exc:
            raise LinkError(f"parameter {name}: {exc}") from None
        echoed = await self.get_param(name)
        if echoed is None:
            raise LinkError(f"parameter {name} was not read back")
        return echoed
