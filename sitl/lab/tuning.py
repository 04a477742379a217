"""Gain tuning by simulation: minimise hover error in turbulence subject to stability (25).

    sitl-tune                                  # E3 wind, ISM+DO/ISM+DO, defaults below
    sitl-tune --generations 8 --population 32 --seeds 16 --out tuning/

Cross-entropy method over five gains: attitude ``omega_c``, observer ``Gamma_a`` and sliding gain
``k_s``, position ``omega_c`` and horizontal observer ``Gamma_p``. Each generation samples a
population from a Gaussian (in log space: all gains are positive scale parameters), rejects
samples that break the stability condition (25) inside the attitude boundary layer,
``4 lambda_min(K) lambda_min(Gamma_a) > 1`` with ``K = k_s J0``, and flies **the whole
population at once**: candidates x seeds as one batch of vehicles whose gains are per-vehicle
arrays (the control laws take arrays wherever they take floats). Every candidate flies the same
seeds (common random numbers), so they are compared on the same gusts and noise. The elite
quarter refits the Gaussian. The objective is the mean over seeds of the horizontal RMS
position error over the scenario's metric segment, for candidates that keep the vehicle's tilt
under ``--tilt-limit`` over the whole flight on every seed; a candidate that needs more tilt is
on the edge of its region of attraction and scores worse than any that does not (see
:func:`objective`).

The result is checked on seeds the search never saw: the default and the tuned gains fly
``--check-seeds`` new seeds each, and ``before_after.png`` shows both distributions. What the
tuned gains cost and how they carry over to the step force (E1) and the 6 N weight (E5) is
flown on ``--carry-over-seeds`` more.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from companion.control.params import AttitudeGains, VehicleParams, attitude_stability_margin

from ..plant.scenario import Scenario, Segment, load_scenario
from .metrics import segment_metrics, tilt_deg
from .simulation import simulate

__all__ = ["GAINS", "Candidate", "Scores", "stability_margin", "evaluate", "objective", "tune", "check",
           "carry_over", "tables", "main"]

GAINS = ("att_omega_c", "att_gamma", "att_k_s", "pos_omega_c", "pos_gamma_xy")
BOUNDS = {
    "att_omega_c": (5.0, 30.0),
    "att_gamma": (1.0, 40.0),
    "att_k_s": (1.0, 40.0),
    "pos_omega_c": (0.8, 4.0),
    "pos_gamma_xy": (0.5, 15.0),
}
"""search box: wide around the paper's 12, 8, 12, 1.5, 3"""

TILT_LIMIT_DEG = 40.0
"""the largest tilt a candidate may need on any search seed, over the whole flight. The paper's gains
peak at 34 deg in E3 (100 seeds, the start into the full 3 m/s wind); gains that need more fly on
the edge of their region of attraction, where a seed the search never saw tips the vehicle over"""

DIVERGED_M = 100.0
"""the score of a flight whose error is not finite or beyond this [m]"""


@dataclass(frozen=True)
class Candidate:
    att_omega_c: float
    att_gamma: float
    att_k_s: float
    pos_omega_c: float
    pos_gamma_xy: float

    @staticmethod
    def defaults(sc: Scenario) -> Candidate:
        a, p = sc.attitude, sc.position
        return Candidate(a.omega_c_rad_s, a.observer_gain_rad_s[0], a.sliding_gain_rad_s[0], p.omega_c_rad_s[0],
                         p.observer_gain_rad_s[0])

    def vector(self) -> np.ndarray:
        return np.array([getattr(self, g) for g in GAINS])


def stability_margin(c: Candidate, vehicle: VehicleParams) -> float:
    """``4 lambda_min(K) lambda_min(Gamma_a)`` of (25) for this candidate (> 1: stable in the layer)."""
    gains = AttitudeGains(observer_gain_rad_s=(c.att_gamma,) * 3, sliding_gain_rad_s=(c.att_k_s,) * 3)
    return attitude_stability_margin(gains, vehicle)


def _population_scenario(sc: Scenario, cands: Sequence[Candidate], n_seeds: int) -> Scenario:
    """One scenario whose gains are arrays: vehicle ``i * n_seeds + j`` flies candidate i."""
    def col(name: str) -> np.ndarray:
        return np.repeat(np.array([getattr(c, name) for c in cands], dtype=float), n_seeds)

    wa, ga, ks = col("att_omega_c"), col("att_gamma"), col("att_k_s")
    wp, gp = col("pos_omega_c"), col("pos_gamma_xy")
    att = dataclasses.replace(sc.attitude, omega_c_rad_s=wa, observer_gain_rad_s=(ga, ga, ga),  # type: ignore[arg-type]
                              sliding_gain_rad_s=(ks, ks, ks))
    gz = np.full_like(gp, sc.position.observer_gain_rad_s[2])
    pos = dataclasses.replace(sc.position, omega_c_rad_s=(wp, wp, wp), observer_gain_rad_s=(gp, gp, gz))  # type: ignore[arg-type]
    return dataclasses.replace(sc, attitude=att, position=pos)


@dataclass(frozen=True)
class Scores:
    """What every candidate flew on every seed, arrays of shape (candidates, seeds)."""

    metric: np.ndarray
    """the metric over the window (a diverged flight: :data:`DIVERGED_M`)"""
    peak_tilt_deg: np.ndarray
    """the largest tilt over the whole flight"""


def _fly(args: tuple[Scenario, list[Candidate], list[int], str, Segment]) -> Scores:
    sc, cands, seeds, metric, seg = args
    pop = _population_scenario(sc, cands, len(seeds))
    log = simulate(pop, "ism_do", "ism_do", [s for _ in cands for s in seeds])
    out = np.empty((len(cands), len(seeds)))
    for i in range(len(cands)):
        for j in range(len(seeds)):
            v = getattr(segment_metrics(log.vehicle(i * len(seeds) + j), seg), metric)
            out[i, j] = v if math.isfinite(v) and v < DIVERGED_M else DIVERGED_M
    tilt = np.nan_to_num(tilt_deg(log), nan=180.0).max(axis=0).reshape(len(cands), len(seeds))
    return Scores(out, tilt)


def evaluate(sc: Scenario, cands: Sequence[Candidate], seeds: Sequence[int], jobs: int = 1,
             metric: str = "rms_horizontal_error_m", segment: Segment | None = None) -> Scores:
    """Metric and peak tilt of every candidate on every seed; split over ``jobs`` processes.

    ``segment`` is the metric window (default: the scenario's first segment).
    """
    cands = list(cands)
    seg = segment or sc.segments[0]
    chunks = [cands[i::jobs] for i in range(jobs) if cands[i::jobs]]
    args = [(sc, chunk, list(seeds), metric, seg) for chunk in chunks]
    if len(args) == 1:
        parts = [_fly(args[0])]
    else:
        with ProcessPoolExecutor(len(args)) as pool:
            parts = list(pool.map(_fly, args))
    metric_out = np.empty((len(cands), len(seeds)))
    tilt_out = np.empty((len(cands), len(seeds)))
    for k, part in enumerate(parts):
        metric_out[k::jobs][: len(part.metric)] = part.metric
        tilt_out[k::jobs][: len(part.metric)] = part.peak_tilt_deg
    return Scores(metric_out, tilt_out)


def objective(scores: Scores, tilt_limit_deg: float = TILT_LIMIT_DEG) -> np.ndarray:
    """One score per candidate: the mean metric over seeds, if its peak tilt stays within the limit on
    every seed; otherwise 1 + (peak tilt - limit) / limit, which ranks it below every candidate that
    stays within (their scores are RMS errors of centimetres) and still orders the ones that do not,
    so that a generation with few feasible samples moves towards feasibility."""
    worst = scores.peak_tilt_deg.max(axis=1)
    mean = scores.metric.mean(axis=1)
    return np.where(worst <= tilt_limit_deg, mean, 1.0 + (worst - tilt_limit_deg) / tilt_limit_deg)


def tune(sc: Scenario, generations: int, population: int, seeds: Sequence[int], jobs: int, rng_seed: int = 0,
         segment: Segment | None = None, log: bool = True,
         tilt_limit_deg: float = TILT_LIMIT_DEG) -> tuple[Candidate, list[dict]]:
    """Cross-entropy search; returns the best candidate seen and one history row per generation."""
    rng = np.random.default_rng(rng_seed)
    lo = np.log([BOUNDS[g][0] for g in GAINS])
    hi = np.log([BOUNDS[g][1] for g in GAINS])
    start = Candidate.defaults(sc)
    mean = np.log(start.vector())
    std = 0.35 * np.ones(len(GAINS))
    history: list[dict] = []
    best: tuple[float, Candidate] = (math.inf, start)
    for gen in range(generations):
        cands: list[Candidate] = [start] if gen == 0 else [best[1]]
        while len(cands) < population:
            x = np.exp(np.clip(rng.normal(mean, std), lo, hi))
            c = Candidate(*(float(v) for v in x))
            if stability_margin(c, sc.vehicle) > 1.0:  # (25): otherwise not a candidate at all
                cands.append(c)
        t0 = time.monotonic()
        flown = evaluate(sc, cands, seeds, jobs, segment=segment)
        scores = objective(flown, tilt_limit_deg)
        order = np.argsort(scores)
        elite = [cands[i] for i in order[: max(2, population // 4)]]
        if scores[order[0]] < best[0]:
            best = (float(scores[order[0]]), cands[order[0]])
        logs = np.log([c.vector() for c in elite])
        mean, std = logs.mean(axis=0), np.maximum(logs.std(axis=0), 0.03)
        history.append({"generation": gen, "best": best[0], "generation_best": float(scores[order[0]]),
                        "median": float(np.median(scores)),
                        "within_tilt_limit": int((flown.peak_tilt_deg.max(axis=1) <= tilt_limit_deg).sum()),
                        "wall_s": time.monotonic() - t0})
        if log:
            print(f"generation {gen}: best {best[0]:.4f} m (this generation {scores[order[0]]:.4f}, median "
                  f"{np.median(scores):.4f}), {time.monotonic() - t0:.0f} s", file=sys.stderr, flush=True)
    return best[1], history


CARRY_OVER = (
    ("tuning", "rms_rate_cmd_deg_s", "RMS rate command (34) [deg/s]"),
    ("tuning", "rms_vertical_error_m", "vertical RMS error [m]"),
    ("E1_step_force", "peak_error_m", "E1 step force: peak error, force on [m]"),
    ("E5_suspended_weight", "peak_error_m", "E5 6 N weight: peak error, attached [m]"),
)
"""what the tuned gains cost and how they carry over: (scenario, metric, label); "tuning" is the tuned
scenario over its window, the others fly their first segment with the paper's gains before and the
tuned ones after"""


def carry_over(sc: Scenario, after: Candidate, seeds: Sequence[int], jobs: int,
               segment: Segment) -> list[dict]:
    """Median over ``seeds`` of each :data:`CARRY_OVER` metric, the scenario's own gains against ``after``."""
    rows = []
    for name, metric, label in CARRY_OVER:
        other = sc if name == "tuning" else load_scenario(name)
        seg = segment if name == "tuning" else other.segments[0]
        flown = evaluate(other, [Candidate.defaults(other), after], seeds, jobs, metric=metric, segment=seg)
        rows.append({"scenario": other.name, "segment": seg.name, "metric": metric, "label": label,
                     "before": float(np.median(flown.metric[0])), "after": float(np.median(flown.metric[1]))})
    return rows


CHECK_SEEDS_FROM = 1001
"""the unseen seeds of the check are 1001, 1002, ...; the search flies 1, 2, ..."""
CARRY_OVER_SEEDS_FROM = 2001


def check(sc: Scenario, segment: Segment, after: Candidate, check_seeds: int, carry_over_seeds: int,
          jobs: int) -> tuple[dict, np.ndarray]:
    """The scenario's own gains against ``after`` on seeds the search never saw: the metric's median,
    mean and worst and the peak tilt over ``check_seeds`` flights each, and the :func:`carry_over`
    table over ``carry_over_seeds`` more; with every flight's metric, shape (2, check_seeds)."""
    before = Candidate.defaults(sc)
    flown = evaluate(sc, [before, after], range(CHECK_SEEDS_FROM, CHECK_SEEDS_FROM + check_seeds), jobs,
                     segment=segment)
    m = flown.metric
    return {
        "scenario": sc.name, "window_s": [segment.start_s, segment.stop_s],
        "objective": "mean horizontal RMS error over the segment, ISM+DO / ISM+DO",
        "before": dataclasses.asdict(before), "after": dataclasses.asdict(after),
        "stability_margin_25": {"before": stability_margin(before, sc.vehicle),
                                "after": stability_margin(after, sc.vehicle)},
        "check_seeds": check_seeds,
        "before_median_m": float(np.median(m[0])), "after_median_m": float(np.median(m[1])),
        "before_mean_m": float(m[0].mean()), "after_mean_m": float(m[1].mean()),
        "before_worst_m": float(m[0].max()), "after_worst_m": float(m[1].max()),
        "before_peak_tilt_deg": float(flown.peak_tilt_deg[0].max()),
        "after_peak_tilt_deg": float(flown.peak_tilt_deg[1].max()),
        "carry_over_seeds": carry_over_seeds,
        "carry_over": carry_over(sc, after, range(CARRY_OVER_SEEDS_FROM, CARRY_OVER_SEEDS_FROM + carry_over_seeds),
                                 jobs, segment) if carry_over_seeds > 0 else [],
    }, m


GAIN_LABELS = {
    "att_omega_c": "attitude `omega_c` [rad/s]",
    "att_gamma": "attitude `Gamma_a` [rad/s]",
    "att_k_s": "attitude `k_s` [rad/s]",
    "pos_omega_c": "position `omega_c` [rad/s]",
    "pos_gamma_xy": "position `Gamma_p,xy` [rad/s]",
}


def _mm(v: float) -> str:
    return f"{1000.0 * v:.1f} mm"


def tables(result: dict) -> str:
    """The three tables docs/sweeps.md publishes, printed from a ``result.json``: the gains, the check on
    unseen seeds and the cost and carry-over."""
    b, a = result["before"], result["after"]
    lines = ["| gain | paper | tuned |", "|---|---|---|"]
    lines += [f"| {GAIN_LABELS[g]} | {b[g]:#.3g} | {a[g]:#.3g} |" for g in GAINS]
    m = result["stability_margin_25"]
    lines += [f"| margin of (25) | {m['before']:#.3g} | {m['after']:#.3g} |", ""]
    lines += [f"| {result['check_seeds']} unseen seeds | median | mean | worst | peak tilt |", "|---|---|---|---|---|"]
    for who, label in (("before", "paper's gains"), ("after", "tuned gains")):
        lines.append(f"| {label} | {_mm(result[who + '_median_m'])} | {_mm(result[who + '_mean_m'])} | "
                     f"{_mm(result[who + '_worst_m'])} | {result[who + '_peak_tilt_deg']:.1f}° |")
    if result["carry_over"]:
        lines += ["", f"| median of {result['carry_over_seeds']} seeds | paper's gains | tuned gains |",
                  "|---|---|---|"]
        for row in result["carry_over"]:
            unit = "deg/s" if row["metric"].endswith("deg_s") else "m"
            fmt = (lambda v: f"{v:.1f} °/s") if unit == "deg/s" else _mm
            lines.append(f"| {row['label'].rsplit(' [', 1)[0]} | {fmt(row['before'])} | {fmt(row['after'])} |")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="sitl-tune", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="E3_wind")
    ap.add_argument("--duration", type=float, help="simulated seconds per flight (default: the scenario's)")
    ap.add_argument("--window", type=float, nargs=2, metavar=("START", "STOP"),
                    help="metric window in seconds (default: the scenario's first segment)")
    ap.add_argument("--generations", type=int, default=6)
    ap.add_argument("--population", type=int, default=24)
    ap.add_argument("--seeds", type=int, default=12, help="seeds per candidate during the search")
    ap.add_argument("--check-seeds", type=int, default=50, help="fresh seeds for the before/after check")
    ap.add_argument("--carry-over-seeds", type=int, default=10,
                    help="fresh seeds for the cost and carry-over table (0: skip it)")
    ap.add_argument("--tilt-limit", type=float, default=TILT_LIMIT_DEG,
                    help="largest tilt [deg] a candidate may need on any search seed (default %(default)s)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("tuning"))
    args = ap.parse_args(argv)
    if not 0.0 < args.tilt_limit < 90.0:
        ap.error(f"--tilt-limit {args.tilt_limit}: expected degrees between 0 and 90")
    sc = load_scenario(args.scenario)
    if args.duration:
        sc = sc.with_changes(duration_s=args.duration)
    seg = Segment("tuning", *args.window) if args.window else sc.segments[0]
    if seg.stop_s > sc.duration_s:
        ap.error(f"metric window {seg.start_s}..{seg.stop_s} s ends after the flight ({sc.duration_s} s)")
    args.out.mkdir(parents=True, exist_ok=True)
    best, history = tune(sc, args.generations, args.population, list(range(1, args.seeds + 1)), args.jobs,
                         segment=seg, tilt_limit_deg=args.tilt_limit)
    result, check_m = check(sc, seg, best, args.check_seeds, args.carry_over_seeds, args.jobs)
    result["tilt_limit_deg"] = args.tilt_limit
    result["history"] = history
    (args.out / "result.json").write_text(json.dumps(result, indent=1))
    (args.out / "tables.md").write_text(tables(result))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.boxplot([check_m[0], check_m[1]], showfliers=True)
    ax.set_xticks([1, 2], ["paper's gains", "tuned gains"])
    ax.set_ylabel("horizontal RMS error [m]")
    ax.set_title(f"{sc.description}\n{args.check_seeds} seeds not used in the search", fontsize=9)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(args.out / "before_after.png", dpi=110)
    plt.close(fig)
    print(json.dumps({k: v for k, v in result.items() if k != "history"}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
