"""The parameter record's decisions, without a vehicle: what is put back, to which value, and what
the summary lists (companion/flight/param_record.py)."""

from __future__ import annotations

from companion.flight.param_record import ParamRecord


def test_each_written_parameter_is_put_back_to_the_value_found_before_the_first_write():
    r = ParamRecord().written("MIS_TAKEOFF_ALT", 2.5, 1.5).written("MPC_LAND_SPEED", 0.7, 1.2)
    r = r.written("MPC_LAND_SPEED", 1.2, 0.4)  # written twice: still back to the first value found
    assert r.to_restore() == (("MPC_LAND_SPEED", 0.7), ("MIS_TAKEOFF_ALT", 2.5))  # last changed first
    assert r.summary()["not_restored"] == {"MIS_TAKEOFF_ALT": 2.5, "MPC_LAND_SPEED": 0.7}  # nothing put back yet


def test_a_parameter_written_back_to_its_original_value_needs_nothing():
    r = ParamRecord().written("SIM_WIND_E", 0.0, 3.0).written("SIM_WIND_E", 3.0, 0.0)
    assert r.to_restore() == () and not r.pending
    assert r.summary() == {"restored": {}, "not_restored": {}, "kept": {}}


def test_a_kept_write_stays_and_is_listed_as_kept():
    r = ParamRecord().written("MPC_LAND_SPEED", 0.7, 1.2, keep=True).written("SIM_WIND_E", 0.0, 2.0)
    assert r.to_restore() == (("SIM_WIND_E", 0.0),)
    r = r.restored("SIM_WIND_E")
    assert r.summary() == {"restored": {"SIM_WIND_E": 0.0}, "not_restored": {}, "kept": {"MPC_LAND_SPEED": 1.2}}


def test_a_write_after_a_kept_one_is_put_back_to_the_kept_value():
    r = ParamRecord().written("MPC_LAND_SPEED", 0.7, 1.2, keep=True).written("MPC_LAND_SPEED", 1.2, 2.0)
    assert r.to_restore() == (("MPC_LAND_SPEED", 1.2),)
    r = ParamRecord().written("MPC_LAND_SPEED", 0.7, 2.0).written("MPC_LAND_SPEED", 2.0, 1.2, keep=True)
    assert r.to_restore() == () and r.summary()["kept"] == {"MPC_LAND_SPEED": 1.2}


def test_what_could_not_be_put_back_is_listed_with_the_value_to_set_by_hand():
    r = ParamRecord().written("GUID_OPTIONS", 0.0, 8.0).written("GUID_TIMEOUT", 3.0, 0.5)
    r = r.restored("GUID_TIMEOUT").give_up()
    assert not r.pending
    assert r.summary() == {"restored": {"GUID_TIMEOUT": 3.0}, "not_restored": {"GUID_OPTIONS": 0.0}, "kept": {}}


def test_a_refused_restore_is_not_tried_again():
    r = ParamRecord().written("X", 1.0, 2.0).not_restored("X")
    assert r.to_restore() == () and r.summary()["not_restored"] == {"X": 1.0}


def test_the_record_is_immutable():
    r = ParamRecord()
    r.written("X", 1.0, 2.0)
    assert r.entries == ()
