"""The simulated vehicle's clients: who gets telemetry, at which rates, how much each may ask, and
who may be forgotten when the table is full.

Every client (a peer: an address that sent a valid frame, or one configured with ``--peer``) has
its own stream rates, starting from the defaults, so one client's SET_MESSAGE_INTERVAL or
REQUEST_DATA_STREAM changes only what *it* receives; its own parameter-list cursor, so a list is
sent a few values per plant step and a repeated request never multiplies the work; and its own
budget of requests that cost an answer (commands, parameter requests, pings).

The table holds :data:`MAX_PEERS` clients. When it is full a newcomer takes the place of the
least active unprotected peer; **protected** are configured peers, the address the active
controller streams setpoints from, and *established* peers (at least
:data:`ESTABLISHED_DATAGRAMS` valid datagrams, the last one within :data:`PROTECT_S`). A churn of
source addresses that talk once each therefore only ever displaces itself; if every peer is
protected the newcomer is refused (counted) until one falls silent. A peer keeps its datagram
count; those of recent addresses that are not peers (refused or evicted) are remembered too
(:data:`SEEN_MEMORY` addresses), so a real client that arrives during a churn becomes established
on its third datagram wherever the churn put it.

Before parsing, each source address has a datagram budget (:class:`InflowGuard`): a flood from
one address is dropped unparsed beyond it, so it cannot take the vehicle's CPU from its world. The
controller's address is exempt (its setpoint rate scales with the speed-up).
"""

from __future__ import annotations

import math
import zlib
from collections import OrderedDict
from dataclasses import dataclass, field

__all__ = [
    "MAX_PEERS", "PEER_TIMEOUT_S", "ESTABLISHED_DATAGRAMS", "PROTECT_S", "SEEN_MEMORY",
    "Bucket", "Peer", "PeerTable", "InflowGuard",
]

Address = tuple[str, int]

MAX_PEERS = 16
PEER_TIMEOUT_S = 30.0
"""a peer silent this long (wall) is forgotten, unless configured"""
ESTABLISHED_DATAGRAMS = 3
"""valid datagrams after which an address counts as a real client (a churn's addresses talk once)"""
PROTECT_S = 5.0
"""an established peer heard within this long (wall) is never evicted; every MAVLink client
heartbeats at 1 Hz"""
SEEN_MEMORY = 4096
"""addresses whose datagram counts are remembered (least recently heard forgotten first)"""
REQUESTS_PER_S = 50.0
REQUEST_BURST = 100.0
"""answers each client may ask for: 50 per wall second, 100 at once (MAVSDK asks for about 30
things while it connects)"""


@dataclass
class Bucket:
    """A token bucket in wall time: ``rate_per_s`` tokens a second, at most ``burst`` saved."""

    rate_per_s: float
    burst: float
    tokens: float = math.nan
    t: float = -math.inf

    def take(self, now: float) -> bool:
        if math.isnan(self.tokens):
            tokens = self.burst
        else:
            tokens = min(self.burst, self.tokens + (now - self.t) * self.rate_per_s)
        self.t = now
        if tokens < 1.0:
            self.tokens = tokens
            return False
        self.tokens = tokens - 1.0
        return True


@dataclass
class Peer:
    """One client: its stream schedule (simulated seconds), parameter-list cursor and request budget."""

    addr: Address
    intervals: dict[int, float]
    """message id -> interval [simulated s]"""
    due: dict[int, float]
    """message id -> when it is next due [simulated s]"""
    pinned: bool = False
    """configured (``--peer``): never evicted or expired"""
    last_heard: float = -math.inf
    """wall time of its newest valid datagram"""
    heard: int = 0
    """valid datagrams from it (before it was a peer too)"""
    next_due: float = 0.0
    param_cursor: int | None = None
    """the next parameter index of a list being sent to it (None: no list in progress)"""
    state_sent_ms: int = -1
    """the stamp of the newest attitude sent to it (lockstep sends the state at each stop once)"""
    requests: Bucket = field(default_factory=lambda: Bucket(REQUESTS_PER_S, REQUEST_BURST))
    seq: int = 0
    """the MAVLink sequence number of the next frame to it: each link numbers its own frames, as
    PX4 numbers each MAVLink instance's (a receiver tells loss, and two senders, by them)"""

    def set_interval(self, msg_id: int, interval_s: float | None, t: float) -> None:
        """Stream ``msg_id`` every ``interval_s`` simulated seconds from now (None: stop it)."""
        if interval_s is None:
            self.intervals.pop(msg_id, None)
            self.due.pop(msg_id, None)
        else:
            self.intervals[msg_id] = interval_s
            self.due[msg_id] = t
        self.next_due = min(self.due.values(), default=math.inf)

    def sent(self, msg_id: int, t: float) -> None:
        """``msg_id`` went out at ``t``: due again at the next multiple of its interval (a grid
        shared by every peer at that rate, so one encoded message serves them all)."""
        interval = self.intervals[msg_id]
        self.due[msg_id] = (math.floor(t / interval + 1e-6) + 1.0) * interval


class PeerTable:
    """The peers, bounded, with the eviction rule of the module docstring."""

    def __init__(self, default_intervals: dict[int, float], pinned: tuple[Address, ...] = (),
                 max_peers: int = MAX_PEERS) -> None:
        self.default_intervals = dict(default_intervals)
        self.max_peers = max_peers
        self.peers: dict[Address, Peer] = {}
        self.seq_salt = 0
        """where each link's sequence numbers start: from this (the vehicle's own port) and the
        client's address, so two vehicles behind one router do not count in step (PX4's counters
        start wherever each instance happens to be)"""
        self.controller: Address | None = None
        """the address the newest accepted setpoint came from"""
        self.seen: OrderedDict[Address, int] = OrderedDict()
        """valid datagrams of recent addresses that are not peers (bounded; a peer keeps its own count)"""
        self.added = self.evicted = self.refused = self.expired = 0
        for addr in pinned:
            self.add(addr, 0.0, pinned=True)

    def __len__(self) -> int:
        return len(self.peers)

    def __contains__(self, addr: object) -> bool:
        return addr in self.peers

    def __iter__(self):  # type: ignore[no-untyped-def]
        return iter(self.peers.values())

    def get(self, addr: Address) -> Peer | None:
        return self.peers.get(addr)

    def add(self, addr: Address, t: float, pinned: bool = False) -> Peer:
        """A new peer with the default streams, all due at ``t`` (simulated); no room check."""
        peer = Peer(addr, dict(self.default_intervals), {m: t for m in self.default_intervals}, pinned=pinned,
                    seq=zlib.crc32(f"{self.seq_salt}>{addr}".encode()) & 0xFF)
        peer.next_due = t if peer.due else math.inf
        self.peers[addr] = peer
        self.added += 1
        return peer

    def heard(self, addr: Address) -> int:
        peer = self.peers.get(addr)
        return peer.heard if peer is not None else self.seen.get(addr, 0)

    def protected(self, peer: Peer, now: float) -> bool:
        return (peer.pinned or peer.addr == self.controller
                or (peer.heard >= ESTABLISHED_DATAGRAMS and now - peer.last_heard < PROTECT_S))

    def note(self, addr: Address, now: float, t: float) -> Peer | None:
        """A valid datagram from ``addr`` at wall time ``now`` (simulated ``t``): its peer, added if
        new and there is room or an unprotected peer to evict; None if refused."""
        peer = self.peers.get(addr)
        if peer is None:
            heard = self.seen.pop(addr, 0) + 1
            if len(self.peers) >= self.max_peers and not self._evict_for(heard, now):
                self.refused += 1
                self._remember(addr, heard)
                return None
            peer = self.add(addr, t)
            peer.heard = heard
        else:
            peer.heard += 1
        peer.last_heard = now
        return peer

    def _remember(self, addr: Address, heard: int) -> None:
        self.seen[addr] = heard
        if len(self.seen) > SEEN_MEMORY:
            self.seen.popitem(last=False)

    def _evict_for(self, heard: int, now: float) -> bool:
        """Make room for a newcomer heard ``heard`` times: the unprotected peer heard least (then
        longest ago) goes, if it has been heard no more than the newcomer."""
        candidates = [p for p in self.peers.values() if not self.protected(p, now)]
        if not candidates:
            return False
        victim = min(candidates, key=lambda p: (p.heard, p.last_heard))
        if victim.heard > heard:
            return False  # a one-off sender never displaces a peer that has talked more
        del self.peers[victim.addr]
        self._remember(victim.addr, victim.heard)
        self.evicted += 1
        return True

    def expire(self, now: float) -> None:
        for addr, peer in list(self.peers.items()):
            if not peer.pinned and addr != self.controller and now - peer.last_heard > PEER_TIMEOUT_S:
                del self.peers[addr]
                self.expired += 1
        if self.controller is not None and self.controller in self.peers:
            if now - self.peers[self.controller].last_heard > PEER_TIMEOUT_S:
                self.controller = None  # silent that long: no longer anyone's controller

    def summary(self) -> list[dict[str, object]]:
        """For the exit report."""
        return [{"addr": f"{p.addr[0]}:{p.addr[1]}", "heard": p.heard, "pinned": p.pinned,
                 "controller": p.addr == self.controller} for p in self.peers.values()]


class InflowGuard:
    """Datagrams each source address may send per wall second before they are dropped unparsed
    (the controller's address is exempt): parsing a flood must not starve the world's steps."""

    def __init__(self, rate_per_s: float, burst: float, memory: int = SEEN_MEMORY) -> None:
        self.rate_per_s, self.burst, self.memory = rate_per_s, burst, memory
        self._buckets: OrderedDict[Address, Bucket] = OrderedDict()

    def allow(self, addr: Address, now: float) -> bool:
        buckets = self._buckets
        bucket = buckets.pop(addr, None)
        if bucket is None:
            bucket = Bucket(self.rate_per_s, self.burst)
            if len(buckets) >= self.memory:
                buckets.popitem(last=False)
        buckets[addr] = bucket
        return bucket.take(now)
