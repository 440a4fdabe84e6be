"""Property builders shared by every exercise's checks: case helpers, determinism, inputs unchanged.

Part of the check registry (:mod:`coursekit.grading.checks`; seed paper section 4, exercises
checked and graded). Each builder returns a property function ``prop(ctx) -> (passed, message)``
for :class:`~coursekit.grading.checks.Check`. The properties judge what the grader observed on
the calls it sent (outputs, and every argument as it was after the call): determinism compares
the outputs of separate calls that got the same seed, and "inputs unchanged" looks at *every*
call of *every* case that ran, so a function cannot keep its side effects to the cases it
guesses are not looked at.

:func:`point` gives a check's weights so that the property that is the operator's definition
weighs half its points, and :func:`all_of` judges a definition of several parts as that one
property (exercises 01-03).
"""

from __future__ import annotations

import numpy as np

from coursekit.grading.runner import changed

#: The encoded ``rng`` argument: each call gets ``numpy.random.default_rng(seed)``.
RNG = {"rng": True}

#: The advice "inputs unchanged" gives for an argument that was modified, by kind of argument.
COPY_ARRAY = "work on a copy (e.g. {name}.copy())"
NEW_ARRAYS = "compute new arrays instead of updating it in place (e.g. no {name} += ...)"
COPY_OBJECT = "work on a copy (copy.deepcopy({name}) or {name}.copy())"
NEW_GENOME = "build and return a new Genome instead"


#: Hint ladders of the properties every check shares (see ``Check.hints``): a nudge first, then
#: where to look; never the answer.
HINTS = {
    "runs": ("The message names the exact call that failed, with its arguments and seed: paste that call into a cell "
             "and run it there, where you can print what happens.",
             "Shrink the input: try the smallest example that still fails and check each line of your function on it.",
             "An error raised inside numpy usually means an array of the wrong shape or dtype reached it: print "
             "x.shape and x.dtype just before the failing line."),
    "deterministic for a seed": (
        "Two calls with the same rng seed must return the same result.",
        "Every random number must come from the rng argument you are given: rng.random(), rng.integers(...), "
        "rng.choice(...), rng.permutation(...).",
        "Search your function (and the helpers it calls) for np.random. and random.: those draw from a global "
        "generator that the seed does not control."),
    "inputs unchanged": (
        "Your function changed an argument it was given; the caller (the evolution loop) still needs the original.",
        "Assignments like x[i] = ..., x += ..., x.sort() or list.append change the object in place.",
        "Copy first (x = x.copy(), or copy.deepcopy(x) for a genome or creature), or build the result as a new "
        "object (np.where, np.concatenate, a new list)."),
}
HINTS["input unchanged"] = HINTS["inputs unchanged"]


def seeds(rng, n: int) -> list[int]:
    """``n`` seeds for the calls of a case, drawn from the grader's generator."""
    return [int(s) for s in rng.integers(0, 2**31, size=n)]


def array(values, dtype: str = "float64") -> dict:
    """A numpy array argument, encoded as plain data."""
    return {"ndarray": np.asarray(values, dtype=dtype).tolist(), "dtype": dtype}


def repeated(seeds_: list, times: int) -> list:
    """Each of ``seeds_`` ``times`` times in a row: the seeds of a case that judges determinism."""
    return [s for s in seeds_ for _ in range(times)]


def deterministic(cid: str, parse=None):
    """The calls of case ``cid`` that got the same seed gave equal results; ``parse`` reads JSON outputs.

    A case that judges it repeats several seeds (:func:`repeated`): a function that draws part of
    its choices from a global generator and part from ``rng`` can land, for one seed, on a choice
    with a single possible outcome (a cut of a 2-long string, a rotation of 2 chromosomes), and
    several seeds make that unlikely; its inputs should leave every random choice several outcomes.
    """
    def prop(ctx):
        outs = [parse(o) if parse else o for o in ctx.out(cid)]
        first = {}
        for seed, out in zip(ctx.case(cid)["seeds"], outs):
            if first.setdefault(seed, out) != out:
                return False, ("two calls with the same seed gave different results; draw every random number from "
                               "the rng argument (no np.random.* or random.*)")
        return True, "same seed, same result"

    return prop


def all_of(*props):
    """A property that holds when every one of ``props`` holds, judged in order; it fails with the first
    failure's message (the parts of an operator's definition, judged as its one point)."""
    def prop(ctx):
        found = []
        for part in props:
            ok, message = part(ctx)
            if not ok:
                return False, message
            found.append(message)
        return True, "; ".join(found)

    return prop


def point(prop: str, props, weights=()) -> tuple:
    """The ``weights`` of a check whose property ``prop`` is the operator's *point*: its definition.

    The point weighs as much as all the other verdicts together ("runs" included), so an answer
    that gets the definition wrong keeps at most half the points however many details it gets
    right, and one that gets it right keeps at least half. Where the definition has several
    parts (interchange *or* clone, both drawn at random; one shared u for both children), the
    point judges them all and names the first that fails. Used by every check of exercises 01-03.

    Args:
        prop: the point's name, one of ``props``.
        props: the check's ``(name, fn)`` properties.
        weights: the other properties' weights where they count more than 1.
    """
    names = [p for p, _ in props]
    if prop not in names:
        raise ValueError(f"point: {prop!r} is not one of the properties {names}")
    w = dict(weights)
    return tuple(weights) + ((prop, 1 + sum(w.get(p, 1) for p in names if p != prop)),)


def unmodified(names: dict, advice: str, what: str = "the {name} argument", cids=None):
    """No call changed the arguments at ``names`` (``{position: name}``).

    Args:
        names: the positions of the array or object arguments to watch, and their names.
        advice: how to avoid it, formatted with ``name`` (e.g. :data:`COPY_ARRAY`).
        what: how the message names the argument, formatted with ``name``.
        cids: the cases to look at (default: every case that ran).
    """
    def prop(ctx):
        ids = list(cids) if cids is not None else [c for c in ctx.cases if (ctx.records.get(c) or {}).get("status") == "ok"]
        if not ids:
            return False, "not checked: no test input ran"
        for cid in ids:
            after = ctx.record(cid).get("inputs_after") or []
            args = ctx.case(cid)["args"]
            for i, name in names.items():
                if i >= len(after) or changed(after[i], args[i]):
                    return False, f"{what.format(name=name)} was modified; {advice.format(name=name)}"
        return True, f"inputs left unchanged on all {len(ids)} test inputs"

    return prop
