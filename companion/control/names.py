"""Every controller of either loop in one registry: its name (TOML, CLI, tables), its label (figures,
summaries), the loops it serves, how figures draw it and its number in the bundled vehicle's
``ATT_CTRL`` parameter. :data:`~companion.control.attitude.ATTITUDE_CONTROLLERS`,
:data:`~companion.control.position.POSITION_CONTROLLERS`, the command lines, mission and sweep
validation, plots, experiments and sweeps all read it, so a new controller is added here once
(plus its law in attitude.py or position.py).

Pure data: importing it pulls in nothing but the standard library.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Controller", "CONTROLLERS", "LOOPS", "CONTROLLER_LABELS", "controller_label", "controllers_for",
           "controller_style", "att_ctrl_kinds"]

LOOPS = ("position", "attitude")


@dataclass(frozen=True)
class Controller:
    """One controller: ``name`` as written in files and on command lines, ``label`` as shown to
    people, ``loops`` it serves (a subset of :data:`LOOPS`), ``color`` of its position-loop
    curves and ``linestyle`` of its attitude-loop curves in figures, ``att_ctrl`` its value of the
    bundled vehicle's ``ATT_CTRL`` parameter (None: not selectable there)."""

    name: str
    label: str
    loops: tuple[str, ...]
    description: str
    color: str = "tab:purple"
    linestyle: str = "-"
    att_ctrl: int | None = None

    def __post_init__(self) -> None:
        if not self.loops or not set(self.loops) <= set(LOOPS):
            raise ValueError(f"controller {self.name!r}: loops {self.loops} must be a non-empty subset of {LOOPS}")


CONTROLLERS: tuple[Controller, ...] = (
    Controller("pd", "PD", ("attitude",), "quaternion PD with feed-forward, no observer", linestyle=":",
               att_ctrl=0),
    Controller("pid", "PID", ("position",), "PID position control (the paper's baseline)", color="tab:gray"),
    Controller("aibc", "AIBC", ("position",), "adaptive integral backstepping (the paper's baseline)",
               color="tab:orange"),
    Controller("pd_do", "PD+DO", ("position", "attitude"), "PD with the disturbance observer",
               color="tab:blue", linestyle="--", att_ctrl=1),
    Controller("ism_do", "ISM+DO", ("position", "attitude"),
               "integral sliding mode with the disturbance observer (the paper's)", color="tab:red",
               linestyle="-", att_ctrl=2),
    Controller("indi", "INDI", ("position", "attitude"), "incremental nonlinear dynamic inversion",
               color="tab:green", linestyle="-."),
)
"""In this order the names of each loop keep their ``kind`` numbers (the index in the loop's tuple)."""

_BY_NAME = {c.name: c for c in CONTROLLERS}
CONTROLLER_LABELS = {c.name: c.label for c in CONTROLLERS}


def controllers_for(loop: str) -> tuple[str, ...]:
    """The names of the controllers that serve ``loop`` ("position" or "attitude"), registry order."""
    if loop not in LOOPS:
        raise ValueError(f"loop {loop!r}: expected one of {LOOPS}")
    return tuple(c.name for c in CONTROLLERS if loop in c.loops)


def controller_label(name: str) -> str:
    """``"ism_do"`` -> ``"ISM+DO"``; an unknown name is shown as it is (a label never stops a figure)."""
    c = _BY_NAME.get(name)
    return c.label if c else name


def controller_style(position: str, attitude: str) -> dict[str, str]:
    """Matplotlib colour (from the position controller) and line style (from the attitude
    controller) of one combination's curves; an unknown name gets the defaults."""
    default = Controller("", "", LOOPS, "")
    return {"color": _BY_NAME.get(position, default).color, "linestyle": _BY_NAME.get(attitude, default).linestyle}


def att_ctrl_kinds() -> tuple[str, ...]:
    """Attitude controller names by their ``ATT_CTRL`` value (0, 1, ...)."""
    numbered = sorted((c.att_ctrl, c.name) for c in CONTROLLERS if c.att_ctrl is not None)
    if [n for n, _ in numbered] != list(range(len(numbered))):
        raise ValueError(f"ATT_CTRL values must be 0..{len(numbered) - 1} without gaps: {numbered}")
    return tuple(name for _, name in numbered)
