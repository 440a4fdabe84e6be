"""Benchmark: what ``coursekit grade`` gives every kind of submission, and how long each takes.

Grades, through the command an instructor runs (``python -m coursekit grade ... --json``, one
batch per set, as root or not, in the bubblewrap sandbox), the checkout's notebooks in five sets:

- **solutions**: ``solutions/*.ipynb``; each must get full marks;
- **exercises**: the untouched skeletons ``exercises/*.ipynb``; each must get 0;
- **do-nothing**: ``tests/adversarial/do_nothing_*.ipynb``, lazy answers to every exercise
  (identity mutations, ``return a, b``, deep copies, zero drag, explicit Euler, ...); each must get 0;
- **back-doors**: ``tests/adversarial/cheats_*.ipynb``, answers that hand in coursekit's own work
  or the grader's oracles; each must get 0;
- **attacks**: every notebook of ``tests/adversarial/make_notebooks.py``'s ``NOTEBOOKS``, graded
  as exercise 01 with short limits (as the test suite does); each must get the points of its
  honest functions: 2 per function left honest, part of 2 for one that does its job but changes
  its caller's arrays, 0 where the grader had to stop all of the notebook's processes. Those
  whose cells the grader had to skip are reported *not graded*, with the reason.

For every notebook the table gives the points, what it should get, whether the grader said it was
graded, and the wall time of its grading (``seconds`` in the results: sandbox, kernel start, the
notebook's cells and the calls). Then the time per notebook of each set (median and largest).

Usage::

    python benchmarks/grading.py                       # all sets
    python benchmarks/grading.py --sets solutions do-nothing --markdown grading.md
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ADV = ROOT / "tests" / "adversarial"
if not (ADV / "make_notebooks.py").exists() or not (ROOT / "solutions").is_dir():
    print(f"no {ADV} or {ROOT / 'solutions'}: this benchmark grades the checkout's solutions and adversarial "
          "notebooks, which the wheel does not carry; run it from a checkout", file=sys.stderr)
    raise SystemExit(0)  # nothing to measure here, as `coursekit bench` leaves out what a machine lacks
sys.path.insert(0, str(ADV))
from make_notebooks import CHEATS, DO_NOTHING, HONEST, NOTEBOOKS  # noqa: E402

sys.path.pop(0)

STEMS = sorted(p.stem for p in (ROOT / "solutions").glob("*.ipynb"))


def _sets() -> dict:
    """set name -> (notebooks, extra grade options, ``expected(path, max points) -> (lo, hi)``: exactly
    ``lo`` when the two are equal, else strictly between them)."""
    slow = ["--timeout", "20", "--cell-timeout", "120"]
    # an attack's honest part: 2 points per honest function, and part of 2 (not all) for one that
    # does its job but breaks a property (its caller's arrays zeroed: "inputs unchanged" fails);
    # 0 where the grader had to stop every process of the notebook (a fork bomb, a full disk)
    attack_points = {}
    for name, spec in NOTEBOOKS.items():
        honest = 0.0 if "not_graded" in spec else 2.0 * (len(HONEST) - len(spec["sabotaged"]))
        attack_points[ADV / f"{name}.ipynb"] = (honest, honest + 2.0 * len(spec.get("fails", {})))
    return {
        "solutions": ([ROOT / "solutions" / f"{s}.ipynb" for s in STEMS], slow, lambda path, top: (top, top)),
        "exercises": ([ROOT / "exercises" / f"{s}.ipynb" for s in STEMS], slow, lambda path, top: (0.0, 0.0)),
        "do-nothing": ([ADV / f"do_nothing_{s}.ipynb" for s in DO_NOTHING], slow, lambda path, top: (0.0, 0.0)),
        "back-doors": ([ADV / f"cheats_{s}.ipynb" for s in CHEATS], slow, lambda path, top: (0.0, 0.0)),
        "attacks": (list(attack_points), ["--exercise", "01_selection", "--timeout", "3", "--cell-timeout", "10",
                                          "--disk-mb", "64"], lambda path, top: attack_points[path]),
    }


def grade(paths, options) -> tuple[dict, float]:
    """The results ``coursekit grade`` writes for ``paths``, and the batch's wall time."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "results.json"
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "coursekit", "grade", *map(str, paths), "--json", str(out), *options],
                              cwd=tmp, capture_output=True, text=True)
        wall = time.perf_counter() - start
        if proc.returncode not in (0, 3) or not out.exists():  # 3: some notebook was not graded (reported per row)
            raise SystemExit(f"coursekit grade failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
        return json.loads(out.read_text()), wall


def main(argv=None) -> None:
    sets = _sets()
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sets", nargs="+", choices=list(sets), default=list(sets))
    ap.add_argument("--markdown", type=Path, help="also write the tables to this file")
    args = ap.parse_args(argv)
    lines = ["| set | notebook | points | expected | graded | seconds |", "|---|---|---:|---:|---|---:|"]
    times, wrong = {}, []
    for name in args.sets:
        paths, options, expected = sets[name]
        results, wall = grade(paths, options)
        print(f"{name}: {len(paths)} notebooks graded in {wall:.0f} s", flush=True)
        for path, nb in zip(paths, results["extra_data"]["notebooks"]):
            lo, hi = expected(path, nb["max_score"])
            ok = nb["score"] == lo if lo == hi else lo < nb["score"] < hi
            want = f"{lo:g}" if lo == hi else f"{lo:g} < s < {hi:g}"
            if not ok:
                wrong.append(f"{name}/{path.name}: {nb['score']:g}, expected {want}")
            graded = "yes" if nb["graded"] else "not graded: " + nb["not_graded"][0][:70].replace("|", "/")
            lines.append(f"| {name} | {path.stem} | {nb['score']:.4g} / {nb['max_score']:g} | {want}{'' if ok else ' (!)'} "
                         f"| {graded} | {nb['seconds']:.1f} |")
            times.setdefault(name, []).append(nb["seconds"])
    lines += ["", "| set | notebooks | median s | largest s |", "|---|---:|---:|---:|"]
    lines += [f"| {name} | {len(t)} | {statistics.median(t):.1f} | {max(t):.1f} |" for name, t in times.items()]
    text = "\n".join(lines)
    print(text)
    print("every notebook got what it should" if not wrong else "NOT AS EXPECTED:\n  " + "\n  ".join(wrong))
    if args.markdown:
        args.markdown.write_text(text + "\n")
    if wrong:
        raise SystemExit(1)


if __name__ == "__main__":
    main()
