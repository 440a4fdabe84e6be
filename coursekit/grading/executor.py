"""The grading child: execute a student notebook in a fresh kernel, then harvest raw outputs.

Seed paper section 4 (students' operators, graded). Started by :mod:`coursekit.grading.grader`
as ``python -m coursekit.grading.executor`` in its own session, under memory limits and, when
the grader runs as root, as an unprivileged user. It never imports student code itself: it
drives an IPython kernel through nbclient.

1. Execute the notebook's code cells (outputs discarded) with a per-cell timeout and
   ``allow_errors``. A cell that kills the kernel (``os._exit``, a crash) or does not finish in
   time is skipped and the notebook re-run from the top in a fresh kernel, so the rest of the
   work still counts.
2. For each check of the grading spec, send one *harvest cell*: the source of
   :mod:`coursekit.grading.runner` executed in a fresh namespace (not the kernel's possibly
   patched ``coursekit``), which calls the student's function on the spec's cases in forked,
   bounded workers and appends raw outputs to the channel file.
3. Write a small execution report (which cells failed or were skipped and why, and whether the
   harvest completed) for the grader, which reports a notebook with skipped cells as not graded.

Nothing the kernel prints is read. The channel holds raw outputs only; verdicts and points are
computed by the grader from its own copy of the cases.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

REPORT_FORMAT = "coursekit.execution/1"
MAX_RESTARTS = 6

_HARVEST = """def _coursekit_harvest():
    import json
    ns = {{"__name__": "coursekit_harvest"}}
    exec(compile({source!r}, "<coursekit-harvest>", "exec"), ns)
    from IPython import get_ipython  # not the notebook's global of that name, which it may have replaced
    ip = get_ipython()
    ns["harvest"](ip.user_ns, json.loads({spec!r}), {channel!r}, set(getattr(ip.compile, "_filename_map", None) or ()) or None)
try:
    _coursekit_harvest()
finally:
    del _coursekit_harvest
"""


def harvest_cell(runner_source: str, spec: dict, channel: str) -> str:
    """The code of one harvest cell (runner source shipped as text, spec as a JSON literal)."""
    return _HARVEST.format(source=runner_source, spec=json.dumps(spec), channel=channel)


def _error_name(cell) -> str | None:
    for out in cell.get("outputs", []):
        if out.get("output_type") == "error":
            return f"{out.get('ename', '?')}: {out.get('evalue', '')}"[:200]
    return None


def execute(nb, spec: dict, channel: str, cwd: str, cell_timeout: float) -> dict:
    """Run the notebook then the harvest cells; return the execution report (plain data)."""
    import nbformat
    from nbclient import NotebookClient
    from nbclient.exceptions import CellTimeoutError, DeadKernelError

    source = Path(__file__).with_name("runner.py").read_text(encoding="utf-8")
    code = [i for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    skip: dict[int, str] = {}
    harvest_timeout = 4 * spec["timeout"] + 90  # the runner stops each check after 4 * timeout + 30 s
    harvested = False
    harvest_problem = None
    cells: dict[int, str] = {}
    for _attempt in range(MAX_RESTARTS + 1):
        run = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(nb.cells[i].source) for i in code])
        client = NotebookClient(run, timeout=cell_timeout, allow_errors=True, interrupt_on_timeout=False,
                                kernel_name="python3", resources={"metadata": {"path": cwd}}, record_timing=False,
                                shutdown_kernel="immediate")
        current = None
        try:
            with client.setup_kernel():
                cells = {}
                for j, i in enumerate(code):
                    if i in skip:
                        continue
                    current = i
                    client.execute_cell(run.cells[j], j)
                    err = _error_name(run.cells[j])
                    cells[i] = f"error: {err}" if err else "ok"
                current = None
                for check in spec["checks"]:
                    one = {**spec, "checks": [check]}
                    run.cells.append(nbformat.v4.new_code_cell(harvest_cell(source, one, channel)))
                    client.timeout = harvest_timeout
                    try:
                        client.execute_cell(run.cells[-1], len(run.cells) - 1)
                        err = _error_name(run.cells[-1])
                        if err and harvest_problem is None:  # the harvest itself failed in the kernel
                            harvest_problem = f"calling {check['function']} failed inside the kernel ({err})"
                    except CellTimeoutError:  # the kernel is wedged: remaining checks get no output
                        harvest_problem = f"calling {check['function']} did not finish within {harvest_timeout:g} s"
                        break
                harvested = True
        except CellTimeoutError:
            if current is None:
                break
            skip[current] = f"did not finish within {cell_timeout:g} s"
            continue
        except DeadKernelError:
            if current is None:  # died during harvesting: what reached the channel counts
                harvest_problem = "the kernel stopped while the graded functions were being called"
                break
            skip[current] = "stopped the kernel (os._exit, a crash or out of memory)"
            continue
        break
    cells.update({i: f"skipped: {why}" for i, why in skip.items()})
    return {"format": REPORT_FORMAT, "harvested": harvested, "harvest_problem": harvest_problem,
            "cells": [{"index": i, "status": cells.get(i, "not run")} for i in code]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m coursekit.grading.executor")
    p.add_argument("--notebook", required=True)
    p.add_argument("--spec", required=True)
    p.add_argument("--channel", required=True)
    p.add_argument("--report", required=True)
    p.add_argument("--cwd", required=True)
    p.add_argument("--cell-timeout", type=float, required=True)
    a = p.parse_args(argv)
    import nbformat

    with open(a.spec, encoding="utf-8") as f:
        spec = json.load(f)
    try:
        nb = nbformat.read(a.notebook, as_version=4)
    except Exception as exc:  # not a notebook: report it, grade as nothing submitted
        report = {"format": REPORT_FORMAT, "harvested": False, "cells": [],
                  "error": f"could not read the notebook: {type(exc).__name__}: {str(exc)[:300]}"}
    else:
        report = execute(nb, spec, a.channel, a.cwd, a.cell_timeout)
    tmp = a.report + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(report, f)
    os.replace(tmp, a.report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
