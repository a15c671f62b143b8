"""The performance table's rows and targets, and the child-process measurements its scripts share.

:data:`TARGETS` is the project's target table: one row per figure, in the
order printed, each with the figure's target and the measured fields the
target bounds. :class:`Table` collects the measured rows; the rows a run did
not measure are filled in by :meth:`Table.finish` ("not run", with the option
that runs them), so every run's table and ``--json`` have every target row.

Used by ``perf_table.py`` (and its ``perf_system.py`` and ``perf_peers.py``
rows); standard library only, besides NumPy for medians.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Target:
    """One figure of the target table.

    Attributes
    ----------
    figure : str
        What is measured, as the table prints it.
    target : str
        The target as printed ('' where the project sets none).
    limits : tuple of (str, float)
        Measured field -> its largest value that meets the target (same units as the field).
    flag : str
        The option that runs the row ('' for the rows of every run).
    """

    figure: str
    target: str
    limits: tuple[tuple[str, float], ...] = ()
    flag: str = ""


#: The target table: row key (the ``--json`` key) -> figure, in the order printed.
TARGETS: dict[str, Target] = {
    "direct_point": Target(
        "direct-physics cycle point (`cycle run --direct`; in-process, one at a time, median)",
        "10 ms",
        (("median_ms", 10.0),),
    ),
    "lut_point": Target("LUT cycle, one point, warm, in-process (median)", "1 ms", (("median_ms", 1.0),)),
    "lut_10000": Target("LUT cycle, 10,000 points in one batch, per point", "30 us", (("us_per_point", 30.0),)),
    "bench_all": Target("`evtms bench all --grid cycle` (15.4 M points), one process", "", (), "--grids"),
    "bench_all_workers": Target(
        "`evtms bench all --grid cycle --workers 2`", "30 s on 2 cores", (("wall_s", 30.0),), "--grids"
    ),
    "maps_build": Target(
        "cycle maps for the simulator: build time (`evtms.system.maps`, into a copy of the LUT folder)",
        "10 s",
        (("seconds", 10.0),),
        "--maps",
    ),
    "demo": Target(
        "`evtms demo -o out/` (fresh folder), time and peak memory",
        "60 s, 600 MB",
        (("wall_s", 60.0), ("rss_mb", 600.0)),
        "--demo",
    ),
    "first_cycle_run": Target(
        "first `evtms cycle run` after new LUTs (builds the cache), time and peak memory",
        "3 s, 500 MB",
        (("wall_s", 3.0), ("rss_mb", 500.0)),
    ),
    "physics_30": Target(
        "`simulate --model physics`, WLTC 30 degC (simulate() call, maps loaded)",
        "10 s",
        (("seconds", 10.0),),
        "--physics",
    ),
    "physics_40_soaked": Target(
        "`simulate --model physics`, WLTC 40 degC, soaked at 40 degC, sun 600 W/m2 (simulate() call)",
        "20 s",
        (("seconds", 20.0),),
        "--physics",
    ),
    "simulate_process": Target(
        "whole `evtms simulate --cycle wltc3b --t-amb 30 -o run.nc --json` process, maps cached (median)",
        "0.5 s",
        (("wall_s", 0.5),),
    ),
    "test_suite": Target("test suite on a clean clone (CI's time)", "", (), "--suite-seconds"),
}


def met(row: dict, target: Target) -> bool | None:
    """Whether ``row`` meets ``target``: None where it has no limit, was not measured, or only a lower bound
    (a timed-out run: ``lower_bound`` True) that is within the limit."""
    if not target.limits:
        return None
    verdicts = []
    for field, limit in target.limits:
        value = row.get(field)
        if not isinstance(value, int | float) or not np.isfinite(value):
            return None
        if row.get("lower_bound"):
            verdicts.append(False if value > limit else None)
        else:
            verdicts.append(value <= limit)
    if False in verdicts:
        return False
    return None if None in verdicts else True


class Table:
    """The measured rows: the target rows (:data:`TARGETS`, in that order) and the detail rows after them."""

    def __init__(self, quiet: bool = False) -> None:
        self.targets: dict[str, dict] = {}
        self.details: list[dict] = []
        self.quiet = quiet

    def add(self, key: str, value: str, **data) -> dict:
        """Row ``key`` of the target table: its measured ``value`` (text) and fields (numbers, for the limits)."""
        target = TARGETS[key]
        row = {"key": key, "figure": target.figure, "value": value, "target": target.target, "peer": "", **data}
        row["met"] = met(row, target)
        self.targets[key] = row
        self._show(row)
        return row

    def detail(self, key: str, figure: str, value: str, **data) -> dict:
        """A detail row (no target of the project's table)."""
        row = {"key": key, "figure": figure, "value": value, "peer": "", **data}
        self.details.append(row)
        self._show(row)
        return row

    def peer(self, key: str, text: str, ratio: float | None = None) -> None:
        """Put a peer's figure beside target row ``key`` (if measured): ``ratio`` = evtms's time / the peer's."""
        row = self.targets.get(key)
        if row is None or "not run" in row["value"]:
            return
        row["peer"] = text if ratio is None else f"{text}: evtms / peer {ratio:.3g}"
        row["peer_ratio"] = ratio

    def finish(self, why: str = "") -> None:
        """Fill every target row not measured: 'not run', with ``why`` or the option that runs it."""
        for key, target in TARGETS.items():
            if key not in self.targets:
                reason = why or (f"add {target.flag}" if target.flag else "not measured")
                self.targets[key] = {
                    "key": key,
                    "figure": target.figure,
                    "value": f"not run ({reason})",
                    "target": target.target,
                    "peer": "",
                    "met": None,
                }

    @property
    def rows(self) -> list[dict]:
        """Target rows in :data:`TARGETS` order, then the detail rows."""
        return [self.targets[k] for k in TARGETS if k in self.targets] + self.details

    def _show(self, row: dict) -> None:
        if not self.quiet:
            verdict = {True: " [met]", False: " [not met]"}.get(row.get("met"), "")
            print(f"  {row['figure']}: {row['value']}{verdict}", flush=True)


# -- child processes ----------------------------------------------------------
def compile_bytecode() -> None:
    """The package's modules compiled to bytecode, as installing it leaves them, so that the
    whole-process rows time what an installed ``evtms`` runs. An editable install writes the
    bytecode on first import, unless ``PYTHONDONTWRITEBYTECODE`` is set, as on some machines:
    there every process compiled the sources again, about 0.13 s of a whole ``simulate``."""
    import compileall

    import evtms

    compileall.compile_dir(Path(evtms.__file__).parent, quiet=1)


def evtms_command() -> list[str]:
    """The ``evtms`` console script of the running Python (not a shell shim), else the one on PATH."""
    exe = Path(sys.executable).with_name("evtms")
    if exe.exists():
        return [str(exe)]
    found = shutil.which("evtms")
    if found is None:
        raise SystemExit("no 'evtms' command found; install the package (pip install -e .)")
    return [found]


#: Runs argv[2:] and writes its wall time and own rusage to argv[1]. A forked child's peak RSS
#: starts from its parent's high-water mark (Linux carries it across exec), so the command is
#: started from this small launcher, not from the benchmark holding the LUTs in memory. Peak RSS
#: counts the pages of memory-mapped files a process touched (the LUT cache's tables, shared with
#: every other process and the page cache): every 0.25 s the launcher also reads the anonymous
#: (private) resident memory of the command's process tree from /proc, the largest process's and
#: the sum over the tree, and keeps their peaks (NaN where there is no /proc), in a thread: the
#: wall time ends at the exit, not at the next sample.
LAUNCHER = """
import json, os, subprocess, sys, threading, time

def private_kb(root):
    children = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    children.setdefault(int(f.read().rsplit(")", 1)[1].split()[1]), []).append(int(d))
            except (OSError, ValueError, IndexError):
                continue
    total = largest = 0
    todo = [root]
    while todo:
        pid = todo.pop()
        todo += children.get(pid, [])
        try:
            with open(f"/proc/{pid}/status") as f:
                kb = next((int(line.split()[1]) for line in f if line.startswith("RssAnon:")), 0)
        except OSError:
            continue
        total, largest = total + kb, max(largest, kb)
    return total, largest

peak = [0, 0, 0]  # the tree's sum, the largest process, samples taken
done = threading.Event()

def sample(pid):
    while not done.wait(0.25):
        total, largest = private_kb(pid)
        peak[:] = max(peak[0], total), max(peak[1], largest), peak[2] + 1

proc_fs = os.path.isdir("/proc/self")
t0 = time.perf_counter()
proc = subprocess.Popen(sys.argv[2:])
sampler = threading.Thread(target=sample, args=(proc.pid,), daemon=True)
if proc_fs:
    sampler.start()
_, status, usage = os.wait4(proc.pid, 0)  # blocking: the wall time to the exit, not to the next sample
wall = time.perf_counter() - t0
done.set()
if proc_fs:
    sampler.join()
tree, one, samples = peak
measured = proc_fs and samples > 0  # a run shorter than a sample has no private figure
nan = float("nan")
with open(sys.argv[1], "w") as f:
    json.dump(
        {
            "wall_s": wall,
            "rss_mb": usage.ru_maxrss / 1024.0,
            "private_mb": one / 1024.0 if measured else nan,
            "private_tree_mb": tree / 1024.0 if measured else nan,
            "rc": os.waitstatus_to_exitcode(status),
        },
        f,
    )
"""


def run_child(cmd: list[str], env: dict[str, str] | None = None, timeout: float | None = None) -> dict:
    """Run ``cmd`` (with ``env`` added to the environment): its wall time [s], peak RSS [MB] (its own rusage),
    exit code, whole output (``out``) and last output lines (``tail``); ``timed_out`` after ``timeout`` [s]."""
    with tempfile.TemporaryDirectory(prefix="evtms-perf-") as tmp, tempfile.TemporaryFile() as out:
        report = Path(tmp) / "rusage.json"
        proc = subprocess.Popen(
            [sys.executable, "-c", LAUNCHER, str(report), *cmd],
            stdout=out,
            stderr=subprocess.STDOUT,
            env={**os.environ, **(env or {})},
            start_new_session=True,  # a timeout ends the launcher and its command together
        )
        timed_out = False
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            timed_out = True
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        except KeyboardInterrupt:  # in its own session the command misses the terminal's Ctrl-C: pass it on
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait()
            raise
        out.seek(0)
        text = out.read().decode(errors="replace")
        tail = text.strip().splitlines()[-3:]
        base = {"out": text, "tail": tail, "timed_out": timed_out}
        if timed_out or not report.exists():
            return {"wall_s": float("nan"), "rss_mb": float("nan"), "rc": -1, **base}
        return {**json.loads(report.read_text()), **base}


def child_row(runs: list[dict]) -> str:
    """Wall time and peak memory of child runs (median, range), and the failures."""
    walls = [r["wall_s"] for r in runs]
    rss = [r["rss_mb"] for r in runs]
    failed = sum(r["rc"] != 0 for r in runs)
    text = f"{np.median(walls):.2f} s, {np.median(rss):.0f} MB"
    private = [r.get("private_mb", np.nan) for r in runs]
    tree = [r.get("private_tree_mb", np.nan) for r in runs]
    if np.isfinite(private).all() and np.isfinite(tree).all():
        text += f" (private {np.median(private):.0f} MB, all processes at once {np.median(tree):.0f} MB)"
    if len(runs) > 1:
        text += f" (median of {len(runs)}; {min(walls):.2f}-{max(walls):.2f} s)"
    if failed:
        text += f"; {failed} run(s) FAILED: {' | '.join(runs[-1]['tail'])}"
    return text


def child_fields(runs: list[dict]) -> dict:
    """The numbers of child runs for a row: median wall time [s] and peak RSS [MB], every run's, failures."""
    ok = [r for r in runs if r["rc"] == 0]
    if not ok:
        return {"failed": len(runs)}
    return {
        "wall_s": float(np.median([r["wall_s"] for r in ok])),
        "rss_mb": float(np.median([r["rss_mb"] for r in ok])),
        "private_mb": float(np.median([r.get("private_mb", np.nan) for r in ok])),
        "private_tree_mb": float(np.median([r.get("private_tree_mb", np.nan) for r in ok])),
        "walls_s": [r["wall_s"] for r in runs],
        "failed": len(runs) - len(ok),
    }


def last_json(text: str) -> dict | None:
    """The last line of ``text`` that is a JSON object (a child's result line), else None."""
    for line in reversed(text.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                return json.loads(line)
            except json.JSONDecodeError:
                continue
    return None
