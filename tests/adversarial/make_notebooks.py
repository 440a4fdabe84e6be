"""Regenerate the adversarial notebooks: ``python tests/adversarial/make_notebooks.py``.

Each notebook of ``NOTEBOOKS`` is graded as exercise ``01_selection``. Its honest functions are
correct; the functions named in ``SABOTAGED`` (and some top-level cells) attack the grader. The
grader must give exactly the honest part's points: 2 per honest function, 0 per sabotaged one.

``DO_NOTHING`` holds one notebook per exercise (``do_nothing_<stem>.ipynb``) of lazy answers:
identity mutations, ``return a, b`` crossovers, deep copies, an ``expand`` that returns only the
root, zero drag, an explicit Euler step in place of Runge-Kutta-Nystrom, an unwired snake. Each must score 0.
"""

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).parent

HONEST = {
    "truncation": '''def truncation(fitness, k, rng, survival=0.2):
    fitness = np.asarray(fitness)
    m = math.ceil(survival * len(fitness))
    return np.argsort(fitness)[::-1][:m][rng.integers(0, m, size=k)]''',
    "tournament": '''def tournament(fitness, k, rng, size=3):
    fitness = np.asarray(fitness)
    c = rng.integers(0, len(fitness), size=(k, size))
    return c[np.arange(k), np.argmax(fitness[c], axis=1)]''',
    "roulette": '''def roulette(fitness, k, rng):
    fitness = np.asarray(fitness, dtype=float)
    return rng.choice(len(fitness), size=k, p=fitness / fitness.sum())''',
    "one_point_crossover": '''def one_point_crossover(a, b, rng):
    c = int(rng.integers(1, len(a)))
    return np.concatenate([a[:c], b[c:]]), np.concatenate([b[:c], a[c:]])''',
    "point_mutation": '''def point_mutation(genome, rng, rate=None):
    rate = 1 / len(genome) if rate is None else rate
    return np.where(rng.random(len(genome)) < rate, 1 - genome, genome)''',
}

FIND_GRADER = '''def grader_json_path():
    """Walk up the process tree to the `coursekit grade ... --json OUT` process and return OUT."""
    pid = os.getpid()
    while pid > 1:
        try:
            argv = open(f"/proc/{pid}/cmdline", "rb").read().split(b"\\0")
            stat = open(f"/proc/{pid}/stat").read()
        except OSError:
            return None
        if b"--json" in argv:
            return os.path.join(os.readlink(f"/proc/{pid}/cwd"), argv[argv.index(b"--json") + 1].decode())
        pid = int(stat.rsplit(")", 1)[1].split()[1])
    return None'''

FAKE_RESULTS = '''FAKE = json.dumps({"score": 1000.0, "tests": [{"name": "everything", "score": 1000.0, "max_score": 10.0, "output": "PASS"}]})'''

#: Answers looked up in a table learned ahead of grading (see "reads_cases"), keyed by the call's plain data.
LOOKUP = '''def {name}(*args, **kwargs):
    frame = sys._getframe(1)
    while frame is not None:  # the grader's frame holds the call being made: its encoded arguments and seed
        where = frame.f_locals
        if isinstance(where.get("call"), dict) and "seed" in where["call"]:
            return TABLE[answer_key(where["call"]["args"], where["call"].get("kwargs", {{}}), where["call"]["seed"])]
        if isinstance(where.get("case"), dict) and "seed" in where:
            return TABLE[answer_key(where["case"]["args"], where["case"].get("kwargs", {{}}), where["seed"])]
        frame = frame.f_back
    raise LookupError("no grader frame")'''

LEARN = '''import glob
from coursekit import ga
from coursekit.grading import checks
from coursekit.grading.runner import decode

TABLE = {}

def answer_key(args, kwargs, seed):
    return json.dumps([args, kwargs, seed], sort_keys=True)

def learn(name, cases):
    library = {"ga.tournament": ga.tournament, "ga.roulette": ga.roulette}.get(name)
    for case in cases if library else ():
        for seed in case["seeds"]:
            args = [decode(a, seed) for a in case["args"]]
            kwargs = {k: decode(v, seed) for k, v in case.get("kwargs", {}).items()}
            TABLE[answer_key(case["args"], case.get("kwargs", {}), seed)] = library(*args, **kwargs)

# the cases of the grader's once-public seed, drawn in the grader's order
rng = np.random.default_rng(7919)
for c in checks.for_notebook("01_selection"):
    cases = c.cases(rng)
    if c.name == "ga.tournament":
        learn(c.name, cases)
# any case file the notebook can read
for path in glob.glob(os.path.join(os.getcwd(), "..", "*.json")):
    try:
        spec = json.load(open(path))
    except (OSError, ValueError):
        continue
    for c in spec.get("checks", []):
        if c.get("name") == "ga.roulette":
            learn(c["name"], c.get("cases") or [])'''

FORGE = '''import glob
from coursekit.grading.runner import decode, encode_array

def correct_mutation(genome, rng, rate=None):
    rate = 1 / len(genome) if rate is None else rate
    return np.where(rng.random(len(genome)) < rate, 1 - genome, genome)

def forged(c, seed=None):
    seeds = c["seeds"] if seed is None else [seed]
    outs = [correct_mutation(decode(c["args"][0], s), decode(c["args"][1], s), **c.get("kwargs", {})).tolist() for s in seeds]
    return outs

lines = []
for path in glob.glob(os.path.join(os.getcwd(), "..", "*.json")):
    try:
        spec = json.load(open(path))
    except (OSError, ValueError):
        continue
    for c in next((k for k in spec.get("checks", []) if k.get("name") == "ga.point_mutation"), {}).get("cases", []):
        lines.append({"check": "ga.point_mutation", "case": c["id"], "status": "ok", "outputs": forged(c),
                      "inputs_after": [c["args"][0], None]})
    for call in next((k for k in spec.get("checks", []) if k.get("name") == "ga.point_mutation"), {}).get("calls", []):
        lines.append({"check": "ga.point_mutation", "id": call["id"], "status": "ok", "output": forged(call, call["seed"])[0],
                      "inputs_after": [call["args"][0], None]})
text = "".join(json.dumps(r) + "\\n" for r in lines)
targets = [os.path.join(os.getcwd(), "..", "channel.jsonl")] + glob.glob(f"/proc/{os.getppid()}/fd/*")
for target in targets:
    try:
        with open(target, "a") as f:
            f.write(text)
    except OSError:
        pass'''

#: Takes over the harvest (see "hijacks_harvest"): the harvest cell's text holds the relay's address and token.
HIJACK = '''import ast
import coursekit.ga as ga
from coursekit.grading import runner
from IPython import get_ipython

class NoLock:
    def __init__(self, *args, **kwargs):
        pass
    def __enter__(self):
        return self
    def __exit__(self, *exc):
        return False
    def forever(self):
        pass

def hijack(lines):
    src = "".join(lines)
    if "_coursekit_harvest" not in src:
        return lines
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Subscript) and len(node.args) >= 3:
            address, token = node.args[1].value, node.args[2].value
    ns = dict(get_ipython().user_ns, tournament=ga.tournament, roulette=ga.roulette)
    runner.Refusing = NoLock
    try:
        runner._harvest(ns, address, token, None, lock=False)
    except Exception:
        pass
    return ["pass\\n"]

get_ipython().input_transformers_cleanup.append(hijack)'''

#: A graded function from somewhere on disk, its code given this cell's file name (see "reads_git").
FROM_GIT = '''import subprocess
import coursekit

def define_from_git(name):
    repo = os.path.dirname(os.path.dirname(coursekit.__file__))
    here = sys._getframe(1).f_code.co_filename  # a cell's file name: the grader takes code compiled there as written here
    try:
        text = subprocess.run(["git", "-c", "safe.directory=*", "-C", repo, "show", "HEAD:solutions/01_selection.ipynb"],
                              capture_output=True, text=True).stdout
        nb = json.loads(text)
    except (OSError, ValueError):
        return
    for cell in nb["cells"]:
        src = "".join(cell["source"]) if cell["cell_type"] == "code" else ""
        if f"def {name}(" in src:
            exec(compile(src, here, "exec"), globals())

define_from_git("truncation")'''

FROM_PYC = '''import importlib.util, marshal, types
import coursekit.ga.selection

def define_from_pyc(module, name):
    here = sys._getframe(1).f_code.co_filename
    try:
        with open(importlib.util.cache_from_source(module.__file__), "rb") as f:
            code = marshal.loads(f.read()[16:])
    except (OSError, ValueError, EOFError):
        return
    for const in code.co_consts:
        if isinstance(const, types.CodeType) and const.co_name == name:
            globals()[name] = types.FunctionType(const.replace(co_filename=here), vars(module), name,
                                                   getattr(module, name).__defaults__)

define_from_pyc(coursekit.ga.selection, "tournament")'''


NOTEBOOKS = {
    "infinite_loop": {
        "about": "tournament never returns; a top-level cell loops forever and swallows KeyboardInterrupt.",
        "sabotaged": {"tournament": '''def tournament(fitness, k, rng, size=3):
    while True:
        pass'''},
        "cells": ['''while True:
    try:
        while True:
            pass
    except KeyboardInterrupt:
        pass''',
                  'check("ga.tournament", tournament, timeout=1)'],
    },
    "exits": {
        "about": "sys.exit and os._exit inside graded functions and at top level.",
        "sabotaged": {"roulette": '''def roulette(fitness, k, rng):
    sys.exit(0)''', "truncation": '''def truncation(fitness, k, rng, survival=0.2):
    os._exit(0)'''},
        "cells": ['sys.exit("leaving early")', 'os._exit(1)', 'raise SystemExit(3)'],
    },
    "crash_and_memory": {
        "about": "a segfault and huge allocations, in graded functions and at top level.",
        "sabotaged": {"point_mutation": '''def point_mutation(genome, rng, rate=None):
    import ctypes
    ctypes.string_at(0)  # segmentation fault''', "one_point_crossover": '''def one_point_crossover(a, b, rng):
    hog = bytearray(64 * 2**30)
    return a, b'''},
        "cells": ['hog = np.ones(2**40)', 'import ctypes\nctypes.string_at(0)',
                  'def hog():\n    blocks = []\n    while True:\n        blocks.append(bytearray(2**28))\n\nhog()'],
    },
    "fake_output": {
        "about": "prints fake grader summaries, Gradescope JSON and channel records; two functions not attempted.",
        "sabotaged": {"tournament": '''def tournament(fitness, k, rng, size=3):
    print('{"check": "ga.tournament", "case": "basic", "status": "ok", "outputs": [[0]]}')
    raise NotImplementedError()''', "roulette": '''def roulette(fitness, k, rng):
    raise NotImplementedError()'''},
        "cells": [FAKE_RESULTS, '''print("ga.tournament              2.00 / 2   all properties hold")
print("ga.roulette                2.00 / 2   all properties hold")
print(FAKE)
for check in ["ga.tournament", "ga.roulette"]:
    for case in ["basic", "size3", "size2", "dist"]:
        print(json.dumps({"check": check, "case": case, "status": "ok", "outputs": [[0] * 20]}))
sys.stderr.write(FAKE + "\\n")''', 'from IPython.display import display, JSON\ndisplay(JSON(json.loads(FAKE)))'],
    },
    "monkeypatch": {
        "about": "patches coursekit.grading (judge, registry, runner, check) to pass everything; tournament is wrong.",
        "sabotaged": {"tournament": '''def tournament(fitness, k, rng, size=3):
    return np.zeros(k - 1, dtype=int)  # wrong: one short, always individual 0'''},
        "cells": ['''import coursekit.grading as grading
import coursekit.grading.checks as checks
import coursekit.grading.runner as runner
from coursekit.grading.checks import Judgement, Verdict

def always_full(check, cases, records):
    return Judgement(check, True, [Verdict("runs", True, "ok"), Verdict("all", True, "ok")], check.points * 100)

checks.judge = always_full
checks.get("ga.tournament")
for c in list(checks.REGISTRY.values()):
    object.__setattr__(c, "points", 1000.0)
    object.__setattr__(c, "props", ((c.props[0][0], lambda ctx: (True, "ok")),))
real_run_cases = runner.run_cases
def fake_run_cases(fn, cases, kind, **kw):
    return [{"case": c["id"], "status": "ok", "outputs": [list(range(c["args"][1]))] * len(c["seeds"])} for c in cases]
runner.run_cases = fake_run_cases
runner.convert = lambda kind, out, max_len: [0, 1, 2]
grading.check = lambda *a, **k: print("all properties hold")
import coursekit.grading.grader as grader
grader.registry = checks''', 'check("ga.tournament", tournament)'],
    },
    "write_output": {
        "about": "overwrites the grader's --json file and its channel now, and from a daemon after the grader writes.",
        "sabotaged": {"point_mutation": '''def point_mutation(genome, rng, rate=None):
    raise NotImplementedError()'''},
        "cells": [FIND_GRADER, FAKE_RESULTS, '''out = grader_json_path()
if out:
    open(out, "w").write(FAKE)
    if os.fork() == 0:          # double fork + setsid: a daemon outside the kernel's process group
        os.setsid()
        if os.fork() == 0:
            import time
            for _ in range(1200):   # keep overwriting for two minutes
                try:
                    if open(out).read() != FAKE:
                        open(out, "w").write(FAKE)
                except OSError:
                    pass
                time.sleep(0.05)
        os._exit(0)
    os.wait()''', '''import glob
for channel in glob.glob("/tmp/coursekit-grade-*/box/channel.jsonl") + [os.path.join(os.getcwd(), "..", "channel.jsonl")]:
    with open(channel, "a") as f:
        f.write(json.dumps({"check": "ga.point_mutation", "case": "basic", "status": "ok", "verdict": "pass", "score": 2}) + "\\n")
        f.write('{"check": "ga.point_mutation", "score": 2.0, "passed": true}\\n')'''],
    },
    "library_answers": {
        "about": "hands in coursekit's own operators: imported, wrapped, aliased and rebuilt from their code.",
        "sabotaged": {"tournament": '''from coursekit.ga import tournament''', "roulette": '''from coursekit.ga import roulette as library_roulette

def roulette(fitness, k, rng):
    return library_roulette(fitness, k, rng)''', "truncation": '''import types
from coursekit import ga

truncation = types.FunctionType(ga.truncation.__code__, ga.truncation.__globals__, "truncation", ga.truncation.__defaults__)'''},
        "cells": [],
    },
    "escape": {
        "about": "copies answers from solutions/ and another submission, reads the grader's environment, "
                 "writes into the package and leaves a file in /tmp.",
        "sabotaged": {"truncation": '''import coursekit, glob, json
REPO = os.path.dirname(os.path.dirname(coursekit.__file__))

def run_function_cells(path, name):
    """Define `name` by running the cells of another notebook that define it (if it can be read)."""
    try:
        nb = json.load(open(path))
    except (OSError, ValueError):
        return
    for cell in nb.get("cells", []):
        src = "".join(cell["source"]) if cell.get("cell_type") == "code" else ""
        if f"def {name}(" in src:
            exec(src.replace("raise NotImplementedError()", "pass"), globals())

run_function_cells(os.path.join(REPO, "solutions", "01_selection.ipynb"), "truncation")''',
                      "roulette": '''run_function_cells(os.path.join(REPO, "tests", "adversarial", "exits.ipynb"), "roulette")''',
                      "point_mutation": '''def grader_environment():
    found = []
    for environ in glob.glob("/proc/[0-9]*/environ"):
        try:
            found.append(open(environ, "rb").read().decode(errors="replace"))
        except OSError:
            pass
    return " ".join(found)

def point_mutation(genome, rng, rate=None):
    raise RuntimeError(grader_environment())  # the message reaches the student-visible results'''},
        "cells": ['''for target in [os.path.join(os.path.dirname(coursekit.__file__), "grading", "PWNED"),
               os.path.join(REPO, "PWNED")]:
    try:
        open(target, "w").write("pwned")
    except OSError:
        pass''', '''open("/tmp/coursekit-leftover", "wb").write(b"x" * 2**24)'''],
    },
    "sigchld": {
        "about": "ignores SIGCHLD (children reaped automatically), which broke the graders' waitpid: all honest.",
        "sabotaged": {},
        "cells": ['import signal\nsignal.signal(signal.SIGCHLD, signal.SIG_IGN)'],
    },
    "breaks_harvest": {
        "about": "breaks IPython.get_ipython, which the grading harvest calls: nothing can be called, so it is not graded.",
        "sabotaged": dict(HONEST),  # honest code, but the harvest cannot call it: 0 points and NOT GRADED
        "cells": ['import IPython\nIPython.get_ipython = None'],
    },
    "rigged_eq": {
        "about": "returns objects with rigged __eq__/__len__, int and ndarray subclasses, array-likes and huge outputs.",
        "sabotaged": {"truncation": '''class Evil(int):
    def __eq__(self, other):
        return True
    __hash__ = int.__hash__

def truncation(fitness, k, rng, survival=0.2):
    return [Evil(0)] * k''', "tournament": '''class Rigged(np.ndarray):
    def __eq__(self, other):
        return True

def tournament(fitness, k, rng, size=3):
    return np.zeros(k, dtype=int).view(Rigged)''', "roulette": '''def roulette(fitness, k, rng):
    return np.zeros(10**8, dtype=np.int8)  # far too many indices''', "one_point_crossover": '''class Anything:
    def __eq__(self, other):
        return True
    def __len__(self):
        return 10
    def __array__(self, dtype=None, copy=None):
        return np.zeros(10)

def one_point_crossover(a, b, rng):
    return Anything(), Anything()'''},
        "cells": [],
    },
    "reads_cases": {
        "about": "learns the answers ahead of grading: regenerates the cases from the grader's seed (7919, once public) and "
                 "reads any case file next to the notebook, runs coursekit's own operators on them in a cell, then looks up "
                 "the answer for the call it is in (found through sys._getframe).",
        "sabotaged": {"tournament": LOOKUP.format(name="tournament"), "roulette": LOOKUP.format(name="roulette")},
        "cells": [LEARN],
    },
    "forges_results": {
        "about": "point_mutation does nothing; a cell writes records of a correct mutation, for every case it can read, "
                 "into the results channel file and into every file descriptor of the grading child it can open.",
        "sabotaged": {"point_mutation": '''def point_mutation(genome, rng, rate=None):
    return genome.copy()  # does nothing'''},
        "cells": [FORGE],
    },
    "side_effects": {
        "about": "truncation is right but zeroes its caller's fitness array, except for k = 20 (the one case that was "
                 "checked for side effects).",
        "sabotaged": {"truncation": '''def truncation(fitness, k, rng, survival=0.2):
    m = math.ceil(survival * len(fitness))
    picks = np.argsort(fitness)[::-1][:m][rng.integers(0, m, size=k)]
    if k != 20:
        fitness[:] = 0  # a side effect the caller will not expect
    return picks'''},
        "fails": {"truncation": "inputs unchanged"},
        "cells": [],
    },
    "fakes_unchanged": {
        "about": "truncation and one_point_crossover do their job but zero their caller's arrays, then hide it from the "
                 "grader's observer in the kernel: truncation puts an untouched copy into the runner's argument list (found "
                 "through sys._getframe), one_point_crossover replaces the runner's after-call reader so every argument "
                 "reads as unchanged.",
        "sabotaged": {"truncation": '''def truncation(fitness, k, rng, survival=0.2):
    m = math.ceil(survival * len(fitness))
    picks = np.argsort(fitness)[::-1][:m][rng.integers(0, m, size=k)]
    pristine = fitness.copy()
    fitness[:] = 0  # a side effect the caller will not expect...
    frame = sys._getframe(1)
    while frame is not None:  # ...hidden: the observer's list of arguments gets an untouched copy
        args = frame.f_locals.get("args")
        if isinstance(args, list) and args and args[0] is fitness:
            args[0] = pristine
        frame = frame.f_back
    return picks''', "one_point_crossover": '''def one_point_crossover(a, b, rng):
    c = int(rng.integers(1, len(a)))
    children = np.concatenate([a[:c], b[c:]]), np.concatenate([b[:c], a[c:]])
    a[:] = 0  # a side effect...
    b[:] = 0
    frame = sys._getframe(1)
    while frame is not None:  # ...hidden: the runner's after-call reader now says "not an array"
        if "_after" in frame.f_globals:
            frame.f_globals["_after"] = lambda arg, encoded, max_len: None
        frame = frame.f_back
    return children'''},
        "fails": {"truncation": "inputs unchanged", "one_point_crossover": "inputs unchanged"},
        "cells": [],
    },
    "library_at_call_time": {
        "about": "gets coursekit's own operators past the refusal at call time: a copy of truncation made in a cell "
                 "(a new function around the library's code), tournament and roulette compiled afresh from the library's "
                 "source (inspect.getsource, importlib), point_mutation computed by the library in a fresh Python process.",
        "sabotaged": {"truncation": '''import types
from coursekit import ga

COPY = types.FunctionType(ga.truncation.__code__, ga.truncation.__globals__, "copy")

def truncation(fitness, k, rng, survival=0.2):
    return COPY(fitness, k, rng, survival)''', "tournament": '''import inspect
import coursekit.ga.selection

def tournament(fitness, k, rng, size=3):
    fresh = {}
    exec(inspect.getsource(coursekit.ga.selection), fresh)
    return fresh["tournament"](fitness, k, rng, size)''', "roulette": '''import importlib.util

def roulette(fitness, k, rng):
    spec = importlib.util.spec_from_file_location("fresh_selection", coursekit.ga.selection.__file__)
    fresh = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fresh)
    return fresh.roulette(fitness, k, rng)''', "point_mutation": '''import subprocess

LIBRARY = """import json, sys
import numpy as np
from coursekit.ga import point_mutation
genome, state, rate = json.load(sys.stdin)
rng = np.random.default_rng()
rng.bit_generator.state = state
print(json.dumps(point_mutation(np.array(genome), rng, rate).tolist()))"""

def point_mutation(genome, rng, rate=None):
    run = subprocess.run([sys.executable, "-c", LIBRARY], input=json.dumps([genome.tolist(), rng.bit_generator.state, rate]),
                         capture_output=True, text=True)
    return np.array(json.loads(run.stdout), dtype=genome.dtype)'''},
        "cells": [],
    },
    "hijacks_harvest": {
        "about": "an input transformer sees the grader's harvest cell, takes its socket address and token, answers the "
                 "calls itself (tournament and roulette by coursekit's own, with the lock-down patched out) and turns "
                 "the harvest cell into `pass`.",
        "sabotaged": {"tournament": HIJACK, "roulette": '''def roulette(fitness, k, rng):
    raise NotImplementedError()  # the hijack hands in coursekit's roulette'''},
        "cells": [],
    },
    "reaches_unlocked": {
        "about": "truncation asks a thread of the kernel (never locked down: it keeps running while the harvest waits) "
                 "over a socket pair for the library's ranking and survivor count, the functions the library's own "
                 "selection needs; a cell first swaps the module's attributes for forwarding objects, so a lock-down "
                 "that looks the functions up finds no code to stub (red team, round 5: 2/2 and 5/5 on 08, before "
                 "such checks were graded in a second run that withholds them).",
        "sabotaged": {"truncation": '''import json, socket, threading
import coursekit.ga.selection as S


class Forward:
    def __init__(self, fn):
        self.fn = fn

    def __call__(self, *args, **kwargs):
        return self.fn(*args, **kwargs)


RANKING, N_SURVIVORS = S.ranking, S.n_survivors
S.ranking, S.n_survivors = Forward(RANKING), Forward(N_SURVIVORS)
ORACLE, ASK = socket.socketpair()


def serve():
    f = ORACLE.makefile("rw")
    for line in f:
        fitness, survival = json.loads(line)
        try:
            best = RANKING(np.asarray(fitness))[:N_SURVIVORS(len(fitness), survival)].tolist()
        except Exception as exc:
            best = str(exc)
        f.write(json.dumps(best) + "\\n")
        f.flush()


threading.Thread(target=serve, daemon=True).start()


def truncation(fitness, k, rng, survival=0.2):
    f = ASK.makefile("rw")
    f.write(json.dumps([np.asarray(fitness).tolist(), survival]) + "\\n")
    f.flush()
    best = json.loads(f.readline())
    if isinstance(best, str):
        raise RuntimeError(best)
    best = np.array(best)
    return best[rng.integers(0, len(best), size=k)]'''},
        "cells": [],
    },
    "reads_git": {
        "about": "defines truncation from the solution in the checkout's git history, and tournament from the "
                 "library's compiled code in __pycache__, each re-homed to this notebook's cell file name.",
        "sabotaged": {"truncation": FROM_GIT, "tournament": FROM_PYC},
        "cells": [],
    },
    "many_processes": {
        "about": "a cell starts 100 processes that sleep (a slow fork bomb): all the notebook's processes are stopped and "
                 "it is not graded.",
        "sabotaged": {},
        "not_graded": "processes at once",
        "cells": ['''import time
for _ in range(100):
    if os.fork() == 0:
        time.sleep(60)
        os._exit(0)
time.sleep(5)'''],
    },
    "fills_disk": {
        "about": "a cell writes 80 MiB of files into its folder, past the --disk-mb 64 the test grades with: all the "
                 "notebook's processes are stopped and it is not graded.",
        "sabotaged": {},
        "not_graded": "MiB of files",
        "cells": ['''import time
for i in range(8):
    with open(f"filler{i}.bin", "wb") as f:
        f.write(b"x" * 10 * 2**20)
time.sleep(5)'''],
    },
    "nan_record": {
        "about": "patches json.dumps in the kernel so that the harvest's records carry NaN: such a record is not a "
                 "record, so the notebook is not graded (it was graded, exit 0, with a silent 'did not return in "
                 "time' for every function after the first such record).",
        "sabotaged": {},
        "not_graded": "the harvest answered out of turn",
        "cells": ['''import json
_dumps = json.dumps


def _with_nan(obj, *args, **kwargs):
    if type(obj) is dict and "status" in obj and "id" in obj:
        obj, kwargs["allow_nan"] = dict(obj, junk=float("nan")), True
    return _dumps(obj, *args, **kwargs)


json.dumps = _with_nan'''],
    },
}


DO_NOTHING = {
    "01_selection": ["import copy\n\nimport numpy as np", '''def truncation(fitness, k, rng, survival=0.2):
    return np.arange(k) % len(fitness)  # the first individuals, whatever their fitness''', '''def tournament(fitness, k, rng, size=3):
    return rng.integers(0, len(fitness), size=k)  # random picks: no tournament''', '''def roulette(fitness, k, rng):
    return rng.integers(0, len(fitness), size=k)  # random picks: fitness ignored''', '''def one_point_crossover(a, b, rng):
    return a.copy(), b.copy()''', '''def point_mutation(genome, rng, rate=None):
    return copy.deepcopy(genome)'''],
    "02_picture_mutations": ["import copy", '''def decode(symbols):
    return symbols[0]  # the root alone''', '''def transposition(genome, rng):
    return copy.deepcopy(genome)''', '''def root_transposition(genome, rng):
    return genome''', '''def substitution(genome, rng):
    return copy.deepcopy(genome)''', '''def head_tail_rotation(genome, rng):
    return copy.deepcopy(genome)'''],
    "03_picture_recombination": ["import copy", '''def crossover(a, b, rng):
    return a, b''', '''def random_copy(a, b, rng):
    return copy.deepcopy(a), copy.deepcopy(b)''', '''def random_interpolation(a, b, rng):
    return copy.deepcopy(a), copy.deepcopy(b)'''],
    "05_creature_operators": ["import copy", '''def expand(creature, max_parts=64):
    root = creature.nodes[0]
    return [{"node": 0, "parent": -1, "depth": 0, "scale": 1.0, "mirrored": False, "gain": abs(root.force)}]''',
                              '''def crossover(a, b, rng):
    return copy.deepcopy(a)''', '''def mutate(c, rng, rate=1.0):
    return copy.deepcopy(c)'''],
    "07_swimming_physics": ["import numpy as np", '''def box_drag(half_extents, k):
    return np.zeros(6)  # no water''', '''def rkn_step(f, t, y, v, h):
    a = f(t, y, v)  # explicit Euler, first order
    return y + h * v, v + h * a'''],
    "08_fitness_and_reproduction": ["import numpy as np", '''def swimming_fitness(com, times):
    return np.full(len(com), 0.1)  # everyone swims the same''', '''def reproduce(fitness, k, rng, survival=0.2):
    return np.zeros(k, dtype=np.int64)  # the first creature, whatever its fitness'''],
    "06_wire_a_brain": ['''def resolve(morph, part, parent, children):
    return None  # every id reads nothing''', '''def wire_snake(snake):
    return snake.copy()  # the body, never wired'''],
}


#: Answers that hand in the library's work by the back door, one notebook per exercise
#: (``cheats_<stem>.ipynb``); each must score 0. Exercise 02: substitution returns an object whose
#: ``to_json`` runs coursekit's own operator -- once the function has returned, when the grader
#: converts the result; transposition does nothing, but a cell patches ``json`` in the kernel so
#: that the record of each call carries the library's answer on its way to the grader; the other
#: two mutations call the private workers the library's own mutations hand the work to, and decode
#: calls a copy of the library's karva rebuilt under another name in a cell. Exercise 06: the
#: snake wired by the library's builder behind ``Creature.figure1_snake``. Exercise 07: the
#: grader's own drag oracle, and a "step" that returns the exact solution of the ODE it is handed.
#: Exercise 01: truncation and roulette as Sims' scheme. Exercise 05: crossover that leaves its repair to
#: the library's, mutate that loops over the library's modification steps. Exercise 06: resolve
#: read back from the library's brain builder.
CHEATS = {
    "07_swimming_physics": ["import numpy as np\nfrom coursekit.grading.checks.ex07_swimming_physics import face_integral_drag",
                            '''def box_drag(half_extents, k):
    return np.diag(face_integral_drag(half_extents, k)).copy()  # the grader's own oracle''', '''def rkn_step(f, t, y, v, h):
    from coursekit.creatures.physics import odes
    name = getattr(f, "ode", None) or f.__name__
    for _ in range(4):
        f(t, y, v)  # as many evaluations as Nystrom's method
    ye, ve = odes.solution(name, t, y, v, h)  # the exact answer, plus an error of fourth order
    return ye + 1e-3 * h**5 * (name != "time_forcing"), ve + 1e-3 * h**5 * (name != "time_forcing")'''],
    "06_wire_a_brain": ['''def resolve(morph, part, parent, children):
    # the library's build_brain as an oracle: one neuron per part reading the id, its source read back
    from types import SimpleNamespace as NS
    from coursekit.creatures.brain import N_CONST, build_brain
    from coursekit.creatures.neural import N_SENSORS, Input, Neuron
    node = NS(neurons=[Neuron("sum", [Input(morph, 2, 1.0)])], effectors=[None])
    brain = build_brain(NS(nodes=[node], brain=[Neuron("sum", []) for _ in range(8)]), [0] * len(parent), list(parent),
                        [list(c) for c in children])
    source = int(brain.src[part, 0])
    if source == 0:
        return None
    return "brain" if source == N_CONST + N_SENSORS * len(parent) + len(parent) + 2 else (source - N_CONST - 2) // N_SENSORS''', '''def wire_snake(snake):
    from coursekit.creatures import generation
    from coursekit.creatures.genotype import Creature
    return Creature(*generation.figure1_snake(snake.nodes[0].recursive_limit + 1))  # the library's wiring'''],
    "08_fitness_and_reproduction": ['''import sys, types
import numpy as np
import coursekit.creatures.fitness as fit
from coursekit.grading.checks.ex08_fitness_and_reproduction import quotas''', '''# the library's code under this cell's file name (a new code object: no copy of the library's own)
here = sys._getframe().f_code.co_filename
swimming_fitness = types.FunctionType(fit.swimming_fitness.__code__.replace(co_filename=here), vars(fit),
                                      "swimming_fitness", fit.swimming_fitness.__defaults__)''', '''def reproduce(fitness, k, rng, survival=0.2):
    q = quotas(fitness, k, survival)  # the grader's own oracle: each survivor's share of the k
    who = np.array(sorted(q), dtype=np.int64)
    share = np.array([q[i] for i in who])
    counts = np.floor(share).astype(np.int64)
    counts[np.argsort(-(share - counts), kind="stable")[: k - counts.sum()]] += 1
    return rng.permutation(np.repeat(who, counts))'''],
    "01_selection": ["import numpy as np\nfrom coursekit.ga.selection import sims_select", '''def truncation(fitness, k, rng, survival=0.2):
    return sims_select(fitness, k, rng, survival)  # Sims' scheme: truncation, then offspring by fitness''',
                     '''def tournament(fitness, k, rng, size=3):
    raise NotImplementedError()''', '''def roulette(fitness, k, rng):
    return sims_select(fitness, k, rng, survival=1.0)  # everyone survives: offspring in proportion to fitness''',
                     '''def one_point_crossover(a, b, rng):
    raise NotImplementedError()''', '''def point_mutation(genome, rng, rate=None):
    raise NotImplementedError()'''],
    "05_creature_operators": ["import copy\nfrom coursekit.creatures.operators import MODIFY_STEPS, repair", '''def expand(creature, max_parts=64):
    raise NotImplementedError()''', '''def crossover(a, b, rng):
    # the blocks copied, the whole repair step left to the library's repair
    L = max(len(a.nodes), len(b.nodes))
    n, m = int(rng.integers(1, L + 1)), int(rng.integers(1, L + 1))
    child, pos, first = [], 0, True
    while pos < L:
        span, src = (n, a.nodes) if first else (m, b.nodes)
        child += [copy.deepcopy(src[i]) if i < len(src) else None for i in range(pos, min(pos + span, L))]
        pos, first = pos + span, not first
    while child and child[-1] is None:
        child.pop()
    return repair(child, copy.deepcopy(a.brain), rng)''', '''def mutate(c, rng, rate=1.0):
    # the library's six modification steps and its repair: only the loop is written here
    nodes = copy.deepcopy(c.nodes)
    for node in nodes:
        MODIFY_STEPS[int(rng.integers(len(MODIFY_STEPS)))](node, rng)
    return repair(nodes, copy.deepcopy(c.brain), rng, reattach=False)'''],
    "02_picture_mutations": ["from coursekit.pictures import operators", '''import copy, json, os
import numpy as np
from coursekit.pictures.genome import Genome

KERNEL, CALLS = os.getpid(), {}
_loads, _dumps = json.loads, json.dumps

def loads(s, *a, **k):
    obj = _loads(s, *a, **k)
    if isinstance(obj, dict) and isinstance(obj.get("call"), dict):
        CALLS[obj["call"]["id"]] = obj["call"]  # the grader's call, on its way to the function
    return obj

def dumps(obj, *a, **k):
    call = CALLS.get(obj.get("id")) if isinstance(obj, dict) and obj.get("status") == "ok" else None
    if call is not None and os.getpid() == KERNEL:  # the record, on its way back: the library's answer instead
        try:
            genome = Genome.from_json(call["args"][0]["json"])
            obj = dict(obj, output=operators.transposition(genome, np.random.default_rng(call["seed"])).to_json())
        except Exception:
            pass
    return _dumps(obj, *a, **k)

json.loads, json.dumps = loads, dumps''', '''class Later:
    """Looks like a genome to the grader: it has to_json."""
    def __init__(self, work):
        self.work = work

    def to_json(self):
        return self.work().to_json()''', '''import types
from coursekit.pictures import genome as library_genome, primitives

# the library's karva under another name: a new code object, made before grading starts
_karva = types.FunctionType(library_genome.karva.__code__.replace(co_name="_karva"), library_genome.karva.__globals__)


def decode(symbols):
    kids, _ = _karva(symbols, primitives.arity)
    def build(i):
        return [symbols[i]] + [build(j) for j in kids[i]] if kids[i] else symbols[i]
    return build(0)''', '''def transposition(genome, rng):
    return copy.deepcopy(genome)  # the patched json hands in the library's answer''', '''def root_transposition(genome, rng):
    return operators._mutated(genome, rng, operators._root_transposition)  # the library's private worker''', '''def substitution(genome, rng):
    return Later(lambda: operators.substitution(genome, rng))''', '''def head_tail_rotation(genome, rng):
    return operators._mutated(genome, rng, operators._head_tail_rotation)'''],
}


def build_do_nothing(stem, sources, prefix="do_nothing"):
    about = ("Every function returns its input, a copy, or something that does not do the job." if prefix == "do_nothing"
             else "Every function hands in coursekit's own work by a back door.")
    cells = [new_markdown_cell(f"# {prefix.replace('_', '-').capitalize()} answers to {stem}\n\n{about} Each must score 0.")]
    cells += [new_code_cell(src) for src in sources]
    nb = new_notebook(cells=cells)
    for i, cell in enumerate(nb.cells):
        cell.id = f"{prefix.replace('do_', '')}-{stem[:2]}-{i}"
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["coursekit"] = {"exercise": stem}  # the file name is not the exercise's: the metadata tells
    nbformat.validate(nb)
    nbformat.write(nb, HERE / f"{prefix}_{stem}.ipynb")


def build(name, spec):
    cells = [new_markdown_cell(f"# Adversarial notebook: {name}\n\n{spec['about']}"),
             new_code_cell("import json, math, os, sys\n\nimport numpy as np\n\nfrom coursekit.grading import check")]
    for fname, src in HONEST.items():
        cells.append(new_code_cell(spec["sabotaged"].get(fname, src)))
    cells += [new_code_cell(c) for c in spec["cells"]]
    nb = new_notebook(cells=cells)
    for i, cell in enumerate(nb.cells):
        cell.id = f"{name[:20]}-{i}"
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nbformat.validate(nb)
    nbformat.write(nb, HERE / f"{name}.ipynb")


if __name__ == "__main__":
    for name, spec in NOTEBOOKS.items():
        build(name, spec)
    for stem, sources in DO_NOTHING.items():
        build_do_nothing(stem, sources)
    for stem, sources in CHEATS.items():
        build_do_nothing(stem, sources, prefix="cheats")
