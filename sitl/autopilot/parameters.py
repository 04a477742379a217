"""The simulated vehicle's parameters: controller gains, firmware behaviour, simulation settings.

Served over the MAVLink parameter protocol (all REAL32), so QGroundControl, MAVProxy or a
script can read them and change them in flight: wind, turbulence, an external force or torque,
a mass error or a weak motor take effect at the next plant step. Names follow PX4 where PX4
has the parameter (COM_OF_LOSS_T, MIS_TAKEOFF_ALT, ...); SIM_* are the simulation's own.

One declarative table (:data:`PX4_ROWS`, :data:`ARDUPILOT_ROWS`, :data:`COMMON_ROWS`; the SIM_* rows
are the plant's own, :mod:`sitl.plant.parameters`): each row
names the field it sets (of the autopilot's :class:`~sitl.autopilot.logic.AutopilotParams`, of the
live :class:`~sitl.plant.scenario.Scenario`, or of the vehicle), its range and its unit. The ranges are
what flies: any value in range, alone or with any others in range, leaves the hovering vehicle
upright (``tests/sitl/test_parameters.py`` sets them all, edges included, in flight), except the
rows marked as deliberate faults (a dead motor, a failed sensor), which end in a defined failsafe.
A value outside its range, a non-integer for an integer parameter, or a write to a read-only one
is refused (the old value is echoed, as PX4 does) with a reason. The table in docs/sitl.md is
:func:`markdown_table`'s output (a test keeps them equal).
"""

from __future__ import annotations

import dataclasses
from typing import Callable

from companion.control.names import att_ctrl_kinds, controller_label

from ..plant.parameters import (D, SIM_ROWS, THRUST_MAX_ROW, XYZ, Param, ParamTable, PlantBinding, Row,
                                bind_rows)
from .logic import Autopilot, Severity

__all__ = ["Row", "Param", "ParamTable", "build_parameters", "CONTROLLER_ROWS", "markdown_table", "PX4_ROWS",
           "ARDUPILOT_ROWS", "COMMON_ROWS", "ATTITUDE_KINDS"]

ATTITUDE_KINDS = att_ctrl_kinds()
"""Attitude controller names by their ATT_CTRL value (the registry, companion/control/names.py)."""



PX4_ROWS: tuple[Row, ...] = (
    Row("COM_OF_LOSS_T", "autopilot.offboard_loss_timeout_s", 0.1, 60.0, "s", "offboard loss timeout"),
    Row("COM_FAIL_ACT_T", "autopilot.failsafe_hold_s", 0.0, 60.0, "s", "hold before landing after offboard loss"),
    Row("MIS_TAKEOFF_ALT", "autopilot.takeoff_alt_m", 0.5, 100.0, "m", "take-off height above home"),
    Row("MPC_TKO_SPEED", "autopilot.takeoff_speed_m_s", 0.2, 3.0, "m/s", "take-off climb speed"),
    Row("MPC_LAND_SPEED", "autopilot.land_speed_m_s", 0.2, 3.0, "m/s", "landing descent speed"),
    Row("COM_DISARM_PRFLT", "autopilot.disarm_preflight_s", 0.0, 120.0, "s", "disarm if no take-off within"),
    Row("COM_DISARM_LAND", "autopilot.disarm_land_s", 0.0, 60.0, "s", "disarm after touch-down"),
    Row("MPC_THR_HOVER", "derived.hover_thrust", 0.0, 1.0, "", "hover thrust, normalised (m g / T_max)",
        read_only=True),
    THRUST_MAX_ROW,
)

ARDUPILOT_ROWS: tuple[Row, ...] = (
    Row("GUID_OPTIONS", "autopilot.guided_options", 0.0, 1023.0, "",
        "bitmask; bit 3 (8): SET_ATTITUDE_TARGET thrust is throttle, else a climb rate", integer=True),
    Row("GUID_TIMEOUT", "autopilot.guided_timeout_s", 0.1, 5.0, "s", "attitude targets older than this are not flown"),
    Row("ATC_ANGLE_MAX", "autopilot.angle_max_deg", 10.0, 80.0, "deg", "maximum lean angle of ArduPilot's own "
        "modes (not of GUIDED attitude targets)"),
    Row("ATC_RATE_FF_ENAB", "autopilot.rate_ff_enabled", 0.0, 1.0, "", "1: attitude targets are shaped by "
        "ATC_INPUT_TC; 0: flown as sent", integer=True),
    Row("ATC_INPUT_TC", "autopilot.input_tc_s", 0.0, 1.0, "s", "time constant of that shaping"),
    Row("ATC_ANGLE_BOOST", "autopilot.angle_boost", 0.0, 1.0, "", "1: throttle divided by the cosine of the "
        "tilt", integer=True),
    Row("MOT_THST_HOVER", "derived.hover_thrust", 0.0, 1.0, "", "hover throttle, normalised: 5 % low at boot, "
        "learnt in flight (10 s time constant)", read_only=True),
)

CONTROLLER_ROWS: tuple[Row, ...] = (
    Row("ATT_CTRL", "controller", 0.0, float(len(ATTITUDE_KINDS) - 1), "",
        "attitude controller: " + ", ".join(f"{i} {controller_label(k)}" for i, k in enumerate(ATTITUDE_KINDS)),
        integer=True),
    Row("ATT_W_C", "scenario.attitude.omega_c_rad_s", 6.0, 20.0, "rad/s", "attitude omega_c"),
    Row("ATT_GAMMA", "scenario.attitude.observer_gain_rad_s", 1.0, 40.0, "rad/s", "torque observer Gamma_a",
        components=XYZ),
    Row("ATT_K_S", "scenario.attitude.sliding_gain_rad_s", 0.0, 20.0, "rad/s", "ISM sliding gain", components=XYZ),
    Row("ATT_EPS", "scenario.attitude.boundary_layer_rad_s", 0.1, 2.0, "rad/s", "ISM boundary layer",
        components=XYZ),
    Row("POS_W_C", "scenario.position.omega_c_rad_s", 0.3, 2.5, "rad/s", "hold position omega_c", components=XYZ),
    Row("POS_GAMMA_XY", "scenario.position.observer_gain_rad_s", 0.3, 12.0, "rad/s",
        "hold force observer, horizontal", components=(1.0, 1.0, None)),
    Row("POS_GAMMA_Z", "scenario.position.observer_gain_rad_s", 0.3, 12.0, "rad/s", "hold force observer, vertical",
        components=D),
)
"""the bundled firmware's attitude loop and the autopilot's hold loop"""

COMMON_ROWS: tuple[Row, ...] = CONTROLLER_ROWS + SIM_ROWS



class _Binding(PlantBinding):
    """The plant's rows, and the autopilot's and its loops' (roots ``autopilot``, ``controller``,
    ``derived``, ``scenario.attitude`` and ``scenario.position``) on one live autopilot."""

    def __init__(self, ap: Autopilot) -> None:
        super().__init__(ap.vehicle, lambda text: ap.say(Severity.WARNING, text))
        self.ap = ap

    def get(self, row: Row) -> float:
        root, *path = row.field.split(".")
        ap, v = self.ap, self.v
        if root == "autopilot":
            if path == ["guided_options"]:
                return 8.0 if ap.params.guided_thrust_is_throttle else 0.0
            return float(getattr(ap.params, path[0])) / row.scale
        if root == "controller":
            return float(ATTITUDE_KINDS.index(v.onboard.controller.kind))
        if root == "derived" and path != ["seed"]:
            return ap.reported_hover_throttle()
        return super().get(row)

    def _set_autopilot(self, row: Row, path: list[str]) -> Callable[[float], None]:
        ap = self.ap
        if path == ["guided_options"]:
            def guided(x: float) -> None:
                ap.params = dataclasses.replace(ap.params, guided_thrust_is_throttle=bool(int(x) & 8))
            return guided

        flag = isinstance(getattr(ap.params, path[0]), bool)

        def apply(x: float) -> None:
            ap.params = dataclasses.replace(ap.params, **{path[0]: bool(x) if flag else x * row.scale})
        return apply

    def _after_scenario(self, table: str) -> Callable[[], None]:
        if table == "attitude":
            return self._attitude
        if table == "position":
            return self._position
        return super()._after_scenario(table)

    def _attitude(self) -> None:
        self.v.set_attitude_gains(self.v.scenario)

    def _position(self) -> None:
        from companion.control.outer_loop import PositionLoop

        sc, ap = self.v.scenario, self.ap
        ap.position_loop = PositionLoop.create(ap.params.hold_controller, sc.vehicle, sc.position, sc.reference)

    def _set_controller(self, row: Row, path: list[str]) -> Callable[[float], None]:
        v = self.v

        def apply(x: float) -> None:
            v.set_attitude_controller(ATTITUDE_KINDS[int(x)])
        return apply


def rows_for(ap: Autopilot) -> tuple[Row, ...]:
    return (ARDUPILOT_ROWS if ap.ardupilot else PX4_ROWS) + COMMON_ROWS


def build_parameters(ap: Autopilot) -> ParamTable:
    """The parameter table bound to one autopilot and its vehicle."""
    return bind_rows(_Binding(ap), rows_for(ap), live=lambda row: row.field.startswith("derived."))


def out_of_range(table: ParamTable) -> list[str]:
    """Parameters whose value (from a scenario, say) is outside their range: what it would take
    a PARAM_SET to do, refused."""
    return [f"{p.name} = {p.value:g} outside [{p.minimum:g}, {p.maximum:g}]" for p in table
            if p.apply is not None and not p.fault and not p.minimum <= p.value <= p.maximum]


def markdown_table(ap: Autopilot, rows: tuple[Row, ...] | None = None) -> str:
    """``rows`` (all of ``ap``'s) as docs/sitl.md shows them, defaults from ``ap``'s scenario."""
    lines = ["| name | default | range | unit | meaning |", "|---|---|---|---|---|"]
    table = build_parameters(ap)
    for row in rows if rows is not None else rows_for(ap):
        p = table.get(row.name)
        assert p is not None
        rng = "read-only" if row.read_only else f"{_num(row.minimum)} .. {_num(row.maximum)}"
        meaning = row.description + (" (integer)" if row.integer and row.name != "ATT_CTRL" else "")
        if row.fault:
            meaning += " — fault"
        lines.append(f"| `{row.name}` | {_num(p.value)} | {rng} | {row.unit} | {meaning} |")
    return "\n".join(lines)


def _num(x: float) -> str:
    return f"{x:.4g}" if abs(x) < 1e6 else f"{x:.6g}"
