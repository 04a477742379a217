"""docs/sweeps.md's sweep tables against what the code flies now, in a short form.

Each table between ``<!-- table: NAME -->`` and ``<!-- /table -->`` is checked by flying the first
seeds (and random samples) of the bundled sweep NAME: those are cases of the published run (same
seeds, same engine, same numbers), so a published median or quartile may differ from the sample's
only by the sampling error of a few seeds, read from the seed-to-seed spread (4 standard errors of
the quantile, :func:`sitl.lab.published.tolerance`), and a published worst case may not be below
the sample's. The published run is the compiled engine's (the default where numba is installed).
"""

import dataclasses
from pathlib import Path

import pytest

from sitl.lab.published import drift, markdown, published_rows
from companion.control.jit import numba_available
from sitl.lab.sweep import load_cases, load_sweep, run_sweep

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
