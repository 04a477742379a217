"""More than one vehicle on a link: the target system, every autopilot heard, two senders claiming
one identity (companion/mavlink/identity.py), decided without sockets; and the link's receive path
fed frames as a router would deliver them (one address, several systems)."""

import random

import pytest
from pymavlink.dialects.v20 import common as mavlink

from companion.mavlink.modes import px4_custom_mode
from companion.config import ConfigError
from companion.mavlink.identity import (AutopilotsHeard, SequenceStreams, VehicleTarget, connection_problem,
                                        resolve_target)
from companion.mission import load_mission
from helpers.links import fed_link

ROUTER = ("127.0.0.1", 14550)


def heartbeat(m):
    return m.heartbeat_encode(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4,
                              mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, px4_custom_mode("HOLD"),
                              mavlink.MAV_STATE_STANDBY).pack(m)


def position(m, x):
    return m.local_position_ned_encode(1000, x, 0.0, -1.0, 0, 0, 0).pack(m)


def test_one_sender_with_loss_reordering_duplicates_and_an_outage_is_one_sender():
    rng = random.Random(3)
    streams = SequenceStreams()
    seq, sent = 0, []
    for i in range(3000):
        seq = (seq + 1) % 256
        if 1000 <= i < 1200 or rng.random() < 0.2:  # an outage of 200 frames, and 20 % loss
            continue
        sent.append(seq)
        if rng.random() < 0.05:
            sent.append(seq)  # duplicated on the way
    for i in range(0, len(sent) - 1, 17):  # some swapped neighbours: reordered
        sent[i], sent[i + 1] = sent[i + 1], sent[i]
    for s in sent:
        streams.add(s)
    assert streams.senders == 1


@pytest.mark.parametrize("ratio", [1, 3, 10])
def test_two_interleaved_senders_are_two_even_when_one_sends_a_tenth_as_much(ratio):
    rng = random.Random(ratio)
    streams = SequenceStreams()
    a, b = 0, 137
    for i in range(400 * ratio):
        a = (a + 1) % 256
        streams.add(a)
        if i % ratio == 0 and rng.random() < 0.9:
            b = (b + 1) % 256
            streams.add(b)
    assert streams.senders == 2


@pytest.mark.parametrize("offset", [0, 1, 5, 16, 17, 31, 40, 128, 250])
def test_two_senders_at_one_rate_are_two_however_close_their_counters_run(offset):
    """Counters within SEQ_BEHIND of each other make one run, the other sender's frames repeats:
    still two senders, within the survey's 100 frames."""
    rng = random.Random(offset)
    streams = SequenceStreams()
    a, b = 0, offset
    while streams.frames < 100:
        for _ in range(rng.choice((1, 1, 2))):  # not strictly alternating: the scheduler's order
            a = (a + 1) % 256
            streams.add(a)
        b = (b + 1) % 256
        streams.add(b)
    assert streams.senders == 2


def test_a_sender_that_does_not_count_is_one_sender():
    """Every frame numbered 0 (pymavlink's ``msg.pack(mav)`` does not advance the counter; simple
    MAVLink code does the same): all repeats, nothing counted on, one sender."""
    streams = SequenceStreams()
    for _ in range(300):
        streams.add(0)
    assert streams.senders == 1


def test_the_absent_target_names_the_systems_heard():
    heard = AutopilotsHeard()
    heard.heartbeat(1, 1, ROUTER)
    heard.heartbeat(3, 1, ROUTER)
    why = connection_problem(VehicleTarget(2), heard, None)
    assert why == "no heartbeat from system 2; heard systems 1, 3"


def test_without_a_target_two_autopilots_are_refused_and_with_one_the_others_are_ignored():
    heard = AutopilotsHeard()
    heard.heartbeat(1, 1, ROUTER)
    heard.heartbeat(2, 1, ROUTER)
    assert "more than one autopilot on this link: systems 1, 2" in connection_problem(VehicleTarget(), heard, (1, 1))
    assert connection_problem(VehicleTarget(2), heard, (2, 1)) is None


def test_one_identity_from_two_addresses_is_two_claimants():
    heard = AutopilotsHeard()
    heard.heartbeat(2, 1, ("127.0.0.1", 5000))
    heard.heartbeat(2, 1, ("127.0.0.1", 5001))
    assert "two autopilots claim system 2 component 1" in connection_problem(VehicleTarget(2), heard, (2, 1))


def test_the_command_line_overrides_the_missions_target_and_says_so():
    assert resolve_target(VehicleTarget(2), VehicleTarget(1, 1)) == (
        VehicleTarget(2), "target: system 2 from the command line, overriding the mission's [target] "
                          "(system 1 component 1)")
    assert resolve_target(None, VehicleTarget(1)) == (VehicleTarget(1), None)
    assert resolve_target(VehicleTarget(1), VehicleTarget(1)) == (VehicleTarget(1), None)


def test_a_missions_target_table_is_read_and_a_bad_one_refused_with_its_line(tmp_path):
    base = (tmp_path / "base.toml")
    steps = '[[steps]]\naction = "takeoff"\naltitude_m = 1\n[[steps]]\naction = "land"\n'
    base.write_text('[target]\nsystem_id = 2\ncomponent_id = 1\n' + steps)
    assert load_mission(base).target == VehicleTarget(2, 1)
    for bad, says in (("system_id = 256", "system_id: expected 1..255"), ('system_id = "2"', "expected an integer"),
                      ("component_id = 1", "component_id: needs a system_id"), ("sysid = 2", "unknown key")):
        f = tmp_path / "bad.toml"
        f.write_text(f"[target]\n{bad}\n" + steps)
        with pytest.raises(ConfigError) as err:
            load_mission(f)
        assert says in str(err.value) and ":2" in str(err.value) or ":1" in str(err.value), str(err.value)


def _fed(frames, target):
    return fed_link(frames, ROUTER, target=target)


def test_behind_a_router_the_target_system_is_followed_and_the_other_ignored():
    v1, v2 = mavlink.MAVLink(None, 1, 1), mavlink.MAVLink(None, 2, 1)
    link = _fed([heartbeat(v1), heartbeat(v2), position(v1, 7.0), position(v2, 3.0)], VehicleTarget(2))
    assert (link.state.sysid, link.state.pos_ned_m) == (2, (3.0, 0.0, -1.0))
    assert link.stats["foreign_messages"] == 1 and link.stats["foreign_heartbeats"] == 1
    assert link.heard.systems() == [1, 2]


def test_a_burst_of_loss_then_the_wrap_is_still_one_sender():
    """One sender, 40 frames lost in a row (a new run begins), then on past the wrap: the new run
    reaches the old one's numbers 256 frames later, which must not read as a second sender (PX4 on
    the plant, a loaded host: "two autopilots claim system 8" in 1 of 21 bench flights)."""
    from companion.mavlink.identity import SequenceStreams

    s = SequenceStreams()
    for seq in range(0, 100):
        s.add(seq % 256)
    after = list(range(140, 140 + 600))
    for i in range(0, len(after) - 1, 2):  # delivered in swapped pairs (two paths, a busy host)
        after[i], after[i + 1] = after[i + 1], after[i]
    for seq in after:
        s.add(seq % 256)
    assert s.senders == 1
