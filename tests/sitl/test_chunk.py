"""The live vehicle's compiled chunks (sitl/plant/chunk.py): the kernel flies the plant steps between
two decisions of the rules as the objects do, hands back to the objects where they must fly, and a
flight is the same flight each time."""

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from companion.control.jit import numba_available
from companion.control.outer_loop import AttitudeSetpoint
from sitl.autopilot import world
from sitl.autopilot.logic import Autopilot, Failsafe, MavResult, Mode
from sitl.plant import chunk
from sitl.plant.scenario import load_scenario
from sitl.plant.vehicle import SimVehicle

pytestmark = pytest.mark.skipif(not numba_available(), reason="numba is not installed: no compiled chunks")

NAN = math.nan
SCENARIO = load_scenario("E3_wind")
"""mean wind and Dryden turbulence: the wind's filter state crosses between the two engines too"""


def vehicle(compiled: bool, seed: int = 3) -> tuple[SimVehicle, Autopilot]:
    v = SimVehicle(SCENARIO, "ism_do", seed, (0.0, 0.0, SCENARIO.airframe.ground_z_m), 0.0, hovering=False)
    if compiled:
        assert v.compile_chunks()
    return v, Autopilot(v)


def fly(ap: Autopilot, seconds: float, steps: int = 10) -> None:
    for _ in range(int(round(seconds / (steps * ap.dt)))):
        world.step(ap, steps)


def airborne(ap: Autopilot) -> None:
    fly(ap, 1.2)
    assert ap.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, (1,)).result == MavResult.ACCEPTED
    assert ap.command(mavlink.MAV_CMD_NAV_TAKEOFF, (0, 0, 0, 0, NAN, NAN, NAN)).result == MavResult.ACCEPTED
    fly(ap, 6.0)
    assert ap.mode == Mode.HOLD and not ap.landed


def test_a_state_through_a_row_into_another_vehicle_is_that_vehicle_s_state_after():
    """Every part of the state crosses: a flying vehicle's, put into one still on the ground, reads
    back as the flying one's (wind filters, tracking queue, estimator, observers, clocks)."""
    flying, ap = vehicle(False)
    airborne(ap)
    grounded, _ = vehicle(False)
    state = chunk.state_of(flying)
    assert chunk.state_of(grounded) != state
    chunk.put_back(grounded, chunk.state_from(chunk.state_row(state).tolist()))
    assert chunk.state_of(grounded) == state


def test_compiled_chunks_hold_the_takeoff_point_in_turbulence_as_the_objects_do():
    """The same seeded vehicle on each engine: each draws its own noise, so the two flights differ by
    the turbulence and sensor noise, and both hold the take-off point as closely (the hold in E3's
    wind holds within a few centimetres)."""
    held = {}
    for compiled in (True, False):
        v, ap = vehicle(compiled)
        airborne(ap)
        worst = 0.0
        for _ in range(100):  # 10 s
            fly(ap, 0.1)
            p = v.state.pos_ned_m
            worst = max(worst, math.hypot(p[0], p[1]), abs(p[2] + 2.5))
        held[compiled] = worst
        counts = v.chunk_counts
        assert (counts["compiled"] > 0.99 * v.steps) if compiled else counts["compiled"] == 0, counts
    assert held[True] < 0.15 and held[False] < 0.15, held


def test_a_seeded_flight_on_compiled_chunks_is_the_same_flight_each_time():
    ends = []
    for _ in range(2):
        v, ap = vehicle(True, seed=11)
        airborne(ap)
        fly(ap, 2.0)
        ends.append((v.t, v.state, v.estimator.q, v.mocap.latest))
    assert ends[0] == ends[1]


def test_an_injected_imu_fault_is_flown_by_the_objects_and_the_firmware_check_catches_it():
    """A NaN IMU from now on: no chunk overlaps the fault's window, the objects fly it, the check
    fails the IMU and the vehicle lands on tracking alone, as it does on the objects alone."""
    for compiled in (True, False):
        v, ap = vehicle(compiled)
        airborne(ap)
        v.faults.imu_nan = (v.t + 0.5, math.inf)
        fly(ap, 1.0)
        assert v.imu_failed and ap.failsafe == Failsafe.IMU_FAILED, (compiled, v.imu_failed, ap.failsafe)
        done_compiled = v.chunk_counts["compiled"]
        fly(ap, 20.0)
        assert ap.landed, compiled
        assert v.chunk_counts["compiled"] == done_compiled  # nothing compiled once the IMU failed


def test_a_chunk_stops_before_a_sample_the_firmware_check_would_reject():
    """A gyro range below what the hover reads: the kernel takes no step, the objects take each one
    and the check rejects their samples (the limits are the monitor's own)."""
    v, ap = vehicle(True)
    airborne(ap)
    v.imu_monitor.max_accel_m_s2 = 1.0  # the hover's specific force is ~9.8 m/s^2: every sample is out of range
    n = v.chunk_counts["objects"]
    rejected = v.imu_monitor.rejected
    world.step(ap, 10)
    assert v.chunk_counts["objects"] == n + 10
    assert v.imu_monitor.rejected == rejected + 10


def test_a_setpoint_of_types_the_kernel_was_not_compiled_for_is_flown_by_the_objects():
    v, ap = vehicle(True)
    airborne(ap)
    odd = AttitudeSetpoint([1.0, 0.0, 0.0, 0.0], (0.0, 0.0, 0.0), 5.0)  # a list: never compiled mid-flight, refused
    n = v.chunk_counts["objects"]
    v.step_many(odd, 10)
    assert v.chunk_counts["refused"] >= 1 and v.chunk_counts["objects"] == n + 10
