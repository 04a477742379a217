"""Processes that need the same compiled kernel at once compile it once (companion/control/jit.py,
compile_once): on an empty cache the test suite's workers each compiled every kernel they flew."""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys
import time
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
import json, sys, time
from pathlib import Path
sys.path[:0] = [{module_dir!r}, {root!r}]
from companion.control.jit import compile_once
from tiny_kernel import summed
print(summed._cache._cache_path, flush=True)
here, other = Path({ready!r} + sys.argv[1]), Path({ready!r} + sys.argv[2])
here.touch()
while not other.exists():  # both ask at the same moment
    time.sleep(0.001)
compile_once(summed, 4)
print(json.dumps({{"misses": sum(summed.stats.cache_misses.values()),
                   "hits": sum(summed.stats.cache_hits.values()), "value": summed(4)}}), flush=True)
'''


def _start(tmp_path: Path, me: str, other: str, cache: str = "cache") -> subprocess.Popen[str]:
    module_dir = tmp_path / "mod"
    module_dir.mkdir(parents=True, exist_ok=True)
    (module_dir / "tiny_kernel.py").write_text(KERNEL_MODULE)
    code = ASK.format(module_dir=str(module_dir), root=str(ROOT), ready=str(tmp_path / "ready-"))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / cache)}
    return subprocess.Popen([sys.executable, "-c", code, me, other], env=env, stdout=subprocess.PIPE, text=True)


def test_two_processes_asking_at_once_compile_the_kernel_once_and_both_fly_it(tmp_path: Path) -> None:
    """GIVEN an empty cache and two processes that ask for the same kernel at the same moment THEN
    one compiles it (a cache miss) and the other, having waited, loads it (a hit); both get its
    numbers."""
    procs = [_start(tmp_path, "a", "b"), _start(tmp_path, "b", "a")]
    results = [json.loads(p.communicate(timeout=120)[0].splitlines()[-1]) for p in procs]
    assert sorted((r["misses"], r["hits"]) for r in results) == [(0, 1), (1, 0)], results
    assert all(r["value"] == 3.0 for r in results)


def test_a_process_waits_while_another_holds_the_kernels_lock_then_compiles_it(tmp_path: Path) -> None:
    """GIVEN the kernel's lock held (as by a process compiling it) WHEN a process asks for the
    kernel THEN it waits, compiling nothing, until the lock is let go; then it compiles it. (The
    kernel's own first call, without compile_once, would not wait.)"""
    # where the kernel's cache will be: numba's folder for its file, under the sources' digest
    probe = _start(tmp_path, "probe", "probe", cache="probe-cache")
    cache = tmp_path / "cache" / Path(probe.communicate(timeout=120)[0].splitlines()[0]).relative_to(
        tmp_path / "probe-cache")
    cache.mkdir(parents=True)
    (tmp_path / "ready-b").touch()  # no partner: go at once
    with open(cache / "tiny_kernel.summed.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        p = _start(tmp_path, "a", "b")
        assert Path(p.stdout.readline().strip()) == cache  # type: ignore[union-attr]
        time.sleep(3.0)  # ample for the small kernel to compile, were it not waiting
        waiting = p.poll() is None
        compiled = list(cache.rglob("*summed*.nbi"))
        fcntl.flock(lock, fcntl.LOCK_UN)
    result = json.loads(p.communicate(timeout=120)[0].splitlines()[-1])
    assert waiting and not compiled, compiled
    assert result == {"misses": 1, "hits": 0, "value": 3.0}
