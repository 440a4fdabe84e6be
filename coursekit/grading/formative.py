"""Formative checks inside an exercise notebook: ``check("ga.tournament", tournament)``.

Seed paper section 4: students get immediate, friendly feedback on their GA operators before the
operators drive the real system. The check generates its cases (seeded), calls the student's
function through :mod:`coursekit.grading.runner` (each call in a forked, memory-limited worker
killed after ``timeout`` seconds), judges with the same :func:`coursekit.grading.checks.judge`
the summative grader uses, and prints one line per property. Messages describe what the function
did and what the specification asks; they never print the solution. Formative checks run in the
student's own kernel, so they are feedback only: marks come from ``coursekit grade``.

After a ``check(...)``, ``hint(...)`` climbs a hint ladder for the first property that does not
hold, one rung per call, in the manner of Kaggle's learntools (``q.check()``, ``q.hint()``): a
nudge, then where to look, then a concrete pointer -- never the solution.
"""

from __future__ import annotations

import numpy as np
from collections.abc import Callable

from coursekit.grading import checks, runner

#: Formative and summative graders use different cases (different seeds) on purpose.
FORMATIVE_SEED = 20260101


def evaluate(name: str, function: Callable, *, timeout: float = 10.0, seed: int = FORMATIVE_SEED,
             memory_mb: int = 2048) -> checks.Judgement:
    """Run check ``name`` on ``function`` and return the :class:`~coursekit.grading.checks.Judgement`.

    Args:
        name: registered check name, e.g. ``"ga.tournament"``.
        function: the student's function.
        timeout: seconds allowed per call.
        seed: seed of the generator that makes the test inputs.
        memory_mb: extra memory a call may allocate.
    """
    check = checks.get(name)
    if not callable(function):
        raise TypeError(f"check({name!r}, function): function must be callable, got {type(function).__name__}")
    if not (isinstance(timeout, (int, float)) and timeout > 0):
        raise ValueError(f"timeout must be a positive number of seconds, got {timeout!r}")
    cases = check.cases(np.random.default_rng(seed))
    records = runner.run_cases(function, cases, check.output, timeout=float(timeout), memory_mb=memory_mb)
    judgement = checks.judge(check, cases, {r["case"]: r for r in records})
    judgement.printed = next((r["printed"] for r in records if r.get("printed")), "")
    _LAST[name] = judgement
    return judgement


#: The last judgement of each check in this kernel, and how far up its hint ladders the student went.
_LAST: dict = {}
_RUNG: dict = {}


def format_judgement(j: checks.Judgement) -> str:
    """The text a student sees for one judgement."""
    head = f"{j.check.name} ({j.check.title})"
    if not j.attempted:
        return f"{head}: {j.verdicts[0].message}"
    n = sum(v.passed for v in j.verdicts)
    lines = [f"{head}: {n}/{len(j.verdicts)} properties hold" + (" -- well done!" if j.passed else "")]
    lines += [f"  {'✓' if v.passed else '✗'} {v.label}: {v.message}" for v in j.verdicts]
    if j.printed:
        lines.append("  your function printed (first test input):\n    " + j.printed.rstrip().replace("\n", "\n    "))
    return "\n".join(lines)


def check(name: str, function: Callable, *, timeout: float = 10.0) -> None:
    """Check your function against the exercise's specification and print a verdict per property.

    Args:
        name: the check's name, e.g. ``"ga.tournament"``.
        function: your function.
        timeout: seconds allowed per call.
    """
    print(format_judgement(evaluate(name, function, timeout=timeout)))


def next_hint(name: str) -> str:
    """The next hint for check ``name``: for its first property that does not hold, one rung higher each call."""
    check = checks.get(name)
    j = _LAST.get(name)
    if j is None:
        return f"Run check({name!r}, {check.function}) first: the hint is for what it finds."
    if not j.attempted:
        return (f"{check.function} is not written yet. Start from its docstring: what does it receive, and what must "
                f"it return? Write the simplest version that returns something of that shape, then check it.")
    failing = next((v for v in j.verdicts if not v.passed and not v.message.startswith("not checked")), None)
    if failing is None:
        return f"All properties of {name} hold: no hint needed."
    ladder = check.ladder(failing.prop)
    if not ladder:
        return (f"'{failing.prop}' does not hold: {failing.message}\nRe-read what the exercise asks for this property "
                "and test your function on the call the message shows.")
    rung = _RUNG.get((name, failing.prop), 0)
    _RUNG[(name, failing.prop)] = min(rung + 1, len(ladder))
    if rung >= len(ladder):
        return (f"That was the last hint for '{failing.prop}' ({len(ladder)} of {len(ladder)}): {ladder[-1]}\n"
                "Re-read the lesson's section on it, or ask your instructor.")
    return f"Hint {rung + 1} of {len(ladder)} for '{failing.prop}': {ladder[rung]}"


def hint(name: str) -> None:
    """Print the next hint for check ``name`` (run ``check(name, function)`` first).

    Each call climbs one rung of the hint ladder for the first property that does not hold; the
    hints guide, they never print the answer.
    """
    print(next_hint(name))
