"""Creatures as grading cases: how they travel to the student's function and how its results are read.

Shared by the checks of exercise 05 (seed paper section 2: the creature operators; see
:mod:`~coursekit.grading.checks.ex05_creature_operators`). A creature argument is its JSON
(:func:`obj`), rebuilt with ``Creature.from_json`` next to the student's function; a result is
parsed and validated by the library (:func:`parse`), never trusted as given.
"""

from __future__ import annotations

import functools
import json

import numpy as np

CREATURE = "coursekit.creatures.genotype:Creature"
MAX_JSON = 2_000_000


def obj(creature):
    return {"object": CREATURE, "json": creature.to_json()}


def creature_cls():
    from coursekit.creatures.genotype import Creature

    return Creature


def random_creature(rng, **kw):
    """A random creature drawn from the library's generator, seeded from ``rng``."""
    return creature_cls().random(np.random.default_rng(int(rng.integers(2**31))), **kw)


@functools.lru_cache(maxsize=1024)
def parse(text):
    """A student's result as a Creature (validated by the library), or raise ValueError/TypeError.

    Cached by its text: the properties of a check read the same results many times (mutation's, 325
    results, about five times each) and never change them."""
    return creature_cls().from_json(text)


def valid_creatures(cids):
    def prop(ctx):
        for cid in cids:
            for k, text in enumerate(ctx.out(cid)):
                try:
                    parse(text)
                except (ValueError, TypeError) as exc:
                    return False, f"call {k + 1} on test input {cid!r} returned an invalid creature: {exc}"
        return True, "every result is a valid Creature"

    return prop


def body_signature(node) -> str:
    """A node's own attributes (not its links or networks): what recombination must keep."""
    d = node.to_dict()
    return json.dumps([d[k] for k in ("size", "joint_type", "joint_pos", "joint_axis", "limits", "force",
                                      "recursive_limit", "recursion")])
