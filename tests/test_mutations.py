"""CI's mutation check: every deliberate bug of the named list must make its tests fail.

See :mod:`helpers.mutations` for the list and the runner; ``make mutations`` regenerates the
score in docs/mutations.md, which must name every mutation of the list.
"""

import pytest
from helpers.mutations import MUTATIONS, REPO, apply, run_all

pytestmark = pytest.mark.slow


def test_every_named_mutation_is_caught():
    outcomes = run_all(MUTATIONS, jobs=2)
    survivors = [o.mutation.name for o in outcomes if not o.caught]
    assert not survivors, f"mutations that no test caught: {survivors}"


def test_every_mutation_still_applies_to_the_source(tmp_path):
    """A stale entry (its text no longer in the file) must fail here, not silently test nothing."""
    for m in MUTATIONS:
        dest = tmp_path / m.path
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_text((REPO / m.path).read_text())
        apply(m, tmp_path)


def test_the_published_score_names_every_mutation():
    text = (REPO / "docs" / "mutations.md").read_text()
    missing = [m.name for m in MUTATIONS if f"| {m.name} |" not in text]
    assert not missing, f"docs/mutations.md is stale (make mutations): {missing}"
