"""The impairment relay as its own process on real UDP sockets: each impairment does what it says."""

import socket
import statistics
import struct
import threading
import time

import pytest

from sitl.netem.relay import SO_TIMESTAMPNS, Impairment, clock_pair, kernel_arrival, main


class Ends:
    """A 'client' socket and a 'vehicle' socket; the relay process sits between them."""

    def __init__(self, relay_fixture, *args: str) -> None:
        self.vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.vehicle.bind(("127.0.0.1", 0))
        self.vehicle.settimeout(0.5)
        if SO_TIMESTAMPNS is not None:  # arrival stamped by the kernel: a late-running receiver adds nothing
            self.vehicle.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        host, port = self.vehicle.getsockname()
        self.relay = relay_fixture(f"{host}:{port}", *args)
        h, _, p = self.relay.url.rpartition(":")
        self.relay_addr = (h, int(p))
        self.client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.client.bind(("127.0.0.1", 0))
        self.client.settimeout(0.5)

    def send_up(self, n: int, spacing_s: float = 0.0005) -> list[tuple[int, float]]:
        """n numbered, time-stamped datagrams client -> vehicle; (number, delay ms) as received.
        A thread receives while they are sent: the arrival time is the delay, and a socket
        buffer left unread would overflow."""
        got: list[tuple[int, float]] = []
        rx = threading.Thread(target=self.receive, args=(got,))
        rx.start()
        for i in range(n):
            self.client.sendto(struct.pack("<Id", i, time.monotonic()), self.relay_addr)
            if spacing_s:
                time.sleep(spacing_s)
        rx.join()
        return got

    def receive(self, got: list[tuple[int, float]]) -> list[tuple[int, float]]:
        while True:
            try:
                data, anc, _, self.relay_vehicle_side = self.vehicle.recvmsg(100, 64)
            except TimeoutError:
                return got
            i, sent = struct.unpack("<Id", data)
            got.append((i, (kernel_arrival(anc) - sent) * 1000))

    def close(self) -> None:
        self.client.close()
        self.vehicle.close()


@pytest.fixture
def ends(relay):
    made = []

    def make(*args: str) -> Ends:
        e = Ends(relay, *args)
        made.append(e)
        return e

    yield make
    for e in made:
        e.close()


def test_loss_rate_is_the_requested_one_and_the_same_seed_loses_the_same_datagrams(ends):
    """2000 datagrams at p = 0.1: the count lost is binomial, sd = sqrt(2000 * 0.1 * 0.9) = 13.4;
    accept +-4 sd (146..254). The same seed drops the same datagrams; another seed does not."""
    a = ends("--up", "loss=0.1", "--seed", "7")
    got_a = {i for i, _ in a.send_up(2000)}
    assert 146 <= 2000 - len(got_a) <= 254
    assert a.relay.stop()["up"]["lost"] == 2000 - len(got_a)
    b = ends("--up", "loss=0.1", "--seed", "7")
    assert {i for i, _ in b.send_up(2000)} == got_a
    c = ends("--up", "loss=0.1", "--seed", "8")
    assert {i for i, _ in c.send_up(2000)} != got_a


def test_without_jitter_or_reordering_every_datagram_keeps_its_place(ends):
    """A burst of 3000 datagrams with no pause between them, and no impairment: delivered in the order
    sent, however close their kernel stamps (docs/faults.md: the relay that reordered bursts). Then
    the same with a 5 ms delay."""
    for args in ((), ("--delay-ms", "5")):
        e = ends(*args)
        order = [i for i, _ in e.send_up(3000, spacing_s=0.0)]
        e.relay.stop()
        assert order == sorted(order), (args, sum(1 for a, b in zip(order, order[1:]) if b < a))


def test_delay_and_jitter_and_the_reordering_jitter_causes(ends):
    """20 +- 10 ms uniform: no delay below 10 ms; above 30 ms only by as much as the relay reports it
    went out late (descheduled past a due time: this shared host stalls processes for tens of ms)
    plus 2 ms; its median lateness under 1 ms (a relay late by design would fail); mean within 3 ms
    of 20 ms. Arrival is stamped by the kernel at both the relay and the receiver. Datagrams 0.5 ms
    apart with a 20 ms jitter spread must overtake each other."""
    e = ends("--delay-ms", "20", "--jitter-ms", "10", "--seed", "1")
    got = e.send_up(400)
    assert len(got) == 400
    delays = [d for _, d in got]
    late = e.relay.stop()["late_ms"]
    assert late["p50"] < 1.0, late
    assert min(delays) >= 10.0 - 0.2 and max(delays) < 30.0 + 2.0 + late["max"], (min(delays), max(delays), late)
    assert abs(statistics.mean(delays) - 20.0) < 3.0 + late["p99"]
    order = [i for i, _ in got]
    assert order != sorted(order)


def test_the_clocks_are_read_as_of_one_instant_even_when_a_read_is_descheduled():
    """Kernel stamps (wall clock) map onto the monotonic clock through one reading of both. A
    process descheduled between the two reads for 0.66 ms mapped every stamp 0.66 ms early, and the
    relay delivered that much early (a 10 ms minimum delay measured 9.34 ms in a fresh-clone CI):
    the wall clock is read between two monotonic reads, and a bracket wider than 20 us is read
    again, the tightest kept. Here the first bracket is split by 0.66 ms, the second is not (the
    wall clock runs 1000 s ahead of the monotonic one): the mapping is the second's, exact."""
    monotonic = iter([10.0, 10.00066, 10.001, 10.001005]).__next__
    wall = iter([1010.0, 1010.001002]).__next__
    now, wall_now = clock_pair(monotonic=monotonic, wall_clock=wall)
    assert abs(wall_now - now - 1000.0) < 5e-6, (now, wall_now)
    split = iter([10.0, 10.00066] * 5).__next__  # never tight: the tightest of the tries is kept
    now, wall_now = clock_pair(monotonic=split, wall_clock=iter([1010.00066] * 5).__next__)
    assert abs(wall_now - now - 1000.0) < 0.00034, (now, wall_now)  # the bracket's midpoint, not its start


def test_duplicates_and_explicit_reordering(ends):
    """p = 0.2 each over 1000 datagrams: binomial mean 200, sd 12.6; accept +-6 sd. Nothing lost."""
    e = ends("--duplicate", "0.2", "--reorder", "0.2", "--reorder-ms", "5", "--seed", "3")
    seqs = [i for i, _ in e.send_up(1000)]
    report = e.relay.stop()
    dups = len(seqs) - len(set(seqs))
    assert dups == report["up"]["duplicated"] and 124 <= dups <= 276
    assert 124 <= report["up"]["reordered"] <= 276
    assert sum(1 for k in range(1, len(seqs)) if seqs[k] < seqs[k - 1]) > 50
    assert set(seqs) == set(range(1000))


def test_an_outage_drops_one_direction_only_for_its_length(ends):
    """Uplink outage from 0.3 s to 0.6 s after the first datagram, datagrams every 10 ms: those sent
    inside it are gone (20 ms margin at each edge), those outside arrive; the downlink works
    throughout."""
    e = ends("--outage", "0.3:0.3:up")
    sent_at = {}
    received: list[tuple[int, float]] = []
    rx = threading.Thread(target=e.receive, args=(received,))
    rx.start()
    t0 = time.monotonic()
    for i in range(90):
        sent_at[i] = time.monotonic() - t0
        e.client.sendto(struct.pack("<Id", i, time.monotonic()), e.relay_addr)
        time.sleep(0.01)
    rx.join()
    got = {i for i, _ in received}
    inside = {i for i, t in sent_at.items() if 0.32 < t < 0.58}
    outside = {i for i, t in sent_at.items() if t < 0.28 or t > 0.62}
    assert len(inside) > 15 and not (inside & got)
    assert outside <= got
    e.vehicle.sendto(b"down", e.relay_vehicle_side)
    assert e.client.recvfrom(100)[0] == b"down"
    assert e.relay.stop()["up"]["outage"] == len(set(range(90)) - got)


def test_bad_options_are_refused_with_a_clear_message(capsys):
    with pytest.raises(ValueError, match="loss must be a probability"):
        Impairment(loss=1.5)
    assert main(["--listen", "127.0.0.1:0", "--loss", "2"]) == 2
    assert "loss must be a probability" in capsys.readouterr().err
    with pytest.raises(SystemExit, match="expected KEY=VALUE"):
        main(["--listen", "127.0.0.1:0", "--up", "lossy=0.1"])


def test_a_stranger_neither_reaches_the_vehicle_nor_diverts_the_downlink():
    """The first sender is the client; 2,657 heartbeats from another address are dropped and
    counted, and the vehicle's replies still go to the client (they used to follow whoever spoke
    last, and the companion behind the relay aborted). After the client's silence (--repin-s) a
    new sender takes over: a companion restarted on another port."""
    import socket
    import threading
    import time

    from sitl.netem.relay import Impairment, Relay

    vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vehicle.bind(("127.0.0.1", 0))
    vehicle.settimeout(2.0)
    relay = Relay(("127.0.0.1", 0), vehicle.getsockname(), Impairment(), Impairment(), repin_s=0.5)
    thread = threading.Thread(target=relay.run, daemon=True)
    thread.start()
    client, stranger, later = (socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(3))
    for s in (client, stranger, later):
        s.bind(("127.0.0.1", 0))
        s.settimeout(2.0)
    try:
        client.sendto(b"client", relay.address)
        assert vehicle.recvfrom(100)[0] == b"client"
        for k in range(2657):
            stranger.sendto(b"stranger", relay.address)
            client.sendto(b"client", relay.address)  # the client keeps talking
            if k % 50 == 0:
                time.sleep(0.002)  # within what the sockets' buffers hold
        n = 0
        vehicle.settimeout(0.3)
        try:
            while True:
                assert vehicle.recvfrom(100)[0] == b"client"
                n += 1
        except TimeoutError:
            pass
        relay_side = relay.vehicle_side.getsockname()
        vehicle.sendto(b"telemetry", relay_side)
        assert client.recvfrom(100)[0] == b"telemetry"
        # every stranger's datagram the relay read was dropped; only the client's reached the vehicle
        up = relay.up.counts
        assert relay.strangers > 2000 and up["received"] > 2000 and up["forwarded"] == up["received"] and n > 0, \
            (relay.strangers, dict(up), n)
        time.sleep(0.7)  # the client falls silent longer than --repin-s
        later.sendto(b"restarted", relay.address)
        vehicle.settimeout(2.0)
        assert vehicle.recvfrom(100)[0] == b"restarted"
        vehicle.sendto(b"telemetry", relay_side)
        assert later.recvfrom(100)[0] == b"telemetry" and relay.repinned == 1
    finally:
        relay.stop()
        thread.join(2)
        for s in (vehicle, client, stranger, later):
            s.close()
