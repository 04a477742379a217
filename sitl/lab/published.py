"""The sweep tables of docs/sweeps.md as functions of a sweep's case table, and a check that the
published figures still agree with what the code flies.

Each table sits in docs/sweeps.md between ``<!-- table: NAME -->`` and ``<!-- /table -->``, NAME a
bundled sweep (sitl/lab/sweeps/NAME.toml). Two kinds:

- a sweep without a parameter grid: one row per controller pair, the metric's median, quartiles
  and worst case over the seeds (``| position / attitude | median | quartiles | worst |``);
- a sweep with one grid parameter: one row per position controller, the median per grid value
  over every seed and random sample (``| median ... | 0 m/s | 1.5 m/s | ... |``).

The table that goes into the page is printed from the sweep's own case table::

    sitl-sweep sitl/lab/sweeps/e3_wind.toml --out runs/
    python -m sitl.lab.published e3_wind runs/e3_wind/cases.csv

:func:`drift` compares a published table with a small re-flight of the same sweep (its first seeds
and samples, which are cases of the published run: the same seeds give the same numbers) and names
every figure that moved past its tolerance (see :func:`tolerance`).
"""

from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from companion.control.attitude import ATTITUDE_CONTROLLERS
from companion.control.names import controller_label
from companion.control.position import POSITION_CONTROLLERS

from .sweep import SweepSpec, load_cases, load_sweep

__all__ = ["Spread", "spread", "pair_spreads", "grid_spreads", "markdown", "published_rows", "tolerance", "drift",
           "main"]

METRIC = "rms_horizontal_error_m"
"""the metric every published sweep table shows"""
UNITS = {"wind_speed_m_s": "m/s", "turbulence_sigma_m_s": "m/s", "force_n": "N"}
DIGITS = 3
"""decimals of a published figure [m]"""


@dataclass(frozen=True)
class Spread:
    """A cell's distribution over its cases."""

    median: float
    q1: float
    q3: float
    worst: float
    n: int


def spread(values: Sequence[float], seeds: int | None = None) -> Spread:
    """``n`` is the number of distinct ``seeds`` when given: cases that share a seed (one per random
    sample of a model error) share their gusts and noise and are not independent draws."""
    v = np.asarray(values, dtype=float)
    return Spread(float(np.median(v)), float(np.percentile(v, 25)), float(np.percentile(v, 75)), float(v.max()),
                  len(v) if seeds is None else seeds)


def _ok(cases: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    return [c for c in cases if c["status"] == "ok"]


def pair_spreads(spec: SweepSpec, cases: Sequence[dict[str, Any]],
                 metric: str = METRIC) -> dict[tuple[str, str], Spread]:
    """(position, attitude) -> the metric's spread over that pair's ok cases, in the sweep's order."""
    ok = _ok(cases)
    return {(p, a): spread([c[metric] for c in ok if (c["position"], c["attitude"]) == (p, a)])
            for a in spec.attitude for p in spec.position}


def grid_spreads(spec: SweepSpec, cases: Sequence[dict[str, Any]],
                 metric: str = METRIC) -> dict[tuple[str, float], Spread]:
    """(position, grid value) -> the metric's spread over every seed and random sample there (the
    sweep's one grid parameter; its one attitude controller)."""
    (param,) = spec.grid
    ok = _ok(cases)
    cells = {(p, v): [c for c in ok if c["position"] == p and math.isclose(c[param], v)]
             for p in spec.position for v in spec.grid[param]}
    return {k: spread([c[metric] for c in cs], seeds=len({c["seed"] for c in cs})) for k, cs in cells.items()}


def _f(x: float) -> str:
    return f"{x:.{DIGITS}f}"


def _grid_header(param: str, v: float) -> str:
    return f"{v:g} {UNITS[param]}" if param in UNITS else f"{param} = {v:g}"


def markdown(spec: SweepSpec, cases: Sequence[dict[str, Any]], metric: str = METRIC) -> str:
    """The published table of ``spec`` from its case table (the lowest median in bold)."""
    if spec.grid:
        (param,) = spec.grid
        cells = grid_spreads(spec, cases, metric)
        lines = ["| median horizontal RMS [m] | " + " | ".join(_grid_header(param, v) for v in spec.grid[param]) + " |",
                 "|---|" + "---|" * len(spec.grid[param])]
        lines += [f"| {controller_label(p)} | " + " | ".join(_f(cells[p, v].median) for v in spec.grid[param]) + " |"
                  for p in spec.position]
        return "\n".join(lines)
    cells = pair_spreads(spec, cases, metric)
    best = min(cells, key=lambda k: cells[k].median)
    lines = ["| position / attitude | median | quartiles | worst |", "|---|---|---|---|"]
    for (p, a), s in cells.items():
        label, med = f"{controller_label(p)} / {controller_label(a)}", _f(s.median)
        if (p, a) == best:
            label, med = f"**{label}**", f"**{med}**"
        lines.append(f"| {label} | {med} | {_f(s.q1)}–{_f(s.q3)} | {_f(s.worst)} |")
    return "\n".join(lines)


_NAMES = {controller_label(n): n for n in (*POSITION_CONTROLLERS, *ATTITUDE_CONTROLLERS)}


def published_rows(page: str, name: str) -> list[list[str]]:
    """The body rows (cells, bold marks removed) of the table ``name`` in ``page``, header row
    first; raises ValueError naming the marker when the table is not there."""
    m = re.search(rf"<!-- table: {re.escape(name)} -->\n(.*?)<!-- /table -->", page, re.S)
    if m is None:
        raise ValueError(f"no '<!-- table: {name} -->' ... '<!-- /table -->' in the page")
    rows = [[c.strip().strip("*").strip() for c in line.strip().strip("|").split("|")]
            for line in m.group(1).splitlines() if line.startswith("|")]
    return [r for r in rows if not all(set(c) <= set("-:") for c in r)]


def tolerance(quantile: float, sample: Spread, published_iqr: float = 0.0, k: float = 4.0) -> float:
    """How far a published quantile may lie from the same quantile of a sample of ``sample.n`` of
    its cases before it is called drift.

    The standard error of the p-quantile of n draws is sqrt(p (1 - p)) / (f(x_p) sqrt(n)); for a
    normal spread sigma that is 1.25 sigma / sqrt(n) at the median and 1.36 sigma / sqrt(n) at a
    quartile. sigma is read from the seed-to-seed spread, IQR / 1.349, taking the wider of the
    sample's and the published IQR (a few seeds whose quartiles happen to lie close would
    otherwise make the check tight). ``k`` = 4 standard errors, plus half a unit of the last
    published decimal: a sample drawn from the published distribution passes all but ~1 in 15,000
    times per figure, and a table the code no longer gives fails.
    """
    sigma = max(sample.q3 - sample.q1, published_iqr) / 1.349
    per_sigma = math.sqrt(quantile * (1 - quantile)) / (math.exp(-_z(quantile) ** 2 / 2) / math.sqrt(2 * math.pi))
    return k * per_sigma * sigma / math.sqrt(sample.n) + 0.5 * 10 ** -DIGITS


def _z(p: float) -> float:
    return {0.25: -0.6745, 0.5: 0.0, 0.75: 0.6745}[p]


def _number(cell: str, where: str) -> float:
    try:
        return float(cell)
    except ValueError:
        raise ValueError(f"{where}: {cell!r} is not a number") from None


def drift(spec: SweepSpec, page: str, cases: Sequence[dict[str, Any]], metric: str = METRIC) -> list[str]:
    """Every published figure of ``spec``'s table in ``page`` that lies past :func:`tolerance` from
    ``cases`` (a re-flight of the sweep's first seeds and samples), and every controller pair or
    grid value the sweep flies that the table lacks or the table shows that the sweep does not fly.

    A worst case is a maximum over the published seeds, of which the sample's are some: it may not
    be below the sample's worst.
    """
    rows = published_rows(page, spec.name)
    header, body = rows[0], rows[1:]
    out: list[str] = []

    def compare(what: str, published: float, got: float, tol: float) -> None:
        if abs(published - got) > tol:
            out.append(f"{what}: published {published:.{DIGITS}f}, now {got:.{DIGITS}f} (tolerance {tol:.{DIGITS}f})")

    if spec.grid:
        (param,) = spec.grid
        cells = grid_spreads(spec, cases, metric)
        columns = [_grid_header(param, v) for v in spec.grid[param]]
        if header[1:] != columns:
            out.append(f"columns {header[1:]} are not the sweep's {columns}")
            return out
        seen = set()
        for r in body:
            p = _NAMES.get(r[0])
            if p not in spec.position:
                out.append(f"row {r[0]!r}: not a position controller of the sweep")
                continue
            seen.add(p)
            for v, cell in zip(spec.grid[param], r[1:]):
                s = cells[p, v]
                compare(f"{r[0]} at {_grid_header(param, v)} median", _number(cell, r[0]), s.median, tolerance(0.5, s))
        out += [f"row {controller_label(p)!r}: flown, not published" for p in spec.position if p not in seen]
        return out
    cells = pair_spreads(spec, cases, metric)
    seen = set()
    for r in body:
        names = tuple(_NAMES.get(x.strip()) for x in r[0].split("/"))
        if names not in cells:
            out.append(f"row {r[0]!r}: not a controller pair of the sweep")
            continue
        seen.add(names)
        s = cells[names]
        q1, q3 = (_number(x, r[0]) for x in r[2].split("–"))
        iqr = q3 - q1
        compare(f"{r[0]} median", _number(r[1], r[0]), s.median, tolerance(0.5, s, iqr))
        compare(f"{r[0]} lower quartile", q1, s.q1, tolerance(0.25, s, iqr))
        compare(f"{r[0]} upper quartile", q3, s.q3, tolerance(0.75, s, iqr))
        worst = _number(r[3], r[0])
        if worst < s.worst - 0.5 * 10 ** -DIGITS:
            out.append(f"{r[0]} worst: published {worst:.{DIGITS}f}, yet seeds {spec.seeds[0]}..{spec.seeds[-1]} "
                       f"alone reach {s.worst:.{DIGITS}f}")
    out += [f"row '{controller_label(p)} / {controller_label(a)}': flown, not published"
            for p, a in cells if (p, a) not in seen]
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m sitl.lab.published SWEEP CASES.csv``: print the table that docs/sweeps.md shows."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 2:
        print("usage: python -m sitl.lab.published SWEEP CASES.csv", file=sys.stderr)
        return 2
    spec = load_sweep(args[0])
    print(markdown(spec, load_cases(Path(args[1]))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
