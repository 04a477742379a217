"""Missions: what the companion flies, as data (TOML or a QGroundControl ``.plan``), checked
completely before anything arms.

One job per module:

- :mod:`.model` — the frozen dataclasses a mission is made of (:class:`Mission`, :class:`Step`, ...);
- :mod:`.load` — mission files in TOML (:func:`load_mission`, which also dispatches ``.plan``);
- :mod:`.plan` — QGroundControl ``.plan`` import (:func:`load_plan`).
"""

from .load import load_mission
from .model import ACTIONS, ControllerConfig, Mission, SafetyConfig, Step, ThrustConfig
from .plan import load_plan

__all__ = ["ACTIONS", "Step", "ControllerConfig", "ThrustConfig", "SafetyConfig", "Mission", "load_mission",
           "load_plan"]
