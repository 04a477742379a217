"""What a vehicle's MAVLink says about its airframe and whether it is flying, one copy.

- :func:`rotor_count`: the rotors of a ``MAV_TYPE`` (HEARTBEAT ``type``, PX4's MAV_TYPE parameter),
  or None where the type does not say (a VTOL, a generic multirotor);
- :func:`lifted_by_rotors`: False for the types whose thrust is not along the body's z axis (a
  fixed wing, a rover, a boat), whose logs a multicopter's force estimate would misread;
- :func:`airborne_from_landed_state`: EXTENDED_SYS_STATE ``landed_state`` as airborne or not;
- :func:`ardupilot_airborne_from_system_status`: ArduCopter's HEARTBEAT ``system_status``, which is
  STANDBY exactly while its land detector says landed (``GCS_MAVLINK_Copter::vehicle_system_status``)
  and ACTIVE in the air; PX4's says armed or not, not landed.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink

__all__ = ["rotor_count", "lifted_by_rotors", "airborne_from_landed_state", "ardupilot_airborne_from_system_status"]

_ROTORS = {
    mavlink.MAV_TYPE_TRICOPTER: 3,
    mavlink.MAV_TYPE_QUADROTOR: 4,
    mavlink.MAV_TYPE_HEXAROTOR: 6,
    mavlink.MAV_TYPE_OCTOROTOR: 8,
    mavlink.MAV_TYPE_DECAROTOR: 10,
    mavlink.MAV_TYPE_DODECAROTOR: 12,
}


_NOT_ROTORCRAFT = {
    mavlink.MAV_TYPE_FIXED_WING,
    mavlink.MAV_TYPE_GROUND_ROVER,
    mavlink.MAV_TYPE_SURFACE_BOAT,
    mavlink.MAV_TYPE_SUBMARINE,
    mavlink.MAV_TYPE_AIRSHIP,
    mavlink.MAV_TYPE_FREE_BALLOON,
    mavlink.MAV_TYPE_ROCKET,
}


def rotor_count(mav_type: int) -> int | None:
    return _ROTORS.get(int(mav_type))


def lifted_by_rotors(mav_type: int) -> bool:
    """False only for types known not to be (a VTOL, a generic or unknown type: True)."""
    return int(mav_type) not in _NOT_ROTORCRAFT


def airborne_from_landed_state(state: int) -> bool | None:
    """ON_GROUND: False; IN_AIR, TAKEOFF, LANDING: True; UNDEFINED (the autopilot does not say): None."""
    if state == mavlink.MAV_LANDED_STATE_ON_GROUND:
        return False
    if state in (mavlink.MAV_LANDED_STATE_IN_AIR, mavlink.MAV_LANDED_STATE_TAKEOFF,
                 mavlink.MAV_LANDED_STATE_LANDING):
        return True
    return None


def ardupilot_airborne_from_system_status(status: int) -> bool | None:
    """STANDBY: landed; ACTIVE: flying; anything else (BOOT, a failsafe's CRITICAL): not said."""
    if status == mavlink.MAV_STATE_STANDBY:
        return False
    if status == mavlink.MAV_STATE_ACTIVE:
        return True
    return None
