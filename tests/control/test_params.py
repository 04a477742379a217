"""Parameter files: defaults are the paper's, bad keys and types fail with file, line and key."""

import pytest

from companion.config import ConfigError, load_dataclass, load_toml, locate
from companion.control.params import AttitudeGains, PositionGains, from_mapping, to_mapping
from sitl.plant.scenario import Scenario, load_scenario


def test_defaults_are_the_papers():
    a, p = AttitudeGains(), PositionGains()
    assert a.omega_c_rad_s == 12.0 and a.observer_gain_rad_s == (8.0, 8.0, 8.0)
    assert p.omega_c_rad_s == (1.5, 1.5, 1.5) and p.observer_gain_rad_s == (3.0, 3.0, 1.5)
    assert p.aibc_gamma_per_s == (4.0, 4.0, 2.0)
    assert p.k_v() == (3.0, 3.0, 3.0) and p.k_p() == (2.25, 2.25, 2.25) and p.k_i() == (0.375,) * 3


def test_round_trip_through_a_mapping():
    g = AttitudeGains(omega_c_rad_s=10.0, observer_gain_rad_s=(1.0, 2.0, 3.0))
    assert from_mapping(AttitudeGains, to_mapping(g)) == g


def test_gains_are_frozen():
    with pytest.raises(AttributeError):
        AttitudeGains().omega_c_rad_s = 3.0  # type: ignore[misc]


def write(tmp_path, text):
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_unknown_key_names_file_line_and_accepted_keys(tmp_path):
    p = write(tmp_path, 'name = "x"\n\n[attitude]\nomega_c_rad_s = 10\nomega_c = 3\n')
    with pytest.raises(ConfigError) as e:
        load_scenario(p)
    assert e.value.line == 5 and e.value.key == "attitude.omega_c"
    assert "omega_c_rad_s" in str(e.value) and str(p) in str(e.value)


def test_wrong_type_names_expected_type(tmp_path):
    p = write(tmp_path, '[position]\nobserver_gain_rad_s = [3, "fast", 1]\n')
    with pytest.raises(ConfigError) as e:
        load_scenario(p)
    assert e.value.line == 2 and "expected a number" in str(e.value)


def test_error_inside_an_array_of_tables_points_at_the_right_item(tmp_path):
    text = (
        '[[forces]]\nkind = "step"\nvalue = [1, 0, 0]\n\n'
        '[[forces]]\nkind = "stepp"\nvalue = [1, 0, 0]\n'
    )
    p = write(tmp_path, text)
    with pytest.raises(ConfigError) as e:
        load_scenario(p)
    assert e.value.key == "forces[1]" and e.value.line == 5 and "stepp" in str(e.value)


def test_syntax_error_reports_line(tmp_path):
    p = write(tmp_path, 'name = "x"\nduration_s = = 3\n')
    with pytest.raises(ConfigError) as e:
        load_scenario(p)
    assert e.value.line == 2


def test_locate_nested_tables():
    text = "[wind]\nmean_ned_m_s = [1,0,0]\n[wind.turbulence]\nenabled = true\nw20 = 3\n"
    assert locate(text, "wind.turbulence.w20") == 5
    assert locate(text, "wind.mean_ned_m_s") == 2


def test_every_bundled_scenario_loads():
    from sitl.plant.scenario import SCENARIO_DIR

    files = sorted(SCENARIO_DIR.glob("*.toml"))
    assert len(files) >= 5
    for f in files:
        assert isinstance(load_scenario(f), Scenario)


def test_load_dataclass_reports_constructor_validation(tmp_path):
    p = write(tmp_path, "[runs]\nposition = [\"pid\", \"lqr\"]\n")
    data, text = load_toml(p)
    with pytest.raises(ConfigError) as e:
        load_dataclass(Scenario, {"name": "x", **data}, p, text)
    assert "lqr" in str(e.value) and e.value.line == 1


def test_attitude_sliding_gain_sits_between_25_and_the_rotor_bandwidth():
    """K = k_s J0 is chosen by two bounds (docs/experiments.md, the attitude boundary layer):
    (25), 4 k_s J0,min Gamma_a > 1, i.e. k_s > 1 / (4 * 3.5e-3 * 8) = 8.9 rad/s for the
    Hummingbird's J0; and the sliding dynamics (rate k_s inside the layer) at least four times
    slower than the rotors' 20 ms lag: k_s <= 1 / (4 * 0.02) = 12.5 rad/s. The paper's 12 fits."""
    from companion.control.params import AttitudeGains, VehicleParams, attitude_stability_margin
    from sitl.plant.airframe import AirframeParams

    gains, vehicle = AttitudeGains(), VehicleParams()
    assert attitude_stability_margin(gains, vehicle) > 1.0
    assert max(gains.sliding_gain_rad_s) <= 1.0 / (4.0 * AirframeParams().rotor_time_constant_s)
