"""Monte-Carlo sweeps: many offline flights, one tidy table.

    sitl-sweep sitl/lab/sweeps/e3_wind.toml                      # all local cores
    sitl-sweep my_sweep.toml --scheduler tcp://10.0.0.5:8786      # a Dask cluster
    sitl-sweep my_sweep.toml --retry-failed                       # re-run only what failed

A sweep file names a scenario, the controller combinations, the seeds, parameter grids
(cartesian) and/or random ranges (uniform, seeded), the metric segment and the metrics::

    name = "e3_wind"
    scenario = "E3_wind"
    position = ["pid", "pd_do", "ism_do"]
    attitude = ["ism_do"]
    seeds = { first = 1, count = 100 }
    segment = "hover"
    metrics = ["rms_horizontal_error_m", "peak_error_m"]
    [grid]
    wind_speed_m_s = [0.0, 3.0]
    [random]
    samples = 20
    seed = 7
    ranges = { "model_error.mass_factor" = [0.9, 1.1] }

Parameters are dotted paths into the scenario (``attitude.omega_c_rad_s``,
``position.observer_gain_rad_s`` — all three axes — or ``position.observer_gain_rad_s[2]``) or
one of the named ones in :data:`NAMED_PARAMETERS`.

Cases that differ only in their seed run as one batch of vehicles (the simulator's array form,
bit-identical to one-vehicle runs). Results are appended to ``OUT/<name>/cases.csv`` as batches
finish: one row per case with its parameters, status and metrics. A re-run skips the cases
already in the table (``--retry-failed`` re-runs the failed ones); a failed case is recorded with
its error, never dropped. The engine (``--engine``; default ``$SITL_ENGINE``, else compiled when
numba is installed) is part of a case: it has a column in the table and is in the case's key, so
one table can hold both engines' numbers side by side but never mixes them, and it travels with
each batch to whatever worker flies it. Execution: on the compiled kernel, one batch after another
in this process, each batch's vehicles in parallel on every core; on the objects engine, local
processes (``--jobs``, default all cores); or any Dask distributed scheduler (``--scheduler
ADDRESS``: a one-line error when it does not answer within ``--connect-timeout`` or has no worker
within ``--worker-timeout``, a line a second while waiting). The same seeds on the same engine
give the same numbers every way.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import itertools
import json
import math
import os
import random
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from companion.config import ConfigError, load_toml, locate
from companion.control.names import controller_label
from companion.control.attitude import ATTITUDE_CONTROLLERS
from companion.control.position import POSITION_CONTROLLERS

from ..plant.scenario import Scenario, Segment, load_scenario
from .metrics import SegmentMetrics, segment_metrics
from .simulation import ENGINES, default_engine, simulate

__all__ = ["SweepSpec", "Task", "Member", "stack_gains", "NAMED_PARAMETERS", "load_sweep", "apply_parameters",
           "plan", "fly_batch", "run_task", "run_sweep", "connect_dask", "SchedulerError", "main"]

SWEEP_DIR = Path(__file__).parent / "sweeps"
METRICS = tuple(f.name for f in dataclasses.fields(SegmentMetrics) if f.name != "segment")


def _wind_speed(sc: Scenario, v: float) -> Scenario:
    return sc.with_changes(wind=dataclasses.replace(sc.wind, mean_ned_m_s=(v, 0.0, 0.0)))


def _turbulence(sc: Scenario, sigma: float) -> Scenario:
    t = sc.wind.turbulence
    turb = dataclasses.replace(t, enabled=sigma > 0.0, sigma_m_s=(sigma, sigma, 2.0 * sigma / 3.0))
    return sc.with_changes(wind=dataclasses.replace(sc.wind, turbulence=turb))


def _mass_error(sc: Scenario, x: float) -> Scenario:
    return sc.with_changes(model_error=dataclasses.replace(sc.model_error, mass_factor=1.0 + x))


def _force(sc: Scenario, magnitude: float) -> Scenario:
    if not sc.forces:
        raise ValueError("force_n: the scenario has no force profile to scale")
    out = []
    for p in sc.forces:
        n = math.sqrt(sum(c * c for c in p.value))
        out.append(dataclasses.replace(p, value=tuple(c * magnitude / n for c in p.value) if n else p.value))
    return sc.with_changes(forces=tuple(out))


NAMED_PARAMETERS: dict[str, Callable[[Scenario, float], Scenario]] = {
    "wind_speed_m_s": _wind_speed,
    "turbulence_sigma_m_s": _turbulence,
    "mass_error": _mass_error,
    "force_n": _force,
}
"""wind_speed_m_s: mean wind along north; turbulence_sigma_m_s: Dryden intensity (u, v; w gets
2/3); mass_error: plant mass = model mass x (1 + value); force_n: every force profile scaled to
this magnitude, direction kept."""


def apply_parameters(sc: Scenario, params: dict[str, float]) -> Scenario:
    """The scenario with ``params`` (named or dotted-path) applied, in order."""
    for path, value in params.items():
        if path in NAMED_PARAMETERS:
            sc = NAMED_PARAMETERS[path](sc, value)
            continue
        table, _, rest = path.partition(".")
        index = None
        if rest.endswith("]"):
            rest, _, idx = rest[:-1].partition("[")
            index = int(idx)
        sub = getattr(sc, table)
        current = getattr(sub, rest)
        if isinstance(current, tuple):
            items = list(current)
            if index is None:
                items = [value] * len(items)
            else:
                items[index] = value
            new: object = tuple(float(x) for x in items)
        elif isinstance(current, bool):
            new = bool(value)
        else:
            new = float(value)
        sc = sc.with_changes(**{table: dataclasses.replace(sub, **{rest: new})})
    return sc


def _check_path(sc: Scenario, path: str) -> None:
    if path in NAMED_PARAMETERS:
        return
    table, _, rest = path.partition(".")
    rest = rest.split("[", 1)[0]
    if not rest or not hasattr(sc, table) or not dataclasses.is_dataclass(getattr(sc, table)) or not hasattr(
        getattr(sc, table), rest
    ):
        raise ValueError(f"{path!r} is not a scenario parameter (a dotted path such as attitude.omega_c_rad_s, "
                         f"or one of {', '.join(NAMED_PARAMETERS)})")


@dataclass(frozen=True)
class SweepSpec:
    name: str
    scenario: Scenario
    position: tuple[str, ...]
    attitude: tuple[str, ...]
    seeds: tuple[int, ...]
    segment: str
    metrics: tuple[str, ...]
    grid: dict[str, list[float]] = field(default_factory=dict)
    random_samples: int = 0
    random_seed: int = 0
    random_ranges: dict[str, tuple[float, float]] = field(default_factory=dict)
    batch_size: int = 100
    source: str = ""

    @property
    def parameter_names(self) -> list[str]:
        return list(self.grid) + list(self.random_ranges)

    def parameter_sets(self) -> list[dict[str, float]]:
        """Grid points x random samples (or just one of them, or one empty set)."""
        grid = [dict(zip(self.grid, combo)) for combo in itertools.product(*self.grid.values())] if self.grid else [{}]
        if not self.random_ranges:
            return grid
        rng = random.Random(self.random_seed)
        samples = [{k: rng.uniform(lo, hi) for k, (lo, hi) in self.random_ranges.items()}
                   for _ in range(self.random_samples)]
        return [{**g, **r} for g in grid for r in samples]


def load_sweep(path: str | Path) -> SweepSpec:
    p = Path(path)
    if not p.exists() and (SWEEP_DIR / f"{path}.toml").exists():
        p = SWEEP_DIR / f"{path}.toml"
    data, text = load_toml(p)

    def fail(key: str, reason: str) -> ConfigError:
        return ConfigError(p, locate(text, key), key, reason)

    allowed = {"name", "description", "scenario", "position", "attitude", "seeds", "segment", "window_s",
               "metrics", "duration_s", "grid", "random", "batch_size"}
    for k in data:
        if k not in allowed:
            raise fail(k, f"unknown key; expected one of: {', '.join(sorted(allowed))}")
    if "scenario" not in data:
        raise fail("", "a sweep needs scenario = \"NAME or path\"")
    scen_path = data["scenario"]
    if not Path(scen_path).exists() and (p.parent / scen_path).exists():
        scen_path = str(p.parent / scen_path)
    sc = load_scenario(scen_path)
    if "duration_s" in data:
        sc = sc.with_changes(duration_s=float(data["duration_s"]))
    position = tuple(data.get("position", sc.runs.position))
    attitude = tuple(data.get("attitude", sc.runs.attitude))
    for key, names, allowed_names in (("position", position, POSITION_CONTROLLERS),
                                      ("attitude", attitude, ATTITUDE_CONTROLLERS)):
        for n in names:
            if n not in allowed_names:
                raise fail(key, f"{n!r}: expected one of {', '.join(allowed_names)}")
    seeds_raw = data.get("seeds", list(sc.runs.seeds))
    if isinstance(seeds_raw, dict):
        if set(seeds_raw) != {"first", "count"}:
            raise fail("seeds", "expected a list of integers or { first = N, count = M }")
        seeds = tuple(range(int(seeds_raw["first"]), int(seeds_raw["first"]) + int(seeds_raw["count"])))
    elif isinstance(seeds_raw, list) and all(isinstance(s, int) for s in seeds_raw):
        seeds = tuple(seeds_raw)
    else:
        raise fail("seeds", "expected a list of integers or { first = N, count = M }")
    if "window_s" in data:  # a metric window of its own, replacing the scenario's segments
        lo, hi = (float(x) for x in data["window_s"])
        sc = sc.with_changes(segments=(Segment("window", lo, hi),))
        data.setdefault("segment", "window")
    segments = [s.name for s in sc.segments]
    segment = data.get("segment", segments[0] if segments else "flight")
    if segments and segment not in segments:
        raise fail("segment", f"expected one of the scenario's segments: {', '.join(segments)}")
    chosen = next((s for s in sc.segments if s.name == segment), None)
    if chosen is not None and chosen.start_s >= sc.duration_s:
        raise fail("segment" if "window_s" not in data else "window_s",
                   f"{segment!r} starts at {chosen.start_s:g} s, after the flight's {sc.duration_s:g} s")
    metrics = tuple(data.get("metrics", ("rms_horizontal_error_m", "rms_error_m", "peak_error_m")))
    for m in metrics:
        if m not in METRICS:
            raise fail("metrics", f"{m!r}: expected one of {', '.join(METRICS)}")
    def numbers(key: str, v: object, n: int | None = None) -> list[float]:
        if not isinstance(v, list) or not v or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                       for x in v) or (n is not None and len(v) != n):
            want = f"a list of {n} numbers" if n else "a list of numbers"
            raise fail(key, f"expected {want}; dotted parameter names must be quoted: "
                            f"\"attitude.omega_c_rad_s\" = [...]")
        return [float(x) for x in v]

    grid = {k: numbers(f"grid.{k}", v) for k, v in data.get("grid", {}).items()}
    rnd = data.get("random", {})
    ranges = {k: tuple(numbers(f"random.ranges.{k}", v, 2)) for k, v in rnd.get("ranges", {}).items()}
    for key in [*grid, *ranges]:
        try:
            _check_path(sc, key)
            apply_parameters(sc, {key: (grid[key][0] if key in grid else ranges[key][0])})
        except (ValueError, TypeError, AttributeError) as exc:
            where = f"grid.{key}" if key in grid else f"random.ranges.{key}"
            raise fail(where, str(exc)) from None
    if ranges and int(rnd.get("samples", 0)) < 1:
        raise fail("random", "random ranges need samples = N (at least 1)")
    return SweepSpec(
        name=str(data.get("name", p.stem)), scenario=sc, position=position, attitude=attitude, seeds=seeds,
        segment=segment, metrics=metrics, grid=grid, random_samples=int(rnd.get("samples", 0)),
        random_seed=int(rnd.get("seed", 0)), random_ranges=ranges, batch_size=int(data.get("batch_size", 100)),
        source=str(p),
    )


# --- tasks -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Member:
    """One parameter set of a batch and the seeds it flies."""

    params: dict[str, float]
    scenario: Scenario
    seeds: tuple[int, ...]


@dataclass(frozen=True)
class Task:
    """One batch of vehicles: one controller pair; parameter sets that differ only in gains; seeds."""

    members: tuple[Member, ...]
    position: str
    attitude: str
    segment: str
    metrics: tuple[str, ...]
    engine: str
    """the simulator that flies it (:data:`~sitl.lab.simulation.ENGINES`): carried with the task, so a
    remote worker flies what the client asked for whatever its own environment says"""

    @property
    def seeds(self) -> tuple[int, ...]:
        return tuple(s for m in self.members for s in m.seeds)


GAIN_TABLES = ("attitude", "position")
"""Scenario tables whose numbers the control laws accept as per-vehicle arrays."""


def is_gain(path: str) -> bool:
    return path.partition(".")[0] in GAIN_TABLES


def stack_gains(members: Sequence[Member]) -> Scenario:
    """One scenario for all members: each gain that differs becomes an array over the vehicles.

    Vehicle order is member by member, seed by seed (as :attr:`Task.seeds`). The members must
    differ only in the gain tables (:func:`plan` groups them so).
    """
    first = members[0].scenario
    counts = [len(m.seeds) for m in members]
    changes: dict[str, Any] = {}
    for table in GAIN_TABLES:
        subs = [getattr(m.scenario, table) for m in members]
        fields: dict[str, Any] = {}
        for f in dataclasses.fields(subs[0]):
            values = [getattr(sub, f.name) for sub in subs]
            if all(v == values[0] for v in values):
                continue
            if isinstance(values[0], tuple):
                fields[f.name] = tuple(np.repeat(np.array([v[i] for v in values], dtype=float), counts)
                                       for i in range(len(values[0])))
            else:
                fields[f.name] = np.repeat(np.array(values, dtype=float), counts)
        if fields:
            changes[table] = dataclasses.replace(subs[0], **fields)
    return first.with_changes(**changes) if changes else first


def case_id(params: dict[str, float], position: str, attitude: str, engine: str, seed: int) -> str:
    """A case's key in the table: its parameters, controllers, engine and seed (two engines' numbers
    for one case are two cases, never one row standing for both)."""
    key = json.dumps({"p": params, "pos": position, "att": attitude, "engine": engine, "seed": seed}, sort_keys=True)
    return hashlib.sha1(key.encode()).hexdigest()[:16]


def plan(spec: SweepSpec, skip: set[str] = frozenset(),  # type: ignore[assignment]
         engine: str | None = None) -> tuple[list[Task], int]:
    """Tasks for every case not in ``skip`` flown on ``engine`` (:func:`default_engine` when None),
    and the total number of cases.

    Cases that differ only in seed, or only in seed and gains, share a task (one batch of
    vehicles) of at most ``batch_size`` vehicles.
    """
    groups: dict[str, list[tuple[dict[str, float], Scenario]]] = {}
    for params in spec.parameter_sets():
        key = json.dumps({k: v for k, v in params.items() if not is_gain(k)}, sort_keys=True)
        groups.setdefault(key, []).append((params, apply_parameters(spec.scenario, params)))
    engine = engine or default_engine()
    tasks: list[Task] = []
    total = 0
    for att in spec.attitude:
        for pos in spec.position:
            for group in groups.values():
                pending: list[Member] = []
                size = 0
                for params, sc in group:
                    total += len(spec.seeds)
                    todo = [s for s in spec.seeds if case_id(params, pos, att, engine, s) not in skip]
                    for i in range(0, len(todo), spec.batch_size):
                        chunk = tuple(todo[i:i + spec.batch_size])
                        if pending and size + len(chunk) > spec.batch_size:
                            tasks.append(Task(tuple(pending), pos, att, spec.segment, spec.metrics, engine))
                            pending, size = [], 0
                        pending.append(Member(params, sc, chunk))
                        size += len(chunk)
                if pending:
                    tasks.append(Task(tuple(pending), pos, att, spec.segment, spec.metrics, engine))
    return tasks, total


def _fly(scenario: Scenario, task: Task, members: Sequence[Member]) -> list[dict[str, Any]]:
    seeds = [s for m in members for s in m.seeds]
    log = simulate(scenario, task.position, task.attitude, seeds if len(seeds) > 1 else seeds[0], engine=task.engine)
    seg = next((s for s in scenario.segments if s.name == task.segment),
               Segment("flight", 0.0, scenario.duration_s + 1e-9))
    rows = []
    i = 0
    for m in members:
        for seed in m.seeds:
            one = log.vehicle(i) if len(seeds) > 1 else log
            i += 1
            metrics = segment_metrics(one, seg)
            values = {k: getattr(metrics, k) for k in task.metrics}
            finite = all(math.isfinite(v) for k, v in values.items() if k != "settling_time_s")
            status = "ok" if finite and metrics.peak_error_m < 100.0 else "diverged"
            rows.append({"case": case_id(m.params, task.position, task.attitude, task.engine, seed),
                         "position": task.position, "attitude": task.attitude, "engine": task.engine, **m.params,
                         "seed": seed, "status": status,
                         "error": "" if status == "ok" else "non-finite or > 100 m error", **values})
    return rows


def _failed(task: Task, m: Member, exc: Exception) -> list[dict[str, Any]]:
    return [{"case": case_id(m.params, task.position, task.attitude, task.engine, s), "position": task.position,
             "attitude": task.attitude, "engine": task.engine, **m.params, "seed": s, "status": "failed",
             "error": f"{type(exc).__name__}: {exc}"[:300], **{k: math.nan for k in task.metrics}}
            for s in m.seeds]


def _fly_member(task: Task, m: Member) -> list[dict[str, Any]]:
    try:
        return _fly(m.scenario, task, [m])
    except Exception as exc:  # recorded per case, never dropped
        return _failed(task, m, exc)


FLOAT_BELOW = 12
"""fewer vehicles than this fly one by one on floats: faster than a small array batch
(docs/sweeps.md, Throughput), and the numbers are the same"""


def fly_batch(task: Task) -> list[dict[str, Any]]:
    """All members of ``task`` as one batch of vehicles (gains stacked); raises if the batch fails."""
    if len(task.seeds) < FLOAT_BELOW and task.engine == "objects":
        return [r for m in task.members for s in m.seeds
                for r in _fly(m.scenario, task, [Member(m.params, m.scenario, (s,))])]
    return _fly(stack_gains(task.members), task, task.members)


def run_task(task: Task) -> list[dict[str, Any]]:
    """Fly one batch and return one row per case (a failure becomes rows with the error).

    Members with different gains fly as one batch with per-vehicle gain arrays; should that batch
    fail, each member flies alone, so an error is attributed to the cases that cause it.
    """
    t0 = time.monotonic()
    try:
        rows = fly_batch(task)
    except Exception as exc:
        if len(task.members) == 1:
            rows = _failed(task, task.members[0], exc)
        else:
            rows = [r for m in task.members for r in _fly_member(task, m)]
    wall = (time.monotonic() - t0) / max(len(rows), 1)
    for r in rows:
        r["wall_s"] = round(wall, 4)
    return rows


# --- execution -------------------------------------------------------------------------------


def _columns(spec: SweepSpec) -> list[str]:
    return ["case", "position", "attitude", "engine", *spec.parameter_names, "seed", "status", "error", *spec.metrics,
            "wall_s"]


def _read_table(path: Path) -> list[dict[str, str]]:
    if not path.exists():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


Submit = Callable[[Task], Any]
Completed = Callable[[list[Any]], Iterable[Any]]


class _Later:
    """A task run when its result is asked for (the in-process executor: one task at a time, so
    rows reach the table as each batch finishes, as with a pool)."""

    def __init__(self, task: Task) -> None:
        self.task = task

    def result(self) -> list[dict[str, Any]]:
        return run_task(self.task)


def default_jobs(engine: str) -> int:
    """1 on the compiled kernel (each batch already runs on every core: more processes would only
    share the cores and load the kernel again), else one process per core."""
    return 1 if engine == "compiled" else os.cpu_count() or 1


class SchedulerError(RuntimeError):
    """The Dask scheduler cannot run the sweep: not reachable, or no worker came in time."""


CONNECT_TIMEOUT_S = 10.0
"""default wait for a Dask scheduler to answer (``--connect-timeout``)"""
WORKER_TIMEOUT_S = 60.0
"""default wait for a Dask scheduler's first worker (``--worker-timeout``)"""


def connect_dask(address: str, connect_timeout_s: float = CONNECT_TIMEOUT_S,
                 worker_timeout_s: float = WORKER_TIMEOUT_S, say: Callable[[str], None] | None = None) -> Any:
    """A ``distributed.Client`` of the scheduler at ``address`` with at least one worker.

    Raises :class:`SchedulerError` (one line) when the scheduler does not answer within
    ``connect_timeout_s`` or has no worker after ``worker_timeout_s``; ``say`` hears the waiting,
    about once a second, so a cluster still starting its workers is not a silent hang.
    """
    from distributed import Client

    try:
        client = Client(address, timeout=connect_timeout_s)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise SchedulerError(f"no Dask scheduler answered at {address} within {connect_timeout_s:g} s "
                             f"({type(exc).__name__}: {reason[:120]})") from None
    t0 = time.monotonic()
    while True:
        waited = time.monotonic() - t0
        try:
            client.wait_for_workers(1, timeout=max(min(1.0, worker_timeout_s - waited), 0.01))
        except TimeoutError:
            waited = time.monotonic() - t0
            if waited >= worker_timeout_s:
                client.close()
                raise SchedulerError(f"the Dask scheduler at {address} has no workers after {worker_timeout_s:g} s "
                                     f"(start some: dask worker {address})") from None
            if say:
                say(f"waiting for a worker at {address}: {waited:.0f}/{worker_timeout_s:g} s")
            continue
        if say:
            say(f"{len(client.scheduler_info()['workers'])} Dask workers at {address}")
        return client


def _executor(engine: str, jobs: int | None, client: Any) -> tuple[Submit, Completed, Callable[[], None]]:
    """(submit, as_completed, close) for this process, local processes or a Dask client."""
    jobs = jobs or default_jobs(engine)
    if client is not None:
        from distributed import as_completed as dask_completed

        return (lambda t: client.submit(run_task, t, pure=False), lambda fs: dask_completed(fs),
                client.close)
    if jobs == 1:
        return _Later, iter, lambda: None
    pool = ProcessPoolExecutor(max_workers=jobs)
    return (lambda t: pool.submit(run_task, t), lambda fs: as_completed(fs), lambda: pool.shutdown(cancel_futures=True))


def _header(path: Path) -> list[str]:
    if not path.exists():
        return []
    with open(path, newline="") as f:
        return next(csv.reader(f), [])


def run_sweep(spec: SweepSpec, out_dir: Path, jobs: int | None = None, scheduler: str | None = None,
              retry_failed: bool = False, progress: bool = True, plots: bool = True, engine: str | None = None,
              connect_timeout_s: float = CONNECT_TIMEOUT_S, worker_timeout_s: float = WORKER_TIMEOUT_S) -> Path:
    """Run every case not yet in the table on ``engine`` (:func:`default_engine` when None, resolved
    here and sent with every task); returns the case table's path. With ``scheduler``, raises
    :class:`SchedulerError` as :func:`connect_dask` does, before anything is written."""
    engine = engine or default_engine()
    if engine not in ENGINES:
        raise ValueError(f"engine {engine!r}: expected one of {', '.join(ENGINES)}")
    folder = out_dir / spec.name
    table = folder / "cases.csv"
    columns = _columns(spec)
    header = _header(table)
    if header and header != columns:
        missing = [c for c in columns if c not in header]
        extra = [c for c in header if c not in columns]
        raise ValueError(f"{table} has other columns than this sweep produces (missing: {', '.join(missing) or '-'}; "
                         f"not ours: {', '.join(extra) or '-'}); use another --out")
    existing = _read_table(table)
    keep = [r for r in existing if not (retry_failed and r["status"] != "ok" and r["engine"] == engine)]
    done = {r["case"] for r in keep}
    tasks, total = plan(spec, done, engine)
    todo = sum(len(t.seeds) for t in tasks)
    say = (lambda text: print(f"sitl-sweep: {text}", file=sys.stderr, flush=True)) if progress else None
    client = connect_dask(scheduler, connect_timeout_s, worker_timeout_s, say) if scheduler and tasks else None
    folder.mkdir(parents=True, exist_ok=True)
    if len(keep) != len(existing):  # rewrite without the failures we are about to retry
        with open(table, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=columns)
            w.writeheader()
            w.writerows(keep)
    if progress:
        print(f"sweep {spec.name} on the {engine} engine: {total} cases, {total - todo} already done, {todo} to run "
              f"in {len(tasks)} batches", file=sys.stderr, flush=True)
    new_file = not header
    if tasks:
        submit, completed, close = _executor(engine, jobs, client)
        t0 = time.monotonic()
        finished = 0
        try:
            with open(table, "a" if not new_file else "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=columns)
                if new_file:
                    w.writeheader()
                futures: list[Any] = [submit(t) for t in tasks]
                for fut in completed(futures):
                    rows = fut.result()
                    w.writerows(rows)
                    f.flush()
                    finished += len(rows)
                    if progress:
                        rate = finished / max(time.monotonic() - t0, 1e-9)
                        left = (todo - finished) / rate
                        print(f"\r  {finished}/{todo} cases, {rate:.1f} cases/s, {left:.0f} s left ",
                              end="", file=sys.stderr, flush=True)
        finally:
            close()
        if progress:
            print(file=sys.stderr)
    if plots:
        draw_sweep(spec, table, engine)
    return table


# --- summary -----------------------------------------------------------------------------------


def load_cases(table: Path) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    for r in _read_table(table):
        out: dict[str, Any] = {}
        for k, v in r.items():
            try:
                out[k] = float(v) if k not in ("case", "position", "attitude", "engine", "status", "error") else v
            except ValueError:
                out[k] = v
        rows.append(out)
    return rows


def draw_sweep(spec: SweepSpec, table: Path, engine: str | None = None) -> list[Path]:
    """Box plots of every metric per controller pair, and each metric against each swept
    parameter, from the table's ok rows (of ``engine`` only, when given); returns the PNGs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in load_cases(table) if r["status"] == "ok" and engine in (None, r["engine"])]
    if not rows:
        return []
    combos = [(p, a) for a in spec.attitude for p in spec.position]
    label = {c: f"{controller_label(c[0])}/{controller_label(c[1])}" for c in combos}
    out = []
    fig, axs = plt.subplots(1, len(spec.metrics), figsize=(5 * len(spec.metrics), 4.5), squeeze=False)
    for ax, metric in zip(axs[0], spec.metrics):
        data = [[r[metric] for r in rows if (r["position"], r["attitude"]) == c] for c in combos]
        ax.boxplot(data, showfliers=True)
        ax.set_xticks(range(1, len(combos) + 1), [label[c] for c in combos], rotation=40, ha="right", fontsize=8)
        ax.set_title(metric, fontsize=9)
        ax.grid(alpha=0.3, axis="y")
    n = len(spec.seeds) * max(1, len(spec.parameter_sets()))
    on = f", {engine} engine" if engine else ""
    fig.suptitle(f"{spec.name}: {spec.scenario.description} ({n} cases per combination{on})", fontsize=10)
    fig.tight_layout()
    path = table.parent / "boxplots.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    out.append(path)
    for param in spec.parameter_names:
        fig, axs = plt.subplots(1, len(spec.metrics), figsize=(5 * len(spec.metrics), 4), squeeze=False)
        for ax, metric in zip(axs[0], spec.metrics):
            for c in combos:
                xs = np.array([r[param] for r in rows if (r["position"], r["attitude"]) == c])
                ys = np.array([r[metric] for r in rows if (r["position"], r["attitude"]) == c])
                ax.scatter(xs, ys, s=6, alpha=0.4, label=label[c])
                if len(set(xs.tolist())) <= 12:
                    u = sorted(set(xs.tolist()))
                    ax.plot(u, [np.median(ys[xs == x]) for x in u], lw=1.2)
            ax.set_xlabel(param)
            ax.set_ylabel(metric)
            ax.grid(alpha=0.3)
        axs[0][0].legend(fontsize=7)
        fig.tight_layout()
        path = table.parent / f"vs_{param.replace('.', '_').replace('[', '_').replace(']', '')}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        out.append(path)
    return out


def summary(spec: SweepSpec, table: Path, engine: str | None = None) -> str:
    """Per controller pair: ok and failed counts, each metric's median and quartiles (rows of
    ``engine`` only, when given)."""
    rows = [r for r in load_cases(table) if engine in (None, r["engine"])]
    on = f" on the {engine} engine" if engine else ""
    lines = [f"sweep {spec.name}: {len(rows)} cases{on} in {table}",
             f"{'position/attitude':>20} {'ok':>5} {'failed':>7} " + " ".join(f"{m + ' median [IQR]':>36}"
                                                                            for m in spec.metrics)]
    for a in spec.attitude:
        for p in spec.position:
            rs = [r for r in rows if r["position"] == p and r["attitude"] == a]
            ok = [r for r in rs if r["status"] == "ok"]
            cells = []
            for m in spec.metrics:
                v = np.array([r[m] for r in ok], dtype=float)
                cells.append(f"{np.median(v):.4g} [{np.percentile(v, 25):.3g}, {np.percentile(v, 75):.3g}]"
                             if len(v) else "-")
            head = f"{p + '/' + a:>20} {len(ok):>5} {len(rs) - len(ok):>7} "
            lines.append(head + " ".join(f"{c:>36}" for c in cells))
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="sitl-sweep", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sweep", help="sweep file, or a bundled name (sitl/lab/sweeps/)")
    ap.add_argument("--out", type=Path, default=Path("sweeps"), help="output folder (default: sweeps)")
    ap.add_argument("--jobs", type=int,
                    help="local worker processes (default: 1 on the compiled kernel, which uses all cores; else all)")
    ap.add_argument("--engine", choices=ENGINES,
                    help="simulator (default: $SITL_ENGINE, else compiled when numba is installed); sent with "
                         "every case to local and Dask workers alike, and recorded in the table's engine column")
    ap.add_argument("--scheduler", help="address of a Dask distributed scheduler, e.g. tcp://host:8786")
    ap.add_argument("--connect-timeout", type=float, default=CONNECT_TIMEOUT_S, metavar="S",
                    help=f"seconds to wait for the scheduler to answer (default {CONNECT_TIMEOUT_S:g})")
    ap.add_argument("--worker-timeout", type=float, default=WORKER_TIMEOUT_S, metavar="S",
                    help=f"seconds to wait for the scheduler's first worker (default {WORKER_TIMEOUT_S:g})")
    ap.add_argument("--retry-failed", action="store_true", help="run the failed cases again")
    ap.add_argument("--no-plots", action="store_true")
    args = ap.parse_args(argv)
    try:
        engine = args.engine or default_engine()
        spec = load_sweep(args.sweep)
        table = run_sweep(spec, args.out, args.jobs, args.scheduler, args.retry_failed, plots=not args.no_plots,
                          engine=engine, connect_timeout_s=args.connect_timeout,
                          worker_timeout_s=args.worker_timeout)
    except (ConfigError, SchedulerError, ValueError) as exc:
        print(f"sitl-sweep: error: {exc}", file=sys.stderr)
        return 2
    print(summary(spec, table, engine))
    return 0



if __name__ == "__main__":
    raise SystemExit(main())
