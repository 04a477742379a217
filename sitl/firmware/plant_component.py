"""The plant as a MAVLink component on the firmware's network: its SIM_* parameters, the EKF
origin, and motion capture for ArduPilot.

With a real autopilot flying the plant, the simulation's own settings (wind, an external force,
a weak motor, a sensor fault) cannot be autopilot parameters. The plant joins the firmware's
MAVLink network through a link of the firmware's own (a PX4 MAVLink instance with forwarding,
ArduPilot's SERIAL2), as component :data:`~companion.mavlink.params.PLANT_COMPID` of the
vehicle's system, and serves :data:`~sitl.plant.parameters.SIM_ROWS` with the parameter protocol:
the firmware routes a companion's or a ground station's PARAM_SET to it like to any component.
A parameter the firmware has is never served: at start the plant asks the firmware for each of
its names, and drops the ones it answers.

It also sets the estimator's origin (SET_GPS_GLOBAL_ORIGIN: with external vision and no GNSS
neither autopilot has one; :func:`estimator_origin`) until the firmware reports it, and, for ArduPilot, whose JSON
interface carries no external vision, sends each tracking sample as VISION_POSITION_ESTIMATE.
Transport-free: the bridge feeds :meth:`receive` and sends what :meth:`tick` returns.
"""

from __future__ import annotations

import dataclasses
import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control import quaternion as quat
from companion.mavlink.params import MAV_PARAM_TYPE_REAL32, PLANT_COMPID, param_name
from sitl.plant.geo import GeoOrigin
from sitl.plant.parameters import ESTIMATE_ONLY, SIM_ROWS, THRUST_MAX_ROW, ParamTable, build_plant_parameters
from sitl.plant.sensors import MocapSample
from sitl.plant.vehicle import SimVehicle

__all__ = ["PlantComponent", "estimator_origin"]

PLANT_ROWS = (THRUST_MAX_ROW, *(r for r in SIM_ROWS if r.name not in ESTIMATE_ONLY))
SIM_NAMES = frozenset(row.name for row in PLANT_ROWS)
PROBE_TRIES = 3
PROBE_INTERVAL_S = 0.5
"""simulated seconds between asks of the firmware for the plant's names"""
ORIGIN_INTERVAL_S = 2.0


def estimator_origin(origin: GeoOrigin, firmware: str) -> GeoOrigin:
    """The origin the plant gives the firmware's estimator when it navigates on motion capture.

    PX4 v1.16's EKF2 keeps altitude above sea level in its state, and with vision as its height
    reference it sets that altitude to the vision height whenever it (re)starts vision height fusion
    (``ev_height_control.cpp``: ``resetAltitudeTo(-measurement)``; the failing-sources reset also adds
    the height bias with the wrong sign). Local z is the origin's altitude minus that, so it jumps
    by the origin's altitude: measured here, +488.0 m after a 10 s tracking dropout on the ground,
    and +979 m (twice the bias) in 2 of 65 bench flights. An origin at 0 m makes the two heights
    one; nothing on this side reads PX4's altitude above sea level. ArduPilot's EKF3 keeps a local
    height and gets the real origin."""
    return dataclasses.replace(origin, alt_m=0.0) if firmware == "px4" else origin


class PlantComponent:
    def __init__(self, vehicle: SimVehicle, origin: GeoOrigin, set_origin: bool = True) -> None:
        self.vehicle = vehicle
        self.origin = origin
        self.sysid = 0
        """the vehicle's system id: the firmware's, learnt from its first heartbeat"""
        self.mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=PLANT_COMPID)
        self.mav.robust_parsing = True
        self.texts: list[str] = []
        """what the plant said (injected faults)"""
        self.params: ParamTable | None = None
        """None until the firmware's names are known"""
        self.shadowed: set[str] = set()
        """SIM_* names the firmware has: not served"""
        self._probes = 0
        self._next_probe_s = 0.0
        self._next_heartbeat_s = 0.0
        self.origin_set = not set_origin
        self._next_origin_s = 5.0
        self.firmware_seen = False
        self.heartbeat: bytes | None = None
        """the newest heartbeat, until the bridge has passed it on to the companion's link"""
        self.stats = {"param_set": 0, "param_refused": 0, "param_read": 0, "param_list": 0}

    # --- in ---------------------------------------------------------------------------------

    def receive(self, data: bytes) -> list[bytes]:
        """Handle what arrived from the firmware's network; returns the replies."""
        try:
            msgs = self.mav.parse_buffer(data) or []
        except Exception:
            return []
        out: list[bytes] = []
        for m in msgs:
            kind = m.get_type()
            if not self.sysid and kind == "HEARTBEAT" and m.get_srcComponent() == 1:
                self.sysid = self.mav.srcSystem = m.get_srcSystem()
            if self.sysid and m.get_srcSystem() == self.sysid and m.get_srcComponent() == 1:
                self.firmware_seen = True
                if kind == "PARAM_VALUE" and self.params is None and param_name(m.param_id) in SIM_NAMES:
                    self.shadowed.add(param_name(m.param_id))
                elif kind == "GPS_GLOBAL_ORIGIN":
                    self.origin_set = True
            if kind == "PARAM_REQUEST_LIST" and self._for_us(m):
                out.extend(self._list())
            elif kind == "PARAM_REQUEST_READ" and self._for_us(m):
                out.extend(self._read(m))
            elif kind == "PARAM_SET" and self._for_us(m):
                out.extend(self._set(m))
        return out

    def _for_us(self, m: object) -> bool:
        ts, tc = m.target_system, m.target_component  # type: ignore[attr-defined]
        return self.params is not None and ts in (0, self.sysid) and tc in (0, PLANT_COMPID)

    def _value(self, index: int) -> bytes:
        assert self.params is not None
        p = self.params.at(index)
        assert p is not None
        return self.mav.param_value_encode(p.name.encode(), float(p.value), MAV_PARAM_TYPE_REAL32, len(self.params),
                                           index).pack(self.mav)

    def _list(self) -> list[bytes]:
        assert self.params is not None
        self.stats["param_list"] += 1
        return [self._value(i) for i in range(len(self.params))]

    def _read(self, m: object) -> list[bytes]:
        assert self.params is not None
        index = m.param_index  # type: ignore[attr-defined]
        if index < 0:
            found = self.params.index(param_name(m.param_id))  # type: ignore[attr-defined]
            if found is None:
                return []  # not ours (the firmware answers for its own)
            index = found
        if self.params.at(index) is None:
            return []
        self.stats["param_read"] += 1
        return [self._value(index)]

    def _set(self, m: object) -> list[bytes]:
        assert self.params is not None
        name = param_name(m.param_id)  # type: ignore[attr-defined]
        index = self.params.index(name)
        if index is None:
            return []
        value = float(m.param_value)  # type: ignore[attr-defined]
        reason = self.params.set(name, value)
        if reason is not None:
            self.stats["param_refused"] += 1
            self.texts.append(reason)
            return [self._text(mavlink.MAV_SEVERITY_WARNING, reason), self._value(index)]  # the old value, echoed
        self.stats["param_set"] += 1
        return [self._value(index)]

    def _text(self, severity: int, text: str) -> bytes:
        return self.mav.statustext_encode(severity, text.encode()[:50]).pack(self.mav)

    # --- out --------------------------------------------------------------------------------

    def tick(self, t_s: float) -> list[bytes]:
        """What is due at world time ``t_s``: heartbeat (1 Hz), the probe of the firmware's names,
        the EKF origin."""
        out: list[bytes] = []
        mav = self.mav
        if not self.sysid:
            return out
        if t_s >= self._next_heartbeat_s:
            self._next_heartbeat_s = t_s + 1.0
            self.heartbeat = mav.heartbeat_encode(mavlink.MAV_TYPE_GENERIC, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
                                                  mavlink.MAV_STATE_ACTIVE).pack(mav)
            out.append(self.heartbeat)
        if self.params is None and self.firmware_seen and t_s >= self._next_probe_s:
            if self._probes < PROBE_TRIES:
                self._probes += 1
                self._next_probe_s = t_s + PROBE_INTERVAL_S
                out.extend(mav.param_request_read_encode(self.sysid, 1, row.name.encode(), -1).pack(mav)
                           for row in PLANT_ROWS if row.name not in self.shadowed)
            else:
                self.params = build_plant_parameters(self.vehicle, self._say, frozenset(self.shadowed) | ESTIMATE_ONLY)
        if not self.origin_set and self.firmware_seen and t_s >= self._next_origin_s:
            self._next_origin_s = t_s + ORIGIN_INTERVAL_S
            o = self.origin
            out.append(mav.set_gps_global_origin_encode(self.sysid, int(round(o.lat_deg * 1e7)),
                                                        int(round(o.lon_deg * 1e7)), int(round(o.alt_m * 1000)),
                                                        int(t_s * 1e6)).pack(mav))
            out.append(mav.command_long_encode(self.sysid, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                                               mavlink.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, 0, 0, 0, 0, 0, 0).pack(mav))
        return out

    def _say(self, text: str) -> None:
        self.texts.append(text)

    def said(self) -> list[bytes]:
        """STATUSTEXTs of what the plant said since the last call (an injected fault)."""
        out = [self._text(mavlink.MAV_SEVERITY_WARNING, t) for t in self.texts]
        self.texts.clear()
        return out

    def vision(self, s: MocapSample) -> bytes:
        """A tracking sample as VISION_POSITION_ESTIMATE (ArduPilot's external navigation)."""
        roll, pitch, yaw = quat.to_euler(s.q)
        p = s.pos_ned_m
        cov = [math.nan] + [0.0] * 20
        return self.mav.vision_position_estimate_encode(int(round(s.time_s * 1e6)), p[0], p[1], p[2], roll, pitch,
                                                        yaw, cov, 0).pack(self.mav)
