"""The firmware's estimator on the plant's motion capture: a tracking dropout on the ground must leave
the estimated height where it was when tracking comes back.

PX4 v1.16's EKF2 restarts vision height fusion by setting its altitude above sea level to the vision
height, so with an origin at 488 m local z came back +488.0 m (measured before
:func:`sitl.firmware.plant_component.estimator_origin` gave PX4 an origin at 0 m; in flight the same
reset put the vehicle 979 m underground in 2 of 65 bench flights). The dropout is 10 s, twice EKF2's
5 s height-fusion timeout, so fusion stops and restarts; the height on the ground is 0 and the
tracking noise is millimetres: 0.1 m bounds anything but a reset to the wrong frame."""

from __future__ import annotations

import time

import pytest
from pymavlink import mavutil

from companion.mavlink.params import PLANT_COMPID
from companion.vehicle_process import FirmwareVehicle
from helpers.firmware import worker_instance
from sitl.firmware.builds import arducopter_binary, px4_build

pytestmark = [pytest.mark.autopilot, pytest.mark.integration]

DROPOUT_S = 10.0


def _pymavlink_url(url: str) -> str:
    return url.replace("://", ":")


@pytest.mark.parametrize("firmware", ["px4", "ardupilot"])
def test_a_tracking_dropout_on_the_ground_keeps_the_height(firmware):  # type: ignore[no-untyped-def]
    build, why = (px4_build if firmware == "px4" else arducopter_binary)()
    if build is None:
        pytest.skip(why)
    vehicle = FirmwareVehicle(firmware, speedup=4.0, lockstep_ms=0, instance=worker_instance(3))
    link = None
    try:
        link = mavutil.mavlink_connection(_pymavlink_url(vehicle.url), source_system=245)
        assert link.wait_heartbeat(timeout=120) is not None
        if firmware == "ardupilot":
            link.mav.request_data_stream_send(link.target_system, 1, mavutil.mavlink.MAV_DATA_STREAM_POSITION, 10, 1)
        dropped_at, z = None, []  # (vehicle s after the dropout began, z)
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:
            msg = link.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=5)
            if msg is None:
                continue
            t = msg.time_boot_ms / 1e3
            if dropped_at is None and t > 20.0:  # the estimator has converged on tracking
                link.mav.param_set_send(link.target_system, PLANT_COMPID, b"SIM_MOCAP_DROP", DROPOUT_S,
                                        mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
                dropped_at = t
            if dropped_at is not None:
                z.append((t - dropped_at, msg.z))
                if t - dropped_at > DROPOUT_S + 10.0:
                    break
        after = [zi for ti, zi in z if ti > DROPOUT_S + 2.0]
        assert after, f"no LOCAL_POSITION_NED after the dropout ({len(z)} during it)"
        assert max(abs(zi) for zi in after) < 0.1, after[-5:]
    finally:
        if link is not None:
            link.close()
        vehicle.stop(timeout_s=30)
