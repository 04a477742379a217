"""Run the paper's experiments (or any scenario file) offline and write what they show.

    sitl-experiments all --out results          # E1-E5
    sitl-experiments E1_step_force E5_suspended_weight --jobs 2
    sitl-experiments sitl/plant/scenarios/E3_wind.toml --seeds 100
    sitl-experiments E3_calm --set position.force_source=measured --out results/measured

Per scenario, in ``OUT/<name>/``: one gzipped CSV time series per run (``runs/``), a metrics
table (``metrics.csv``: one row per controller combination, seed and segment) and a PNG figure.
``OUT/summary.md`` collects the median over seeds of every experiment run. Runs are spread
over processes (``--jobs``, default: all cores); every run is seeded, so results repeat.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from companion.control.names import controller_label

from ..plant.scenario import SCENARIO_DIR, Scenario, apply_settings, load_scenario, parse_setting
from .claims import claims_for, judge
from .metrics import SegmentMetrics, flight_metrics
from .results import Case, ExperimentResult
from .simulation import FlightLog, simulate

__all__ = ["run_experiment", "main", "PAPER_EXPERIMENTS"]

PAPER_EXPERIMENTS = (
    "E1_step_force",
    "E2_chirp_torque",
    "E3_calm",
    "E3_wind",
    "E4_waypoints",
    "E5_suspended_weight",
)

SUMMARY_FIELDS = (
    "rms_error_m",
    "peak_error_m",
    "excursion_m",
    "swing_past_m",
    "settling_time_s",
    "steady_tilt_deg",
    "peak_tilt_deg",
    "steady_force_estimate_n",
    "rms_force_estimate_error_n",
)


def cases_of(sc: Scenario, seeds: Sequence[int] | None = None) -> list[Case]:
    return [Case(p, a, s) for a in sc.runs.attitude for p in sc.runs.position for s in (seeds or sc.runs.seeds)]


def _run_case(args: tuple[Scenario, Case, str | None, bool]) -> tuple[Case, list[SegmentMetrics], FlightLog | None]:
    sc, case, series_dir, keep = args
    log = simulate(sc, case.position, case.attitude, case.seed)
    if series_dir is not None:
        log.to_csv(os.path.join(series_dir, f"{case.key}.csv.gz"))
    return case, flight_metrics(log), (log if keep else None)


def run_experiment(
    scenario: Scenario,
    out_dir: Path | None = None,
    seeds: Sequence[int] | None = None,
    jobs: int | None = None,
    progress: bool = False,
) -> ExperimentResult:
    """Fly every case of ``scenario``; with ``out_dir``, write time series, metrics and figure."""
    cases = cases_of(scenario, seeds)
    first_seed = cases[0].seed
    series_dir = None
    if out_dir is not None:
        series_dir = str(out_dir / "runs")
        os.makedirs(series_dir, exist_ok=True)
    work = [(scenario, c, series_dir, c.seed == first_seed) for c in cases]
    result = ExperimentResult(scenario)
    jobs = jobs or os.cpu_count() or 1
    t0 = time.monotonic()
    done = 0

    def collect(items: Iterable[tuple[Case, list[SegmentMetrics], FlightLog | None]]) -> None:
        nonlocal done
        for case, metrics, log in items:
            result.metrics[case] = metrics
            if log is not None:
                result.logs[case] = log
            done += 1
            if progress:
                rate = done / max(time.monotonic() - t0, 1e-9)
                left = (len(work) - done) / rate
                print(f"\r  {scenario.name}: {done}/{len(work)} runs, {rate:.2f} runs/s, {left:.0f} s left ",
                      end="", file=sys.stderr, flush=True)

    if jobs == 1 or len(work) == 1:
        collect(map(_run_case, work))
    else:
        with ProcessPoolExecutor(max_workers=min(jobs, len(work))) as pool:
            collect(pool.map(_run_case, work))
    if progress:
        print(file=sys.stderr)
    # keep the combinations in the scenario's order, whatever order the workers finished in
    result.metrics = {c: result.metrics[c] for c in cases}
    if out_dir is not None:
        write_metrics(result, out_dir / "metrics.csv")
        result.figure = draw_figure(result, out_dir)
    return result


def write_metrics(result: ExperimentResult, path: Path) -> None:
    rows = result.rows()
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def draw_figure(result: ExperimentResult, out_dir: Path) -> Path:
    from . import plots

    sc = result.scenario
    path = out_dir / f"{sc.name}.png"
    if sc.figure == "boxplot":
        seg = sc.segments[0].name if sc.segments else None
        groups = {}
        for title, name in (("horizontal RMS error [m]", "rms_horizontal_error_m"),
                            ("vertical RMS error [m]", "rms_vertical_error_m"),
                            ("rate command noise, RMS |omega_d| [deg/s]", "rms_rate_cmd_deg_s")):
            vals = result.values(name, seg)
            groups[title] = {f"{controller_label(p)}/{controller_label(a)}": v for (p, a), v in vals.items()}
        n = len(next(iter(vals.values())))
        return plots.boxplot_figure(groups, f"{sc.description} - {n} seeds per combination", path)
    return plots.draw(list(result.logs.values()), path)


def summary_table(result: ExperimentResult) -> str:
    """Markdown table: median over seeds per combination and segment."""
    sc = result.scenario
    head = ["controller (pos / att)", "segment", *SUMMARY_FIELDS]
    lines = [f"### {sc.name}: {sc.description}", "", "| " + " | ".join(head) + " |",
             "|" + "---|" * len(head)]
    combos: dict[tuple[str, str], list[list[SegmentMetrics]]] = {}
    for case, segs in result.metrics.items():
        combos.setdefault((case.position, case.attitude), []).append(segs)
    for (p, a), runs in combos.items():
        for i, seg in enumerate(runs[0]):
            cells = [f"{controller_label(p)} / {controller_label(a)}", seg.segment]
            for name in SUMMARY_FIELDS:
                v = float(np.median([getattr(r[i], name) for r in runs]))
                cells.append("n/a" if math.isnan(v) else f"{v:.3g}")
            lines.append("| " + " | ".join(cells) + " |")
    n_seeds = len(next(iter(combos.values())))
    lines += ["", f"(median over {n_seeds} seed{'s' if n_seeds > 1 else ''})", ""]
    lines += claims_table(result)
    return "\n".join(lines)


def claims_table(result: ExperimentResult) -> list[str]:
    """The paper's claims about this scenario (sitl/lab/claims.py), judged on this result."""
    out = []
    for c in claims_for(result.scenario.name):
        try:
            v = judge(c, result)
        except KeyError as exc:  # a controller the claim needs was not flown
            out.append(f"- {c.name}: not judged ({exc})")
            continue
        out.append(f"- {c.name}: **{'holds' if v.holds else 'FAILS'}**" + ("" if v.holds else f" ({v.detail})"))
    return (["Claims (every seed; E3: medians):", "", *out, ""]) if out else []


def resolve(names: Sequence[str]) -> list[Scenario]:
    out: list[Scenario] = []
    for name in names:
        if name == "all":
            out += [load_scenario(SCENARIO_DIR / f"{n}.toml") for n in PAPER_EXPERIMENTS]
        else:
            out.append(load_scenario(name))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="sitl-experiments", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenarios", nargs="*", default=["all"],
                    help="'all' (E1-E5), bundled names (E1_step_force) or paths to scenario files")
    ap.add_argument("--out", type=Path, default=Path("results"), help="output folder (default: results)")
    ap.add_argument("--seeds", type=int, help="run seeds 1..N instead of the scenario's own list")
    ap.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    ap.add_argument("--list", action="store_true", help="list the bundled scenarios and exit")
    ap.add_argument("--engine", choices=("compiled", "objects"),
                    help="simulator (default: compiled when numba is installed; sets SITL_ENGINE for workers too)")
    ap.add_argument("--set", action="append", default=[], metavar="TABLE.KEY=VALUE",
                    help="change a scenario parameter for every scenario run, e.g. position.force_source=measured "
                         "or position.observer_uses_imu=true (repeatable)")
    args = ap.parse_args(argv)
    if args.engine:
        os.environ["SITL_ENGINE"] = args.engine
    if args.list:
        for p in sorted(SCENARIO_DIR.glob("*.toml")):
            print(f"{p.stem:24s} {load_scenario(p).description}")
        return 0
    from companion.config import ConfigError

    try:
        scenarios = resolve(args.scenarios)
        settings = dict(parse_setting(s) for s in args.set)
        scenarios = [apply_settings(sc, settings) for sc in scenarios]
    except (ConfigError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    seeds = list(range(1, args.seeds + 1)) if args.seeds else None
    args.out.mkdir(parents=True, exist_ok=True)
    summaries = []
    for sc in scenarios:
        t0 = time.monotonic()
        res = run_experiment(sc, args.out / sc.name, seeds, args.jobs, progress=True)
        table = summary_table(res)
        summaries.append(table)
        print(table)
        print(f"  -> {res.figure} ({time.monotonic() - t0:.0f} s)\n")
    (args.out / "summary.md").write_text("# Experiment summary\n\n" + "\n".join(summaries))
    print(f"summary: {args.out / 'summary.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
