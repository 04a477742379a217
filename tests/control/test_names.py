"""The controller registry: every loop's names, numbers, labels and figure styles come from it."""

import pytest

from companion.control import attitude, position
from companion.control.names import CONTROLLERS, Controller, att_ctrl_kinds, controller_label, controllers_for
from companion.control.params import PositionGains


def test_each_loop_lists_exactly_the_controllers_that_serve_it_and_its_kind_numbers_name_them():
    """Attitude controllers are numbered by their place in the loop's tuple; each position
    controller builds the constants of one family, whose type has its step function."""
    assert attitude.ATTITUDE_CONTROLLERS == tuple(c.name for c in CONTROLLERS if "attitude" in c.loops)
    assert position.POSITION_CONTROLLERS == tuple(c.name for c in CONTROLLERS if "position" in c.loops)
    names = attitude.ATTITUDE_CONTROLLERS
    assert [names[k] for k in (attitude.PD, attitude.PD_DO, attitude.ISM_DO, attitude.INDI)] == [
        "pd", "pd_do", "ism_do", "indi"]
    families = {name: type(position.position_const(name, PositionGains(), 1.0, 9.81, 0.01))
                for name in position.POSITION_CONTROLLERS}
    assert families == {"pid": position.PidConst, "aibc": position.AibcConst, "pd_do": position.DoConst,
                        "ism_do": position.DoConst, "indi": position.DoConst}
    assert set(position.STEPS) == set(families.values())


def test_every_controller_has_a_label_of_its_own_and_a_distinct_figure_style_in_its_loop():
    labels = [c.label for c in CONTROLLERS]
    assert len(set(labels)) == len(labels) and all(controller_label(c.name) == c.label for c in CONTROLLERS)
    pos = [c.color for c in CONTROLLERS if "position" in c.loops]
    att = [c.linestyle for c in CONTROLLERS if "attitude" in c.loops]
    assert len(set(pos)) == len(pos) and len(set(att)) == len(att)
    assert controller_label("lqr") == "lqr"  # a name it does not know is shown as it is


def test_att_ctrl_numbers_are_the_bundled_vehicles_parameter_values_and_a_gap_is_refused():
    assert att_ctrl_kinds() == ("pd", "pd_do", "ism_do")  # ATT_CTRL 0, 1, 2 as published in docs/sitl.md
    from sitl.autopilot.parameters import CONTROLLER_ROWS

    row = next(r for r in CONTROLLER_ROWS if r.name == "ATT_CTRL")
    assert row.maximum == 2.0 and row.description.endswith("0 PD, 1 PD+DO, 2 ISM+DO")
    with pytest.raises(ValueError, match="loops"):
        Controller("x", "X", ("outer",), "")
    with pytest.raises(ValueError, match="unknown loop|expected one of"):
        controllers_for("outer")
