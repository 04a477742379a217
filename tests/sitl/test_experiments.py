"""The paper's claims, E1-E5, asserted on the offline closed loop with fixed seeds.

Each experiment is flown once per module (all controllers, seeds as stated) through the same
runner the ``sitl-experiments`` command uses. Tolerances are derived in each docstring.
"""

import dataclasses
import math

import numpy as np
import pytest

from sitl.experiments import Case, run_experiment
from sitl.metrics import euler_deg, flight_metrics
from sitl.scenario import load_scenario
from sitl.simulation import simulate

pytestmark = pytest.mark.slow
JOBS = 2


def seg(result, position, segment, attitude="ism_do", seed=None):
    seeds = sorted({c.seed for c in result.metrics})
    case = Case(position, attitude, seed if seed is not None else seeds[0])
    return next(m for m in result.metrics[case] if m.segment == segment)


@pytest.fixture(scope="module")
def e1():
    return run_experiment(load_scenario("E1_step_force"), jobs=JOBS)


@pytest.fixture(scope="module")
def e2():
    return run_experiment(load_scenario("E2_chirp_torque"), jobs=JOBS)


@pytest.fixture(scope="module")
def e3():
    return run_experiment(load_scenario("E3_wind"), seeds=[1, 2, 3], jobs=JOBS)


@pytest.fixture(scope="module")
def e4():
    return run_experiment(load_scenario("E4_waypoints"), jobs=JOBS)


@pytest.fixture(scope="module")
def e5():
    return run_experiment(load_scenario("E5_suspended_weight"), jobs=JOBS)


# --- E1 (Fig. 6) ---------------------------------------------------------------------


def test_e1_pd_do_settles_faster_than_pid(e1):
    """Settling into a 5 cm band after the 2 N onset. PID's slowest pole (-0.23 rad/s, a 4.3 s
    time constant) cannot remove a 1.3 m error within the 7 s the force acts; the force DO
    (Gamma = 5 rad/s) hands the PD loop a cancelled disturbance within ~1 s."""
    pd_do = seg(e1, "pd_do", "force on").settling_time_s
    pid = seg(e1, "pid", "force on").settling_time_s
    assert pd_do < 4.0
    assert math.isnan(pid) or pid > pd_do + 2.0


def test_e1_ism_do_has_the_smallest_peak_error(e1):
    peaks = {p: seg(e1, p, "force on").peak_error_m for p in ("pid", "aibc", "pd_do", "ism_do")}
    assert min(peaks, key=peaks.get) == "ism_do"
    assert peaks["ism_do"] < 0.8 * peaks["pd_do"]  # ideal point-mass loop: 0.106 vs 0.185 m


def test_e1_ism_do_undershoots_after_release(e1):
    """The integral of the sliding variable, built up while the force acted, pushes the vehicle
    past its resting point on the way back. On the ideal point mass the swing is 38% of the
    release excursion; the attitude loop's lag slows the return, so we require > 15%. PD+DO,
    without the integral, does not swing past (< 5%)."""
    ism = seg(e1, "ism_do", "released")
    pd = seg(e1, "pd_do", "released")
    assert ism.swing_past_m > 0.15 * abs(ism.excursion_m)
    assert pd.swing_past_m < 0.05 * abs(pd.excursion_m)


# --- E2 (Fig. 7) ---------------------------------------------------------------------


def test_e2_roll_is_held_at_sixty_degrees(e2):
    """tan(roll) = F_y / (m g) = 8.496 / (0.5 * 9.81) = sqrt(3): 60.0 deg. 1 deg of tolerance
    covers the accelerometer bias (0.05 m/s^2 is 0.3 deg of thrust direction) and noise."""
    log = e2.logs[Case("ism_do", "ism_do", 1)]
    roll, _, _ = euler_deg(log)
    m = (log.t > 8) & (log.t < 12)
    assert abs(abs(roll[m]).mean() - 60.0) < 1.0


def test_e2_estimate_follows_the_slow_component_of_the_torque(e2):
    """The torque observer is a first-order low-pass (Gamma_a = 8 rad/s) of the measured
    disturbance, so its estimate should equal the true torque passed through that same filter,
    up to the estimate's noise (~3e-3 N m from the differentiated gyro). The chirp itself
    (0.02-0.04 N m) is ~10 times larger: the fast part is left to the sliding term."""
    log = e2.logs[Case("ism_do", "ism_do", 1)]
    dt = log.t[1] - log.t[0]
    alpha = 1 - math.exp(-8.0 * dt)
    lp = np.zeros_like(log["htx"])
    for k in range(1, len(lp)):
        lp[k] = lp[k - 1] + alpha * (log["htx"][k] - lp[k - 1])
    chirp = (log.t > 12) & (log.t < 24)
    err = log["htx_hat"][chirp] - lp[chirp]
    assert np.sqrt(np.mean(err**2)) < 0.005
    const = (log.t > 8) & (log.t < 12)
    assert abs(log["htx_hat"][const].mean() - log["htx"][const].mean()) < 0.002


def test_e2_sliding_variable_goes_to_zero_while_the_torque_is_constant(e2):
    """Once the estimate has absorbed the constant torque, s has nothing left to integrate: its
    mean over the constant phase is within noise of zero (|mean| < 0.05 rad/s, eps = 1 rad/s)."""
    log = e2.logs[Case("ism_do", "ism_do", 1)]
    const = (log.t > 8) & (log.t < 12)
    assert abs(log["sx_att"][const].mean()) < 0.05


def test_e2_without_attitude_do_the_torque_moves_the_vehicle(e2):
    """PD attitude leaves an attitude error tau / (J w^2) ~ 0.1 rad under the 0.05 N m torque,
    which tilts the thrust and pushes the vehicle off by decimetres; the attitude DO removes it."""
    pd = seg(e2, "ism_do", "60 deg, constant torque", attitude="pd").rms_error_m
    do = seg(e2, "ism_do", "60 deg, constant torque", attitude="ism_do").rms_error_m
    assert pd > 10 * do


# --- E3 (Fig. 8b) --------------------------------------------------------------------


def medians(result, attitude):
    vals = result.values("rms_horizontal_error_m", "hover")
    return {p: float(np.median(v)) for (p, a), v in vals.items() if a == attitude}


def test_e3_do_controllers_beat_pid_and_aibc_in_turbulence(e3):
    """Over the ISM+DO attitude loop in 3 m/s turbulent wind, the position DOs (Gamma = 3 rad/s)
    follow the drag fluctuation that PID's integral (slowest pole 0.23 rad/s) cannot: we require
    the DO controllers' median horizontal RMS error to be below half of PID's and AIBC's."""
    m = medians(e3, "ism_do")
    for do in ("pd_do", "ism_do"):
        for base in ("pid", "aibc"):
            assert m[do] < 0.5 * m[base], (do, base, m)


def test_e3_attitude_do_lowers_the_horizontal_error_of_every_position_controller(e3):
    """Gusts act at the rotor plane, 3 cm above the centre of mass, and the model errors add a
    constant torque: the PD attitude loop lets both tilt the thrust. Every position controller
    does better over the ISM+DO attitude loop (median over seeds)."""
    with_do, pd = medians(e3, "ism_do"), medians(e3, "pd")
    for p in ("pid", "aibc", "pd_do", "ism_do"):
        assert with_do[p] < pd[p], (p, with_do[p], pd[p])


# --- E4 (Fig. 9) ---------------------------------------------------------------------


def test_e4_waypoints_are_flown_at_large_tilt_within_the_rate_limit(e4):
    """Reference limited to 2 m/s, 6 m/s^2 (31 deg) and 20 m/s^3; feedback adds the rest, so
    tilts reach ~50 deg (the paper: 'up to 50 deg'): we require 40..62 deg. The rate command is
    clipped in norm, so it can never exceed 250 deg/s, and it does reach the limit."""
    limit = 250.0
    for p in ("pid", "aibc", "pd_do", "ism_do"):
        m = seg(e4, p, "waypoints")
        assert m.peak_rate_cmd_deg_s <= limit + 1e-6
        assert 40.0 < m.peak_tilt_deg < 62.0, (p, m.peak_tilt_deg)
    assert max(seg(e4, p, "waypoints").peak_rate_cmd_deg_s for p in ("pd_do", "ism_do")) > 0.95 * limit


def test_e4_position_speed_and_yaw_are_tracked(e4):
    """Yaw turns by 90 deg at up to 90 deg/s; the attitude loop (12 rad/s) tracks it within a few
    degrees: RMS yaw error < 4 deg. The DO controllers keep the position RMS error under 15 cm;
    the speed overshoots the 2 m/s reference (the paper saw 3 m/s) but stays below 3.2 m/s."""
    ref_speed_max = 0.0
    for p in ("pid", "aibc", "pd_do", "ism_do"):
        m = seg(e4, p, "waypoints")
        assert m.rms_yaw_error_deg < 4.0, p
    for p in ("pd_do", "ism_do"):
        assert seg(e4, p, "waypoints").rms_error_m < 0.15
        log = e4.logs[Case(p, "ism_do", 1)]
        speed = np.sqrt(log["vx"] ** 2 + log["vy"] ** 2 + log["vz"] ** 2)
        ref_speed_max = max(ref_speed_max, np.sqrt(log["vx_ref"] ** 2 + log["vy_ref"] ** 2 + log["vz_ref"] ** 2).max())
        assert 2.0 < speed.max() < 3.2
    assert ref_speed_max <= 2.0 + 1e-9


# --- E5 (Fig. 10) --------------------------------------------------------------------


def test_e5_do_controllers_hover_at_45_degrees_holding_position(e5):
    """6 N against 0.63 * 9.81 = 6.18 N of weight: atan(6 / 6.18) = 44.2 deg; +-1.5 deg covers
    the accelerometer bias and the drag of the residual motion. Position is held: RMS error over
    the last 10 s of the attached phase below 2 cm, settled into 5 cm within 4 s."""
    for p in ("pd_do", "ism_do"):
        m = seg(e5, p, "attached")
        assert abs(m.steady_tilt_deg - 44.2) < 1.5, p
        assert m.settling_time_s < 4.0, p
        log = e5.logs[Case(p, "ism_do", 1)]
        late = (log.t > 12) & (log.t < 22)
        err = np.sqrt((log["x"] - log["x_ref"]) ** 2 + (log["y"] - log["y_ref"]) ** 2)[late]
        assert np.sqrt(np.mean(err**2)) < 0.02, p
        assert abs(m.steady_force_estimate_n - 6.0) < 0.3, p


def test_e5_release_pushes_back_without_swinging_past(e5):
    """SPEC section 7: the release pushes the vehicle back by about what the onset pushed it
    forward (within 25%); the claim is that it does not then swing past its resting point. For
    PD+DO, linear theory gives no swing at all (a critically damped loop driven by a one-signed
    pulse); for ISM+DO the boundary layer's reset discards the integral (next test). We allow
    5% of the excursion for noise (a few millimetres on ~35 cm)."""
    for p in ("pd_do", "ism_do"):
        onset, release = seg(e5, p, "attached"), seg(e5, p, "released")
        assert release.excursion_m < 0 < onset.excursion_m
        assert abs(abs(release.excursion_m) - onset.excursion_m) < 0.25 * onset.excursion_m, p
        assert release.swing_past_m < 0.05 * abs(release.excursion_m), (p, release.swing_past_m)


def test_e5_the_anti_windup_reset_is_what_prevents_the_ism_overshoot():
    """Without the reset, the ISM integral built during the hold swings the vehicle ~30% past
    its resting point after release (as in E1, where s stays inside the layer)."""
    sc = load_scenario("E5_suspended_weight")
    sc = sc.with_changes(position=dataclasses.replace(sc.position, anti_windup=False), duration_s=30.0,
                         segments=(sc.segments[0], dataclasses.replace(sc.segments[1], stop_s=30.0)))
    release = flight_metrics(simulate(sc, "ism_do", "ism_do", 1))[1]
    assert release.swing_past_m > 0.15 * abs(release.excursion_m)


def test_e5_aibc_estimate_stalls_and_its_error_persists(e5):
    """AIBC's estimate gamma v~ vanishes once the vehicle stops moving, so it never identifies the
    6 N (steady estimate < 1.5 N); only the slow integral (poles ~ -0.1 rad/s with gamma = 8)
    is left, and 20 s later the error is still decimetres while the DO controllers hold to cm."""
    aibc = seg(e5, "aibc", "attached")
    assert aibc.steady_force_estimate_n < 1.5
    log = e5.logs[Case("aibc", "ism_do", 1)]
    late = (log.t > 17) & (log.t < 22)
    assert np.abs(log["x"][late] - log["x_ref"][late]).mean() > 0.3
