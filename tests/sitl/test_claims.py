"""The paper's claims (sitl/lab/claims.py) on the paper's configuration over five seeds, each with
its broken twin: a deliberately broken variant on which the same check must fail.

A twin flies only what its claim needs (one seed, the shortest flight that holds the segment);
where the broken variant is "a DO loop whose observer is dead", the PD runs the fixture already
flew stand in for it (:func:`relabel`), which costs nothing.
"""

import dataclasses

import pytest

from sitl.lab.claims import CLAIMS, judge
from sitl.lab.experiments import run_experiment
from sitl.lab.results import Case, ExperimentResult
from sitl.plant.scenario import Segment, apply_settings, load_scenario

pytestmark = pytest.mark.slow
SEEDS = [1, 2, 3, 4, 5]
JOBS = 2
PAPER = ("pid", "aibc", "pd_do", "ism_do")
"""the paper's controllers: the claims are about them (INDI is compared in the experiments)"""


def fly(name, seeds=SEEDS, settings=None, position=None, attitude=None, duration_s=None, segments=None):
    sc = load_scenario(name)
    if settings:
        sc = apply_settings(sc, settings)
    runs = dataclasses.replace(sc.runs, position=tuple(position or sc.runs.position),
                               attitude=tuple(attitude or sc.runs.attitude))
    sc = sc.with_changes(runs=runs)
    if duration_s is not None:
        sc = sc.with_changes(duration_s=duration_s)
    if segments is not None:
        sc = sc.with_changes(segments=tuple(s for s in sc.segments if s.name in segments))
    return run_experiment(sc, seeds=seeds, jobs=JOBS)


def relabel(result, source, target):
    """A result whose ``target`` (position, attitude) runs are the ``source`` ones: e.g. PD attitude
    runs standing in for an ISM+DO attitude loop whose observer and sliding term are dead."""
    metrics = {c: m for c, m in result.metrics.items() if (c.position, c.attitude) != target}
    for c, m in result.metrics.items():
        if (c.position, c.attitude) == source:
            metrics[Case(target[0], target[1], c.seed)] = m
    return ExperimentResult(result.scenario, metrics)


def merged(base, twin):
    """``base`` with every run of the controller pairs that ``twin`` flew replaced by the twin's."""
    pairs = {(c.position, c.attitude) for c in twin.metrics}
    metrics = {c: m for c, m in base.metrics.items() if (c.position, c.attitude) not in pairs}
    metrics.update(twin.metrics)
    return ExperimentResult(base.scenario, metrics)


def claim(name):
    return next(c for c in CLAIMS if c.name == name)


def holds(name, result):
    v = judge(claim(name), result)
    assert v.holds, v.detail


def fails(name, result):
    v = judge(claim(name), result)
    assert not v.holds, f"the broken twin passes {name!r}: {v.detail}"


def test_every_claim_has_a_test_here():
    text = open(__file__).read()
    assert all(f'"{c.name}"' in text for c in CLAIMS)


@pytest.fixture(scope="module")
def e1():
    return fly("E1_step_force", position=PAPER)


@pytest.fixture(scope="module")
def e2():
    return fly("E2_chirp_torque", attitude=("ism_do", "pd_do", "pd"), duration_s=24.0,
               segments=("60 deg, constant torque", "chirp"))


@pytest.fixture(scope="module")
def e3():
    """30 s instead of 45, metrics over 15..30 s: the baselines' start transient is in the
    ideal-PID yardstick as well (it starts from rest too), so the shorter window is fair."""
    sc = load_scenario("E3_wind")
    runs = dataclasses.replace(sc.runs, position=PAPER, attitude=("pd", "ism_do"))
    sc = sc.with_changes(duration_s=30.0, segments=(Segment("hover", 15.0, 30.0),), runs=runs)
    return run_experiment(sc, seeds=SEEDS, jobs=JOBS)


@pytest.fixture(scope="module")
def e4():
    return fly("E4_waypoints", position=PAPER)


@pytest.fixture(scope="module")
def e5():
    return fly("E5_suspended_weight", position=("pd_do", "ism_do"))


# --- E1 --------------------------------------------------------------------------------------


def test_e1_pd_do_settles_faster_than_pid(e1):
    holds("E1 PD+DO settles faster than PID", e1)
    dead_observer = fly("E1_step_force", [1], {"position.observer_gain_rad_s": 1e-3}, ("pid", "pd_do"),
                        duration_s=8.0, segments=("force on",))
    fails("E1 PD+DO settles faster than PID", dead_observer)


@pytest.fixture(scope="module")
def e1_without_sliding():
    """The ISM+DO position controller with its sliding gain at zero: PD+DO in disguise."""
    return fly("E1_step_force", [1], {"position.sliding_gain_rad_s": 0.0}, ("pd_do", "ism_do"))


def test_e1_ism_do_has_the_smallest_peak(e1, e1_without_sliding):
    holds("E1 ISM+DO has the smallest peak", e1)
    fails("E1 ISM+DO has the smallest peak", e1_without_sliding)


def test_e1_ism_do_undershoots_after_release(e1, e1_without_sliding):
    holds("E1 ISM+DO undershoots after release", e1)
    fails("E1 ISM+DO undershoots after release", e1_without_sliding)


def e1_fig6_figures(result):
    """Issue 14's E1 targets on Fig. 6's parameters, as far as the law reaches them: ISM+DO peaks
    within 0.115 m and PD+DO within 0.195 m in every seed, and ISM+DO is back within 5 cm in at most
    1.20 s: the law's own 1.15 s on an ideal point mass (tests/control/test_position.py) plus
    50 ms; the target's 1.05 s is faster than the law (docs/experiments.md, E1)."""
    peak = result.values("peak_error_m", "force on")
    settle = result.values("settling_time_s", "force on")
    return peak[("ism_do", "ism_do")], settle[("ism_do", "ism_do")], peak[("pd_do", "ism_do")]


def test_e1_lands_on_fig6_on_the_papers_simulated_sensing(e1):
    """E1 (a simulation in the paper) measures the acceleration as the paper's simulation does;
    the twin differentiates motion capture and matches (30) to it, as E3-E5's hardware does, and
    is 4-9 cm off Fig. 6."""
    peaks, settles, pd_peaks = e1_fig6_figures(e1)
    assert max(peaks) <= 0.115 and max(settles) <= 1.20 and max(pd_peaks) <= 0.195, (peaks, settles, pd_peaks)
    mocap = {"position.observer_uses_imu": False, "position.observer_match_delay_s": 0.035,
             "position.observer_match_cutoff_hz": 5.0}
    twin = fly("E1_step_force", [1], mocap, ("pd_do", "ism_do"), duration_s=8.0, segments=("force on",))
    peaks, settles, pd_peaks = e1_fig6_figures(twin)
    assert not (max(peaks) <= 0.115 and max(settles) <= 1.20 and max(pd_peaks) <= 0.195)


# --- E2 --------------------------------------------------------------------------------------


def test_e2_roll_held_at_60_deg(e2):
    holds("E2 roll held at 60 deg", e2)
    capped = fly("E2_chirp_torque", [1], {"reference.tilt_max_rad": 0.8727}, ("ism_do",), ("ism_do",),
                 duration_s=12.0, segments=("60 deg, constant torque",))
    fails("E2 roll held at 60 deg", capped)


def test_e2_estimate_follows_the_slow_component(e2):
    holds("E2 estimate follows the slow component", e2)
    fails("E2 estimate follows the slow component", relabel(e2, ("ism_do", "pd"), ("ism_do", "ism_do")))


def test_e2_sliding_variable_goes_to_zero(e2):
    holds("E2 sliding variable goes to zero", e2)
    no_observer = fly("E2_chirp_torque", [1], {"attitude.observer_gain_rad_s": 1e-3}, ("ism_do",), ("ism_do",),
                      duration_s=12.0, segments=("60 deg, constant torque",))
    fails("E2 sliding variable goes to zero", no_observer)


def test_e2_attitude_do_removes_the_torque_error(e2):
    holds("E2 attitude DO removes the torque's error", e2)
    dead = relabel(relabel(e2, ("ism_do", "pd"), ("ism_do", "ism_do")), ("ism_do", "pd"), ("ism_do", "pd_do"))
    fails("E2 attitude DO removes the torque's error", dead)


# --- E3 --------------------------------------------------------------------------------------


def e3_twin(settings, position, seeds=(1,)):
    sc = apply_settings(load_scenario("E3_wind"), settings)
    runs = dataclasses.replace(sc.runs, position=position, attitude=("ism_do",))
    sc = sc.with_changes(duration_s=30.0, segments=(Segment("hover", 15.0, 30.0),), runs=runs)
    return run_experiment(sc, seeds=list(seeds), jobs=JOBS)


def test_e3_dos_beat_pid_in_wind(e3):
    holds("E3 DOs beat PID in wind", e3)
    dead_observers = e3_twin({"position.observer_gain_rad_s": 1e-3}, ("pd_do", "ism_do"))
    fails("E3 DOs beat PID in wind", merged(e3, dead_observers))
    # a PID that is not the one the paper compares with (its integral switched off) fails the
    # claim too, instead of making it easy to win
    broken_pid = e3_twin({"position.integral_limit_m_s2": 1e-9}, ("pid",))
    fails("E3 DOs beat PID in wind", merged(e3, broken_pid))


def test_e3_dos_beat_aibc_in_wind(e3):
    """Not reproduced by the gain-matched AIBC, whose estimate observes the drag like a DO;
    reproduced over five seeds by the literal h = gamma v~ (not gain-matched). A literal AIBC
    with its integral off is no yardstick and fails."""
    fails("E3 DOs beat AIBC in wind", e3)
    literal = {"position.aibc_estimate": "velocity_feedback"}
    holds("E3 DOs beat AIBC in wind", merged(e3, e3_twin(literal, ("aibc",), SEEDS)))
    broken = e3_twin({**literal, "position.integral_limit_m_s2": 1e-9}, ("aibc",))
    fails("E3 DOs beat AIBC in wind", merged(e3, broken))


def test_e3_attitude_do_lowers_every_position_error(e3):
    holds("E3 attitude DO lowers every position error", e3)
    dead = e3
    for p in ("pid", "aibc", "pd_do", "ism_do"):
        dead = relabel(dead, (p, "pd"), (p, "ism_do"))
    fails("E3 attitude DO lowers every position error", dead)


# --- E4 --------------------------------------------------------------------------------------


def test_e4_large_tilts_within_the_gyro_rating(e4):
    """Not reproduced on the paper's configuration, and the test says so: the command is limited
    to 250 deg/s, but the filtered rate lags the attitude reference it belongs to, the attitude
    loop closes the gap at whatever rate it takes, and the body turns at 280-360 deg/s, past the
    gyro's 300. With the attitude reference itself filtered and rate-limited (omega_d its exact
    motion: reference.filter_attitude) the same check holds over five seeds."""
    fails("E4 large tilts within the gyro rating", e4)
    consistent = fly("E4_waypoints", settings={"reference.filter_attitude": True}, position=("pd_do", "ism_do"))
    holds("E4 large tilts within the gyro rating", consistent)


def test_e4_position_speed_and_yaw_tracked(e4):
    holds("E4 position, speed and yaw tracked", e4)
    dead_observer = fly("E4_waypoints", [1], {"position.observer_gain_rad_s": 1e-3}, ("pd_do", "ism_do"))
    fails("E4 position, speed and yaw tracked", dead_observer)


# --- E5 --------------------------------------------------------------------------------------


def test_e5_dos_hover_at_45_deg_holding_position(e5):
    holds("E5 DOs hover at 45 deg holding position", e5)
    capped = fly("E5_suspended_weight", [1], {"reference.tilt_max_rad": 0.6981}, ("pd_do", "ism_do"),
                 duration_s=22.0, segments=("attached", "attached, late"))
    fails("E5 DOs hover at 45 deg holding position", capped)


def test_e5_release_without_swinging_past(e5):
    holds("E5 release without swinging past", e5)
    segs = (Segment("attached", 2.0, 22.0), Segment("released", 22.0, 30.0))
    for settings in ({"position.anti_windup": False},  # the reset of [29] is what prevents it
                     {"position.observer_match_delay_s": 0.0, "position.observer_match_cutoff_hz": 0.0}):
        sc = apply_settings(load_scenario("E5_suspended_weight"), settings)
        sc = sc.with_changes(duration_s=30.0, segments=segs,
                             runs=dataclasses.replace(sc.runs, position=("ism_do",)))
        twin = run_experiment(sc, seeds=[1], jobs=1)
        fails("E5 release without swinging past", merged(e5, twin))


def test_e5_aibc_estimate_stalls_and_its_error_persists():
    """Not reproduced by the gain-matched AIBC (its observer finds the 6 N, as any observer of a
    constant does); reproduced over five seeds by the literal h = gamma v~, which is not
    gain-matched (velocity gain 3 + 8). A broken AIBC (integral off) fails the check too."""
    attached = ("attached", "attached, late")
    matched = fly("E5_suspended_weight", [1], position=("aibc",), duration_s=22.0, segments=attached)
    fails("E5 AIBC estimate stalls and its error persists", matched)
    literal = {"position.aibc_estimate": "velocity_feedback"}
    holds("E5 AIBC estimate stalls and its error persists",
          fly("E5_suspended_weight", SEEDS, literal, ("aibc",), duration_s=22.0, segments=attached))
    broken = fly("E5_suspended_weight", [1], {**literal, "position.integral_limit_m_s2": 1e-9}, ("aibc",),
                 duration_s=22.0, segments=attached)
    fails("E5 AIBC estimate stalls and its error persists", broken)
