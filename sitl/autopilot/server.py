"""The simulated vehicle on the wire: MAVLink 2 over UDP, paced in real time or faster.

One asyncio task steps the autopilot at the plant rate, keeping simulated time at
``speedup`` times wall time (if the machine stalls it or cannot keep up, the simulated world
pauses rather than racing to catch up, and the overrun is counted), and sends each telemetry
stream when it is due in simulated time.
Datagrams are handled between steps as they arrive: each is parsed on its own (a truncated
packet cannot swallow the next one), every message is checked for its target, and anything
malformed, oversized, mis-addressed or out of range is dropped and counted — never raised.

Clients do not interfere (:mod:`sitl.autopilot.peers`): each has its own stream rates, its own paced
parameter list and its own request budget; answers go to the client that asked (STATUSTEXT,
HEARTBEAT-rate streams and parameter changes go to all); a flood from one address is dropped
unparsed beyond its budget; the controller's address is never evicted from the peer table.

Incoming wire messages become :class:`~sitl.autopilot.logic.Autopilot` calls here; outgoing state
becomes messages in :mod:`sitl.autopilot.telemetry`. Each plant step runs under
:class:`~sitl.autopilot.guard.StepGuard`: a numerical fault or a loss of control ends in a defined
failsafe, never in the loop's death.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from pymavlink.dialects.v20 import ardupilotmega as mavlink
# commands answered by the server itself (the rest go to the autopilot)
from pymavlink.dialects.v20.ardupilotmega import (
    MAV_CMD_GET_HOME_POSITION,
    MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
    MAV_CMD_REQUEST_MESSAGE,
    MAV_CMD_SET_MESSAGE_INTERVAL,
)

from companion.control import quaternion as quat
from companion.control.vector import Vec3
from companion.mavlink import ftp
from companion.mavlink.events import CATALOGUE_PATH, encode_event_frame
from companion.mavlink.framing import Payload, pack_message, pack_payload
from companion.mavlink.signing import VEHICLE_ACCEPTS_UNSIGNED, SignatureCheck, enable_signing, is_signed
from companion.mavlink.udp import UdpEndpoint
from companion.mavlink.wire import new_parser, parse_datagram

from ..percentiles import percentiles_ms
from .events import catalogue, event_id
from .guard import StepGuard
from .logic import Autopilot, MavResult, Severity
from .pacing import REPEAT_WALL_S, Pass, Wait, WorldPacing
from .shaping import NAN3, TrajectoryTarget, body_to_ned
from .parameters import ParamTable, build_parameters
from .peers import MAX_PEERS, REQUESTS_PER_S, Address, Bucket, InflowGuard, Peer, PeerTable
from .telemetry import DEFAULT_RATES_HZ, GeoOrigin, Message, Telemetry

__all__ = ["ServerConfig", "MavlinkServer", "MAX_PEERS", "PX4_LISTEN", "PX4_PEER", "trajectory_target"]

MAX_DATAGRAM = 4096
DATAGRAM_BYTES = 1400
"""the frames sent to one client in one stretch of the loop share datagrams of at most this many
bytes (an Ethernet MTU less the IP and UDP headers, with room to spare), as ArduPilot's UDP links
pack whole frames (companion/mavlink/udp.py)"""
MAX_REASONS = 64
"""distinct rejection reasons kept by name; the rest are counted as "other" (a fuzzer or an
attacker must not grow the vehicle's memory with made-up parameter names or command ids)"""
PARAMS_PER_STEP = 2
"""parameter values sent to one client listing them, per plant step (a repeated request restarts
nothing and adds nothing)"""
PARAM_VALUES_PER_S = 200.0
"""parameter values sent to all listing clients together, per wall second (their lists take turns;
one list of 45 takes 0.23 s): the cost of answering lists is bounded in the CPU time it takes,
whatever the speed-up and however many clients ask"""
MAX_STREAM_HZ = 250.0
"""no stream faster than this (simulated Hz; a faster SET_MESSAGE_INTERVAL is clamped to it)"""
NEWCOMER_STREAMS_PER_SIM_S = 400.0
"""stream messages per simulated second shared by all peers that are not protected (sitl.autopilot.peers:
not configured, not the controller, fewer than 3 datagrams or silent for 5 s); the protected get
all of theirs. A churn of addresses, each a peer with the default streams (380/s), would otherwise
cost the vehicle one send per message per address"""
MAX_PEER_STREAMS_HZ = 600.0
"""the most messages per simulated second one client's streams may add up to (the defaults: 380);
a SET_MESSAGE_INTERVAL beyond it is denied"""
DATAGRAMS_PER_SIM_S = 200.0
"""the datagram budget of one source address, per simulated second of the speed-up (a companion
sends about 110: setpoints at 100 Hz and a heartbeat); the controller's address is exempt"""
REQUESTS = frozenset({"COMMAND_LONG", "COMMAND_INT", "PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET",
                      "PING", "TIMESYNC", "REQUEST_DATA_STREAM", "MISSION_REQUEST_LIST", "LOG_REQUEST_LIST",
                      "SERIAL_CONTROL", "MISSION_COUNT", "MISSION_CLEAR_ALL"})
"""messages that cost an answer: each client's are limited (sitl.autopilot.peers.REQUESTS_PER_S)"""


PX4_LISTEN = ("127.0.0.1", 14580)
"""where PX4 SITL's onboard (API) link listens (instance 0: ``mavlink start -u 14580 -o 14540``)"""
PX4_PEER = ("127.0.0.1", 14540)
"""where PX4 SITL sends that link: MAVSDK's and the companion's ``udpin://0.0.0.0:14540``"""


@dataclass
class ServerConfig:
    listen: tuple[str, int] = PX4_LISTEN
    peers: tuple[tuple[str, int], ...] = ()
    """addresses to send to from the start (clients that listen, e.g. MAVSDK's udpin://)"""
    speedup: float = 1.0
    sysid: int = 1
    compid: int = 1
    origin: GeoOrigin = field(default_factory=GeoOrigin)
    rates_hz: dict[int, float] = field(default_factory=lambda: dict(DEFAULT_RATES_HZ))
    max_catchup_wall_s: float = 0.05
    """a delay of the loop (a busy host) up to this many wall seconds is caught up by stepping
    back to back; a longer one is skipped (the world pauses), so a client never sees a burst of
    vehicle time its loop cannot follow. It matches the companion's clock, which re-anchors after
    50 ms of silence: a pause it does not see as one would look like telemetry turning old."""
    wait_for_setpoints_s: float = 0.0
    """0: off. Otherwise, while the vehicle flies a companion's setpoint stream and the newest
    setpoint is older than this many *simulated* seconds, the world waits (up to
    ``max_wait_wall_s`` of wall time) and repeats its newest attitude and position every 20 ms of
    wall time, clock stopped. A setpoint's age counts from the telemetry stamp it carries in
    ``time_boot_ms`` (the companion's does; else from its arrival), so a companion that still sends
    but is starved of CPU and acting on old telemetry is waited for too. A companion stalled by a
    busy host (a process descheduled for 0.3 s is 1.2 simulated seconds at 4x) then finds the
    world where it left it, instead of a vehicle that flew on without it. The simulator's
    counterpart of PX4's lockstep; a real vehicle never waits, so tests of link outages leave it
    off. Counted: ``setpoint_waits``, ``waited_ms``."""
    max_wait_wall_s: float = 1.0
    """after this long the stream is taken as gone, not late: time runs on (to the failsafe).
    Counted only while this process is awake (a stall of the whole machine adds one loop pass)."""
    lockstep_period_s: float = 0.0
    """0: off. Otherwise **lockstep**: while the vehicle flies a companion's stream, the world advances
    only as setpoints arrive — each setpoint, stamped with the telemetry it was computed from, lets
    it run to that stamp plus one period, where it stops and sends its attitude and IMU at once, so
    the companion's next tick has the state it waits for (PX4 and its simulators work this way).
    Host load then changes how long a flight takes, not what it measures. ``speedup`` stays the
    upper bound; a stream gone for ``max_wait_wall_s`` (awake) hands time back to the failsafes."""
    signing_key: bytes | None = None
    """MAVLink 2 signing: sign everything sent, and act only on frames signed with this key"""
    boot_time_s: float = 0.0
    """how long the vehicle had been up when the simulation started [s]: every stamp sent starts
    there (``time_boot_ms`` wraps 2^32 ms after boot, 49.7 days; ``time_usec`` runs on)"""


FORWARDED = frozenset({"NAMED_VALUE_FLOAT", "NAMED_VALUE_INT", "DEBUG_VECT", "DEBUG"})
"""messages for the ground station, routed on as an autopilot does"""
FORWARD_PER_S = 100
"""routed messages one sender may have forwarded per vehicle second (:meth:`MavlinkServer._forward`)"""


class MavlinkServer:
    """MAVLink endpoint of one :class:`Autopilot`; :meth:`run` until ``stop`` is set."""

    def __init__(self, ap: Autopilot, config: ServerConfig | None = None) -> None:
        self.ap = ap
        self.config = cfg = config or ServerConfig()
        ap.origin_alt_m = cfg.origin.alt_m
        self.mav = mavlink.MAVLink(None, srcSystem=cfg.sysid, srcComponent=cfg.compid)
        self.parser = new_parser()
        autopilot = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA if ap.ardupilot else mavlink.MAV_AUTOPILOT_PX4
        self.telemetry = Telemetry(ap, self.mav, cfg.origin, autopilot, int(round(cfg.boot_time_s * 1000.0)))
        self.params: ParamTable = build_parameters(ap)
        self.guard = StepGuard(ap)
        """steps the autopilot: a numerical fault or a loss of control ends in a defined failsafe"""
        self.stats: Counter[str] = Counter()
        self.rejections: Counter[str] = Counter()
        self.signing_rejections: Counter[str] = Counter()
        """frames dropped by the signature check, by reason and message name"""
        self.signature_check: SignatureCheck | None = None
        if cfg.signing_key is not None:
            enable_signing(self.mav, cfg.signing_key)
            self.signature_check = SignatureCheck(cfg.signing_key, allow_unsigned=VEHICLE_ACCEPTS_UNSIGNED)
        self._signing_reported: set[str] = set()
        # ArduCopter sends only HEARTBEAT (and STATUSTEXT) until a client asks for streams
        rates = {mavlink.MAVLINK_MSG_ID_HEARTBEAT: 1.0} if ap.ardupilot else cfg.rates_hz
        self.peers = PeerTable({m: 1.0 / hz for m, hz in rates.items() if hz > 0}, cfg.peers)
        """who gets telemetry, each at its own rates (sitl.autopilot.peers)"""
        self.inflow = InflowGuard(DATAGRAMS_PER_SIM_S * max(cfg.speedup, 1.0), DATAGRAMS_PER_SIM_S)
        self._non_peer_requests = Peer(("", 0), {}, {}).requests
        """one request budget shared by every address the full peer table refused"""
        self._source: Address | None = None
        """the address of the datagram being handled (answers go there)"""
        self._peer: Peer | None = None
        """its peer (None: not in the table)"""
        self._param_queue: dict[Address, None] = {}
        """peers with a parameter list in progress, in turn order"""
        self._param_budget = Bucket(PARAM_VALUES_PER_S, 2.0 * PARAMS_PER_STEP)
        self._newcomer_streams = Bucket(NEWCOMER_STREAMS_PER_SIM_S * cfg.speedup, 100.0)
        self.transport: UdpEndpoint | None = None
        self.pacing = WorldPacing(cfg.speedup, ap.dt, cfg.lockstep_period_s, cfg.wait_for_setpoints_s,
                                  cfg.max_wait_wall_s, cfg.max_catchup_wall_s, self.stats)
        """when the world may step (sitl.autopilot.pacing)"""
        self.setpoint_age_s: deque[float] = deque(maxlen=100_000)
        """vehicle seconds from a setpoint's telemetry stamp to its arrival, the latest ones"""
        self.setpoint_age_max_s = 0.0
        """the same, the largest since start"""
        self._next_due = 0.0
        self._last_warning: dict[str, float] = {}
        self._setpoint_arrived = asyncio.Event()
        self._waiting = False
        """the run task waits for a setpoint (:meth:`_after_datagrams` may step the world)"""
        self._pending_pass: tuple[Pass, float] | None = None
        """a pass that yielded in a catch-up: its plan and wall clock (the next pass goes on with it)"""
        self._setpoint_new = False
        """a setpoint arrived while the run task waited (:meth:`_after_datagrams` acts on it)"""
        self._pass_error: Exception | None = None
        self._stop: asyncio.Event | None = None
        self._duration_s: float | None = None
        self._last_expire = 0.0
        self._forwarded: dict[tuple[str, int], tuple[float, int]] = {}
        self._event_seq = 0
        self._catalogue = catalogue()
        self._handlers: dict[str, Callable[[Any], None]] = {
            "COMMAND_LONG": self._command_long,
            "COMMAND_INT": self._command_int,
            "SET_ATTITUDE_TARGET": self._set_attitude_target,
            "SET_POSITION_TARGET_LOCAL_NED": self._set_position_target,
            "PARAM_REQUEST_LIST": self._param_request_list,
            "PARAM_REQUEST_READ": self._param_request_read,
            "PARAM_SET": self._param_set,
            "PING": self._ping,
            "TIMESYNC": self._timesync,
            "REQUEST_DATA_STREAM": self._request_data_stream,
            "MISSION_REQUEST_LIST": self._mission_request_list,
            "FILE_TRANSFER_PROTOCOL": self._file_transfer,
            "LOG_REQUEST_LIST": self._log_request_list,
            "SET_POSITION_TARGET_GLOBAL_INT": self._set_position_target_global,
            "MISSION_COUNT": self._mission_count,
            "MISSION_CLEAR_ALL": self._mission_clear_all,
            "SERIAL_CONTROL": self._serial_control,
        }
        self._link_commands: dict[int, Callable[[Any, int, tuple[float, ...]], None]] = {
            MAV_CMD_SET_MESSAGE_INTERVAL:
                lambda msg, cmd, p: self._ack(msg, cmd, self._set_message_interval(p[0], p[1])),
            MAV_CMD_REQUEST_MESSAGE: lambda msg, cmd, p: self._request_message(msg, cmd, p[0]),
            MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
                lambda msg, cmd, p: self._request_message(msg, cmd, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION),
            MAV_CMD_GET_HOME_POSITION:
                lambda msg, cmd, p: self._request_message(msg, cmd, mavlink.MAVLINK_MSG_ID_HOME_POSITION),
        }
        """commands the server answers itself: message rates and one-off messages"""

    # --- sending -------------------------------------------------------------------------

    def _pack(self, msg: Message, peer: Peer | None = None) -> bytes:
        """The frame, numbered in ``peer``'s own sequence (a client that is no peer: the vehicle's
        shared one). ``pack`` alone does not advance the number; a receiver uses it to see loss and
        to tell two senders apart, so each client sees an unbroken count, whatever the others get."""
        mav = self.mav
        seq = mav.seq if peer is None else peer.seq
        if mav.signing.sign_outgoing:  # the signature needs pymavlink's link state
            if isinstance(msg, Payload):
                msg = msg.message()
            shared, mav.seq = mav.seq, seq
            buf = msg.pack(mav)
            mav.seq = shared
        elif isinstance(msg, Payload):
            buf = pack_payload(msg, seq, mav.srcSystem, mav.srcComponent)
        else:
            buf = pack_message(msg, seq, mav.srcSystem, mav.srcComponent)
        if peer is None:
            mav.seq = (seq + 1) % 256
        else:
            peer.seq = (seq + 1) % 256
        return buf

    def _deliver(self, to: Iterable[Peer | Address], payload: Message | bytes,
                 count: bool = True) -> None:
        """The way out (the streams' tick, on the hot path, packs and sends the same way itself):
        ``payload`` to each of ``to``. A message is packed in each peer's own
        sequence (an address that is no peer: the shared one); a frame packed elsewhere (an event, a
        frame forwarded) goes as it is. ``count``: one more in ``sent`` however many receive it
        (telemetry counts a message once when it encodes it)."""
        if self.transport is None:
            return
        sendto = self.transport.sendto
        frame = payload if isinstance(payload, bytes) else None
        any_sent = False
        for dest in to:
            peer, addr = (dest, dest.addr) if isinstance(dest, Peer) else (self.peers.get(dest), dest)
            sendto(frame if frame is not None else self._pack(payload, peer), addr)  # type: ignore[arg-type]
            any_sent = True
        if count and any_sent:
            self.stats["sent"] += 1

    def send(self, msg: Message | bytes) -> None:
        """To every peer (STATUSTEXT, events, parameter changes)."""
        self._deliver(self.peers, msg)

    def reply(self, msg: mavlink.MAVLink_message) -> None:
        """To the client whose request is being handled (to every peer if none is)."""
        self._deliver(self.peers if self._source is None else [self._source], msg)

    def say(self, severity: int, text: str) -> None:
        self.send(self.telemetry.statustext(severity, text))

    def _drain_messages(self) -> None:
        msgs = self.ap.messages
        while msgs:
            sev, text = msgs.popleft()
            ev = event_id(text) if not self.ap.ardupilot and self.signature_check is None else None
            if ev is None:
                self.say(int(sev), text)
            else:  # PX4 v1.16 reports these as EVENTs (readable with the catalogue it serves over FTP)
                self._event_seq += 1
                self.send(encode_event_frame(self._event_seq, self.config.sysid, self.config.compid, ev,
                                             self.telemetry.time_boot_ms, self._event_seq, int(sev)))

    def _file_transfer(self, msg: Any) -> None:
        """MAVLink FTP, read-only and one file: the event catalogue (what PX4 serves at this path)."""
        if msg.target_system not in (0, self.config.sysid):
            return
        req = ftp.decode(bytes(msg.payload))
        blob = self._catalogue
        if req.opcode == ftp.OPEN_FILE_RO:
            path = req.data.split(b"\x00", 1)[0].decode("ascii", "replace")
            ok = path == CATALOGUE_PATH and not self.ap.ardupilot
            reply = (ftp.reply(req, ftp.ACK, 1, 0, len(blob).to_bytes(4, "little")) if ok else
                     ftp.reply(req, ftp.NAK, 0, 0, bytes([ftp.ERR_FILE_NOT_FOUND])))
        elif req.opcode == ftp.READ_FILE:
            chunk = blob[req.offset:req.offset + min(req.size or ftp.DATA_MAX, ftp.DATA_MAX)]
            reply = (ftp.reply(req, ftp.ACK, None, req.offset, chunk) if chunk else
                     ftp.reply(req, ftp.NAK, None, req.offset, bytes([ftp.ERR_EOF])))
        elif req.opcode == ftp.BURST_READ_FILE:
            for packet in ftp.burst(req, blob):
                self.reply(self.mav.file_transfer_protocol_encode(0, msg.get_srcSystem(), msg.get_srcComponent(),
                                                                 list(packet)))
            return
        elif req.opcode in (ftp.TERMINATE_SESSION, ftp.RESET_SESSIONS):
            reply = ftp.reply(req, ftp.ACK)
        else:  # listing, writing, CRCs: not served; the client falls back or reports it
            reply = ftp.reply(req, ftp.NAK, None, 0, bytes([ftp.ERR_UNKNOWN_COMMAND]))
        self.reply(self.mav.file_transfer_protocol_encode(0, msg.get_srcSystem(), msg.get_srcComponent(),
                                                         list(reply)))

    def _warn_once(self, key: str, text: str, every_s: float = 5.0) -> None:
        """A STATUSTEXT for a rejected input, at most once per ``every_s`` (simulated) per kind."""
        key = _bounded_key(self._last_warning, key)
        t = self.ap.t
        if t - self._last_warning.get(key, -math.inf) >= every_s:
            self._last_warning[key] = t
            self.say(Severity.WARNING, text)

    def _telemetry_tick(self) -> None:
        """Each peer's due streams; a message due for several peers at once is encoded and packed
        once (streams of one rate share a grid of simulated time)."""
        t = self.ap.t
        if self._param_queue:
            self._send_param_lists()
        soon = t + 1e-9
        if soon < self._next_due or self.transport is None:
            return
        now = time.monotonic()
        table = self.peers
        plan: list[tuple[Peer, list[int]]] = []
        for peer in table:
            if soon < peer.next_due:
                continue
            shared = not table.protected(peer, now)
            ids: list[int] = []
            for msg_id, due in peer.due.items():
                if soon < due:
                    continue
                if shared and not self._newcomer_streams.take(now):
                    # the newcomers' share is spent: this one waits 0.1 s, then gets one of each
                    self.stats["streams_shed"] += 1
                    peer.next_due = t + 0.1
                    break
                ids.append(msg_id)
            else:
                peer.next_due = math.inf  # set below, once its streams are sent
            plan.append((peer, ids))
        # each message encoded once, in one order for every peer (the controller's first), and packed for
        # each peer in its own sequence (signed frames leave in the order they were signed: none looks
        # like a replay)
        if len(plan) == 1:
            order = plan[0][1]
        else:
            order = list(dict.fromkeys(m for peer, ids in sorted(plan, key=lambda p: p[0].addr != table.controller)
                                       for m in ids))
            rank = {m: i for i, m in enumerate(order)}
            plan = [(peer, sorted(ids, key=rank.__getitem__)) for peer, ids in plan]
        enc = self.telemetry.encoders
        encoded: dict[int, Message | None] = {}
        made = 0
        for msg_id in order:
            encoded[msg_id] = msg = enc[msg_id]()
            made += msg is not None
        self.stats["sent"] += made
        attitude = mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION
        sendto, pack = self.transport.sendto, self._pack
        for peer, ids in plan:
            addr = peer.addr
            for msg_id in ids:
                msg = encoded[msg_id]
                if msg is not None:  # None: nothing valid to say now (e.g. no position)
                    sendto(pack(msg, peer), addr)
                    if msg_id == attitude:
                        peer.state_sent_ms = self.telemetry.time_boot_ms
                peer.sent(msg_id, t)
            if peer.next_due == math.inf:
                peer.next_due = min(peer.due.values(), default=math.inf)
        self._next_due = min((p.next_due for p in table), default=math.inf)

    def set_interval(self, msg_id: int, interval_s: float | None, peer: Peer | None = None) -> None:
        """Stream ``msg_id`` to ``peer`` (None: every peer) every ``interval_s`` simulated seconds
        (None: stop it)."""
        for p in [peer] if peer is not None else list(self.peers):
            p.set_interval(msg_id, interval_s, self.ap.t)
        self._next_due = min((p.next_due for p in self.peers), default=math.inf)

    # --- receiving -----------------------------------------------------------------------

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        """Never raises: whatever arrives, the vehicle keeps flying (errors are counted)."""
        try:
            self._datagram(data, addr)
        except Exception:
            self.stats["internal_errors"] += 1
        finally:
            self._source = self._peer = None

    def _datagram(self, data: bytes, addr: tuple[str, int]) -> None:
        st = self.stats
        st["datagrams"] += 1
        now = time.monotonic()
        if addr != self.peers.controller and not self.inflow.allow(addr, now):
            st["flood_dropped"] += 1  # beyond this address's budget: not even parsed
            return
        if len(data) > MAX_DATAGRAM:
            st["oversized"] += 1
            return
        parsed = parse_datagram(self.parser, data)
        if parsed.bad:
            st["bad_data"] += parsed.bad
        if parsed.truncated:
            st["truncated"] += 1
        good = False
        check = self.signature_check
        self._source = addr
        for msg in parsed.messages:
            kind = msg.get_type()
            st["messages"] += 1
            if check is not None:
                reason = check.verdict(msg)
                if reason is not None:
                    self._drop_unauthentic(msg, kind, reason)
                    continue
                if not is_signed(msg):
                    continue  # allowed unsigned: no effect, and no telemetry for its sender
            if not good:  # the first valid message of the datagram: its sender is a client
                good = True
                self._peer = self.peers.note(addr, now, self.ap.t)
                self._next_due = min(self._next_due, self._peer.next_due) if self._peer else self._next_due
            if kind in REQUESTS:
                budget = self._peer.requests if self._peer is not None else self._non_peer_requests
                if not budget.take(now):
                    st["rate_limited"] += 1
                    self._warn_once(f"rate limit {msg.get_srcSystem()}",
                                    f"Requests from {msg.get_srcSystem()} over {REQUESTS_PER_S:g}/s: dropped")
                    continue
            if kind in FORWARDED:
                self._forward(bytes(msg.get_msgbuf()), addr)
                continue
            handler = self._handlers.get(kind)
            if handler is None:
                continue
            try:
                handler(msg)
            except Exception:  # a handler bug or a field we could not use: drop, count, go on
                st["handler_errors"] += 1
        self._drain_messages()

    def _forward(self, frame: bytes, addr: tuple[str, int]) -> None:
        """A companion's state for the ground stations (as an autopilot routes it): to every other
        peer, at most FORWARD_PER_S a *vehicle* second from one sender (a flood is dropped and
        counted). The budget follows the simulated clock, as the sender's rate does: a companion's
        40 messages a vehicle second are 320 a wall second at 8x, and a wall-second budget cut them
        to a third (what a ground station saw of a flown force estimate on an idle host)."""
        now = self.ap.t
        window, count = self._forwarded.get(addr, (now, 0))
        if not 0.0 <= now - window < 1.0:
            window, count = now, 0
        if count >= FORWARD_PER_S:
            self.stats["forward_dropped"] += 1
            return
        self._forwarded[addr] = (window, count + 1)
        if len(self._forwarded) > MAX_PEERS * 4:
            self._forwarded.clear()
        if self.transport is None:
            return
        self._deliver([peer for peer in self.peers if peer.addr != addr], frame, count=False)
        self.stats["forwarded"] += 1

    def _drop_unauthentic(self, msg: Any, kind: str, reason: str) -> None:
        """Count a frame that failed the signature check; say so once per reason (not per frame:
        a flood must not become a flood of STATUSTEXTs)."""
        self.stats["signing_rejected"] += 1
        self.signing_rejections[f"{reason} {kind}"] += 1
        if reason not in self._signing_reported:
            self._signing_reported.add(reason)
            # the reason and the sender first: a STATUSTEXT holds 50 characters
            self.say(Severity.WARNING, f"Dropped {reason} from {msg.get_srcSystem()}: {kind}")

    def _expire_peers(self) -> None:
        self.peers.expire(time.monotonic())
        for addr in [a for a in self._param_queue if a not in self.peers]:
            del self._param_queue[addr]

    def _for_us(self, msg: Any, comp_field: str = "target_component") -> bool:
        ok = msg.target_system in (0, self.config.sysid) and getattr(msg, comp_field, 0) in (0, self.config.compid)
        if not ok:
            self.stats["wrong_target"] += 1
        return ok

    def _reject(self, reason: str) -> None:
        self.stats["rejected"] += 1
        self.rejections[_bounded_key(self.rejections, reason)] += 1
        self._warn_once(reason, f"Rejected: {reason}")

    # --- commands --------------------------------------------------------------------------

    def _ack(self, msg: Any, command: int, result: int) -> None:
        self.reply(self.mav.command_ack_encode(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))

    def _command_long(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        self._command(msg, msg.command, params)

    def _command_int(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        params = (msg.param1, msg.param2, msg.param3, msg.param4, float(msg.x), float(msg.y), msg.z)
        self._command(msg, msg.command, params)

    def _command(self, msg: Any, command: int, params: tuple[float, ...]) -> None:
        """The commands about the link are answered here (:attr:`_link_commands`); the rest go to the
        autopilot, and its result is the acknowledgement."""
        answer = self._link_commands.get(command)
        if answer is not None:
            answer(msg, command, params)
            return
        result = self.ap.command(command, params, msg.get_srcSystem())
        if result.result != MavResult.ACCEPTED:
            self.rejections[_bounded_key(self.rejections, f"command {command}: {result.reason}")] += 1
        self._ack(msg, command, int(result.result))

    def _set_message_interval(self, msg_id: float, interval_us: float) -> int:
        if not (math.isfinite(msg_id) and math.isfinite(interval_us)):
            self._reject("message interval: non-finite parameters")
            return MavResult.DENIED
        mid = int(msg_id)
        if mid not in self.telemetry.encoders or mid == mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            self._reject(f"message interval: cannot stream message {mid}")
            return MavResult.DENIED
        peer = self._requesting_peer()
        if peer is None:
            self._reject("message interval: no room for another client")
            return MavResult.TEMPORARILY_REJECTED
        if interval_us == -1:
            self.set_interval(mid, None, peer)
        elif interval_us == 0:
            hz = DEFAULT_RATES_HZ.get(mid, 0.0)
            self.set_interval(mid, 1.0 / hz if hz > 0 else None, peer)
        elif interval_us > 0:
            interval = max(interval_us * 1e-6, 1.0 / MAX_STREAM_HZ, self.ap.dt)
            others = sum(1.0 / i for m, i in peer.intervals.items() if m != mid)
            if others + 1.0 / interval > MAX_PEER_STREAMS_HZ:
                self._reject(f"message interval: over {MAX_PEER_STREAMS_HZ:g} messages/s for one client")
                return MavResult.DENIED
            self.set_interval(mid, interval, peer)
        else:
            self._reject("message interval: negative interval")
            return MavResult.DENIED
        return MavResult.ACCEPTED

    def _requesting_peer(self) -> Peer | None:
        """The peer whose request is being handled; outside a datagram (a test calling a handler),
        the only peer if there is exactly one."""
        if self._source is not None:
            return self._peer
        peers = list(self.peers)
        return peers[0] if len(peers) == 1 else None

    def _request_message(self, msg: Any, command: int, msg_id: float) -> None:
        """ACK, then the requested message (the order PX4 uses)."""
        if not math.isfinite(msg_id) or int(msg_id) not in self.telemetry.encoders:
            self._reject("request message: cannot send that message")
            self._ack(msg, command, MavResult.DENIED)
            return
        reply = self.telemetry.encoders[int(msg_id)]()
        if reply is None:
            self._ack(msg, command, MavResult.TEMPORARILY_REJECTED)
            return
        self._ack(msg, command, MavResult.ACCEPTED)
        self.reply(reply)

    # --- setpoints -------------------------------------------------------------------------

    def _set_attitude_target(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        rates = (msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate)
        reason = self.ap.attitude_target(msg.get_srcSystem(), msg.type_mask, tuple(msg.q), rates, msg.thrust)
        if reason is not None:
            self._reject(f"attitude target: {reason}")
            return
        self._setpoint_accepted(msg.time_boot_ms)

    def _setpoint_accepted(self, time_boot_ms: int) -> None:
        """The companion stamps a setpoint with the vehicle time of the telemetry it was computed
        from: its age here is the whole loop's latency (PX4 ignores the field; 0 = unstamped), and
        what ``wait_for_setpoints_s`` measures (from arrival when unstamped)."""
        stamp_t = self.telemetry.sim_time_of(time_boot_ms)
        age = self.ap.t - stamp_t
        if self._source is not None:
            self.peers.controller = self._source  # protected from eviction and from the flood budget
        if time_boot_ms and 0.0 <= age < 60.0:
            self.setpoint_age_s.append(age)
            self.setpoint_age_max_s = max(self.setpoint_age_max_s, age)
            self.pacing.setpoint(stamp_t)
        else:
            self.pacing.setpoint(self.ap.t)
        if self._waiting:
            self._setpoint_new = True  # the world's wait ends once the datagrams are read (_after_datagrams)
        else:
            self._setpoint_arrived.set()

    def _set_position_target_global(self, msg: Any) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT (PX4 flies it; MAVSDK's set_position_global): refused, said once
        per 5 s, not ignored in silence."""
        if self._for_us(msg):
            self._reject("GLOBAL_INT setpoint: use LOCAL_NED")

    def _set_position_target(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        target = trajectory_target(msg, self.ap.vehicle.estimator.q)
        reason = target if isinstance(target, str) else self.ap.position_target(msg.get_srcSystem(), target)
        if reason is not None:
            self._reject(f"position target: {reason}")
            return
        self._setpoint_accepted(msg.time_boot_ms)

    # --- parameters ----------------------------------------------------------------------

    def _param_value_msg(self, index: int) -> mavlink.MAVLink_message | None:
        p = self.params.at(index)
        if p is None:
            return None
        return self.mav.param_value_encode(
            p.name.encode("ascii"), float(p.value), mavlink.MAV_PARAM_TYPE_REAL32, len(self.params), index)

    def _param_value(self, index: int, to_all: bool = False) -> None:
        msg = self._param_value_msg(index)
        if msg is not None:
            (self.send if to_all else self.reply)(msg)

    def _param_request_list(self, msg: Any) -> None:
        """The list is sent to the requester a few values per plant step (_send_param_lists); a
        request while its list is in progress changes nothing."""
        if not self._for_us(msg):
            return
        peer = self._requesting_peer()
        if peer is None:
            self._reject("param list: no room for another client")
            return
        if peer.param_cursor is None:
            peer.param_cursor = 0
            self._param_queue[peer.addr] = None
            self.stats["param_lists"] += 1

    def _send_param_lists(self) -> None:
        """This step's share of the parameter lists in progress: up to PARAMS_PER_STEP values to
        each, as many in all as PARAM_VALUES_PER_S allows, the lists taking turns (the queue
        rotates)."""
        bucket = self._param_budget
        budget = 0
        while budget < PARAMS_PER_STEP * len(self._param_queue) and bucket.take(time.monotonic()):
            budget += 1
        queue = self._param_queue
        for addr in list(queue):
            queue.pop(addr)
            peer = self.peers.get(addr)
            if peer is None or peer.param_cursor is None:
                continue
            if budget <= 0:
                queue[addr] = None  # its turn comes first next step
                continue
            for _ in range(min(PARAMS_PER_STEP, budget)):
                budget -= 1
                msg = self._param_value_msg(peer.param_cursor)
                if msg is not None:
                    self._deliver((peer,), msg)
                peer.param_cursor += 1
                if peer.param_cursor >= len(self.params):
                    peer.param_cursor = None
                    break
            if peer.param_cursor is not None:
                queue[addr] = None  # to the back

    def _param_request_read(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        index = msg.param_index
        if index < 0:
            name = _param_name(msg.param_id)
            found = self.params.index(name)
            if found is None:
                self._reject(f"param read: unknown parameter {name!r}")
                self._param_error(msg, -1)
                return
            index = found
        if self.params.at(index) is None:
            self._reject(f"param read: no parameter at index {index}")
            self._param_error(msg, index)
            return
        self._param_value(index)

    def _param_set(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        name = _param_name(msg.param_id)
        index = self.params.index(name)
        reason = self.params.set(name, float(msg.param_value))
        if reason is not None:
            self._reject(f"param set: {reason}")
        if index is not None:
            self._param_value(index, to_all=reason is None)  # the value in force (the old one if refused)
        else:
            self._param_error(msg, -1)

    def _param_error(self, msg: Any, index: int) -> None:
        """PARAM_ERROR (DOES_NOT_EXIST) for a read or write of a parameter this vehicle does not have,
        to the asker: a client stops asking at once (ArduPilot 4.7 answers so; PX4 v1.16 only logs it on
        its console, and MAVSDK retries it into a timeout)."""
        name = _param_name(msg.param_id).encode("ascii", "replace")[:16]
        self.reply(self.mav.param_error_encode(msg.get_srcSystem(), msg.get_srcComponent(), name, index,
                                               mavlink.MAV_PARAM_ERROR_DOES_NOT_EXIST))

    # --- small protocols -------------------------------------------------------------------

    def _ping(self, msg: Any) -> None:
        if msg.target_system == 0:  # a request: answer it, addressed to the sender
            self.reply(self.mav.ping_encode(msg.time_usec, msg.seq, msg.get_srcSystem(), msg.get_srcComponent()))

    def _timesync(self, msg: Any) -> None:
        """A request (tc1 = 0) is answered with our simulated time in tc1 and the request's ts1, to the
        requester (this dialect's TIMESYNC has no target fields)."""
        if msg.tc1 == 0:
            self.reply(self.mav.timesync_encode(self.telemetry.time_usec * 1000, msg.ts1))

    def _request_data_stream(self, msg: Any) -> None:
        """Start (the default rates) or stop (all but HEARTBEAT) the requester's streams."""
        if not self._for_us(msg):
            return
        peer = self._requesting_peer()
        if peer is None:
            self._reject("data stream: no room for another client")
            return
        if msg.start_stop == 0 and msg.req_stream_id == mavlink.MAV_DATA_STREAM_ALL:
            for mid in list(peer.intervals):
                if mid != mavlink.MAVLINK_MSG_ID_HEARTBEAT:
                    self.set_interval(mid, None, peer)
        elif msg.start_stop:
            for mid, hz in DEFAULT_RATES_HZ.items():
                self.set_interval(mid, 1.0 / hz, peer)

    def _log_request_list(self, msg: Any) -> None:
        """The vehicle keeps no logs (its flight record is the client's .tlog): the empty list, as the
        MAVLink log protocol answers it, one LOG_ENTRY with num_logs 0. (PX4 v1.16 with no log directory
        stays silent, and MAVSDK's get_entries times out; with logs it lists its ULogs.)"""
        if not self._for_us(msg):
            return
        self.reply(self.mav.log_entry_encode(0, 0, 0, 0, 0))

    SHELL_REPLY = (b"nsh: the bundled vehicle has no shell; PX4's runs under sitl --firmware px4\n"
                   b"nsh> ")
    """what a MAVLink shell (MAVSDK's Shell, QGroundControl's MAVLink Console) shows for any input"""

    def _serial_control(self, msg: Any) -> None:
        """SERIAL_CONTROL to the shell device (what PX4 serves its NuttShell on): answered, as PX4's shell
        answers, with SERIAL_CONTROL replies carrying text -- here that there is no shell. Other devices
        (serial passthrough) and replies are ignored, as PX4 ignores them."""
        target = (getattr(msg, "target_system", 0), getattr(msg, "target_component", 0))  # MAVLink 2 extensions
        if target[0] not in (0, self.config.sysid) or target[1] not in (0, self.config.compid):
            return
        if msg.device != mavlink.SERIAL_CONTROL_DEV_SHELL or msg.flags & mavlink.SERIAL_CONTROL_FLAG_REPLY:
            return
        if msg.count == 0:
            return  # a poll for output: there is none
        text = self.SHELL_REPLY
        for start in range(0, len(text), 70):
            chunk = text[start:start + 70]
            self.reply(self.mav.serial_control_encode(
                mavlink.SERIAL_CONTROL_DEV_SHELL, mavlink.SERIAL_CONTROL_FLAG_REPLY, 0, 0, len(chunk),
                list(chunk.ljust(70, b"\x00"))))

    def _mission_count(self, msg: Any) -> None:
        """A mission, fence or rally upload: refused at once with MISSION_ACK UNSUPPORTED (the bundled
        autopilot flies no missions; ``sitl --firmware px4`` does), so an uploader stops instead of
        retrying into a timeout."""
        if not self._for_us(msg):
            return
        self._reject("mission upload: no missions here")
        self.reply(self.mav.mission_ack_encode(msg.get_srcSystem(), msg.get_srcComponent(),
                                               mavlink.MAV_MISSION_UNSUPPORTED, getattr(msg, "mission_type", 0)))

    def _mission_clear_all(self, msg: Any) -> None:
        """Nothing is stored, so clearing succeeds (MAVSDK's clear_mission, QGroundControl's clear)."""
        if not self._for_us(msg):
            return
        self.reply(self.mav.mission_ack_encode(msg.get_srcSystem(), msg.get_srcComponent(),
                                               mavlink.MAV_MISSION_ACCEPTED, getattr(msg, "mission_type", 0)))

    def _mission_request_list(self, msg: Any) -> None:
        if not self._for_us(msg):
            return
        self.reply(self.mav.mission_count_encode(msg.get_srcSystem(), msg.get_srcComponent(), 0,
                                                 getattr(msg, "mission_type", 0)))

    def lateness_ms(self) -> dict[str, float]:
        """Percentiles of how late (wall clock) the loop started steps that were due."""
        return percentiles_ms(self.pacing.lateness_s)

    def setpoint_age_ms(self) -> dict[str, float]:
        """Percentiles of the age of stamped setpoints on arrival [vehicle ms] (the latest 100k), and
        the largest since start."""
        return percentiles_ms(self.setpoint_age_s) | {"max_since_start": round(1000.0 * self.setpoint_age_max_s, 3)}

    # --- running -------------------------------------------------------------------------

    async def start(self) -> None:
        # the loop's own passes flush before each wait (:meth:`run`), the reader's callback at its end
        endpoint = UdpEndpoint(self.datagram_received, self._socket_error, coalesce_bytes=DATAGRAM_BYTES,
                               flush_soon=False, after_batch=self._after_datagrams)
        endpoint.open(self.config.listen)
        self.transport = endpoint
        self.peers.seq_salt = endpoint.sockname[1]

    def _socket_error(self, exc: OSError) -> None:  # e.g. ICMP port unreachable for a peer
        self.stats["socket_errors"] += 1

    @property
    def address(self) -> tuple[str, int]:
        assert self.transport is not None
        return self.transport.sockname

    async def run(self, stop: asyncio.Event, duration_s: float | None = None) -> None:
        """Step as :class:`~sitl.autopilot.pacing.WorldPacing` says until ``stop`` is set (or
        ``duration_s`` simulated): one :meth:`_pass` after another, each followed by what it asks
        (a sleep, or a wait for the next setpoint that :meth:`_after_datagrams` may end by stepping
        the world itself)."""
        if self.transport is None:
            await self.start()
        ap, pacing = self.ap, self.pacing
        pacing.start(time.monotonic(), ap.t)
        cpu0, t0 = time.process_time(), ap.t
        self._last_expire = pacing.run_wall0
        self._stop, self._duration_s = stop, duration_s
        try:
            while not stop.is_set():
                if duration_s is not None and ap.t >= duration_s:
                    break
                after = self._pass()
                if after is None:
                    self._waiting = True
                    try:
                        with contextlib.suppress(TimeoutError):  # a datagram's callback sets the event
                            async with asyncio.timeout(REPEAT_WALL_S):  # no task per wait, as wait_for makes
                                await self._setpoint_arrived.wait()
                    finally:
                        self._waiting = False
                    if self._pass_error is not None:
                        raise self._pass_error
                elif after >= 0.0:
                    await asyncio.sleep(after)
        finally:
            self.run_wall_s = time.monotonic() - pacing.run_wall0
            self.run_cpu = {"cpu_s": round(time.process_time() - cpu0, 3), "sim_s": round(ap.t - t0, 3)}
            if self.transport is not None:
                self.transport.close()
                self.transport = None

    _AT_ONCE = -1.0
    """:meth:`_pass`: the next pass follows at once (the world stopped where it waits for a setpoint)"""

    def _pass(self) -> float | None:
        """One pass of the world's loop: wait (None: for a setpoint, the state at a lockstep stop sent),
        or step to where :meth:`WorldPacing.plan` says, then the wall seconds to sleep before the next
        pass (:data:`_AT_ONCE`: none, not even a yield). A catch-up yields every 50 steps (0.0) and the
        next pass goes on to the same target."""
        ap, pacing = self.ap, self.pacing
        if self._pending_pass is None:
            now = time.monotonic()
            wait = pacing.wait(now, ap.t, ap.follows_stream)
            if wait is not Wait.RUN:
                if wait is Wait.BEGIN:
                    self._send_state_now()
                elif wait is Wait.REPEAT:
                    self._repeat_state()
                pacing.resume(now, ap.t)
                self._setpoint_arrived.clear()
                self._flush()
                return None
            self._pending_pass = (pacing.plan(now, ap.t, ap.follows_stream), now)
        step, now = self._pending_pass
        steps = 0
        while ap.t + 0.5 * ap.dt <= step.target_t:
            n = self.chunk_steps(step.target_t)
            self.step(n)
            if pacing.late(ap.t, ap.follows_stream):
                break  # catching up, too: never more than the wait ahead of the companion
            steps += n
            if steps >= 50:
                self._flush()
                return 0.0  # let datagrams in during long catch-ups
        self._pending_pass = None
        if ap.messages:
            self._drain_messages()
        if now - self._last_expire > 1.0:
            self._expire_peers()
            self._last_expire = now
        pause = pacing.sleep_s(time.monotonic(), ap.t, step.locked)
        if step.locked and pacing.late(ap.t, ap.follows_stream):
            # at the lockstep stop: straight to the wait for the next setpoint (the state at the stop
            # leaves with this pass's frames)
            return self._AT_ONCE
        self._flush()
        return pause

    def _after_datagrams(self) -> None:
        """Lockstep: a setpoint that ends the world's wait steps the world here, in the callback that
        read it, to the next stop and its state sent, where the run task would be woken to do the
        same (a pass of the event loop and a task switch less per setpoint). Anything else (a sleep
        to keep, the end of the run, an error) goes back to the task."""
        if not self._setpoint_new:
            return
        self._setpoint_new = False
        stop, duration_s = self._stop, self._duration_s
        try:
            while stop is not None and not stop.is_set() and (duration_s is None or self.ap.t < duration_s):
                after = self._pass()
                if after is None:
                    return  # waiting again; the run task's wait goes on
                if after >= 0.0:
                    break
        except Exception as exc:  # the run task raises it, as it would have raised it itself
            self._pass_error = exc
        self._setpoint_arrived.set()

    def _flush(self) -> None:
        """What this pass of the loop sent, out now (coalesced), before it waits."""
        if self.transport is not None:
            self.transport.flush()

    run_wall_s: float | None = None
    run_cpu: dict[str, float] | None = None
    """the process's CPU seconds while :meth:`run` ran, and the simulated seconds it flew, once it has
    returned (the vehicle's sustained cost, its boot left out: benchmarks/bench_lockstep.py)"""
    """wall seconds :meth:`run` lasted, once it has returned"""

    @property
    def longest_wait_s(self) -> float:
        return self.pacing.longest_wait_s

    def pace(self) -> dict[str, float]:
        """How the world kept its speed (:meth:`WorldPacing.report`)."""
        return self.pacing.report(time.monotonic(), self.ap.t, self.run_wall_s)

    def chunk_steps(self, target_t: float) -> int:
        """How many plant steps the next :meth:`step` takes: up to ``target_t`` and at most the position
        loop's period (the rules run at least at that rate), one at least. A stream due within it goes
        at its end, a little late, as an autopilot's streams go on the loop that serves them; one
        streamed faster than the rules run ends the chunk where it is due, so it keeps its rate."""
        ap = self.ap
        n = min(ap.pos_div, int(round((target_t - ap.t) / ap.dt)))
        due = self._next_due
        if self.transport is not None and due < ap.t + n * ap.dt - 1e-9:
            fastest = min((min(p.intervals.values(), default=math.inf) for p in self.peers), default=math.inf)
            if fastest < ap.pos_div * ap.dt - 1e-9:
                n = min(n, int(math.ceil((due - ap.t) / ap.dt - 1e-6)))
        return max(n, 1)

    def step(self, steps: int = 1) -> None:
        """``steps`` plant steps under one decision of the rules, then the telemetry due; whatever
        goes wrong, the loop goes on (a fault in the steps is the guard's; one in building telemetry
        is counted)."""
        self.guard.step(steps)
        try:
            self._telemetry_tick()
            if self.ap.messages:
                self._drain_messages()
        except Exception:
            self.stats["telemetry_errors"] += 1

    def _send_state_now(self) -> None:
        """Lockstep: the state at the stop, now, to each peer that streams it and has not had this
        instant's attitude yet."""
        stamp = self.telemetry.time_boot_ms
        peers = [p for p in self.peers if p.state_sent_ms != stamp]
        for p in peers:
            p.state_sent_ms = stamp
        self._send_streamed(peers, (mavlink.MAVLINK_MSG_ID_HIGHRES_IMU, mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION))

    def _repeat_state(self) -> None:
        """While waiting: the newest attitude and position again, same stamp (the clock stood still)."""
        self._send_streamed(list(self.peers),
                            (mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED))

    def _send_streamed(self, peers: list[Peer], msg_ids: tuple[int, ...]) -> None:
        enc = self.telemetry.encoders
        for msg_id in msg_ids:
            to = [p for p in peers if msg_id in p.intervals]
            if to:
                msg = enc[msg_id]()
                if msg is not None:
                    self._deliver(to, msg)


_TYPEMASK_POS = (mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE, mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE,
                 mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE)
_TYPEMASK_VEL = (mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE, mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE,
                 mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE)
_TYPEMASK_ACC = (mavlink.POSITION_TARGET_TYPEMASK_AX_IGNORE, mavlink.POSITION_TARGET_TYPEMASK_AY_IGNORE,
                 mavlink.POSITION_TARGET_TYPEMASK_AZ_IGNORE)


def trajectory_target(msg: Any, q: tuple) -> TrajectoryTarget | str:
    """SET_POSITION_TARGET_LOCAL_NED as PX4 v1.16 reads it (mavlink_receiver.cpp), or why it is refused.

    MAV_FRAME_LOCAL_NED: each position, velocity and acceleration component given unless its type_mask
    bit says ignore. MAV_FRAME_BODY_NED: the velocity rotated by the heading (all of it ignored if any of
    its bits is set), the acceleration by the attitude ``q``, the position ignored. Yaw and yaw rate as
    their bits say. Refused, as PX4 refuses them: any other frame, and an acceleration sent as a force."""
    mask, frame = msg.type_mask, msg.coordinate_frame
    pos, vel, acc = (msg.x, msg.y, msg.z), (msg.vx, msg.vy, msg.vz), (msg.afx, msg.afy, msg.afz)

    def given(values: tuple, bits: tuple) -> Vec3:
        return tuple(math.nan if mask & b else float(v) for v, b in zip(values, bits))  # type: ignore[return-value]

    if frame == mavlink.MAV_FRAME_LOCAL_NED:
        p, v, a = given(pos, _TYPEMASK_POS), given(vel, _TYPEMASK_VEL), given(acc, _TYPEMASK_ACC)
    elif frame == mavlink.MAV_FRAME_BODY_NED:
        p = NAN3
        yaw = float(quat.to_euler(q)[2])
        v = NAN3 if any(mask & b for b in _TYPEMASK_VEL) else body_to_ned(tuple(map(float, vel)), yaw)  # type: ignore[arg-type]
        a_body = tuple(0.0 if mask & b else float(x) for x, b in zip(acc, _TYPEMASK_ACC))
        a = NAN3 if all(mask & b for b in _TYPEMASK_ACC) else quat.rotate(q, a_body)  # type: ignore[arg-type]
    else:
        return f"frame {frame} unsupported"
    if mask & mavlink.POSITION_TARGET_TYPEMASK_FORCE_SET and not all(math.isnan(c) for c in a):
        return "force not supported"
    yaw_sp = math.nan if mask & mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE else float(msg.yaw)
    yaw_rate = math.nan if mask & mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE else float(msg.yaw_rate)
    return TrajectoryTarget(p, v, a, yaw_sp, yaw_rate)


def _bounded_key(table: dict[str, Any], key: str) -> str:
    return key if key in table or len(table) < MAX_REASONS else "other"


def _param_name(raw: object) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\x00", 1)[0]
