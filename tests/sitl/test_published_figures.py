"""docs/sweeps.md's sweep tables against what the code flies now, in a short form.

Each table between ``<!-- table: NAME -->`` and ``<!-- /table -->`` is checked by flying the first
seeds (and random samples) of the bundled sweep NAME: those are cases of the published run (same
seeds, same engine, same numbers), so a published median or quartile may differ from the sample's
only by the sampling error of a few seeds, read from the seed-to-seed spread (4 standard errors of
the quantile, :func:`sitl.lab.published.tolerance`), and a published worst case may not be below
the sample's. The published run is the compiled engine's (the default where numba is installed).
"""

import dataclasses
import re
from pathlib import Path

import pytest

from sitl.lab.published import drift, markdown, published_rows
from companion.control.jit import numba_available
from sitl.lab.sweep import load_cases, load_sweep, run_sweep
from sitl.lab.tuning import GAIN_LABELS, GAINS, Candidate, check, tables
from sitl.plant.scenario import load_scenario

PAGE = Path(__file__).resolve().parents[2] / "docs" / "sweeps.md"

pytestmark = pytest.mark.skipif(not numba_available(), reason="the published tables are the compiled engine's")

SHORT = {"e3_wind": {"seeds": 8}, "wind_and_mass": {"seeds": 10, "random_samples": 1}}
"""how much of each sweep the check flies: 120 flights of 45 s each, a few seconds on the compiled kernel"""

STALE_E3 = """<!-- table: e3_wind -->
| position / attitude | median | quartiles | worst |
|---|---|---|---|
| PID / PD | 0.330 | 0.278–0.362 | 0.502 |
| AIBC / PD | 0.275 | 0.216–0.316 | 0.457 |
| PD+DO / PD | 0.557 | 0.533–0.590 | 0.694 |
| ISM+DO / PD | 0.105 | 0.081–0.129 | 0.263 |
| PID / ISM+DO | 0.259 | 0.219–0.280 | 0.394 |
| AIBC / ISM+DO | 0.208 | 0.166–0.245 | 0.351 |
| PD+DO / ISM+DO | 0.056 | 0.050–0.060 | 0.091 |
| **ISM+DO / ISM+DO** | **0.027** | 0.025–0.029 | 0.039 |
<!-- /table -->
"""
"""the table docs/sweeps.md published until the check existed (eight pairs of the fifteen flown)"""


def short_form(name):
    spec = load_sweep(name)
    cut = SHORT[name]
    return dataclasses.replace(spec, seeds=spec.seeds[:cut["seeds"]],
                               random_samples=cut.get("random_samples", spec.random_samples))


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    out = tmp_path_factory.mktemp("published")
    result = {}
    for name in SHORT:
        spec = short_form(name)
        table = run_sweep(spec, out, progress=False, plots=False, engine="compiled")
        result[name] = (spec, load_cases(table))
    return result


@pytest.mark.parametrize("name", list(SHORT))
def test_the_published_table_is_what_the_code_flies(flown, name):
    spec, cases = flown[name]
    assert all(c["status"] == "ok" for c in cases)
    problems = drift(spec, PAGE.read_text(), cases)
    assert not problems, f"docs/sweeps.md, table {name} (regenerate it with the command beside it):\n" + \
        "\n".join(problems)


def test_the_stale_e3_table_is_caught(flown):
    spec, cases = flown["e3_wind"]
    problems = "\n".join(drift(spec, STALE_E3, cases))
    for figure in ("AIBC / PD median: published 0.275", "PD+DO / PD median: published 0.557",
                   "'INDI / PD': flown, not published"):
        assert figure in problems


def test_a_table_printed_from_the_cases_passes_its_own_check(flown):
    spec, cases = flown["wind_and_mass"]
    page = f"<!-- table: {spec.name} -->\n{markdown(spec, cases)}\n<!-- /table -->\n"
    assert drift(spec, page, cases) == []
    moved = page.replace(markdown(spec, cases).splitlines()[2].split("|")[2].strip(), "0.999", 1)
    assert len(drift(spec, moved, cases)) == 1


def test_a_page_without_the_markers_is_refused_by_name():
    with pytest.raises(ValueError, match="<!-- table: e3_wind -->"):
        published_rows("| a | b |\n", "e3_wind")


TUNING_BLOCK = re.compile(r"<!-- tuning: ([\w-]+) -->\n(.*?)<!-- /tuning -->", re.S)
NUMBER = re.compile(r"-?\d+(?:\.\d+)?")


def tuning_blocks(page: str) -> dict[str, list[list[str]]]:
    """The tuning tables of the page: name -> rows of cells (header and rule left out)."""
    blocks = {}
    for name, body in TUNING_BLOCK.findall(page):
        rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in body.strip().splitlines()]
        blocks[name] = rows[2:]
    return blocks


def cell_drift(name: str, published: list[list[str]], flown: list[list[str]], rel: float) -> list[str]:
    """Every cell whose number moved by more than ``rel`` plus half a unit of its last printed digit."""
    problems = []
    for row_p, row_f in zip(published, flown, strict=True):
        for cell_p, cell_f in zip(row_p[1:], row_f[1:], strict=True):
            p, f = float(NUMBER.search(cell_p)[0]), float(NUMBER.search(cell_f)[0])
            digits = len(cell_p.split(".")[1].split()[0].rstrip("°")) if "." in cell_p else 0
            if abs(f - p) > rel * abs(p) + 0.5 * 10.0 ** -digits:
                problems.append(f"{name}, {row_p[0]}: published {cell_p}, flown {cell_f}")
    return problems


def test_the_published_tuning_tables_are_what_the_code_flies():
    """docs/sweeps.md's tuning tables: the published tuned gains (as printed, three digits) flown on the
    same unseen and carry-over seeds must give the published figures within 2 %. Same seeds, same
    engine: the difference is the rounding of the published gains, measured at 0.2-0.4 % of the
    check medians. The search itself (64 s on two cores) is not re-run: its result is the gains."""
    blocks = tuning_blocks(PAGE.read_text())
    assert set(blocks) == {"gains", "check", "carry-over"}
    gains = {row[0]: float(row[2]) for row in blocks["gains"]}
    tuned = Candidate(*(gains[GAIN_LABELS[g]] for g in GAINS))
    check_seeds = int(NUMBER.search(PAGE.read_text().split("<!-- tuning: check -->")[1].splitlines()[1])[0])
    carry_seeds = int(NUMBER.search(PAGE.read_text().split("<!-- tuning: carry-over -->")[1].splitlines()[1])[0])
    sc = load_scenario("E3_wind")
    result, _ = check(sc, sc.segments[0], tuned, check_seeds, carry_seeds, jobs=2)
    flown = tuning_blocks("".join(f"<!-- tuning: {n} -->\n{t}\n<!-- /tuning -->\n" for n, t in
                                  zip(("gains", "check", "carry-over"), tables(result).strip().split("\n\n"))))
    problems = [p for name in blocks for p in cell_drift(name, blocks[name], flown[name], rel=0.02)]
    assert not problems, "docs/sweeps.md, tuning (regenerate with the sitl-tune command beside it):\n" + \
        "\n".join(problems)
    assert result["after_worst_m"] < 0.1, "a tuned flight on an unseen seed left the hover"
