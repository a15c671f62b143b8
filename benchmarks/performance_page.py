"""docs/performance.md, written whole from the page's text and the benchmarks' last runs.

The page is ``performance_page.md`` (this folder) with its ``{{header}}`` and
one ``{{name}}`` per measured table filled in from ``performance.json``, which
holds the last run of each benchmark that writes one: ``perf_table.py --write``
(``cycle``) and ``system_study.py --write`` (``system``). A run replaces its own
entry and the page is written again, its header naming, per table, the script,
date, machine and git commit of the run behind it. Edit the text in
``performance_page.md``, never in docs/performance.md.

Run:  python benchmarks/performance_page.py        (the page again, from the stored runs)

Standard library only: the tests check that the page is what this module writes.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import subprocess
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
TEMPLATE = HERE / "performance_page.md"
RESULTS = HERE / "performance.json"
PAGE = HERE.parent / "docs" / "performance.md"

#: The measured tables: name -> (heading on the page, the command that writes it).
TABLES = {
    "cycle": ("Cycle and whole jobs", "python benchmarks/perf_table.py luts/ --all --write"),
    "system": ("System simulation", "python benchmarks/system_study.py luts/ --write"),
}


def machine(code: Path = HERE.parent / "evtms") -> dict[str, str]:
    """When, on what and on which code a measurement runs: date, CPU model, cores, load average, and the git
    commit of the checkout holding ``code`` (the evtms package the benchmark imports)."""
    cpu = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    load = f"{os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else "n/a"
    return {
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "cpu": cpu,
        "cores": str(cores),
        "load": load,
        "commit": git_commit(code),
    }


def git_commit(folder: Path) -> str:
    """The short commit of the checkout holding ``folder``, ``+ uncommitted changes`` where ``folder`` has
    some; '' outside git."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=folder, capture_output=True, text=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "."], cwd=folder, capture_output=True, text=True)
    except OSError:
        return ""
    if head.returncode != 0:
        return ""
    return head.stdout.strip() + (" + uncommitted changes" if dirty.stdout.strip() else "")


# -- the measured tables ------------------------------------------------------
def measured_line(m: dict) -> str:
    """The one 'measured on' line of a table."""
    load = f", load average {m['load']}" if m.get("load") not in (None, "", "n/a") else ""
    return f"Measured on {m['date']}, {m['cpu']}, {m['cores']} cores{load}."


def cycle_table(entry: dict) -> str:
    """perf_table.py's rows: the target table (figure, measured, target, met, peer), then the detail rows.

    Rows without a ``met`` field (runs stored before the table had one) make the one table of
    figure, measured value and target."""
    rows = entry["rows"]
    if not any("met" in r for r in rows):
        lines = ["| figure | measured | target |", "|---|---|---|"]
        lines += [_cells(r["figure"], r["value"], r.get("target")) for r in rows]
        return "\n".join(lines)
    verdict = {True: "yes", False: "no"}
    lines = ["| figure | measured | target | met | peer |", "|---|---|---|---|---|"]
    lines += [
        _cells(r["figure"], r["value"], r.get("target"), verdict.get(r["met"]), r.get("peer"))
        for r in rows
        if "met" in r
    ]
    details = [r for r in rows if "met" not in r]
    if details:
        lines += ["", "| detail | measured | peer |", "|---|---|---|"]
        lines += [_cells(r["figure"], r["value"], r.get("peer")) for r in details]
    return "\n".join(lines)


def _cells(*cells: str | None) -> str:
    """One Markdown table row; an empty cell is '| |'."""
    return "|" + "|".join(f" {c} " if c else " " for c in cells) + "|"


def system_table(entry: dict) -> str:
    """system_study.py's performance figures (seconds) as the table of the page."""
    p, n = entry["performance"], entry.get("repeat", 20)
    return "\n".join(
        [
            "| figure | measured | target / reference |",
            "|---|---|---|",
            f"| time loop, WLTC 1800 s at dt 0.1 s (maps loaded, compiled; median of {n}) "
            f"| {p['loop_dt0.1_s'] * 1e3:.1f} ms | 200 ms; thesis 686 ms (refrigerant loop alone), Simscape 72.5 s, "
            "FASTSim-3 46-53 ms (no refrigerant loop) |",
            f"| the same at dt 1 s | {p['loop_dt1_s'] * 1e3:.2f} ms | |",
            "| `simulate()` call at dt 0.1 s (set-up, loop, records, ledgers) "
            f"| {p['simulate_call_dt0.1_s'] * 1e3:.1f} ms | |",
            "| whole command `evtms simulate --cycle wltc3b --t-amb 30 -o run.nc --json`, maps cached "
            f"| {p['cli_wall_s']:.2f} s | 0.5 s |",
            f"| sweep of {p['sweep_runs']} ambients in one call (`--t-amb -20:45:{p['sweep_runs']}`) "
            f"| {p['sweep_wall_s']:.2f} s, {p['sweep_per_run_s'] * 1e3:.0f} ms per run | |",
        ]
    )


RENDER = {"cycle": cycle_table, "system": system_table}


# -- the page -----------------------------------------------------------------
def header(results: dict) -> str:
    rows = ["| tables | written by | measured | machine | evtms commit |", "|---|---|---|---|---|"]
    for name, (heading, command) in TABLES.items():
        anchor = heading.lower().replace(" ", "-")
        if name not in results:
            rows.append(f"| [{heading}](#{anchor}) | `{command}` | not yet | | |")
            continue
        m = results[name]["machine"]
        rows.append(
            f"| [{heading}](#{anchor}) | `{command}` | {m['date']} | {m['cpu']}, {m['cores']} cores "
            f"| {m.get('commit') or 'not recorded'} |"
        )
    return "\n".join(
        [
            "# Performance",
            "",
            "<!-- Written by benchmarks/performance_page.py from benchmarks/performance_page.md and",
            "     benchmarks/performance.json: edit those, not this file. -->",
            "",
            "How fast evtms runs, measured by the scripts in `benchmarks/`. The benchmarks write this",
            "page whole: the tables below are from these runs, each other table names the script that",
            "measured it.",
            "",
            *rows,
        ]
    )


def render(results: dict, template: str | None = None) -> str:
    """The whole page from the stored runs."""
    text = TEMPLATE.read_text(encoding="utf-8") if template is None else template
    text = text.replace("{{header}}", header(results))
    for name, (_, command) in TABLES.items():
        entry = results.get(name)
        table = (
            measured_line(entry["machine"]) + "\n\n" + RENDER[name](entry)
            if entry
            else f"Not measured yet: `{command}`."
        )
        text = text.replace("{{" + name + "}}", "\n" + table)
    return text


def load(path: Path = RESULTS) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


def write(name: str, entry: dict, results_path: Path = RESULTS, page: Path = PAGE) -> Path:
    """Store ``entry`` (its ``machine`` and what ``RENDER[name]`` reads) as table ``name``'s run; write the page."""
    if name not in TABLES:
        raise ValueError(f"unknown table {name!r}; the page has {sorted(TABLES)}")
    results = load(results_path) if results_path.exists() else {}
    results[name] = entry
    text = render(results)  # before anything is written: a bad entry leaves both files as they were
    results_path.write_text(json.dumps(results, indent=1, default=str) + "\n", encoding="utf-8")
    page.write_text(text, encoding="utf-8")
    return page


if __name__ == "__main__":
    PAGE.write_text(render(load()), encoding="utf-8")
    print(f"wrote {PAGE}")
