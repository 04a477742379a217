"""A UDP relay that impairs a MAVLink link: loss, delay with jitter, duplication, reordering, outages.

    sitl-relay --listen 127.0.0.1:14600 --to 127.0.0.1:14580 --loss 0.1 --delay-ms 20 --jitter-ms 10
    sitl-relay ... --up loss=0.3 --down delay_ms=80        # per direction
    sitl-relay ... --outage 12:2.5 --outage 30:1:up        # scheduled outages (s after the first packet)
    kill -USR1 <pid>                                      # an outage of --signal-outage-s, now

Put it between a client and a vehicle: the client connects to ``--listen``, the relay forwards
to ``--to`` from its own socket and sends the vehicle's replies back to the client. The client is
``--client HOST:PORT`` if given, else the first address that speaks; another sender is dropped
and counted (``strangers``) — it may neither reach the vehicle nor divert its downlink — unless
the client has been silent for ``--repin-s`` (3 s: a companion restarted on another port takes
over). "up" is client -> vehicle (setpoints, commands), "down" is vehicle -> client (telemetry).

Per datagram and direction, in this order: an outage drops it; it is lost with probability
``loss``; otherwise it is delivered after ``delay_ms`` plus a uniform jitter in
``[-jitter_ms, +jitter_ms]`` (never negative; datagrams overtake each other when the jitter
exceeds their spacing); with probability ``reorder`` it is held ``reorder_ms`` longer still;
with probability ``duplicate`` a second copy follows ``duplicate_gap_ms`` later. Every draw comes
from one seeded generator per direction, so the same seed and the same traffic give the same
impairment. A datagram's delay counts from its arrival in the kernel (SO_TIMESTAMPNS on Linux),
so time the relay itself spent descheduled before reading it is not added; time it spent
descheduled past a delivery's due time is, and is reported (``late_ms``: p50, p99, max). On
SIGTERM/SIGINT the relay prints ``relay: stopped {json}`` with its counters.
"""

from __future__ import annotations

import argparse
import dataclasses
import heapq
import json
import math
import random
import selectors
import signal
import socket
import struct
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Callable, Sequence

from ..percentiles import percentiles_ms

__all__ = ["Impairment", "Outage", "Relay", "SO_TIMESTAMPNS", "clock_pair", "kernel_arrival", "main"]

MAX_DATAGRAM = 65535
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35 if sys.platform.startswith("linux") else None)
"""kernel receive stamps as a struct timespec (Linux's value; Python's socket module may lack the name)"""


@dataclass(frozen=True)
class Impairment:
    """What happens to the datagrams of one direction."""

    loss: float = 0.0
    delay_ms: float = 0.0
    jitter_ms: float = 0.0
    duplicate: float = 0.0
    duplicate_gap_ms: float = 1.0
    reorder: float = 0.0
    reorder_ms: float = 10.0

    def __post_init__(self) -> None:
        for name in ("loss", "duplicate", "reorder"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name} must be a probability in [0, 1], got {v}")
        for name in ("delay_ms", "jitter_ms", "duplicate_gap_ms", "reorder_ms"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")


@dataclass(frozen=True)
class Outage:
    start_s: float
    """seconds after the first datagram the relay sees"""
    duration_s: float
    direction: str = "both"

    def covers(self, t_s: float, direction: str) -> bool:
        return self.direction in ("both", direction) and self.start_s <= t_s < self.start_s + self.duration_s


@dataclass
class _Direction:
    name: str
    imp: Impairment
    rng: random.Random
    counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(
        ("received", "forwarded", "lost", "outage", "duplicated", "reordered"), 0))
    last_due: float = -math.inf
    """the latest due time given so far: without jitter, a datagram never overtakes an earlier one"""


class Relay:
    """The relay's state and one select loop; :meth:`run` until :meth:`stop`."""

    def __init__(self, listen: tuple[str, int], to: tuple[str, int], up: Impairment, down: Impairment,
                 outages: Sequence[Outage] = (), seed: int = 0, signal_outage_s: float = 2.0,
                 client: tuple[str, int] | None = None, repin_s: float = 3.0) -> None:
        self.to = to
        self.fixed_client = client
        self.repin_s = repin_s
        self.client_heard = -float("inf")
        self.strangers = 0
        """datagrams from another sender than the client: dropped"""
        self.repinned = 0
        self.client_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.client_side.bind(listen)
        self.vehicle_side = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.vehicle_side.bind((listen[0], 0))
        for s in (self.client_side, self.vehicle_side):
            s.setblocking(False)
            if SO_TIMESTAMPNS is not None:
                s.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        self.late_s: deque[float] = deque(maxlen=100_000)
        """how late past its due time each of the latest deliveries went out [s]"""
        self.up = _Direction("up", up, random.Random(f"{seed}:up"))
        self.down = _Direction("down", down, random.Random(f"{seed}:down"))
        self.outages: list[Outage] = list(outages)
        self.signal_outage_s = signal_outage_s
        self.client: tuple[str, int] | None = client
        self.t0: float | None = None
        self._queue: list[tuple[float, int, bool, bytes]] = []  # (due, seq, upward, data)
        self._seq = 0
        self._running = True
        self.max_queue = 0

    @property
    def address(self) -> tuple[str, int]:
        return self.client_side.getsockname()  # type: ignore[no-any-return]

    def outage_now(self, duration_s: float | None = None, direction: str = "both") -> None:
        """Start an outage now (the SIGUSR1 handler)."""
        now = self._elapsed(time.monotonic())
        self.outages.append(Outage(now, self.signal_outage_s if duration_s is None else duration_s, direction))

    def stop(self) -> None:
        self._running = False

    def _elapsed(self, now: float) -> float:
        if self.t0 is None:
            self.t0 = now
        return now - self.t0

    def _schedule(self, d: _Direction, data: bytes, now: float) -> None:
        c, imp, rng = d.counts, d.imp, d.rng
        c["received"] += 1
        t = self._elapsed(now)
        if any(o.covers(t, d.name) for o in self.outages):
            c["outage"] += 1
            return
        if rng.random() < imp.loss:
            c["lost"] += 1
            return
        delay = imp.delay_ms + (rng.uniform(-imp.jitter_ms, imp.jitter_ms) if imp.jitter_ms else 0.0)
        reordered = rng.random() < imp.reorder
        if reordered:
            c["reordered"] += 1
            delay += imp.reorder_ms
        due = now + max(delay, 0.0) / 1000.0
        if not (imp.jitter_ms or reordered):
            due = d.last_due = max(due, d.last_due)
        copies = [due]
        if rng.random() < imp.duplicate:
            c["duplicated"] += 1
            copies.append(due + imp.duplicate_gap_ms / 1000.0)
        for when in copies:
            self._seq += 1
            heapq.heappush(self._queue, (when, self._seq, d is self.up, data))
        self.max_queue = max(self.max_queue, len(self._queue))

    def _deliver(self, now: float) -> None:
        q = self._queue
        while q and q[0][0] <= now:
            due, _, upward, data = heapq.heappop(q)
            self.late_s.append(now - due)
            try:
                if upward:
                    self.vehicle_side.sendto(data, self.to)
                    self.up.counts["forwarded"] += 1
                elif self.client is not None:
                    self.client_side.sendto(data, self.client)
                    self.down.counts["forwarded"] += 1
            except OSError:  # e.g. ICMP port unreachable from a peer that went away
                pass

    def _read(self, sock: socket.socket, upward: bool) -> None:
        now, wall_now = clock_pair()  # one mapping of kernel stamps for the whole batch
        for _ in range(256):  # bounded: one busy side cannot starve the other
            try:
                data, anc, _, addr = sock.recvmsg(MAX_DATAGRAM, 64)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                continue
            if upward and not self._from_client(addr, now):
                self.strangers += 1
                continue
            self._schedule(self.up if upward else self.down, data, kernel_arrival(anc, now, wall_now))

    def _from_client(self, addr: tuple[str, int], now: float) -> bool:
        """Whether a datagram from ``addr`` is the client's (pinning the first sender, or a new one
        after the client's silence)."""
        if addr != self.client:
            if self.fixed_client is not None or now - self.client_heard <= self.repin_s:
                return False
            if self.client is not None:
                self.repinned += 1
            self.client = addr
        self.client_heard = now
        return True

    def run(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self.client_side, selectors.EVENT_READ, True)
        sel.register(self.vehicle_side, selectors.EVENT_READ, False)
        try:
            while self._running:
                now = time.monotonic()
                timeout = 0.05 if not self._queue else max(0.0, min(0.05, self._queue[0][0] - now))
                for key, _ in sel.select(timeout):
                    self._read(key.fileobj, key.data)  # type: ignore[arg-type]
                self._deliver(time.monotonic())
        finally:
            sel.close()
            self.client_side.close()
            self.vehicle_side.close()

    def report(self) -> dict:
        return {"up": self.up.counts, "down": self.down.counts, "max_queue": self.max_queue,
                "client": list(self.client) if self.client else None, "strangers": self.strangers,
                "repinned": self.repinned,
                "late_ms": percentiles_ms(self.late_s) or {"p50": 0.0, "p99": 0.0, "max": 0.0, "n": 0},
                "outages": [dataclasses.asdict(o) for o in self.outages],
                "impairment": {"up": dataclasses.asdict(self.up.imp), "down": dataclasses.asdict(self.down.imp)}}


def clock_pair(tries: int = 5, monotonic: Callable[[], float] = time.monotonic,
               wall_clock: Callable[[], float] = time.time) -> tuple[float, float]:
    """(monotonic, wall) clocks as of one instant, to map kernel stamps (wall) onto the monotonic
    clock. Read one after the other, a process descheduled between the two reads (a busy host)
    would map every stamp early by the gap, and the relay would deliver that much early (0.66 ms:
    a 10 ms minimum delay measured 9.34 in a fresh-clone CI); so the wall clock is read between two
    monotonic reads, and the tightest of ``tries`` brackets is kept (under 20 us: at once)."""
    best = (math.inf, 0.0, 0.0)
    for _ in range(tries):
        a = monotonic()
        wall = wall_clock()
        b = monotonic()
        if b - a < best[0]:
            best = (b - a, 0.5 * (a + b), wall)
        if b - a < 20e-6:
            break
    return best[1], best[2]


def kernel_arrival(ancillary: list[tuple[int, int, bytes]], now: float | None = None,
                   wall_now: float | None = None) -> float:
    """The kernel's arrival stamp (wall clock) on the monotonic clock; ``now`` without one.
    ``now`` and ``wall_now``: the two clocks as of one instant (:func:`clock_pair`, once for a batch
    of datagrams: read again for each, the later ones would be moved earlier by the time spent
    reading, and overtake); both read here if ``now`` is not given."""
    if now is None:
        now, wall_now = clock_pair()
    elif wall_now is None:
        wall_now = time.time()
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS and len(data) >= 16:
            sec, nsec = struct.unpack("qq", data[:16])
            return min(now, now - (wall_now - (sec + nsec * 1e-9)))
    return now


def _address(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    try:
        return host or "127.0.0.1", int(port)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT, got {text!r}") from None


def _outage(text: str) -> Outage:
    parts = text.split(":")
    try:
        if len(parts) not in (2, 3) or (len(parts) == 3 and parts[2] not in ("up", "down", "both")):
            raise ValueError
        return Outage(float(parts[0]), float(parts[1]), parts[2] if len(parts) == 3 else "both")
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected START_S:DURATION_S[:up|down|both], got {text!r}") from None


def _overrides(base: Impairment, items: Sequence[str], flag: str) -> Impairment:
    names = {f.name for f in dataclasses.fields(Impairment)}
    changes: dict[str, float] = {}
    for item in items:
        key, eq, value = item.partition("=")
        if not eq or key not in names:
            raise SystemExit(f"sitl-relay: {flag} {item!r}: expected KEY=VALUE with KEY one of {sorted(names)}")
        try:
            changes[key] = float(value)
        except ValueError:
            raise SystemExit(f"sitl-relay: {flag} {item!r}: {value!r} is not a number") from None
    return dataclasses.replace(base, **changes)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="sitl-relay", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--listen", type=_address, default=("127.0.0.1", 14600), help="where the client connects")
    ap.add_argument("--to", type=_address, default=("127.0.0.1", 14580), help="the vehicle (default: sitl's port)")
    ap.add_argument("--loss", type=float, default=0.0, help="probability, both directions")
    ap.add_argument("--delay-ms", type=float, default=0.0)
    ap.add_argument("--jitter-ms", type=float, default=0.0)
    ap.add_argument("--duplicate", type=float, default=0.0)
    ap.add_argument("--reorder", type=float, default=0.0)
    ap.add_argument("--reorder-ms", type=float, default=10.0)
    ap.add_argument("--up", action="append", default=[], metavar="KEY=VALUE", help="client -> vehicle only")
    ap.add_argument("--down", action="append", default=[], metavar="KEY=VALUE", help="vehicle -> client only")
    ap.add_argument("--outage", type=_outage, action="append", default=[], metavar="START:DURATION[:DIR]")
    ap.add_argument("--signal-outage-s", type=float, default=2.0, help="length of the outage SIGUSR1 starts")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--client", type=_address, default=None,
                    help="the only client (default: the first sender; another is taken after --repin-s of silence)")
    ap.add_argument("--repin-s", type=float, default=3.0, help="client silence after which a new sender is the client")
    args = ap.parse_args(argv)
    try:
        base = Impairment(args.loss, args.delay_ms, args.jitter_ms, args.duplicate, 1.0, args.reorder, args.reorder_ms)
        up, down = _overrides(base, args.up, "--up"), _overrides(base, args.down, "--down")
        if not args.repin_s > 0:
            raise ValueError(f"--repin-s {args.repin_s:g}: expected a positive number of seconds")
        relay = Relay(args.listen, args.to, up, down, args.outage, args.seed, args.signal_outage_s, args.client,
                      args.repin_s)
    except (ValueError, OSError) as exc:
        print(f"sitl-relay: {exc}", file=sys.stderr)
        return 2
    signal.signal(signal.SIGTERM, lambda *_: relay.stop())
    signal.signal(signal.SIGINT, lambda *_: relay.stop())
    signal.signal(signal.SIGUSR1, lambda *_: relay.outage_now())
    host, port = relay.address
    print(f"relay: listening on {host}:{port}, forwarding to {args.to[0]}:{args.to[1]}", flush=True)
    relay.run()
    print("relay: stopped " + json.dumps(relay.report()), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
