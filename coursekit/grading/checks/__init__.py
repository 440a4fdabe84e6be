"""The check registry: one definition per exercise function, shared by formative and summative grading.

Implements the assessment side of the seed paper's teaching model (section 4, "students implement
the GA operators, then their operators drive the real systems"): every graded function has a
:class:`Check` that

- produces input *cases* as plain JSON data from a seeded generator (``cases(rng)``);
- names how the student's result is turned into plain data (``output``: a conversion kind that
  :mod:`coursekit.grading.runner` understands, with strict type checks);
- names its *properties*, each judging (cases, plain records) into a :class:`Verdict`, so that
  :func:`judge` turns a run into per-property verdicts and points.

Formative checks (:mod:`coursekit.grading.formative`) run all three in the student's kernel;
the summative grader (:mod:`coursekit.grading.grader`) generates cases and judges in its own
process and lets only the calls happen next to student code. Points per check and the list of
checks per exercise notebook live here, never in a notebook.

Adding checks for a new exercise ``NN_topic.ipynb``: write ``coursekit/grading/checks/exNN_topic.py``
that calls :func:`register` for each check and :func:`exercise` for ``"NN_topic"``; it is found on
disk (:func:`check_modules`), one module per exercise. Property builders every exercise needs
(determinism for a seed, inputs unchanged, seeds and encoded arrays) are in :mod:`.properties`.
"""

from __future__ import annotations

import importlib
import json
import pkgutil
import re
from dataclasses import dataclass
from typing import Callable

import numpy as np

STATUS_OK = "ok"
#: Statuses a runner record may carry; anything else is refused.
STATUSES = ("ok", "not_implemented", "error", "timeout", "died", "missing", "bad_output")


@dataclass(frozen=True)
class Verdict:
    """One property of one check: did it hold, and a friendly message saying why (never the answer)."""

    prop: str
    passed: bool
    message: str
    weight: int = 1  #: how many properties it counts for in the score (Check.weights)

    @property
    def label(self) -> str:
        """The property's name, with its weight when it counts for more than one."""
        return self.prop if self.weight == 1 else f"{self.prop} (counts {self.weight}x)"


@dataclass(frozen=True)
class Check:
    """A graded function.

    Attributes:
        name: registry key, e.g. ``"ga.tournament"``.
        function: the name the notebook must define, e.g. ``"tournament"``.
        params: the function's parameter names, in order (for messages).
        points: maximum points.
        title: human name for messages.
        output: runner conversion kind for one call's result (``"indices"``, ``"array"``, ``"array_pair"``).
        cases: ``cases(rng) -> list[dict]`` of plain JSON case descriptions (see the runner module).
        props: ``[(property, fn)]`` with ``fn(ctx: Context) -> (passed, message)``.
        gates: how many leading properties are *gates*: the validity of the result, then that the
            function does its job at all (the genome changes, the child holds material of both
            parents, more than the root is expanded, drag opposes the motion, the step is of fourth
            order). When a gate fails the check scores 0 and the later properties are not
            judged, so no property can pass vacuously: a do-nothing, identity or copy
            implementation keeps inputs unchanged and is deterministic, and earns nothing for it.
        hints: ``((property, (hint, ...)), ...)``: the hint ladder of a property, from a nudge to a
            concrete pointer, never the answer (formative ``hint(...)``). Shared properties have
            ladders in :data:`.properties.HINTS`.
        reference: ``"module:attr"`` names of coursekit's own implementations of the function.
            The summative grader refuses them while the student's function runs (an import, an
            alias or a wrapper of the library's version scores 0), and refuses a graded function
            that is not defined in the notebook at all; its sandbox withholds them (and a check's
            own independent oracle, listed here too) from the kernel (:mod:`..withheld`).
        library_uses: those of ``reference`` the library itself calls while the exercise's
            *other* functions are graded (the picture operators decode genomes with ``karva``):
            the sandbox keeps them for those, and this check is graded in a second run of the
            notebook that withholds them too (:func:`..withheld.runs`).
        weights: ``((property, weight), ...)``: properties that count for more than one in the
            score -- the operator's point (its randomness, every kind of change, the rule that
            stops an exploit), so that an answer doing one easy part of the job does not earn
            nearly full marks. The others count 1, and so does "runs".
    """

    name: str
    function: str
    params: tuple
    points: float
    title: str
    output: str
    cases: Callable[[np.random.Generator], list]
    props: tuple
    gates: int = 1
    reference: tuple = ()
    hints: tuple = ()
    library_uses: tuple = ()
    weights: tuple = ()

    def __post_init__(self):
        if not set(self.library_uses) <= set(self.reference):
            raise ValueError(f"check {self.name!r}: library_uses must be part of reference, got {self.library_uses!r}")
        if type(self.gates) is not int or not 1 <= self.gates <= max(1, len(self.props)):
            raise ValueError(f"check {self.name!r}: gates must be an int in 1..{max(1, len(self.props))} "
                             f"(at most the number of props), got {self.gates!r}")
        names = {p for p, _ in self.props}
        odd = [(p, w) for p, w in self.weights if p not in names or type(w) is not int or w < 1]
        if odd:
            raise ValueError(f"check {self.name!r}: weights must name properties with an int weight >= 1, got {odd}")
        unknown = [p for p, _ in self.hints if p not in names]
        if unknown:
            raise ValueError(f"check {self.name!r}: hints name unknown properties {unknown}; properties: {sorted(names)}")

    def ladder(self, prop: str) -> tuple:
        """The hints for property ``prop`` (its own, else the shared ones for its kind), in order."""
        from coursekit.grading.checks.properties import HINTS

        own = dict(self.hints).get(prop)
        return tuple(own) if own else HINTS.get(prop, ())


@dataclass
class Judgement:
    """The verdicts on one check and the points they earn."""

    check: Check
    attempted: bool
    verdicts: list
    score: float
    printed: str = ""  # what the function printed (formative feedback only)

    @property
    def passed(self) -> bool:
        return self.attempted and all(v.passed for v in self.verdicts)


class NotRun(Exception):
    """A property needs the outputs of a case on which the function failed."""


class Context:
    """What a property function sees: the cases (decoded) and the plain outputs of those that ran."""

    def __init__(self, cases, records):
        self.cases = {c["id"]: c for c in cases}
        self.records = records

    def case(self, cid):
        return self.cases[cid]

    def arg(self, cid, i):
        """Positional argument ``i`` of case ``cid`` as a Python/numpy value (rng args give None)."""
        a = self.cases[cid]["args"][i]
        if isinstance(a, dict):
            if "ndarray" in a:
                return np.array(a["ndarray"], dtype=np.dtype(a["dtype"]))
            if "object" in a:  # the grader's own import of the library, never the student's kernel
                from coursekit.grading.values import library_attr

                return library_attr(a["object"]).from_json(a["json"])
            return None
        return a

    def kwarg(self, cid, name, default=None):
        return self.cases[cid].get("kwargs", {}).get(name, default)

    def out(self, cid):
        """The list of plain outputs of case ``cid`` (one per seed); :class:`NotRun` if it failed."""
        rec = self.records.get(cid)
        if rec is None or rec.get("status") != STATUS_OK:
            raise NotRun(cid)
        return rec["outputs"]

    def record(self, cid):
        self.out(cid)
        return self.records[cid]


def describe_object(v) -> str:
    """An object argument (``{"object": "module:Class", "json": ...}``, the grader's own case data) in a
    few words: the object's own short repr (``Creature(4 nodes, 2 brain neurons)``), never its JSON."""
    name = v["object"].rpartition(":")[2]
    try:
        data = json.loads(v["json"])
    except (TypeError, ValueError):
        data = None
    if isinstance(data, dict) and isinstance(data.get("paths"), list):  # centre-of-mass paths (exercise 08)
        paths = data["paths"]
        return f"{name}: {len(paths)} creature{'s' * (len(paths) != 1)}, {len(paths[0]) if paths else 0} samples each"
    try:
        from coursekit.grading.values import library_attr

        text = repr(library_attr(v["object"]).from_json(v["json"]))
    except Exception:  # noqa: BLE001 -- a description only
        text = ""
    if isinstance(data, dict) and isinstance(data.get("ode"), str):  # a counting right-hand side (exercise 07)
        return f"{name}({data['ode']!r})"
    return text if text and len(text) <= 160 and "\n" not in text and " object at 0x" not in text else f"{name}(...)"


def describe_value(v):
    """A short description of an argument value for messages."""
    if isinstance(v, dict) and v.get("rng") is True:
        return None
    if isinstance(v, dict) and "object" in v:
        return describe_object(v)
    if isinstance(v, dict) and "function" in v:
        return v["function"].replace(":", ".")
    if isinstance(v, dict) and "ndarray" in v:
        a = np.array(v["ndarray"], dtype=np.dtype(v["dtype"]))
        return np.array2string(a, threshold=12, edgeitems=4, precision=3, separator=", ")
    return repr(v)


def describe_call(check: Check, case: dict, call: int = 0) -> str:
    """``tournament(fitness=array([...]), k=20, rng=np.random.default_rng(7), size=3)``."""
    seed = case["seeds"][min(call, len(case["seeds"]) - 1)]
    parts = []
    for name, v in zip(check.params, case["args"]):
        d = describe_value(v)
        parts.append(f"{name}=np.random.default_rng({seed})" if d is None else f"{name}={d}")
    parts += [f"{k}={describe_value(v)}" for k, v in case.get("kwargs", {}).items()]
    return f"{check.function}({', '.join(parts)})"


_FAILURE = {
    "error": "raised {error}",
    "timeout": "did not return in time ({error}); is there an infinite loop?",
    "died": "stopped the process: {error}",
    "bad_output": "returned something unusable: {error}",
    "missing": "could not be called: {error}",
}


def judge(check: Check, cases: list, records: dict) -> Judgement:
    """Turn the plain records of one check (``records[case_id]``) into verdicts and points.

    Used identically by formative ``check(...)`` and by the summative grader.
    """
    recs = [records.get(c["id"]) or {"status": "timeout", "error": "no result came back"} for c in cases]
    if any(r.get("status") == "not_implemented" for r in recs):
        msg = f"not attempted yet: {check.function} raises NotImplementedError. Replace that line with your code and run the cell again."
        return Judgement(check, False, [Verdict("attempted", False, msg)], 0.0)
    if all(r.get("status") == "missing" for r in recs):
        return Judgement(check, False, [Verdict("attempted", False, f"not attempted: {recs[0].get('error', '')}")], 0.0)
    verdicts = []
    bad = [(c, r) for c, r in zip(cases, recs) if r.get("status") != STATUS_OK]
    if bad:
        c, r = bad[0]
        how = _FAILURE.get(r.get("status"), "failed: {error}").format(error=r.get("error", "?"))
        more = f" (and failed on {len(bad) - 1} more test inputs)" if len(bad) > 1 else ""
        verdicts.append(Verdict("runs", False, f"{describe_call(check, c, r.get('call', 0))} {how}{more}"))
    else:
        calls = sum(len(c["seeds"]) for c in cases)
        verdicts.append(Verdict("runs", True, f"ran on {len(cases)} test inputs ({calls} calls)"))
    ctx = Context(cases, records)
    closed = None  # the first gate that failed: nothing after it is judged
    for i, (prop, fn) in enumerate(check.props):
        if closed is not None:
            ok, msg = False, f"not checked until {closed!r} holds"
        else:
            try:
                ok, msg = fn(ctx)
            except NotRun as exc:
                ok, msg = False, f"not checked: it needs the result for test input {exc.args[0]!r}, which failed"
            except Exception as exc:  # a malformed output the property did not foresee: fail, never crash grading
                ok, msg = False, f"could not be checked on this output ({type(exc).__name__})"
            if not ok and i < check.gates:
                closed = prop
        verdicts.append(Verdict(prop, bool(ok), msg, dict(check.weights).get(prop, 1)))
    total = sum(v.weight for v in verdicts)
    score = 0.0 if closed is not None else check.points * sum(v.weight for v in verdicts if v.passed) / total
    return Judgement(check, True, verdicts, round(score, 4))


REGISTRY: dict[str, Check] = {}
EXERCISES: dict[str, tuple[str, ...]] = {}


def register(check: Check) -> Check:
    """Add a check to the registry (names are unique)."""
    if check.name in REGISTRY:
        raise ValueError(f"check name {check.name!r} is already registered")
    REGISTRY[check.name] = check
    return check


def exercise(stem: str, names: list[str]) -> None:
    """Declare which checks grade the exercise notebook ``<stem>.ipynb``."""
    missing = [n for n in names if n not in REGISTRY]
    if missing:
        raise ValueError(f"exercise {stem!r}: unknown checks {missing}; registered: {sorted(REGISTRY)}")
    EXERCISES[stem] = tuple(names)


#: A check module: ``ex<NN>_<topic>`` grades the exercise notebook ``<NN>_<topic>.ipynb``.
CHECK_MODULE = re.compile(r"^ex(\d+_\w+)$")
_LOADED = False


def check_modules() -> list[str]:
    """The names of this package's check modules (``ex01_selection``, ...), found on disk, sorted."""
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if CHECK_MODULE.match(m.name))


def _load() -> None:
    """Import every check module once (each registers its checks and declares its exercise)."""
    global _LOADED
    if _LOADED:
        return
    for name in check_modules():
        importlib.import_module(f"{__name__}.{name}")
    _LOADED = True


def get(name: str) -> Check:
    """The check called ``name``; ``ValueError`` listing the known names otherwise."""
    if not isinstance(name, str):
        raise TypeError(f"check name must be a str, got {type(name).__name__}")
    _load()
    if name not in REGISTRY:
        raise ValueError(f"unknown check {name!r}; known checks: {', '.join(sorted(REGISTRY))}")
    return REGISTRY[name]


def for_notebook(stem: str) -> tuple[Check, ...]:
    """The checks that grade the exercise notebook with this file stem (e.g. ``"01_selection"``)."""
    _load()
    if stem not in EXERCISES:
        raise ValueError(f"no exercise is registered for notebook {stem!r}; known: {', '.join(sorted(EXERCISES))}")
    return tuple(REGISTRY[n] for n in EXERCISES[stem])
