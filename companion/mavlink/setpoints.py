"""The type_masks the companion and the tests send, named once from pymavlink's bits (a set bit means
*ignore*).

SET_ATTITUDE_TARGET: attitude + thrust with all body rates ignored (what ArduPilot is sent); attitude
+ thrust + yaw rate as feed-forward (PX4); body rates + thrust with the attitude ignored.
SET_POSITION_TARGET_LOCAL_NED: position, velocity, acceleration and yaw used, yaw rate ignored.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

__all__ = ["RATES_IGNORED", "ROLL_PITCH_RATES_IGNORED", "ATTITUDE_IGNORED", "POSITION_TARGET_MASK"]

ROLL_PITCH_RATES_IGNORED = (mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE
                            | mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE)
RATES_IGNORED = ROLL_PITCH_RATES_IGNORED | mavlink.ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE
ATTITUDE_IGNORED = mavlink.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
POSITION_TARGET_MASK = mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
