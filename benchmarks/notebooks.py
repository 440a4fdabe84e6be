"""Run every lesson, solution and demo notebook top to bottom and print a table of run times.

Usage::

    python benchmarks/notebooks.py --cores 2               # classroom profile, lessons/ solutions/ demos/
    python benchmarks/notebooks.py --profile ci --only lessons/0
    python benchmarks/notebooks.py --cores 2 --markdown timings.md
    python benchmarks/notebooks.py --cores 2 --only lessons/ --estimates check   # are the lessons' notes still true?
    python benchmarks/notebooks.py --cores 2 --only lessons/ --estimates write   # measure and rewrite them

Each notebook runs in a fresh kernel (nbclient) from its own folder, as a student's Run All
would. Cells are numbered from 0, as nbformat counts them (markdown cells included). For each the
table gives the wall time (kernel start included), the CPU time of the kernel and the processes it
started, the slowest cell, the cells longer than ``--long`` seconds and which of those showed no
progress bar (a tqdm bar or widget in their output), the 1-minute load average when it ended, and
whether the notebook stays within the course's budget of ``--budget`` seconds on an idle machine.
On a machine shared with other work the wall time grows with the load while the CPU time does not: a CPU time
well under the wall time with a load above the core count means the notebook waited for the CPU.
"Cells on an idle machine" adds up, cell by cell, the smaller of the cell's wall and CPU time:
what the cells would take with the cores to themselves (a cell waiting for something else than
the CPU keeps its wall time; one that kept several cores busy is counted at no more than the CPU
time of all its processes, an upper bound on a busy machine).

``--sections`` adds the run time of every ``## `` section. ``--estimates write`` puts a time
estimate under each section heading of the lessons (measured computing time plus reading time,
see :func:`estimate_minutes`; computing is counted as on an idle machine) and refreshes the
"about N minutes to read, run and try; Run All takes about N s" line of their header;
``--estimates check`` reports the notes that no longer match the measurement. Only cell sources
change: the notebooks stay without outputs. ``--cores N`` pins this process and the kernels it
starts to N CPU cores (Linux), to measure a 2-core laptop on a bigger machine. A notebook that
raises is reported as FAILED with the error. This is a measurement, not a test: nothing here
fails the test suite.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import time
from datetime import datetime
from pathlib import Path

import nbformat
import psutil
from nbclient import NotebookClient
from nbclient.exceptions import CellExecutionError

ROOT = Path(__file__).resolve().parent.parent
FOLDERS = ("lessons", "solutions", "demos")

PROSE_WORDS_PER_MINUTE = 150  # careful reading of technical prose, formulas and tables
CODE_LINES_PER_MINUTE = 15  # reading a code cell before running it
TRY_MINUTES = 3  # a "Try this" prompt or a self-check: a few minutes of the student's own work
NOTE = re.compile(r"^\*About \d+ min: (?:under 1 s|(\d+) s) of computing, plus (?:reading|reading and trying)\.\*$")
RUN_ALL = re.compile(r"Run All takes about \d+ s")
TOTAL = re.compile(r"about \d+ minutes to read, run and try")
HEADER = ("*Time: about 0 minutes to read, run and try; Run All takes about 0 s on a 2-core machine (classroom profile, "
          "`coursekit bench notebooks`).*")


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


class _CpuMeter:
    """CPU seconds (user + system) used so far by a kernel and every process it started.

    Finished children count once the kernel has waited for them (the operating system adds them
    to the kernel's own account); running ones (worker pools) are read live. A worker that ends
    between two readings without being waited for is missed: the figure is a lower bound."""

    def __init__(self):
        self.process, self.seen = None, {}

    def attach(self, pid: int | None) -> None:
        self.process = psutil.Process(pid) if pid else None

    def read(self) -> float:
        if self.process is None:
            return 0.0
        try:
            procs = [self.process] + self.process.children(recursive=True)
        except psutil.Error:
            procs = []
        for p in procs:
            try:
                t = p.cpu_times()
            except psutil.Error:
                continue
            own = t.user + t.system
            if p.pid == self.process.pid:
                own += t.children_user + t.children_system
            self.seen[p.pid] = max(self.seen.get(p.pid, 0.0), own)
        return sum(self.seen.values())


def run_notebook(path: Path, timeout: float, long: float) -> dict:
    nb = nbformat.read(path, as_version=4)
    meter, cpu_at = _CpuMeter(), {}

    def before(cell, cell_index, **_):
        if meter.process is None:
            provisioner = getattr(client.km, "provisioner", None)
            meter.attach(getattr(provisioner, "pid", None))
            cpu_at["start"] = [0.0, meter.read()]  # the kernel's own start-up
        cpu_at[cell_index] = [meter.read(), None]

    def after(cell, cell_index, **_):
        cpu_at[cell_index][1] = meter.read()

    client = NotebookClient(nb, timeout=timeout, kernel_name="python3", record_timing=True,
                            resources={"metadata": {"path": str(path.parent)}},
                            on_cell_execute=before, on_cell_executed=after)
    start, error = time.perf_counter(), None
    try:
        client.execute()
    except CellExecutionError as exc:
        error = str(exc).strip().splitlines()[-1][:120]
    except Exception as exc:  # a kernel that died or timed out: report it, go on with the next notebook
        error = f"{type(exc).__name__}: {exc}"[:120]
    wall = time.perf_counter() - start
    startup = cpu_at.pop("start", [0.0, 0.0])[1]
    cpu = {i: (b - a) if b is not None else 0.0 for i, (a, b) in cpu_at.items()}
    walls = {i: _seconds(c) for i, c in enumerate(nb.cells) if c.cell_type == "code"}
    # what a cell would take on an idle machine: its wall time, unless it spent less time on the CPU
    # (a busy machine made it wait); a cell waiting for something else than the CPU keeps its wall time
    computing = {i: min(w, cpu[i]) if cpu.get(i, 0.0) > 0.05 else w for i, w in walls.items()}
    cells = [(i, _seconds(c), _has_progress(c)) for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    slow_i, slow_s, _ = max(cells, key=lambda c: c[1]) if cells else (0, 0.0, True)
    longer = [(i, s, bar) for i, s, bar in cells if s > long]
    return {"notebook": path.relative_to(ROOT).as_posix(), "path": path, "seconds": wall,
            "cpu_seconds": startup + sum(cpu.values()), "startup": startup, "load": os.getloadavg()[0],
            "slowest_cell": slow_i,
            "slowest_seconds": slow_s, "long_cells": len(longer),
            "long_without_bar": [i for i, _, bar in longer if not bar], "error": error,
            "computing": computing, "sections": sections(nb, computing)}


# --- sections and their time estimates ------------------------------------------------------------

def _headings(source: str) -> list[int]:
    """Line numbers of the ``## `` headings in a markdown source (``###`` belongs to its section)."""
    return [k for k, line in enumerate(source.splitlines()) if line.startswith("## ")]


def sections(nb, cell_seconds: dict[int, float]) -> list[dict]:
    """The notebook's ``## `` sections in order: heading, position, computing seconds, words, code lines.

    A section runs from its heading to the next one; a markdown cell may hold several headings
    (its text is split between them), a code cell belongs to the last heading above it. The
    part before the first heading (title, goals, imports) is not a section. Estimate notes
    already in the text are not counted as words."""
    found, current = [], None
    for ci, cell in enumerate(nb.cells):
        if cell.cell_type == "markdown":
            lines = cell.source.splitlines()
            marks = _headings(cell.source)
            if current is not None:
                current["words"] += _words(lines[:marks[0]] if marks else lines)
            for n, k in enumerate(marks):
                end = marks[n + 1] if n + 1 < len(marks) else len(lines)
                current = {"heading": lines[k][3:].strip(), "cell": ci, "line": k, "seconds": 0.0,
                           "words": _words(lines[k + 1:end]), "code_lines": 0}
                found.append(current)
        elif cell.cell_type == "code" and current is not None:
            current["seconds"] += cell_seconds.get(ci, 0.0)
            current["code_lines"] += sum(1 for line in cell.source.splitlines() if line.strip())
    return found


def _words(lines: list[str]) -> int:
    return sum(len(line.split()) for line in lines if not NOTE.match(line.strip()))


def _tries(heading: str) -> bool:
    h = heading.lower()
    return "try this" in h or "self-check" in h or "exercise" in h


def estimate_minutes(section: dict) -> int:
    """Minutes a student spends on a section: its computing time, plus reading the prose at
    :data:`PROSE_WORDS_PER_MINUTE` and the code at :data:`CODE_LINES_PER_MINUTE`, plus
    :data:`TRY_MINUTES` for a "Try this" or self-check section; rounded up, at least one."""
    seconds = (section["seconds"] + 60 * section["words"] / PROSE_WORDS_PER_MINUTE
               + 60 * section["code_lines"] / CODE_LINES_PER_MINUTE + 60 * TRY_MINUTES * _tries(section["heading"]))
    return max(1, math.ceil(seconds / 60))


def note(section: dict) -> str:
    """The estimate line written under a section heading."""
    s = section["seconds"]
    computing = "under 1 s" if s < 1 else f"{round(s)} s"
    rest = "reading and trying" if _tries(section["heading"]) else "reading"
    return f"*About {estimate_minutes(section)} min: {computing} of computing, plus {rest}.*"


def noted(nb) -> list[str | None]:
    """The estimate note of each section as the notebook has it now (None where missing)."""
    out = []
    for s in sections(nb, {}):
        lines = nb.cells[s["cell"]].source.splitlines()
        following = [line.strip() for line in lines[s["line"] + 1:s["line"] + 3] if line.strip()]
        out.append(following[0] if following and NOTE.match(following[0]) else None)
    return out


def stale(old: str | None, new: str) -> bool:
    """True when a note no longer tells the measured truth: missing, or its minutes differ, or its
    computing time is off by more than 5 s and a quarter (runs on one machine vary by about that)."""
    if old is None:
        return True
    if old.split(":")[0] != new.split(":")[0]:
        return True
    a, b = NOTE.match(old).group(1), NOTE.match(new).group(1)
    a, b = float(a or 0), float(b or 0)
    return abs(a - b) > max(5.0, 0.25 * max(a, b))


def write_estimates(nb, cell_seconds: dict[int, float], run_all: float | None = None) -> int:
    """Put the measured estimate note under every section heading of ``nb`` (in place); refresh
    "Run All takes about N s" in the first cell when ``run_all`` is given. Returns the number of
    notes changed. Running it twice with the same times changes nothing the second time."""
    changed = 0
    found = sections(nb, cell_seconds)
    for s in reversed(found):  # from the bottom, so the line numbers above stay valid
        cell = nb.cells[s["cell"]]
        lines = cell.source.splitlines()
        k = s["line"]
        after = k + 1
        while after < len(lines) and not lines[after].strip():
            after += 1
        new = note(s)
        if after < len(lines) and NOTE.match(lines[after].strip()):
            if lines[after].strip() == new:
                continue
            lines[after] = new
        else:
            lines[k + 1:k + 1] = ["", new] + ([""] if k + 1 < len(lines) else [])
            lines[k + 1:] = _drop_double_blank(lines[k + 1:])
        cell.source = "\n".join(lines) + ("\n" if cell.source.endswith("\n") else "")
        changed += 1
    if run_all is not None and nb.cells:
        head = nb.cells[0]
        text = head.source
        if not (RUN_ALL.search(text) and TOTAL.search(text)):  # a lesson without the line gets it under its title
            title, _, rest = text.partition("\n")
            text = f"{title}\n\n{HEADER}\n" + (f"\n{rest.lstrip(chr(10))}" if rest.strip() else "")
        text = RUN_ALL.sub(f"Run All takes about {round(run_all)} s", text)
        text = TOTAL.sub(f"about {total_minutes(nb, cell_seconds)} minutes to read, run and try", text)
        if text != head.source:
            head.source = text
    return changed


def total_minutes(nb, cell_seconds: dict[int, float]) -> int:
    """A whole lesson's estimate: its sections' (:func:`estimate_minutes`) plus reading what comes
    before the first section (its goals, the imports and their run time)."""
    found = sections(nb, cell_seconds)
    first = found[0]["cell"] if found else len(nb.cells)
    intro = {"heading": "", "seconds": sum(cell_seconds.get(i, 0.0) for i in range(first)),
             "words": sum(_words(c.source.splitlines()) for c in nb.cells[:first] if c.cell_type == "markdown"),
             "code_lines": sum(1 for c in nb.cells[:first] if c.cell_type == "code" for line in c.source.splitlines()
                               if line.strip())}
    return estimate_minutes(intro) + sum(estimate_minutes(s) for s in found)


def _drop_double_blank(lines: list[str]) -> list[str]:
    out = []
    for line in lines:
        if not line.strip() and out and not out[-1].strip():
            continue
        out.append(line)
    return out


def estimates(rows, mode: str) -> tuple[str, int]:
    """Check or write the lessons' estimate notes from the measured rows; a report and the number
    of notes that were (or would have to be) changed."""
    from coursekit.atomic import atomic_write

    report, count = [], 0
    for r in rows:
        if not r["notebook"].startswith("lessons/") or r["error"]:
            continue
        nb = nbformat.read(r["path"], as_version=4)
        found, have = sections(nb, r["computing"]), noted(nb)
        bad = [(s, old) for s, old in zip(found, have) if stale(old, note(s))]
        if not (nb.cells and RUN_ALL.search(nb.cells[0].source) and TOTAL.search(nb.cells[0].source)):
            count += 1
            report.append(f"{r['notebook']}: no 'about N minutes to read, run and try; Run All takes about N s' line")
        count += len(bad)
        for s, old in bad:
            report.append(f"{r['notebook']} / {s['heading']}: noted {old or '(nothing)'}; measured {note(s)}")
        if mode == "write":
            text = nbformat.writes(nb)
            write_estimates(nb, r["computing"], run_all=_idle(r))
            if nbformat.writes(nb) != text:
                atomic_write(r["path"], nbformat.writes(nb) + "\n")
    return "\n".join(report) or "every section's estimate matches the measurement", count


# --- the table --------------------------------------------------------------------------------------

def _idle(r) -> float:
    """Seconds a Run All would take on an idle machine: the kernel's start-up plus every cell's
    smaller of wall and CPU time."""
    return r["startup"] + sum(r["computing"].values())


def table(rows, budget: float, long: float) -> str:
    head = (f"| notebook | run time (s) | CPU time (s) | cells on an idle machine (s) | slowest cell (s) "
            f"| cells > {long:g} s | of them without a progress bar | load at end "
            f"| within {budget:g} s on an idle machine |\n"
            "|---|---:|---:|---:|---:|---:|---|---:|---|")
    lines = [head]
    for r in rows:
        ok = "FAILED: " + r["error"] if r["error"] else ("yes" if _idle(r) <= budget else "NO")
        bare = ", ".join(f"cell {i}" for i in r["long_without_bar"]) or "-"
        lines.append(f"| {r['notebook']} | {r['seconds']:.1f} | {r['cpu_seconds']:.1f} | {_idle(r):.1f} "
                     f"| {r['slowest_seconds']:.1f} (cell {r['slowest_cell']}) | {r['long_cells']} | {bare} "
                     f"| {r['load']:.1f} | {ok} |")
    total, cpu = sum(r["seconds"] for r in rows), sum(r["cpu_seconds"] for r in rows)
    idle = sum(_idle(r) for r in rows)
    kept = sum(_idle(r) <= budget and not r["error"] for r in rows)
    lines.append(f"| **all {len(rows)}** | {total:.1f} | {cpu:.1f} | {idle:.1f} | | | | | {kept} of {len(rows)} |")
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
    ap.add_argument("--estimates", choices=("check", "write"),
                    help="check the lessons' per-section time notes against this run, or rewrite them from it")
    args = ap.parse_args(argv)
    if args.estimates and args.profile != "classroom":
        ap.error("--estimates: the lessons' notes give classroom times; run with --profile classroom")
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
    load = os.getloadavg()
    print(f"{len(paths)} notebooks, profile {args.profile}, {cores} CPU cores (of {os.cpu_count()} on the machine), "
          f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f} at the start", file=sys.stderr)
    rows = []
    for p in paths:
        rows.append(run_notebook(p, args.timeout, args.long))
        r = rows[-1]
        print(f"  {r['notebook']}: {r['seconds']:.1f} s, CPU {r['cpu_seconds']:.1f} s, load {r['load']:.1f}"
              + (f"  FAILED: {r['error']}" if r["error"] else ""), file=sys.stderr)
    load = os.getloadavg()
    text = table(rows, args.budget, args.long)
    text += (f"\n\nprofile {args.profile}, {cores} CPU cores; load average (1, 5, 15 min) at the end "
             f"{load[0]:.1f} {load[1]:.1f} {load[2]:.1f}")
    if args.sections:
        text += "\n\n" + "\n".join(f"{r['notebook']}: " + "; ".join(f"{s['heading']} {s['seconds']:.1f} s"
                                                                      for s in r["sections"]) for r in rows)
    code = 1 if any(r["error"] for r in rows) else 0
    if args.estimates:
        report, count = estimates(rows, args.estimates)
        verb = "rewritten" if args.estimates == "write" else "out of date"
        text += f"\n\nsection estimates ({count} {verb}):\n{report}"
        code = code or int(args.estimates == "check" and count > 0)
    print(text)
    if args.markdown:
        from coursekit.atomic import atomic_write

        atomic_write(args.markdown, text + "\n")
    return code


if __name__ == "__main__":
    sys.exit(main())
