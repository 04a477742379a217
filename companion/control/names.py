"""What each controller is called where people read it (plots, tables, summaries): one table for
every controller of either loop (:data:`~companion.control.attitude.ATTITUDE_CONTROLLERS`,
:data:`~companion.control.position.POSITION_CONTROLLERS`), so that a new controller is named once."""

from __future__ import annotations

__all__ = ["CONTROLLER_LABELS", "controller_label"]

CONTROLLER_LABELS = {"pd": "PD", "pid": "PID", "aibc": "AIBC", "pd_do": "PD+DO", "ism_do": "ISM+DO", "indi": "INDI"}


def controller_label(name: str) -> str:
    """``"ism_do"`` -> ``"ISM+DO"``; an unknown name is shown as it is (a label never stops a figure)."""
    return CONTROLLER_LABELS.get(name, name)
