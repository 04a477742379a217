"""Missions: what the companion flies, as data (TOML or a QGroundControl ``.plan``), checked
completely before anything arms.

One job per module:

- :mod:`.model` — the frozen dataclasses a mission is made of (:class:`Mission`, :class:`Step`, ...);
- :mod:`.safety` — the safety volume around home (:class:`SafetyVolume`), pure, for the loaders and
  for the flight runtime (:meth:`SafetyVolume.breach`, :meth:`SafetyVolume.margin_m`);
- :mod:`.envelope` — the table of what every number may be, file bounds, safe names;
- :mod:`.validate` — the whole-mission checks every loader runs;
- :mod:`.load` — mission files in TOML (:func:`load_mission`, the one way in, also for ``.plan``);
- :mod:`.plan` — QGroundControl ``.plan`` import (:func:`load_plan`);
- :mod:`.show` — what ``companion check`` prints about an accepted mission (steps in NED, the
  warning for missions too low for a vehicle on GPS).
"""

from .envelope import ENVELOPE, Problem, Range, is_safe_component, safe_component
from .load import load_mission
from .model import ACTIONS, ControllerConfig, Mission, SafetyConfig, Step, ThrustConfig
from .plan import load_plan
from .safety import FenceCircle, FencePolygon, SafetyVolume
from .validate import extent, validate

__all__ = ["ACTIONS", "Step", "ControllerConfig", "ThrustConfig", "SafetyConfig", "SafetyVolume", "FenceCircle",
           "FencePolygon", "Mission", "load_mission", "load_plan", "validate", "extent", "safe_component",
           "is_safe_component", "ENVELOPE", "Range", "Problem"]
