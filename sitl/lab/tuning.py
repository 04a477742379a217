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
position error over the scenario's metric segment.

The result is checked on seeds the search never saw: the default and the tuned gains fly
``--check-seeds`` new seeds each, and ``before_after.png`` shows both distributions.
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
from .metrics import segment_metrics
from .simulation import simulate

__all__ = ["GAINS", "Candidate", "stability_margin", "evaluate", "tune", "main"]

GAINS = ("att_omega_c", "att_gamma", "att_k_s", "pos_omega_c", "pos_gamma_xy")
BOUNDS = {
    "att_omega_c": (5.0, 30.0),
    "att_gamma": (1.0, 40.0),
    "att_k_s": (1.0, 40.0),
    "pos_omega_c": (0.8, 4.0),
    "pos_gamma_xy": (0.5, 15.0),
}
"""search box: wide around the paper's 12, 8, 12, 1.5, 3"""


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


def _fly(args: tuple[Scenario, list[Candidate], list[int], str, Segment]) -> np.ndarray:
    sc, cands, seeds, metric, seg = args
    pop = _population_scenario(sc, cands, len(seeds))
    log = simulate(pop, "ism_do", "ism_do", [s for _ in cands for s in seeds])
    out = np.empty((len(cands), len(seeds)))
    for i in range(len(cands)):
        for j in range(len(seeds)):
            v = getattr(segment_metrics(log.vehicle(i * len(seeds) + j), seg), metric)
            out[i, j] = v if math.isfinite(v) and v < 100.0 else 100.0  # a diverged vehicle scores badly
    return out


def evaluate(sc: Scenario, cands: Sequence[Candidate], seeds: Sequence[int], jobs: int = 1,
             metric: str = "rms_horizontal_error_m", segment: Segment | None = None) -> np.ndarray:
    """Metric of every candidate on every seed, shape (candidates, seeds); split over ``jobs``.

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
    out = np.empty((len(cands), len(seeds)))
    for k, part in enumerate(parts):
        out[k::jobs][: len(part)] = part
    return out


def tune(sc: Scenario, generations: int, population: int, seeds: Sequence[int], jobs: int, rng_seed: int = 0,
         segment: Segment | None = None, log: bool = True) -> tuple[Candidate, list[dict]]:
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
        scores = evaluate(sc, cands, seeds, jobs, segment=segment).mean(axis=1)
        order = np.argsort(scores)
        elite = [cands[i] for i in order[: max(2, population // 4)]]
        if scores[order[0]] < best[0]:
            best = (float(scores[order[0]]), cands[order[0]])
        logs = np.log([c.vector() for c in elite])
        mean, std = logs.mean(axis=0), np.maximum(logs.std(axis=0), 0.03)
        history.append({"generation": gen, "best": best[0], "generation_best": float(scores[order[0]]),
                        "median": float(np.median(scores)), "wall_s": time.monotonic() - t0})
        if log:
            print(f"generation {gen}: best {best[0]:.4f} m (this generation {scores[order[0]]:.4f}, median "
                  f"{np.median(scores):.4f}), {time.monotonic() - t0:.0f} s", file=sys.stderr, flush=True)
    return best[1], history


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
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("tuning"))
    args = ap.parse_args(argv)
    sc = load_scenario(args.scenario)
    if args.duration:
        sc = sc.with_changes(duration_s=args.duration)
    seg = Segment("tuning", *args.window) if args.window else sc.segments[0]
    if seg.stop_s > sc.duration_s:
        ap.error(f"metric window {seg.start_s}..{seg.stop_s} s ends after the flight ({sc.duration_s} s)")
    args.out.mkdir(parents=True, exist_ok=True)
    best, history = tune(sc, args.generations, args.population, list(range(1, args.seeds + 1)), args.jobs,
                         segment=seg)
    before = Candidate.defaults(sc)
    fresh = list(range(1001, 1001 + args.check_seeds))
    check = evaluate(sc, [before, best], fresh, args.jobs, segment=seg)
    result = {
        "scenario": sc.name, "window_s": [seg.start_s, seg.stop_s],
        "objective": "mean horizontal RMS error over the segment, ISM+DO / ISM+DO",
        "before": dataclasses.asdict(before), "after": dataclasses.asdict(best),
        "stability_margin_25": {"before": stability_margin(before, sc.vehicle),
                                "after": stability_margin(best, sc.vehicle)},
        "check_seeds": len(fresh),
        "before_median_m": float(np.median(check[0])), "after_median_m": float(np.median(check[1])),
        "before_mean_m": float(check[0].mean()), "after_mean_m": float(check[1].mean()),
        "history": history,
    }
    (args.out / "result.json").write_text(json.dumps(result, indent=1))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.boxplot([check[0], check[1]], showfliers=True)
    ax.set_xticks([1, 2], ["paper's gains", "tuned gains"])
    ax.set_ylabel("horizontal RMS error [m]")
    ax.set_title(f"{sc.description}\n{len(fresh)} seeds not used in the search", fontsize=9)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(args.out / "before_after.png", dpi=110)
    plt.close(fig)
    print(json.dumps({k: v for k, v in result.items() if k != "history"}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
