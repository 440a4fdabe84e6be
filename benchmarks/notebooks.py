"""Run every lesson, solution and demo notebook top to bottom and print a table of run times.

Usage::

    python benchmarks/notebooks.py                 # classroom profile, lessons/ solutions/ demos/
    python benchmarks/notebooks.py --profile ci --only lessons/0
    python benchmarks/notebooks.py --cores 2 --markdown timings.md

Each notebook runs in a fresh kernel (nbclient) from its own folder, as a student's Run All
would. Cells are numbered from 0, as nbformat counts them (markdown cells included). For each the table gives the wall time, the slowest cell, the cells longer than
``--long`` seconds and which of those showed no progress bar (a tqdm bar or widget in their
output), and whether the notebook stayed within the course's budget of ``--budget`` seconds.
``--sections`` adds the run time of every ``## `` section (the lessons' time
estimates). ``--cores N`` pins this process and the kernels it starts to N CPU cores (Linux), to measure a
2-core laptop on a bigger machine. A notebook that raises is reported as FAILED with the error.
This is a measurement, not a test: nothing here fails the test suite.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from datetime import datetime
from pathlib import Path

import nbformat
from nbclient import NotebookClient
from nbclient.exceptions import CellExecutionError

ROOT = Path(__file__).resolve().parent.parent
FOLDERS = ("lessons", "solutions", "demos")


def _seconds(cell) -> float:
    timing = cell.get("metadata", {}).get("execution", {})
    start, end = timing.get("iopub.execute_input"), timing.get("shell.execute_reply")
    if not (start and end):
        return 0.0
    parse = lambda s: datetime.fromisoformat(s.replace("Z", "+00:00"))  # noqa: E731
    return (parse(end) - parse(start)).total_seconds()


def _has_progress(cell) -> bool:
    for out in cell.get("outputs", []):
        data = out.get("data", {})
        if "application/vnd.jupyter.widget-view+json" in data:
            return True
        text = out.get("text", "") if out.get("output_type") == "stream" else ""
        if "%|" in text or "it/s]" in text or "s/it]" in text:
            return True
    return False


def run_notebook(path: Path, timeout: float, long: float) -> dict:
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(nb, timeout=timeout, kernel_name="python3", record_timing=True,
                            resources={"metadata": {"path": str(path.parent)}})
    start, error = time.perf_counter(), None
    try:
        client.execute()
    except CellExecutionError as exc:
        error = str(exc).strip().splitlines()[-1][:120]
    except Exception as exc:  # a kernel that died or timed out: report it, go on with the next notebook
        error = f"{type(exc).__name__}: {exc}"[:120]
    wall = time.perf_counter() - start
    cells = [(i, _seconds(c), _has_progress(c)) for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    sections, current = [], ("(before the first section)", 0.0)
    for c in nb.cells:  # run time per "## " section, for the time estimates in the lessons
        heading = next((line[3:].strip() for line in c.source.splitlines() if line.startswith("## ")), None)
        if c.cell_type == "markdown" and heading:
            sections.append(current)
            current = (heading, 0.0)
        elif c.cell_type == "code":
            current = (current[0], current[1] + _seconds(c))
    sections = [x for x in sections + [current] if x[1] > 0 or not x[0].startswith("(")]
    slow_i, slow_s, _ = max(cells, key=lambda c: c[1]) if cells else (0, 0.0, True)
    longer = [(i, s, bar) for i, s, bar in cells if s > long]
    return {"notebook": path.relative_to(ROOT).as_posix(), "seconds": wall, "slowest_cell": slow_i,
            "slowest_seconds": slow_s, "long_cells": len(longer),
            "long_without_bar": [i for i, _, bar in longer if not bar], "error": error, "sections": sections}


def table(rows, budget: float, long: float) -> str:
    head = (f"| notebook | run time (s) | slowest cell (s) | cells > {long:g} s | of them without a progress bar "
            f"| within {budget:g} s |\n|---|---:|---:|---:|---|---|")
    lines = [head]
    for r in rows:
        ok = "FAILED: " + r["error"] if r["error"] else ("yes" if r["seconds"] <= budget else "NO")
        bare = ", ".join(f"cell {i}" for i in r["long_without_bar"]) or "-"
        lines.append(f"| {r['notebook']} | {r['seconds']:.1f} | {r['slowest_seconds']:.1f} (cell {r['slowest_cell']}) "
                     f"| {r['long_cells']} | {bare} | {ok} |")
    total = sum(r["seconds"] for r in rows)
    lines.append(f"| **all {len(rows)}** | {total:.1f} | | | | {sum(r['seconds'] <= budget and not r['error'] for r in rows)}"
                 f" of {len(rows)} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="classroom", choices=("classroom", "ci"))
    ap.add_argument("--only", default="", help="run only notebooks whose path (e.g. lessons/05) contains this")
    ap.add_argument("--cores", type=int, default=0, help="pin to this many CPU cores (0: leave as is)")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds allowed per cell")
    ap.add_argument("--budget", type=float, default=60.0, help="seconds a notebook may take (the course's budget)")
    ap.add_argument("--long", type=float, default=5.0, help="a cell longer than this should show a progress bar")
    ap.add_argument("--markdown", type=Path, help="also write the table to this file")
    ap.add_argument("--sections", action="store_true", help="also print the run time of every '## ' section")
    args = ap.parse_args(argv)
    os.environ["COURSEKIT_PROFILE"] = args.profile
    if args.cores:
        if not hasattr(os, "sched_setaffinity"):
            ap.error("--cores needs Linux (os.sched_setaffinity)")
        cpus = sorted(os.sched_getaffinity(0))[:args.cores]
        os.sched_setaffinity(0, cpus)  # kernels started below inherit it
        for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ[var] = str(args.cores)
    paths = [p for folder in FOLDERS for p in sorted((ROOT / folder).glob("*.ipynb"))
             if args.only in p.relative_to(ROOT).as_posix()]
    if not paths:
        ap.error(f"no notebook matches --only {args.only!r}")
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"{len(paths)} notebooks, profile {args.profile}, {cores} CPU cores", file=sys.stderr)
    rows = []
    for p in paths:
        rows.append(run_notebook(p, args.timeout, args.long))
        r = rows[-1]
        print(f"  {r['notebook']}: {r['seconds']:.1f} s" + (f"  FAILED: {r['error']}" if r["error"] else ""), file=sys.stderr)
    text = table(rows, args.budget, args.long)
    if args.sections:
        text += "\n\n" + "\n".join(f"{r['notebook']}: " + "; ".join(f"{h} {t:.1f} s" for h, t in r["sections"]) for r in rows)
    print(text)
    if args.markdown:
        from coursekit.atomic import atomic_write

        atomic_write(args.markdown, text + "\n")
    return 1 if any(r["error"] for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
