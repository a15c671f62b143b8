"""Processes that need one kernel the numba cache does not hold yet compile it once, in one of them."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

import pytest

from evtms._jit import numba_enabled

KERNEL = """
import numpy as np
from evtms._jit import jit


@jit
def kernel(x):
    total = 0.0
    for i in range(x.size):
        v = x[i]
        total += np.sin(v) * np.cos(v) + np.sqrt(abs(v)) - np.exp(-v * v)
    return total
"""

CALLER = """
import os, sys, time
from pathlib import Path
import numpy as np
sys.path.insert(0, sys.argv[1])
import compile_lock_kernel as m
go = Path(sys.argv[2])
while not go.exists():
    time.sleep(0.01)
m.kernel(np.arange(3.0))
stats = m.kernel.stats
print(sum(stats.cache_misses.values()), sum(stats.cache_hits.values()))
"""


@pytest.mark.skipif(not numba_enabled(), reason="numba is not importable (or EVTMS_NO_NUMBA is set)")
def test_concurrent_processes_compile_a_new_kernel_once(tmp_path):
    (tmp_path / "compile_lock_kernel.py").write_text(textwrap.dedent(KERNEL))
    go = tmp_path / "go"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", CALLER, str(tmp_path), str(go)], env=env, stdout=subprocess.PIPE, text=True
        )
        for _ in range(3)
    ]
    time.sleep(2.0)  # every caller imported and waiting
    go.touch()
    counts = [tuple(map(int, p.communicate(timeout=120)[0].split())) for p in procs]
    assert all(p.returncode == 0 for p in procs)
    # One compiled it (a cache miss); the others waited on its lock and loaded it (cache hits).
    assert sorted(counts) == [(0, 1), (0, 1), (1, 0)], counts
