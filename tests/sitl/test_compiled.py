"""The compiled kernel (sitl/plant/kernel.py) against the paths it must agree with.

- interpreted (NUMBA_DISABLE_JIT=1, in a subprocess) and compiled: the same source, the same
  numbers within 1e-12 over a full E3 flight in turbulent wind with every noise on (the noise is
  counter-based, so both draw the same numbers);
- compiled and the object-based simulator (the live vehicle's path) with noise off: the same laws,
  the same flight, for each experiment and every controller family;
- a batch (vehicles in parallel threads, each with its own seed and gains) and the same vehicles
  flown one at a time: bit for bit.

The kernel is compiled once per source digest and cached on disk (companion/control/jit.py), so
only the first run on a machine pays the compile (~20 s).
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from companion.control.position import DoConst
from sitl.lab.simulation import LOG_COLUMNS, simulate
from sitl.lab.sweep import Member, stack_gains
from sitl.plant.scenario import Scenario, load_scenario
from sitl.plant.sensors import SensorParams

pytest.importorskip("numba")

ROOT = Path(__file__).resolve().parents[2]

QUIET = SensorParams(gyro_noise_rad_s=0.0, gyro_bias_rad_s=0.0, accel_noise_m_s2=0.0, accel_bias_m_s2=0.0,
                     mocap_pos_noise_m=0.0, mocap_att_noise_rad=0.0)
"""every sensor exact: the two simulators then draw nothing (their noise generators differ)"""


def _quiet(sc: Scenario) -> Scenario:
    """``sc`` without noise or turbulence.

    The paths must agree to the last bits, not merely closely: the 8-bit rotor commands turn a
    difference of one ulp that lands on a level boundary into a whole level (4 rad/s), and the
    flights then part by 1e-4 m (this is how CPython's ``x ** 0.5``, a pow() one ulp off where
    compiled code takes the square root, was found)."""
    wind = dataclasses.replace(sc.wind, turbulence=dataclasses.replace(sc.wind.turbulence, enabled=False))
    return sc.with_changes(sensors=QUIET, wind=wind)


def _table(log: object) -> np.ndarray:
    return np.column_stack([log[c] for c in LOG_COLUMNS])  # type: ignore[index]


INTERPRETED = """
import sys
import numpy as np
from sitl.lab.simulation import LOG_COLUMNS, simulate
from sitl.plant.scenario import load_scenario

log = simulate(load_scenario("E3_wind"), "ism_do", "ism_do", 7, engine="compiled")
np.save(sys.argv[1], np.column_stack([log[c] for c in LOG_COLUMNS]))
"""


def test_interpreted_and_compiled_kernels_agree_over_a_full_e3_flight_in_turbulence(tmp_path: Path) -> None:
    out = tmp_path / "interpreted.npy"
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1", "PYTHONPATH": str(ROOT)}
    # the interpreted flight (~7 s of CPU) runs in its own process while this one flies compiled
    proc = subprocess.Popen([sys.executable, "-c", INTERPRETED, str(out)], cwd=ROOT, env=env)
    try:
        sc = load_scenario("E3_wind")
        assert sc.wind.turbulence.enabled and sc.sensors.gyro_noise_rad_s > 0.0  # the flight draws noise
        compiled = _table(simulate(sc, "ism_do", "ism_do", 7, engine="compiled"))
        assert proc.wait(timeout=600) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    interpreted = np.load(out)
    assert compiled.shape == interpreted.shape == (int(sc.duration_s * sc.log_rate_hz), len(LOG_COLUMNS))
    assert np.isfinite(compiled).all()
    np.testing.assert_allclose(compiled, interpreted, rtol=0, atol=1e-12)
    # and the flight is not trivially still: turbulence moved it by centimetres
    assert np.ptp(compiled[:, LOG_COLUMNS.index("x")]) > 0.01


@pytest.mark.parametrize(("name", "position", "attitude", "duration_s"), [
    ("E3_wind", "ism_do", "ism_do", None),
    ("E3_wind", "pid", "pd", 10.0),
    ("E3_calm", "aibc", "pd_do", 10.0),
    ("E1_step_force", "pd_do", "ism_do", 10.0),
    ("E2_chirp_torque", "ism_do", "ism_do", 6.0),
    ("E4_waypoints", "ism_do", "ism_do", 12.0),
    ("E5_suspended_weight", "indi", "indi", 8.0),
])
def test_compiled_kernel_flies_as_the_object_simulator(name: str, position: str, attitude: str,
                                                      duration_s: float | None) -> None:
    sc = _quiet(load_scenario(name))
    compiled = _table(simulate(sc, position, attitude, 3, duration_s, engine="compiled"))
    objects = _table(simulate(sc, position, attitude, 3, duration_s, engine="objects"))
    assert compiled.shape == objects.shape
    scale = np.maximum(np.abs(objects).max(axis=0), 1.0)
    worst = np.abs(compiled - objects).max(axis=0) / scale
    assert worst.max() < 1e-12, dict(zip(LOG_COLUMNS, worst))


def test_a_parallel_batch_flies_each_vehicle_as_it_flies_alone() -> None:
    """Five vehicles, two gain sets, in parallel threads: each is bit for bit its one-vehicle run
    (threads share nothing but the read-only profiles and waypoints)."""
    sc = load_scenario("E1_step_force").with_changes(duration_s=3.0)
    stiff = sc.with_changes(position=dataclasses.replace(sc.position, omega_c_rad_s=(2.5, 2.5, 1.5)))
    members = [Member({}, sc, (4, 9, 11)), Member({}, stiff, (4, 20))]
    batch = simulate(stack_gains(members), "ism_do", "ism_do", [4, 9, 11, 4, 20], engine="compiled")
    i = 0
    for m in members:
        for seed in m.seeds:
            one = simulate(m.scenario, "ism_do", "ism_do", seed, engine="compiled")
            np.testing.assert_array_equal(_table(batch.vehicle(i)), _table(one))
            i += 1
    # the two gain sets did fly differently (the gains reached the vehicles)
    assert np.abs(batch["x"][:, 0] - batch["x"][:, 3]).max() > 1e-4


def _rows(members: list[tuple[Scenario, tuple[int, ...]]]) -> tuple[np.ndarray, tuple[np.ndarray, ...], int, int]:
    """(flight_codec rows, the batch's arrays, plant steps, log rows) of ISM+DO vehicles."""
    from sitl.plant import kernel as K

    consts = [K.flight_const(sc, "ism_do", "ism_do", s) for sc, seeds in members for s in seeds]
    sc = members[0][0]
    steps = int(round(sc.duration_s * sc.plant_rate_hz))
    codec = K.flight_codec(K.position_family(consts[0]))
    return (np.array([codec.pack(c) for c in consts]), codec.arrays(consts[0]), steps,
            -(-steps // consts[0].log_div))


def test_a_batch_in_lanes_flies_each_vehicle_as_it_flies_alone() -> None:
    """Seven vehicles in turbulence with every noise on, two gain sets: a whole group of lanes
    and a padded one, on two threads, each vehicle bit for bit what it flies alone (the lanes
    compute what the float code computes, lane by lane; a vehicle read from the wrong lane, a
    padded lane kept or a per-vehicle number taken as the batch's would each break it)."""
    from sitl.plant import kernel as K

    sc = load_scenario("E3_wind").with_changes(duration_s=2.0)
    stiff = sc.with_changes(position=dataclasses.replace(sc.position, omega_c_rad_s=(2.5, 2.5, 1.5)),
                            attitude=dataclasses.replace(sc.attitude, omega_c_rad_s=15.0))
    rows, arrays, steps, n_log = _rows([(sc, (4, 9, 11, 12)), (stiff, (4, 20, 21))])
    n = rows.shape[0]
    assert K.lanes_apply(DoConst, rows) and n > K.lanes.W and n % K.lanes.W != 0  # the lanes path, a padded group
    lanes_log, lanes_final = np.empty((n, n_log, len(LOG_COLUMNS))), np.empty((n, 3))
    K.fly_batch(DoConst, rows, *arrays, steps, lanes_log, lanes_final, threads=2)
    one_log, one_final = np.empty_like(lanes_log), np.empty_like(lanes_final)
    for i in range(n):
        K.fly_one_by_one(DoConst, rows[i:i + 1], *arrays, steps, one_log[i:i + 1], one_final[i:i + 1], threads=1)
    np.testing.assert_array_equal(lanes_log, one_log)
    np.testing.assert_array_equal(lanes_final, one_final)
    # every vehicle flew its own flight: the seeds and the gains reached their lanes
    x = one_log[:, :, LOG_COLUMNS.index("x")]
    assert min(np.abs(x[i] - x[j]).max() for i in range(n) for j in range(i)) > 1e-5


def test_a_batch_that_differs_in_a_shared_number_flies_one_by_one_with_the_same_numbers() -> None:
    """A vehicle mass differs between vehicles: no lanes (the mass is one number for the whole
    group of lanes), and the batch still flies each vehicle as it flies alone."""
    from sitl.plant import kernel as K

    sc = load_scenario("E3_wind").with_changes(duration_s=0.5)
    heavy = sc.with_changes(vehicle=dataclasses.replace(sc.vehicle, mass_kg=1.2 * sc.vehicle.mass_kg))
    rows, arrays, steps, n_log = _rows([(sc, (1, 2, 3)), (heavy, (4, 5))])
    assert not K.lanes_apply(DoConst, rows)
    n = rows.shape[0]
    batch_log, batch_final = np.empty((n, n_log, len(LOG_COLUMNS))), np.empty((n, 3))
    K.fly_batch(DoConst, rows, *arrays, steps, batch_log, batch_final)
    for i in range(n):
        one_log, one_final = np.empty((1, n_log, len(LOG_COLUMNS))), np.empty((1, 3))
        K.fly_one_by_one(DoConst, rows[i:i + 1], *arrays, steps, one_log, one_final)
        np.testing.assert_array_equal(batch_log[i], one_log[0])


def test_codecs_of_different_structures_name_their_compiled_functions_apart():
    """Compiled code keeps a function by its name and argument types: two families' unpacks (same
    arguments) compiled in different processes and loaded from the disk cache into one must not
    share a name, or one family's flight would be unpacked by the other's code."""
    from sitl.plant import kernel as K

    names = [K.flight_codec(f).unpack.__name__ for f in K._CODECS]
    assert len(set(names)) == len(names) == 3
