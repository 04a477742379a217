"""Pure control core (numpy only, no I/O, no clocks): every ``dt`` is passed in.

Modules, one concept each:

- :mod:`.vector`       component-wise 3-vector algebra; components are floats or batch arrays
- :mod:`.quaternion`   scalar-first Hamilton unit quaternions (section II.A)
- :mod:`.params`       frozen parameter dataclasses with the paper's defaults, loaded from mappings
- :mod:`.allocation`   "+" rotor allocation (4) in FRD, both directions
- :mod:`.observers`    torque (15), (19) and force (30) disturbance observers
- :mod:`.attitude`     PD, PD+DO, ISM+DO attitude tracking (section III)
- :mod:`.position`     PID, AIBC, PD+DO, ISM+DO position control (section IV, V)
- :mod:`.reference`    force -> attitude, thrust and rate reference (32)-(34)
- :mod:`.trajectory`   velocity-limited waypoint reference
- :mod:`.outer_loop`   the position loop of Fig. 3, composed from the above
"""

from .attitude import ATTITUDE_CONTROLLERS, AttitudeController
from .outer_loop import AttitudeSetpoint, PositionLoop, PositionMeasurement
from .params import (
    AttitudeGains,
    ParamError,
    PositionGains,
    ReferenceParams,
    TrajectoryParams,
    VehicleParams,
)
from .position import POSITION_CONTROLLERS, PositionController
from .trajectory import PositionReference, ReferenceFilter

__all__ = [
    "ATTITUDE_CONTROLLERS",
    "POSITION_CONTROLLERS",
    "AttitudeController",
    "AttitudeGains",
    "AttitudeSetpoint",
    "ParamError",
    "PositionController",
    "PositionGains",
    "PositionLoop",
    "PositionMeasurement",
    "PositionReference",
    "ReferenceFilter",
    "ReferenceParams",
    "TrajectoryParams",
    "VehicleParams",
]
