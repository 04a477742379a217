"""Processes that need the same compiled kernel at once compile it once (companion/control/jit.py,
compile_once): on an empty cache the test suite's four workers each compiled every kernel they flew."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("numba")

ROOT = Path(__file__).resolve().parents[2]

KERNEL_MODULE = '''
from companion.control.jit import kernel


@kernel
def summed(n: int) -> float:
    acc = 0.0
    for k in range(n):
        acc += k * 0.5
    return acc
'''

ASK = '''
import json, os, sys, time
from pathlib import Path
sys.path[:0] = [{module_dir!r}, {root!r}]
from companion.control.jit import compile_once
from tiny_kernel import summed
here, other = Path({ready!r} + sys.argv[1]), Path({ready!r} + sys.argv[2])
here.touch()
while not other.exists():  # both ask at the same moment
    time.sleep(0.001)
{ask}
print(json.dumps({{"misses": sum(summed.stats.cache_misses.values()),
                   "hits": sum(summed.stats.cache_hits.values()), "value": summed(4)}}))
'''


def _two_at_once(tmp_path: Path, ask: str) -> list[dict]:
    module_dir = tmp_path / "mod"
    module_dir.mkdir(parents=True)
    (module_dir / "tiny_kernel.py").write_text(KERNEL_MODULE)
    code = ASK.format(module_dir=str(module_dir), root=str(ROOT), ready=str(tmp_path / "ready-"), ask=ask)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    procs = [subprocess.Popen([sys.executable, "-c", code, a, b], env=env, stdout=subprocess.PIPE, text=True)
             for a, b in (("a", "b"), ("b", "a"))]
    return [json.loads(p.communicate(timeout=120)[0]) for p in procs]


def test_two_processes_asking_at_once_compile_the_kernel_once_and_both_fly_it(tmp_path: Path) -> None:
    """GIVEN an empty cache and two processes that ask for the same kernel at the same moment THEN
    one compiles it (a cache miss) and the other, having waited, loads it (a hit); both get its
    numbers. Without compile_once (the kernel's own first call), both compile: the control case."""
    with_lock = _two_at_once(tmp_path / "once", "compile_once(summed, 4)")
    assert sorted((r["misses"], r["hits"]) for r in with_lock) == [(0, 1), (1, 0)], with_lock
    assert all(r["value"] == 3.0 for r in with_lock)

    without = _two_at_once(tmp_path / "plain", "summed(4)")
    assert [r["misses"] for r in without] == [1, 1], without
