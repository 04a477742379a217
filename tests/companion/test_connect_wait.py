"""How long connecting may take (companion/link/base.py ConnectWait): --connect-timeout bounds the
heartbeat and the telemetry together; only a vehicle with attitude and no position yet gets
--position-wait more, and every line says which limit is running."""

from companion.link.base import ConnectWait


def test_without_attitude_the_connect_timeout_is_the_deadline_whatever_position_wait_says():
    assert ConnectWait(10.0).deadline_s(has_attitude=False) == 10.0
    assert ConnectWait(10.0, position_wait_s=60.0).deadline_s(has_attitude=False) == 10.0


def test_attitude_without_position_gets_exactly_position_wait_more():
    assert ConnectWait(10.0).deadline_s(has_attitude=True) == 10.0
    assert ConnectWait(10.0, position_wait_s=60.0).deadline_s(has_attitude=True) == 70.0


def test_the_lines_name_the_limit_that_runs_and_the_failure_names_the_option_to_wait_longer():
    w = ConnectWait(10.0, position_wait_s=30.0)
    assert "--connect-timeout 10 s" in w.progress(4.0, has_attitude=False)
    assert "then up to 30 s more (--position-wait)" in w.progress(4.0, has_attitude=True)
    assert "waiting up to 15 s more (--position-wait 30)" in w.progress(25.0, has_attitude=True)
    assert "no attitude and no position within 10 s" in w.failure(10.0, has_attitude=False)
    assert "--position-wait S" in ConnectWait(10.0).failure(10.0, has_attitude=True)
    assert "--position-wait S" not in w.failure(40.0, has_attitude=True)
