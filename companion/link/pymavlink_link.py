"""MAVLink on the wire with pymavlink, over asyncio UDP: PX4 and ArduPilot.

Datagrams go from the socket (every waiting one at each wake-up: :mod:`.udp`) into a bounded
queue (full: dropped and counted, never grown) and are parsed by :meth:`PymavlinkLink.run`,
everything queued at each wake-up. Only messages from
the autopilot this link locked on to update the state: the target system (and component) when
one was chosen, else the first autopilot heard, and connecting is refused when the target is
absent, when two senders claim its identity, or (without a target) when more than one autopilot
is on the link (:mod:`companion.mavlink.identity`). Nothing is addressed to any other system. Commands
are sent as COMMAND_LONG and retried until their COMMAND_ACK arrives. Every datagram, in and
out, is handed to the ``traffic`` hook for the flight's ``.tlog``.

With a signing key, everything sent is signed and only frames signed with the key (and not
replayed) are believed: a spoofed heartbeat or position cannot steer the controller.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections import Counter
from typing import Any, Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control.quaternion import Quat
from companion.control.vector import Vec3

from .base import ConnectWait, LinkError, TrafficHook, VehicleLink
from .url import Endpoint, parse_endpoint
from .flavour import ARDUPILOT, PX4, flavour_for
from companion.mavlink import ftp
from companion.mavlink.boot_time import boot_ms
from companion.mavlink.commands import FORCE_ARM_DISARM, result_text
from companion.mavlink.events import MSG_ID_EVENT, EventCatalogue, parse_event
from companion.mavlink.identity import (SURVEY_FRAMES, SURVEY_HEARTBEATS, SURVEY_S, AutopilotsHeard, VehicleTarget,
                                        connection_problem)
from companion.mavlink.setpoints import POSITION_TARGET_MASK
from companion.mavlink.params import MAV_PARAM_TYPE_REAL32, PLANT_COMPID, decode_value, encode_value, param_name
from companion.mavlink.signing import SignatureCheck, describe_rejections, enable_signing, fingerprint
from companion.mavlink.stream import SerialEndpoint, TcpEndpoint
from companion.mavlink.udp import UdpEndpoint
from companion.mavlink.wire import new_parser, parse_datagram

__all__ = ["PymavlinkLink"]

QUEUE_SIZE = 2000
NOTHING_HEARD_S = 3.0
"""wall seconds of complete silence after which connecting gives up and says what to check"""
ACCEL_UPDATED = mavlink.HIGHRES_IMU_UPDATED_XACC | mavlink.HIGHRES_IMU_UPDATED_YACC | mavlink.HIGHRES_IMU_UPDATED_ZACC
"""HIGHRES_IMU fields_updated: all three accelerations are new"""
MAX_PARAMS = 4096
"""parameter values kept (PX4 has about 1500)"""

# telemetry the controller needs, and how often (Hz); asked for at connection
STREAM_RATES_HZ = {
    mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: 100.0,
    mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 60.0,
    mavlink.MAVLINK_MSG_ID_HIGHRES_IMU: 100.0,
    mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 5.0,
    mavlink.MAVLINK_MSG_ID_ODOMETRY: 10.0,  # for its reset_counter: estimator resets announced (a
    # change is matched to a jump within 0.25 s); more is parsing a simulator at 20x cannot spare
}


class PymavlinkLink(VehicleLink):
    def __init__(self, url: str, traffic: TrafficHook | None = None, sysid: int = 255, compid: int = 191,
                 command_timeout_s: float = 1.0, command_retries: int = 5, signing_key: bytes | None = None,
                 target: VehicleTarget | None = None) -> None:
        super().__init__(target, traffic)
        self.heard = AutopilotsHeard()
        """every autopilot identity heard: its addresses and sequence runs (two claimants, other systems)"""
        self._surveying = True
        """connecting: datagrams from every address are read (their heartbeats only), to hear every autopilot"""
        self._first_heartbeat = math.nan
        self._chosen_heartbeats = 0
        """heartbeats of the chosen autopilot: the survey's clock in its own time (a simulated one may run fast)"""
        self.endpoint = parse_endpoint(url)
        self.direction = "in" if self.endpoint.kind == "udpin" else "out"
        self.address = (self.endpoint.host, self.endpoint.port) if self.endpoint.kind != "serial" else (
            self.endpoint.device, self.endpoint.baud)
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        self.parser = new_parser()
        self.signature_check: SignatureCheck | None = None
        self.signing_rejections: Counter[str] = Counter()
        if signing_key is not None:
            enable_signing(self.mav, signing_key)
            self.signature_check = SignatureCheck(signing_key, allow_unsigned=frozenset({"RADIO_STATUS"}))
        self.command_timeout_s = command_timeout_s
        self.command_retries = command_retries
        """5 tries: with 10% loss each way one try fails 19% of the time; 3 tries would still fail
        0.7% of commands, 5 tries 0.02%"""
        self._transport: UdpEndpoint | TcpEndpoint | SerialEndpoint | None = None
        self._peer: tuple[str, int] | None = self.address if self.direction == "out" else None
        self._queue: asyncio.Queue[tuple[bytes, float, tuple[str, int]]] = asyncio.Queue(maxsize=QUEUE_SIZE)
        self._acks: dict[int, asyncio.Future[int]] = {}
        self._command_lock = asyncio.Lock()
        """one command in flight at a time: an ACK names only the command id, not the request"""
        self._params: dict[str, asyncio.Future[float]] = {}
        self._param_asked: dict[str, set[int]] = {}
        """the components a parameter request went to that have not said they lack it (PARAM_ERROR):
        one component's "no such parameter" ends the wait only when it was the last one asked"""
        self._param_types: dict[str, int] = {}
        self._param_owner: dict[str, int] = {}
        """which component serves each parameter: the autopilot's, or the simulated plant's
        (PLANT_COMPID, ``sitl --firmware``) for one the autopilot does not have"""
        self._plant_heard = False
        """the vehicle's system has a simulated plant's component (its heartbeat was heard)"""
        self._highres_seen = False
        self._ftp_reply: asyncio.Future[ftp.Packet] | None = None
        self._ftp_lock = asyncio.Lock()
        self.event_error = ""
        self.autopilot_version: str | None = None
        self.events: EventCatalogue | None = None
        """PX4's event texts, fetched from the vehicle at connection (None: events read as ids)"""
        self._connected = asyncio.Event()
        self._closed = False

    # --- transport -------------------------------------------------------------------------

    async def open(self) -> None:
        e = self.endpoint
        if e.kind == "tcp":
            tcp = TcpEndpoint(self._received, self._socket_error, self._stream_closed)
            try:
                await tcp.open(e.host, e.port)
            except (OSError, TimeoutError) as exc:
                why = getattr(exc, "strerror", None) or "no answer"
                raise LinkError(f"cannot connect to tcp://{e.host}:{e.port}: {why}. Is the autopilot running and "
                                "serving TCP there (ArduPilot SITL: 5760)?") from None
            self._transport, self._peer = tcp, tcp.peer
        elif e.kind == "serial":
            serial = SerialEndpoint(self._received, self._socket_error, self._stream_closed)
            try:
                serial.open(e.device, e.baud, e.flow_control)
            except OSError as exc:
                raise LinkError(f"cannot open {e.device}: {exc.strerror or exc}. Wired, and yours to open "
                                "(the dialout group)?") from None
            self._transport, self._peer = serial, serial.peer
        else:
            local = self.address if self.direction == "in" else ("0.0.0.0", 0)
            endpoint = UdpEndpoint(self._received, self._socket_error)
            try:
                endpoint.open(local)
            except OSError as exc:
                raise LinkError(f"cannot open UDP {local[0]}:{local[1]}: {exc.strerror or exc}") from None
            self._transport = endpoint
        self._send(self.mav.heartbeat_encode(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID,
                                             0, 0, mavlink.MAV_STATE_ACTIVE))

    async def close(self) -> None:
        self._closed = True
        if self._transport is not None:
            self._transport.close()
            self._transport = None
        for fut in [*self._acks.values(), *self._params.values()]:
            if not fut.done():
                fut.cancel()

    def _send(self, msg: Any) -> None:
        if self._transport is None or self._peer is None:
            return
        buf = msg.pack(self.mav)
        self._transport.sendto(buf, self._peer)
        self.stats["sent"] += 1
        if self.traffic is not None:
            self.traffic(buf)

    @property
    def rx_queue_depth(self) -> int:
        return self._queue.qsize()

    def _stream_closed(self) -> None:
        self.stats["stream_closed"] += 1  # TCP closed by the other end: nothing more will arrive

    def _socket_error(self, exc: OSError) -> None:
        self.stats["socket_errors"] += 1

    def _received(self, data: bytes, addr: tuple[str, int]) -> None:
        self.stats["received"] += 1
        if self._peer is not None and addr != self._peer and not self._surveying:
            self.stats["foreign_datagrams"] += 1
            return
        try:
            self._queue.put_nowait((data, time.monotonic(), addr))  # stamped on arrival, not when parsed
        except asyncio.QueueFull:
            self.stats["dropped_queue_full"] += 1

    # --- reading ---------------------------------------------------------------------------

    async def run(self, stop: asyncio.Event) -> None:
        """Parse everything queued at each wake-up. One message per wake-up would never drain a
        backlog while datagrams keep arriving (the event loop reads one per iteration), and the
        controller would then fly on telemetry that stays as old as the backlog (a 2 h soak at
        5x did: 0.75 vehicle-seconds behind for 6 s, and the vertical loop went unstable)."""
        heartbeat_next = 0.0
        queue = self._queue
        while not self._closed and not stop.is_set():
            item: tuple[bytes, float, tuple[str, int]] | None = None
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(0.2):  # no task per datagram, as wait_for makes
                    item = await queue.get()
            while item is not None:
                data, arrived, addr = item
                if self.traffic is not None:
                    self.traffic(data)
                self._parse(data, arrived, addr)
                self.rx_lag_s = lag = time.monotonic() - arrived
                if lag > self.rx_lag_max_s:
                    self.rx_lag_max_s = lag
                item = queue.get_nowait() if not queue.empty() else None
            if self._fresh:  # the tick for what came in runs now, on the whole of it
                self._tell()
            now = time.monotonic()
            if now >= heartbeat_next:
                self._send(self.mav.heartbeat_encode(mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
                                                     mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE))
                heartbeat_next = now + 1.0

    def _telemetry_in(self) -> None:
        self._fresh = True  # told once the queue is read (run): a datagram carries several frames

    def _parse(self, data: bytes, wall: float, addr: tuple[str, int] | None = None) -> None:
        parsed = parse_datagram(self.parser, data)
        if parsed.bad:
            self.stats["bad_data"] += parsed.bad
        check = self.signature_check
        for msg in parsed.messages:
            kind = msg.get_type()
            if check is not None:
                reason = check.verdict(msg)
                if reason is not None:
                    self.stats["signing_rejected"] += 1
                    self.signing_rejections[f"{reason} {kind}"] += 1
                    continue
            try:
                src, comp = _source(msg, kind)
                self.heard.frame(src, comp, addr, msg.get_seq())
                if self._peer is not None and addr != self._peer:  # udpin, connecting: another sender
                    self._stranger(kind, msg, src, comp, addr)
                    continue
                self._handle(kind, msg, wall, addr)
            except Exception:  # a malformed field must not stop the reader
                self.stats["handler_errors"] += 1

    def _stranger(self, kind: str, msg: Any, src: int, comp: int, addr: tuple[str, int] | None) -> None:
        """A frame from an address other than the vehicle's (udpin, while connecting): its heartbeat is
        heard (another autopilot, or a second claimant of ours); nothing else of it is believed."""
        self.stats["foreign_datagrams"] += 1
        if kind == "HEARTBEAT" and flavour_for(msg.autopilot) is not None:
            self.heard.heartbeat(src, comp, addr)

    def _handle(self, kind: str, msg: Any, wall: float, addr: tuple[str, int] | None = None) -> None:
        st = self.state
        src, comp = _source(msg, kind)
        if kind == "HEARTBEAT":
            flavour = flavour_for(msg.autopilot)
            if flavour is None:
                if st.sysid and src == st.sysid and comp == PLANT_COMPID:
                    self._plant_heard = True
                return  # a ground station or a component that is not an autopilot
            self.heard.heartbeat(src, comp, addr)
            if st.sysid == 0 and self.target.matches(src, comp):
                st.sysid, st.compid, st.autopilot = src, comp, flavour.name
                st.vehicle_type = msg.type
                self.flavour = flavour
                self._first_heartbeat = wall
                if self._peer is None and addr is not None:
                    self._peer = addr  # udpin: the chosen autopilot's address is the vehicle's
            if src != st.sysid or comp != st.compid:
                self.stats["foreign_heartbeats"] += 1
                return
            self._chosen_heartbeats += 1
            if flavour is not self.flavour or msg.type != st.vehicle_type:
                # the locked autopilot cannot change its kind: a forged or misrouted heartbeat
                self.stats["heartbeats_of_another_kind"] += 1
                return
            st.armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
            st.mode = flavour.mode_name(msg.custom_mode)
            st.offboard = st.mode in flavour.offboard_names
            st.failsafe = msg.system_status in (mavlink.MAV_STATE_CRITICAL, mavlink.MAV_STATE_EMERGENCY)
            st.wall_heartbeat = wall
            st.wall_last = wall
            if not self._connected.is_set():
                self._connected.set()
            return
        if st.sysid and src == st.sysid and comp == PLANT_COMPID and kind in ("PARAM_VALUE", "STATUSTEXT"):
            self._plant_message(kind, msg)  # the simulated plant's own component (sitl --firmware)
            return
        if st.sysid == 0 or src != st.sysid or comp != st.compid:
            # telemetry counts only from the autopilot's own component, not any component of its system
            self.stats["foreign_messages"] += 1
            return
        st.wall_last = wall
        handler = _HANDLERS.get(kind)
        if handler is not None:
            handler(self, msg, wall, comp)

    # --- the autopilot's messages, one handler each (_HANDLERS) ----------------------------

    def _on_attitude(self, msg: Any, wall: float, comp: int) -> None:
        self._sample(msg.time_boot_ms * 1e-3, wall, self.state.set_attitude, (msg.q1, msg.q2, msg.q3, msg.q4),
                     (msg.rollspeed, msg.pitchspeed, msg.yawspeed), wraps=True)

    def _on_position(self, msg: Any, wall: float, comp: int) -> None:
        self._sample(msg.time_boot_ms * 1e-3, wall, self.state.set_position, (msg.x, msg.y, msg.z),
                     (msg.vx, msg.vy, msg.vz), wraps=True)

    def _on_odometry(self, msg: Any, wall: float, comp: int) -> None:
        """Only its reset counter, placed at the newest believed stamp: the position comes from
        LOCAL_POSITION_NED (one stream), and ODOMETRY's time_usec never feeds the clock (PX4's on
        the plant runs up to 0.7 s ahead of its time_boot_ms)."""
        st = self.state
        if msg.frame_id in (mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_LOCAL_FRD) and math.isfinite(st.t):
            st.set_reset_counter(msg.reset_counter, st.t)

    def _on_highres_imu(self, msg: Any, wall: float, comp: int) -> None:
        if msg.fields_updated & ACCEL_UPDATED == ACCEL_UPDATED:
            self._highres_seen = True
            self._sample(msg.time_usec * 1e-6, wall, self.state.set_imu, (msg.xacc, msg.yacc, msg.zacc))

    def _on_scaled_imu(self, msg: Any, wall: float, comp: int) -> None:
        """An autopilot without HIGHRES_IMU: the first IMU's accelerometer, in milli-g."""
        if not self._highres_seen:
            g = 9.80665e-3
            self._sample(msg.time_boot_ms * 1e-3, wall, self.state.set_imu,
                         (msg.xacc * g, msg.yacc * g, msg.zacc * g), wraps=True)

    def _on_extended_sys_state(self, msg: Any, wall: float, comp: int) -> None:
        self.state.landed_state = msg.landed_state

    def _on_sys_status(self, msg: Any, wall: float, comp: int) -> None:
        prearm = mavlink.MAV_SYS_STATUS_PREARM_CHECK
        # ArduPilot sets the bit in "present" and "health"; PX4 v1.16 only ever in "health"
        if msg.onboard_control_sensors_present & prearm or self.flavour is PX4:
            self.state.armable = bool(msg.onboard_control_sensors_health & prearm)

    def _on_statustext(self, msg: Any, wall: float, comp: int) -> None:
        self.state.add_text(msg.severity, msg.text)

    def _on_event(self, msg: Any, wall: float, comp: int) -> None:
        """PX4's events (not in pymavlink's dialects): their text from the catalogue fetched at connection."""
        event = parse_event(_payload(msg))
        if event is not None:
            text = self.events.text(event) if self.events is not None else f"PX4 event 0x{event.id:08x}"
            self.state.add_text(event.severity, text)
            self.stats["events"] += 1

    def _on_ftp(self, msg: Any, wall: float, comp: int) -> None:
        if msg.target_system in (0, self.mav.srcSystem) and self._ftp_reply is not None \
                and not self._ftp_reply.done():
            self._ftp_reply.set_result(ftp.decode(bytes(msg.payload)))

    def _on_command_ack(self, msg: Any, wall: float, comp: int) -> None:
        """Only an answer addressed to us (0: broadcast, as some autopilots do) to a command in flight."""
        us = (self.mav.srcSystem, self.mav.srcComponent)
        if msg.target_system not in (0, us[0]) or msg.target_component not in (0, us[1]):
            self.stats["acks_not_for_us"] += 1
            return
        fut = self._acks.get(msg.command)
        if fut is None or fut.done():
            self.stats["acks_unasked"] += 1
            return
        if msg.result != mavlink.MAV_RESULT_IN_PROGRESS:
            fut.set_result(msg.result)

    def _on_autopilot_version(self, msg: Any, wall: float, comp: int) -> None:
        v = msg.flight_sw_version
        kinds = {0: "dev", 64: "alpha", 128: "beta", 192: "rc", 255: "official"}
        custom = bytes(msg.flight_custom_version).hex()[:16]
        self.autopilot_version = (f"{v >> 24 & 0xFF}.{v >> 16 & 0xFF}.{v >> 8 & 0xFF} "
                                  f"{kinds.get(v & 0xFF, v & 0xFF)} ({custom})")

    def _on_param_error(self, msg: Any, wall: float, comp: int) -> None:
        """ArduPilot 4.7+ answers a read of a parameter it does not have, instead of silence."""
        if msg.target_system in (0, self.mav.srcSystem):
            name = param_name(msg.param_id)
            fut, asked = self._params.get(name), self._param_asked.get(name, set())
            if fut is not None and not fut.done() and comp in asked:
                asked.discard(comp)
                self.stats["param_errors"] += 1
                if not asked or (asked == {PLANT_COMPID} and not self._plant_heard):
                    fut.set_result(math.nan)

    def _on_param_value(self, msg: Any, wall: float, comp: int) -> None:
        st = self.state
        name = param_name(msg.param_id)
        if name not in st.params and len(st.params) >= MAX_PARAMS:
            self.stats["params_dropped"] += 1  # a vehicle, or someone posing as one, inventing names
            return
        value = decode_value(msg.param_value, msg.param_type, bytewise=self.flavour is PX4)
        st.params[name] = value
        if not self.params_complete and 0 < msg.param_count <= len(st.params):
            self.params_complete = True
        self._param_types[name] = msg.param_type
        self._param_owner[name] = st.compid
        fut = self._params.get(name)
        if fut is not None and not fut.done():
            fut.set_result(value)

    def _plant_message(self, kind: str, msg: Any) -> None:
        """The plant's component: its SIM_* parameters (REAL32, never a name the autopilot has) and
        what it says (an injected fault)."""
        if kind == "STATUSTEXT":
            self.state.add_text(msg.severity, msg.text)
            return
        name = param_name(msg.param_id)
        if name not in self._param_owner and len(self._param_owner) >= MAX_PARAMS:
            self.stats["params_dropped"] += 1
            return
        if self._param_owner.get(name) == self.state.compid:
            return  # the autopilot's parameter: never the plant's
        self._param_owner[name] = PLANT_COMPID
        self._param_types[name] = MAV_PARAM_TYPE_REAL32
        value = float(msg.param_value)
        self.state.params[name] = value
        fut = self._params.get(name)
        if fut is not None and not fut.done():
            fut.set_result(value)

    # --- connection ----------------------------------------------------------------------

    async def wait_connected(self, timeout_s: float, position_wait_s: float = 0.0) -> None:
        """Heartbeat, then navigation telemetry, all within ``timeout_s`` of wall time from now; up
        to ``position_wait_s`` more for a position if attitude already flows
        (:class:`~companion.link.base.ConnectWait`). The streams are asked for meanwhile, best
        effort: requests a peer never answers are dropped at the deadline."""
        where = self.endpoint.url
        start = time.monotonic()
        hinted = False
        while not self.stats["received"] and time.monotonic() - start < timeout_s:
            if not hinted and time.monotonic() - start >= NOTHING_HEARD_S:
                hinted = True  # say what to check early, and go on listening (a vehicle may boot later)
                if self.progress is not None:
                    self.progress(self._silence_hint(NOTHING_HEARD_S) + f"; still listening, up to {timeout_s:g} s")
            await asyncio.sleep(0.05)
        if not self.stats["received"]:
            raise LinkError(self._silence_hint(timeout_s))
        try:
            await asyncio.wait_for(self._connected.wait(), max(start + timeout_s - time.monotonic(), 0.05))
        except TimeoutError:
            beats = {k.rsplit(" ", 1)[0]: n for k, n in self.signing_rejections.items() if k.endswith(" HEARTBEAT")}
            if beats:
                assert self.signature_check is not None
                hint = {"wrong key": f": does the vehicle have our key (fingerprint "
                                     f"{fingerprint(self.signature_check.key)})?",
                        "unsigned": ": the vehicle does not sign (give it the key, or drop ours)",
                        "stale timestamp": ": compare both machines' clocks (UTC)",
                        "future timestamp": ": compare both machines' clocks (UTC)"}.get(max(beats, key=beats.get), "")
                raise LinkError(f"heartbeats from {where} refused: {describe_rejections(beats)}{hint}") from None
            absent = connection_problem(self.target, self.heard, None)
            if absent is not None and self.heard.systems():
                raise LinkError(f"{absent} (within --connect-timeout {timeout_s:g} s at {where})") from None
            if self.signature_check is None:
                hint = ("; if the vehicle uses MAVLink signing, give its key "
                        "(--signing-key-file or $MAVLINK_SIGNING_KEY)")
            else:
                hint = (f"; a signing vehicle ignores a wrong key: does it have ours (fingerprint "
                        f"{fingerprint(self.signature_check.key)})?")
            raise LinkError(f"{where} answers, but with no autopilot heartbeat within {timeout_s:g} s (a ground "
                            f"station or another program on that port?){hint}") from None
        # every autopilot on the link is heard before anything is addressed to the chosen one
        survey_end = min(self._first_heartbeat + SURVEY_S, start + timeout_s)
        while time.monotonic() < survey_end and not self._surveyed():
            await asyncio.sleep(0.01)
        self._refuse_if_not_ours()
        self.progress_line(self._heard_line())
        # the requests go out while the wait for telemetry (and its progress lines) runs
        asking = asyncio.create_task(self._ask_for_telemetry())
        try:
            await self._wait_navigation(ConnectWait(timeout_s, position_wait_s), start)
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(asking, max(start + timeout_s - time.monotonic(), 0.0))
        finally:
            if not asking.done():
                asking.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await asking
        self._refuse_if_not_ours()  # telemetry flows: two senders' sequence runs show by now
        self._surveying = False
        # what is not telemetry, once telemetry flows (each bounded on its own: a few seconds at most)
        if self.flavour is not ARDUPILOT:
            await self._load_events()
        if not self._highres_seen:  # an autopilot without HIGHRES_IMU: its SCALED_IMU, if it has one
            await self.command_long(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_SCALED_IMU,
                                    1e6 / STREAM_RATES_HZ[mavlink.MAVLINK_MSG_ID_HIGHRES_IMU], require_ack=False,
                                    attempts=2)
            await asyncio.sleep(0.3)

    def _surveyed(self) -> bool:
        """Heard enough of the chosen autopilot to know whether another claims it: two of its own
        heartbeat periods and SURVEY_FRAMES of its frames (two senders' runs each add several)."""
        st = self.state
        frames = sum(s.frames for (si, ci, _), s in self.heard.streams.items() if (si, ci) == (st.sysid, st.compid))
        return self._chosen_heartbeats >= SURVEY_HEARTBEATS and frames >= SURVEY_FRAMES

    def _refuse_if_not_ours(self) -> None:
        """LinkError if this link must not be flown: two claimants of the locked identity, or
        (without a target) more than one autopilot (:func:`connection_problem`)."""
        problem = connection_problem(self.target, self.heard, (self.state.sysid, self.state.compid))
        if problem is not None:
            self.stats["identity_refused"] += 1
            raise LinkError(problem)

    def _heard_line(self) -> str:
        others = [s for s in self.heard.systems() if s != self.state.sysid]
        return (f"flying system {self.state.sysid} component {self.state.compid} ({self.target.describe()})"
                + (f"; ignoring systems {', '.join(map(str, others))} on this link" if others else ""))

    def progress_line(self, text: str) -> None:
        if self.progress is not None:
            self.progress(text)

    async def _ask_for_telemetry(self) -> None:
        """The streams the controller needs, the autopilot's version and every parameter (for the
        flight record: they arrive while the mission flies)."""
        assert self.flavour is not None
        if self.flavour is ARDUPILOT:
            await self._prepare_ardupilot()
        for msg_id, hz in STREAM_RATES_HZ.items():
            await self.command_long(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz, require_ack=False)
        self._send(self.mav.param_request_list_encode(self.state.sysid, self.state.compid))
        await self.command_long(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
                                require_ack=False, attempts=2)

    def _silence_hint(self, after_s: float) -> str:
        """What to check when nothing at all arrived in ``after_s``: the endpoint first, then signing."""
        why = nothing_heard(self.endpoint, after_s)
        if self.endpoint.kind == "udpout":  # a signing vehicle ignores us, and is silent too
            why += (". Last: a vehicle that uses MAVLink signing stays silent to a companion without its key "
                    "(give its key: --signing-key-file)" if self.signature_check is None else
                    f". Last: a signing vehicle ignores a wrong key: does it have ours (fingerprint "
                    f"{fingerprint(self.signature_check.key)})?")
        return why

    async def fetch_file(self, path: str, timeout_s: float = 1.0, max_bytes: int = 4 << 20) -> bytes:
        """A file from the autopilot over MAVLink FTP (LinkError if it cannot be read)."""
        async with self._ftp_lock:
            seq = 0

            async def request(opcode: int, session: int = 0, offset: int = 0, data: bytes = b"",
                              size: int | None = None) -> ftp.Packet:
                nonlocal seq
                for _ in range(3):
                    seq += 1
                    self._ftp_reply = asyncio.get_running_loop().create_future()
                    self._send(self.mav.file_transfer_protocol_encode(
                        0, *self._vehicle(),
                        list(ftp.encode(seq, session, opcode, offset, data, size))))
                    try:
                        return await asyncio.wait_for(self._ftp_reply, timeout_s)
                    except TimeoutError:
                        continue
                raise LinkError(f"MAVLink FTP: no answer reading {path}")

            opened = await request(ftp.OPEN_FILE_RO, data=path.encode() + b"\x00")
            if opened.opcode != ftp.ACK:
                raise LinkError(f"MAVLink FTP: cannot open {path}")
            session, out = opened.session, bytearray()
            try:
                while len(out) < max_bytes:
                    got = await request(ftp.READ_FILE, session, len(out), size=ftp.DATA_MAX)
                    if got.opcode == ftp.NAK:
                        if got.data[:1] == bytes([ftp.ERR_EOF]):
                            break
                        raise LinkError(f"MAVLink FTP: reading {path} failed")
                    if not got.data:
                        break
                    out += got.data
            finally:
                with contextlib.suppress(LinkError):
                    await request(ftp.TERMINATE_SESSION, session)
            return bytes(out)

    async def _load_events(self) -> None:
        """PX4's event catalogue, so refusals read as text (best effort: a few seconds at most)."""
        try:
            blob = await asyncio.wait_for(self.fetch_file("/etc/extras/all_events.json.xz"), 8.0)
            self.events = EventCatalogue.from_bytes(blob)
            self.stats["event_texts"] = len(self.events)
        except (LinkError, TimeoutError, ValueError, OSError) as exc:
            self.stats["event_texts_unavailable"] += 1
            self.event_error = str(exc) or type(exc).__name__

    async def _prepare_ardupilot(self) -> None:
        """ArduPilot sends only HEARTBEAT and STATUSTEXT until streams are asked for."""
        self._send(self.mav.request_data_stream_encode(self.state.sysid, self.state.compid,
                                                       mavlink.MAV_DATA_STREAM_ALL, 10, 1))

    # --- commands --------------------------------------------------------------------------

    async def command_long(self, command: int, *params: float, require_ack: bool = True,
                           attempts: int | None = None) -> int:
        """Send until acknowledged (at most ``attempts`` times); the MAV_RESULT (LinkError if never
        acknowledged). Commands queue behind each other (one in flight)."""
        async with self._command_lock:
            return await self._command_long(command, *params, require_ack=require_ack, attempts=attempts)

    async def _command_long(self, command: int, *params: float, require_ack: bool = True,
                            attempts: int | None = None) -> int:
        p = list(params) + [0.0] * (7 - len(params))
        target = self._vehicle()
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[int] = loop.create_future()
        self._acks[command] = fut
        try:
            for attempt in range(attempts or self.command_retries):
                self._send(self.mav.command_long_encode(*target, command, attempt, *p))
                try:
                    return await asyncio.wait_for(asyncio.shield(fut), self.command_timeout_s)
                except TimeoutError:
                    continue
        finally:
            self._acks.pop(command, None)
        if not require_ack:
            return -1
        raise LinkError(f"command {command} was not acknowledged after {attempts or self.command_retries} tries")

    async def _expect(self, command: int, *params: float, what: str) -> None:
        before = self.state.texts_seen
        result = await self.command_long(command, *params)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            reason = await self._refusal_reason(before)
            raise LinkError(f"{what} refused ({result_text(result)})"
                            f"{': ' + reason if reason else ''}")

    async def _set_mode(self, mode: tuple[int, int], what: str) -> None:
        await self._expect(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, *mode, what=what)

    async def set_arming_mode(self) -> None:
        assert self.flavour is not None
        mode = ARDUPILOT.offboard_mode if self.flavour is ARDUPILOT else PX4.hold_mode
        await self._set_mode(mode, "the arming mode")

    async def arm(self) -> None:
        await self._expect(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, what="arming")

    async def disarm(self, force: bool = False) -> None:
        await self._expect(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, FORCE_ARM_DISARM if force else 0,
                           what="disarming")

    async def takeoff(self, altitude_m: float) -> None:
        if self.flavour is PX4:
            if await self.get_param("MIS_TAKEOFF_ALT") is not None:
                await self.set_param("MIS_TAKEOFF_ALT", altitude_m)
            await self._expect(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan,
                               what="take-off")
        else:
            await self._expect(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, altitude_m, what="take-off")

    async def start_offboard(self) -> None:
        assert self.flavour is not None
        await self._set_mode(self.flavour.offboard_mode, "offboard mode")

    async def hold(self, attempts: int | None = None) -> None:
        assert self.flavour is not None
        result = await self.command_long(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                                         *self.flavour.hold_mode, attempts=attempts)
        if result != mavlink.MAV_RESULT_ACCEPTED:
            raise LinkError(f"hold mode refused ({result_text(result)})")

    async def land(self) -> None:
        assert self.flavour is not None
        await self._set_mode(self.flavour.land_mode, "land mode")

    # --- setpoints and parameters ----------------------------------------------------------

    def _vehicle(self) -> tuple[int, int]:
        """The locked autopilot's system and component: everything addressed goes there, and
        nothing is addressed before there is one (never a default system 1)."""
        st = self.state
        if not st.sysid:
            raise LinkError("no autopilot chosen yet: nothing is addressed before one is")
        return st.sysid, st.compid

    def send_attitude_target(self, q: Quat, body_rates_rad_s: Vec3, thrust: float, type_mask: int = 0,
                             stamp_s: float | None = None) -> None:
        t_ms = self._setpoint_ms(stamp_s)
        self._send(self.mav.set_attitude_target_encode(
            t_ms, *self._vehicle(), type_mask, [float(c) for c in q],
            float(body_rates_rad_s[0]), float(body_rates_rad_s[1]), float(body_rates_rad_s[2]), float(thrust)))
        self.stats["setpoints"] += 1

    def send_position_target(self, pos_ned_m: Vec3, vel_ned_m_s: Vec3, accel_ned_m_s2: Vec3, yaw_rad: float,
                             stamp_s: float | None = None) -> None:
        t_ms = self._setpoint_ms(stamp_s)
        self._send(self.mav.set_position_target_local_ned_encode(
            t_ms, *self._vehicle(), mavlink.MAV_FRAME_LOCAL_NED, POSITION_TARGET_MASK,
            *(float(c) for c in (*pos_ned_m, *vel_ned_m_s, *accel_ned_m_s2)), float(yaw_rad), 0.0))
        self.stats["setpoints"] += 1

    def send_debug(self, t_s: float, vectors: dict[str, Vec3], values: dict[str, float]) -> None:
        t_us, t_ms = int(max(t_s, 0.0) * 1e6), boot_ms(t_s)
        for name, v in vectors.items():
            self._send(self.mav.debug_vect_encode(name.encode()[:10], t_us, *(float(c) for c in v)))
        for name, x in values.items():
            self._send(self.mav.named_value_float_encode(t_ms, name.encode()[:10], float(x)))

    async def _param(self, name: str, send: Any, asked: set[int], timeout_s: float = 1.0, retries: int = 3
                     ) -> float | None:
        """Send (and resend) a request about ``name`` to the components ``asked`` until one answers
        with its value, or every one of them has answered that it has no such parameter."""
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[float] = loop.create_future()
        self._params[name] = fut
        self._param_asked[name] = set(asked)
        try:
            for _ in range(retries):
                send()
                try:
                    value = await asyncio.wait_for(asyncio.shield(fut), timeout_s)
                except TimeoutError:
                    continue
                return None if math.isnan(value) else value  # NaN: PARAM_ERROR, no such parameter
        finally:
            self._params.pop(name, None)
            self._param_asked.pop(name, None)
        return None

    async def get_param(self, name: str, timeout_s: float = 1.0, retries: int = 3) -> float | None:
        """The parameter's value from whichever component serves it: asked of the autopilot and,
        until its owner is known, of a simulated plant's component too (the first answer wins;
        the plant never serves a name the autopilot has)."""
        sysid, compid = self._vehicle()
        owner = self._param_owner.get(name)
        targets = [owner] if owner is not None else [compid, PLANT_COMPID]

        def ask() -> None:
            for compid in targets:
                self._send(self.mav.param_request_read_encode(sysid, compid, name.encode("ascii"), -1))
        return await self._param(name, ask, set(targets), timeout_s, retries)

    async def set_param(self, name: str, value: float) -> float:
        """Set in the parameter's own type (known from a read: PX4 refuses a REAL32 write to an
        integer parameter, and encodes integers bytewise)."""
        if name not in self._param_types and await self.get_param(name) is None:
            raise LinkError(f"parameter {name}: the autopilot has no such parameter")
        sysid, compid = self._vehicle()
        owner = self._param_owner.get(name, compid)
        target = (sysid, owner)
        ptype = self._param_types.get(name, MAV_PARAM_TYPE_REAL32)
        try:
            wire = encode_value(value, ptype, bytewise=self.flavour is PX4 and owner != PLANT_COMPID)
        except ValueError as exc:
            raise LinkError(f"parameter {name}: {exc}") from None
        echoed = await self._param(name, lambda: self._send(self.mav.param_set_encode(
            *target, name.encode("ascii"), wire, ptype)), {owner}, retries=self.command_retries)
        if echoed is None:
            raise LinkError(f"parameter {name} was not acknowledged")
        return echoed


def _payload(msg: Any) -> bytes:
    """The payload of a frame pymavlink could not decode (MAVLink 2: 10-byte header, 2-byte CRC)."""
    raw = bytes(msg.get_msgbuf())
    start = 10 if raw[:1] == b"\xfd" else 6
    return raw[start:start + raw[1]]


def _source(msg: Any, kind: str) -> tuple[int, int]:
    """Sending system and component; read from the frame for messages pymavlink could not decode
    (it leaves their header unset)."""
    if kind.startswith("UNKNOWN_"):
        raw = bytes(msg.get_msgbuf())
        return (raw[5], raw[6]) if raw[:1] == b"\xfd" else (raw[3], raw[4])
    return msg.get_srcSystem(), msg.get_srcComponent()


def nothing_heard(e: Endpoint, after_s: float) -> str:
    """What to check when nothing at all arrived."""
    if e.kind == "udpout":
        return (f"nothing heard from {e.url} in {after_s:g} s: is the vehicle running, listening on port {e.port}? "
                f"A vehicle that sends first (PX4 SITL sends to 14540) needs udpin://0.0.0.0:PORT instead")
    if e.kind == "udpin":
        return (f"nothing arrived on {e.url} in {after_s:g} s: is the vehicle running, and sending to port "
                f"{e.port}? A vehicle that listens (the bundled one) needs udp://HOST:PORT instead")
    if e.kind == "tcp":
        return f"connected to {e.url}, but nothing arrived in {after_s:g} s: is that a MAVLink port?"
    return (f"nothing arrived on {e.device} in {after_s:g} s: wired (TX to RX), the same baud as the autopilot's "
            f"port ({e.baud}), and MAVLink enabled on it (PX4 MAV_1_CONFIG, ArduPilot SERIAL2_PROTOCOL=2)?")


_HANDLERS: dict[str, Callable[[PymavlinkLink, Any, float, int], None]] = {
    "ATTITUDE_QUATERNION": PymavlinkLink._on_attitude,
    "LOCAL_POSITION_NED": PymavlinkLink._on_position,
    "ODOMETRY": PymavlinkLink._on_odometry,
    "HIGHRES_IMU": PymavlinkLink._on_highres_imu,
    "SCALED_IMU": PymavlinkLink._on_scaled_imu,
    "EXTENDED_SYS_STATE": PymavlinkLink._on_extended_sys_state,
    "SYS_STATUS": PymavlinkLink._on_sys_status,
    "STATUSTEXT": PymavlinkLink._on_statustext,
    f"UNKNOWN_{MSG_ID_EVENT}": PymavlinkLink._on_event,
    "FILE_TRANSFER_PROTOCOL": PymavlinkLink._on_ftp,
    "COMMAND_ACK": PymavlinkLink._on_command_ack,
    "AUTOPILOT_VERSION": PymavlinkLink._on_autopilot_version,
    "PARAM_ERROR": PymavlinkLink._on_param_error,
    "PARAM_VALUE": PymavlinkLink._on_param_value,
}
"""what the chosen autopilot's own component says, by message name; anything else is ignored"""
