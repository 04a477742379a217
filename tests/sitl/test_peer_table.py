"""The peer table's rules (sitl.autopilot.peers) on their own, with wall time passed in."""

from __future__ import annotations

import math

from sitl.autopilot.peers import PROTECT_S, Bucket, PeerTable


def test_a_churn_only_ever_displaces_itself() -> None:
    table = PeerTable({}, max_peers=4)
    for now in (0.0, 0.5, 1.0):
        table.note(("gcs", 1), now, 0.0)
    table.note(("companion", 2), 1.0, 0.0)
    table.controller = ("companion", 2)
    for i in range(1000):
        assert table.note(("churn", i), 1.0 + i * 1e-3, 0.0) is not None
    assert ("gcs", 1) in table and ("companion", 2) in table and len(table) == 4
    assert table.evicted == 998 and table.refused == 0


def test_the_peer_table_refuses_a_newcomer_only_while_every_peer_is_protected() -> None:
    table = PeerTable({}, max_peers=2)
    for now in (0.0, 0.1, 0.2):
        table.note(("a", 1), now, 0.0)
        table.note(("b", 2), now, 0.0)
    assert table.note(("c", 3), 0.3, 0.0) is None and table.refused == 1
    assert table.note(("c", 3), 0.4, 0.0) is None  # heard twice: still less than the others
    late = 0.2 + PROTECT_S + 0.1  # a and b silent past the protection; c has talked as much as they
    table.note(("a", 1), late, 0.0)
    assert table.note(("c", 3), late, 0.0) is not None
    assert ("b", 2) not in table and table.evicted == 1


def test_a_token_bucket_refills_at_its_rate() -> None:
    b = Bucket(10.0, 5.0)
    assert sum(b.take(0.0) for _ in range(20)) == 5
    assert sum(b.take(0.5) for _ in range(20)) == 5  # 10/s x 0.5 s, capped at the burst
    assert not b.take(0.55) and b.take(0.65)
    assert math.isclose(b.tokens, 0.5)
