"""The ``coursekit`` command: start the course, run demos, build and grade exercises, benchmark."""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent  # the checkout, where solutions/ and exercises/ are authored
DEFAULT_COURSE_DIR = "coursekit-course"


def number(kind: type, low: float, *, above: bool = False):
    """An argparse type: a finite ``kind`` (int or float) >= ``low`` (> with ``above``); argparse
    names the option when the value is not one."""
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            value = None
        if value is None or not math.isfinite(value) or (value <= low if above else value < low):
            raise argparse.ArgumentTypeError(f"must be {'an integer' if kind is int else 'a number'} "
                                             f"{'>' if above else '>='} {low:g}, got {text}")
        return value
    return parse


def probability(text: str) -> float:
    """An argparse type: a number from 0 to 1."""
    value = number(float, 0)(text)
    if value > 1:
        raise argparse.ArgumentTypeError(f"must be a number from 0 to 1, got {text}")
    return value


def _lab(folder: Path, open_rel: str, no_browser: bool, extra: list[str]) -> int:
    """JupyterLab serving the working folder ``folder`` (lessons link to ../exercises), opened at ``open_rel``.

    It runs in this process (not a child): stopping ``coursekit lab`` stops the server. JupyterLab's
    news pop-up and update check are off (``--LabApp.news_url=None``, ``--LabApp.check_for_updates_class``)."""
    from jupyterlab.labapp import LabApp

    argv = [f"--ServerApp.root_dir={folder}", f"--LabApp.default_url=/lab/tree/{open_rel}",
            "--LabApp.news_url=None", "--LabApp.check_for_updates_class=jupyterlab.NeverCheckForUpdate"]
    if no_browser:
        argv.append("--no-browser")
    if hasattr(os, "geteuid") and os.geteuid() == 0:  # containers and CI machines run as root
        argv.append("--allow-root")
    print(f"coursekit: starting JupyterLab on {folder / open_rel}")
    LabApp.launch_instance(argv=argv + list(extra))
    return 0


def _working_copy(folder: str) -> Path | None:
    """Copy the course into ``folder`` (never overwriting a student's changes) and say what happened."""
    from coursekit.course import copy_course

    try:
        report = copy_course(folder)
    except (OSError, FileNotFoundError) as e:
        print(f"coursekit: {e}", file=sys.stderr)
        return None
    print(f"coursekit: {report}")
    return report.folder


def _cmd_lab(args: argparse.Namespace) -> int:
    """Copy the course into the working folder and open JupyterLab on its lessons."""
    folder = _working_copy(args.dir)
    if folder is None:
        return 2
    return _lab(folder, "lessons", args.no_browser, args.extra)


def _cmd_demo(args: argparse.Namespace) -> int:
    from coursekit import demos

    sizes = dict(population=args.population, generations=args.generations, seconds=args.seconds, seed=args.seed,
                 workers=args.workers, budget=args.budget, rhythm=args.rhythm)
    if args.name != "pictures":
        try:
            demos.swimmer_sizes(args.population, args.generations, args.seconds, args.workers, args.budget)
        except ValueError as e:
            print(f"coursekit demo: --{e}", file=sys.stderr)
            return 2
        out = Path(args.out or ("coursekit-demo" if args.name is None else "swimmers-demo"))
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            print(f"coursekit demo: --out {out}: cannot make this folder ({e.strerror})", file=sys.stderr)
            return 2
    if args.name is None:
        result = demos.both(out, **sizes)
        summary = result["swimmers"]
        print(f"best swimmer: {summary['best_speed']:.3f} m/s = {summary['best_body_lengths_per_second']:.3f} body lengths/s, "
              f"{summary['best_parts']} parts; audit: {summary['audit']}")
        _say_budget(summary)
        print(f"demo written in {result['wall_seconds']:.0f} s (evolution {summary['wall_seconds']['evolution']:.0f} s "
              f"on {summary['workers']} processes); open {result['index']}")
        return 0
    if args.name == "swimmers":
        summary = demos.swimmers(out, **sizes)
        print(f"best swimmer: {summary['best_speed']:.3f} m/s = {summary['best_body_lengths_per_second']:.3f} body lengths/s "
              f"(fitness {summary['best_fitness']:.4f} m/s), {summary['best_parts']} parts")
        print(f"audit: {summary['audit']}")
        _say_budget(summary)
        print(f"wrote {', '.join(summary['files'])} to {out}/")
        return 0
    folder = _working_copy(args.dir)
    if folder is None:
        return 2
    return _lab(folder, "demos/picture_breeding.ipynb", args.no_browser, args.extra)


def _say_budget(summary: dict) -> None:
    if summary["stopped_by_budget"]:
        print(f"evolution stopped after generation {summary['generations']} of {summary['generations_planned']}: the next "
              f"would have ended after the {summary['budget']:g} s budget (--budget 0 breeds them all)")


def _cmd_grade(args: argparse.Namespace) -> int:
    from coursekit.grading.grader import main as grade_main

    return grade_main(args)


def _cmd_exercises(args: argparse.Namespace) -> int:
    from coursekit.grading.authoring import main as authoring_main

    return authoring_main(args)


#: What each benchmark needs beyond coursekit's own dependencies: (module, how to install it).
BENCH_NEEDS = {"swimmers": [("mujoco", "pip install 'coursekit[mujoco]'")]}


def _has_cuda() -> bool:
    import torch

    return torch.cuda.is_available()


#: Benchmarks of hardware a machine may lack: (what, whether it is here). ``coursekit bench``
#: with no names leaves them out where it is absent; named, they run and say so themselves.
BENCH_HARDWARE = {"gpu": ("a CUDA GPU", _has_cuda)}


def _cmd_bench(args: argparse.Namespace) -> int:
    """Run ``benchmarks/NAME.py`` (from the checkout, or as installed with the wheel)."""
    import importlib.util

    from coursekit.course import source

    try:
        bench_dir = source() / "benchmarks"
    except FileNotFoundError as e:
        print(f"coursekit bench: {e}", file=sys.stderr)
        return 2
    have = sorted(p.stem for p in bench_dir.glob("*.py") if not p.stem.startswith("_"))
    if not have:
        print(f"coursekit bench: no benchmark scripts in {bench_dir}; reinstall coursekit or run from a checkout", file=sys.stderr)
        return 2
    if not args.names and {"-h", "--help"} & set(args.extra):  # with names, -h goes to the scripts: their own options
        print("usage: coursekit bench [NAME ...] [options of the scripts]\n\nruns benchmarks/NAME.py (default: all); "
              f"`coursekit bench NAME --help` shows a script's options.\nbenchmarks: {', '.join(have)}")
        return 0
    names = list(args.names or have)
    if not args.names:
        for n, (what, present) in BENCH_HARDWARE.items():
            if n in names and not present():
                print(f"coursekit bench: leaving out {n}: it measures {what}, which this machine lacks", file=sys.stderr)
                names.remove(n)
    unknown = [n for n in names if n not in have]
    if unknown:
        print(f"coursekit bench: no benchmark named {unknown[0]!r}; have {', '.join(have)}", file=sys.stderr)
        return 2
    missing = [(n, mod, how) for n in names for mod, how in BENCH_NEEDS.get(n, []) if importlib.util.find_spec(mod) is None]
    if missing:
        for n, mod, how in missing:
            print(f"coursekit bench: {n} needs {mod}; install it with: {how}", file=sys.stderr)
        return 2
    rc = 0
    for name in names:
        print(f"== benchmarks/{name}.py {' '.join(args.extra)}".rstrip(), flush=True)
        rc |= subprocess.call([sys.executable, str(bench_dir / f"{name}.py"), *args.extra])
    return rc


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="coursekit", description="Genetic algorithms for computer graphics: swimmers and genetic pictures.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    s = sub.add_parser("lab", help="copy the course into a working folder and open JupyterLab on its lessons")
    s.add_argument("dir", nargs="?", default=DEFAULT_COURSE_DIR,
                   help=f"your working folder (default ./{DEFAULT_COURSE_DIR}); the course is copied there, "
                        "and a file you changed is never overwritten")
    s.add_argument("--no-browser", action="store_true", help="do not open a browser window")
    s.set_defaults(func=_cmd_lab)

    s = sub.add_parser("demo", help="instructor demos: both into one folder with an index.html (no name), "
                                    "evolve swimmers (files), breed pictures (JupyterLab)")
    s.add_argument("name", nargs="?", choices=["swimmers", "pictures"],
                   help="one demo (default: both, into --out with an index.html)")
    s.add_argument("--out", help="output folder (default coursekit-demo/; swimmers alone: swimmers-demo/)")
    s.add_argument("--dir", default=DEFAULT_COURSE_DIR, help=f"pictures: the working folder the course is copied to (default ./{DEFAULT_COURSE_DIR})")
    s.add_argument("--population", type=number(int, 2), help="population size (default by COURSEKIT_PROFILE)")
    s.add_argument("--generations", type=number(int, 0), help="generations (default by COURSEKIT_PROFILE)")
    s.add_argument("--seconds", type=number(float, 0, above=True), help="swimming seconds per evaluation")
    s.add_argument("--seed", type=number(int, 0), default=0, help="random seed (default 0)")
    s.add_argument("--workers", type=number(int, 1), help="processes the swimmers swim in (default: one per core)")
    s.add_argument("--budget", type=number(float, 0), help="seconds the swimmers' evolution may take: no generation is begun that "
                   "would end after them (default by COURSEKIT_PROFILE: 75 in the classroom; 0: no limit)")
    s.add_argument("--rhythm", type=probability, help="share of the first swimmers' effectors driven by oscillators of one "
                   "frequency (default 0.5; 0: random wiring only, as the shipped demo champion was bred)")
    s.add_argument("--no-browser", action="store_true", help="pictures: do not open a browser window")
    s.set_defaults(func=_cmd_demo)

    s = sub.add_parser("grade", help="grade exercise notebooks in isolated kernels (Gradescope JSON)")
    s.add_argument("notebooks", nargs="+", help="notebooks to grade")
    s.add_argument("--json", dest="json_out", help="write Gradescope-format results here")
    s.add_argument("--timeout", type=float, default=60.0, help="seconds allowed per student call (default 60)")
    s.add_argument("--cell-timeout", type=float, default=300.0, help="seconds allowed per notebook cell (default 300)")
    s.add_argument("--memory-mb", type=int, default=4096, help="memory the notebook's processes may hold together, in MiB of resident memory "
                   "(not address space; default 4096); over it the notebook is reported as not graded")
    s.add_argument("--exercise", help="grade as this exercise (default: each notebook's metadata field coursekit.exercise, "
                   "else its file stem, e.g. 01_selection)")
    s.add_argument("--notebook-timeout", type=float, default=3600.0,
                   help="seconds allowed for a whole notebook, cells and graded calls (default 3600); "
                        "past them it is stopped and reported as not graded")
    s.add_argument("--max-processes", type=int, default=64, help="processes a notebook may run at once (default 64); "
                   "past them all of its processes are stopped and it is reported as not graded")
    s.add_argument("--disk-mb", type=int, default=1024, help="MiB of files a notebook may write in its folder (default 1024); "
                   "past them all of its processes are stopped and it is reported as not graded")
    s.add_argument("--seed", type=number(int, 0), help="seed of the grading cases (default: fresh ones every run; "
                   "the results name each notebook's seed, so a run can be repeated exactly)")
    s.add_argument("--unsafe", action="store_true",
                   help="grade even where the bubblewrap sandbox cannot be set up (notebooks can then read "
                        "solutions/ and other submissions)")
    s.set_defaults(func=_cmd_grade)

    s = sub.add_parser("exercises", help="build exercises/ from solutions/, or check they are in sync")
    s.add_argument("action", choices=["build", "check"])
    s.add_argument("--solutions", default=str(ROOT / "solutions"))
    s.add_argument("--exercises", default=str(ROOT / "exercises"))
    s.set_defaults(func=_cmd_exercises)

    s = sub.add_parser("bench", add_help=False,  # -h is the scripts' own (see _cmd_bench)
                       help="run the benchmarks (tables against a reference, same run); other options go to the scripts")
    s.add_argument("names", nargs="*", help="benchmark names (default: all)")
    s.set_defaults(func=_cmd_bench)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, unknown = parser.parse_known_args(argv)
    if args.command == "lab" or (args.command == "demo" and args.name == "pictures"):
        args.extra = unknown  # everything else goes to JupyterLab (--port=..., --ServerApp.*)
    elif args.command == "bench":
        args.extra = unknown  # options of the benchmark scripts (--quick, --batches ...)
    elif unknown:
        parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    return int(args.func(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
