"""The paper's genetic operators on picture genomes (section 3.3).

Four mutations ``(genome, rng) -> genome`` (section 3.3.1) and three recombinations
``(a, b, rng) -> (child, child)`` (section 3.3.2). Every operator keeps the length of every
string and the head/tail rule (a tail position only ever receives a ZeroArgChrom), so every
result decodes without repair. Genomes are immutable, so inputs are never modified.

The PreHeader is a ring of head chromosomes: the mutations treat it as one more string that
has a head and no tail of its own (its tail is the strings it links). A mutation picks its
string uniformly among those it can act on.

Recombination pairs string ``k`` of one parent with string ``k`` of the other (and PreHeader
with PreHeader) where both have the same length; parents with no such pair are refused.

**Aimed at the coding part.** A change that lands in a non-coding chromosome (after a string's
open reading frame, or in a string the PreHeader does not reach) leaves the picture as it was:
drawn uniformly, two children in three of a gallery click looked like a parent or a sibling
(measured, issue 12). So every operator picks its sites among the coding ones where the genome
has any (a coding chromosome to replace, a head or tail with coding chromosomes to rotate, a
string pair that differs where a parent codes ...), and repeats its draw, at most
:data:`TRIES` times, while its result's expression (:func:`coding`) equals its input's (for a
recombination: until both children differ from both parents and from each other, else the
draw that came closest). The operation itself is the paper's, and non-coding chromosomes are
kept (they may code after a later mutation). Repeats use the same ``rng``, so a seed still
gives one result. Swapped arguments of a commutative primitive (``plus``, ``times`` ...) are no
change (:func:`coding`); changes the genome cannot see (a constant under ``round``) are left
to the gallery's preview (:mod:`.variety`).

Choices where the paper is silent (documented so students can reproduce them):

- transposition: the region (head without the root, or tail) is picked uniformly among those
  with at least two positions; interchange and clone are equally likely.
- root transposition: "replaced by a second chromosome" is an interchange of the root with
  that head chromosome; "or by a clone" copies it onto the root; equally likely.
- head/tail rotation: head or tail equally likely; a left rotation by 1..len-1 steps.
- crossover: one split position q in 1..L-1 of one string pair; ``splits`` repeats it with a
  new q on the same pair (two splits give two-point crossover).
- random copy: in each string pair, each child receives one chromosome of the other parent,
  from any position whose chromosome is valid at the (arbitrary) target position.
- random interpolation: one aligned position of a string pair is picked (preferring
  positions whose two chromosomes share a parameter); with ``u ~ U(0, 1)``, child one gets
  ``lerp(c_a, c_b, u)`` and child two ``lerp(c_b, c_a, u)``. ``lerp`` (:func:`lerp_chromosome`)
  interpolates every parameter the two primitives share by name (``(1 - u) p_a + u p_b``: a
  constant's value, a colour's RGB, a noise's frequency and lattice offsets, a blur's sigma
  ...) and takes the symbol - the discrete part of a function - and its other parameters
  from the nearer parent (``c_a`` when ``u < 0.5``).
"""

from __future__ import annotations

import functools
from typing import Sequence

import numpy as np

from . import primitives as P
from .genome import Chromosome, Genome, random_chromosome

__all__ = ["transposition", "root_transposition", "substitution", "head_tail_rotation",
           "crossover", "random_copy", "random_interpolation", "lerp_chromosome",
           "coding", "TRIES", "MUTATIONS", "RECOMBINATIONS"]


def _check(genome, name="genome"):
    if not isinstance(genome, Genome):
        raise TypeError(f"{name}: expected a Genome, got {type(genome).__name__}")


def _check_rng(rng):
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")


def _keys(g: Genome) -> list:
    return list(range(len(g.strings))) + (["pre"] if g.preheader else [])


def _get(g: Genome, k) -> tuple[list[Chromosome], int]:
    """Chromosomes of string ``k`` (or the PreHeader) and its head length."""
    if k == "pre":
        return list(g.preheader), len(g.preheader)
    s = g.strings[k]
    return list(s.chromosomes), s.head_length


_EDITED: dict = {}  # (id(string), ids of the new chromosomes) -> (string, new string)
_EDITED_MAX = 2048


def _put(g: Genome, k, chroms) -> Genome:
    """``g`` with the chromosomes of string ``k`` (or the PreHeader) replaced by ``chroms``.

    An operator repeats its draw (:data:`TRIES`) and the gallery applies it to the same
    parents again and again, so the same edit of the same string comes back: the new string
    is looked up by the identity of the old one and of the new chromosomes (an entry holds
    them all, so their ids stay theirs) and shared, with its hash and decoded tree. The
    genome is a new one every time: a session tells its children apart by identity."""
    if k == "pre":
        return g.replace_string("pre", chroms)
    old = g.strings[k]
    key = (id(old), *map(id, chroms))
    hit = _EDITED.get(key)
    if hit is None or hit[0] is not old:
        if len(_EDITED) >= _EDITED_MAX:
            _EDITED.clear()
        hit = _EDITED[key] = (old, old.replace(chroms))
    return g.replace_string(k, hit[1])


def _regions(g: Genome, k, with_root: bool) -> list[range]:
    chroms, h = _get(g, k)
    head = range(0 if with_root else 1, h)
    return [r for r in (head, range(h, len(chroms))) if len(r) >= 2]


def _pick(rng, seq):
    return seq[int(rng.integers(len(seq)))]


def _first(*candidates):
    """The first non-empty list of ``candidates`` (the last one when all are empty)."""
    for c in candidates:
        if c:
            return c
    return candidates[-1]


# ---- aiming at the coding part ------------------------------------------------------------

TRIES = 8
"""Draws an operator makes, at most, until its result's coding part differs from the inputs'."""


def _expressed(node, strings=None):
    """``(chromosome, (children's values ...))`` of the tree ``node``; with the genome's
    ``strings``, a string's part is kept with the string (a child shares most of its strings
    with its parent, and their decoded trees: :meth:`Genome.decode`)."""
    k, i = node.site
    if strings is not None and i == 0 and k != "pre":  # the root of string k
        s = strings[k]
        cached = s.__dict__.get("_expressed")
        if cached is not None and cached[0] is node:
            return cached[1]
        value = _expressed(node)
        object.__setattr__(s, "_expressed", (node, value))
        return value
    kids = tuple(_expressed(c, strings) for c in node.children)
    if len(kids) == 2 and P.get(node.symbol).commutative:
        kids = _in_order(*kids)
    return (node.chromosome, kids)


def _in_order(a: tuple, b: tuple) -> tuple:
    """The two arguments of a commutative node in an order that does not depend on which came
    first: by hash, then (two different values of one hash) by their text."""
    ha, hb = hash(a), hash(b)
    if ha < hb or (ha == hb and (a == b or repr(a) < repr(b))):
        return a, b
    return b, a


@functools.lru_cache(maxsize=4096)
def coding(genome: Genome) -> tuple:
    """The coding part of ``genome`` as a comparable value: equal for two genomes exactly when
    their expression trees are equal (same primitives, parameters and shape), whatever their
    non-coding chromosomes and the order of a commutative primitive's two arguments
    (:attr:`~.primitives.Primitive.commutative`: ``(plus x y)`` is ``(plus y x)``). It is
    hashable and compared within one process (the order of swapped arguments follows their
    hashes). (Kept for the last few thousand genomes: the gallery asks again
    and again about the same parents, and an operator repeating its draw makes the same
    children again.)"""
    return _expressed(genome.decode(), genome.strings)


@functools.lru_cache(maxsize=4096)
def _active(g: Genome) -> dict:
    return {k: frozenset(v) for k, v in g.active.items()}


def _mutated(genome, rng, draw) -> Genome:
    """``draw(genome, rng)`` until the coding part changes (at most :data:`TRIES` draws)."""
    _check_rng(rng)
    before = coding(genome)
    for _ in range(TRIES):
        child = draw(genome, rng)
        if coding(child) != before:
            return child
    return child


def _recombined(a, b, rng, draw) -> tuple[Genome, Genome]:
    """``draw(a, b, rng)`` until both children's coding parts differ from both parents' and
    from each other (at most :data:`TRIES` draws; otherwise the draw that came closest)."""
    _check_rng(rng)
    parents = (coding(a), coding(b))
    best, best_score = None, -1
    for _ in range(TRIES):
        ca, cb = draw(a, b, rng)
        xa, xb = coding(ca), coding(cb)
        score = (xa not in parents) + (xb not in parents) + (xa != xb)
        if score > best_score:
            best, best_score = (ca, cb), score
        if score == 3:
            break
    return best


# ---- mutations (section 3.3.1) ------------------------------------------------------------

# Where a mutation may act depends on the genome only: worked out once per genome (a mutation
# repeats its draw on the same genome, and the gallery mutates the same parents again and again).

@functools.lru_cache(maxsize=1024)
def _transposition_spots(genome: Genome) -> list:
    act = _active(genome)
    spots = [(k, r) for k in _keys(genome) for r in _regions(genome, k, with_root=False)]
    return _first([(k, r) for k, r in spots if act[k] & set(r)], spots)


def _transposition(genome: Genome, rng: np.random.Generator) -> Genome:
    act = _active(genome)
    k, region = _pick(rng, _transposition_spots(genome))
    chroms, _ = _get(genome, k)
    i = _pick(rng, _first([i for i in region if i in act[k]], list(region)))
    others = [j for j in region if j != i]
    j = _pick(rng, _first([j for j in others if chroms[j] != chroms[i]], others))
    if rng.random() < 0.5:
        chroms[i], chroms[j] = chroms[j], chroms[i]
    else:
        chroms[i] = chroms[j]
    return _put(genome, k, chroms)


def transposition(genome: Genome, rng: np.random.Generator) -> Genome:
    """Two chromosomes of one string, both in the head (never the root) or both in the tail,
    are interchanged, or the first is replaced by a clone of the second.

    Aimed at the coding part: the first chromosome is a coding one and the second differs
    from it (where the genome has such a pair), and the draw is repeated (at most
    :data:`TRIES` times) while the expression stays the same."""
    _check(genome)
    return _mutated(genome, rng, _transposition)


@functools.lru_cache(maxsize=1024)
def _root_keys(genome: Genome) -> list:
    act = _active(genome)
    keys = [k for k in _keys(genome) if _get(genome, k)[1] >= 2]
    return _first([k for k in keys if 0 in act[k]], keys)


def _root_transposition(genome: Genome, rng: np.random.Generator) -> Genome:
    k = _pick(rng, _root_keys(genome))
    chroms, h = _get(genome, k)
    j = _pick(rng, _first([j for j in range(1, h) if chroms[j] != chroms[0]], list(range(1, h))))
    if rng.random() < 0.5:
        chroms[0], chroms[j] = chroms[j], chroms[0]
    else:
        chroms[0] = chroms[j]
    return _put(genome, k, chroms)


def root_transposition(genome: Genome, rng: np.random.Generator) -> Genome:
    """The root of a string is interchanged with another head chromosome of the same string,
    or replaced by a clone of it. ValueError if no string has a head of length >= 2.

    Aimed at the coding part: a string whose root codes, a head chromosome that differs from
    the root, and the draw repeated (at most :data:`TRIES` times) while the expression stays
    the same."""
    _check(genome)
    if not any(_get(genome, k)[1] >= 2 for k in _keys(genome)):
        raise ValueError("root_transposition: needs a string or PreHeader with head length >= 2")
    return _mutated(genome, rng, _root_transposition)


@functools.lru_cache(maxsize=1024)
def _substitution_sites(genome: Genome) -> tuple[list, dict]:
    act = _active(genome)
    keys = _keys(genome)
    return (_first([k for k in keys if act[k]], keys),
            {k: _first(sorted(act[k]), list(range(len(_get(genome, k)[0])))) for k in keys})


def substitution(genome: Genome, rng: np.random.Generator, symbols: Sequence[str] | None = None) -> Genome:
    """A chromosome is replaced by a new random one valid for its place (head or tail).

    Aimed at the coding part: the chromosome is a coding one, and the draw is repeated (at
    most :data:`TRIES` times) while the expression stays the same.

    Args:
        symbols: primitive names the new chromosome may use (default: all).
    """
    _check(genome)

    def draw(genome, rng):
        keys, sites = _substitution_sites(genome)
        k = _pick(rng, keys)
        chroms, h = _get(genome, k)
        i = _pick(rng, sites[k])
        chroms[i] = random_chromosome(rng, "head" if i < h else "tail", symbols)
        return _put(genome, k, chroms)
    return _mutated(genome, rng, draw)


@functools.lru_cache(maxsize=1024)
def _rotation_spots(genome: Genome) -> list:
    act = _active(genome)
    spots = [(k, r) for k in _keys(genome) for r in _regions(genome, k, with_root=True)]

    def varied(k, r):
        part = _get(genome, k)[0][r.start:r.stop]
        return any(c != part[0] for c in part)
    return _first([(k, r) for k, r in spots if act[k] & set(r) and varied(k, r)],
                  [(k, r) for k, r in spots if varied(k, r)], spots)


def _head_tail_rotation(genome: Genome, rng: np.random.Generator) -> Genome:
    k, region = _pick(rng, _rotation_spots(genome))
    chroms, _ = _get(genome, k)
    part = chroms[region.start:region.stop]
    steps = int(rng.integers(1, len(part)))
    chroms[region.start:region.stop] = part[steps:] + part[:steps]
    return _put(genome, k, chroms)


def head_tail_rotation(genome: Genome, rng: np.random.Generator) -> Genome:
    """A string is split into head and tail, one of them rotated several steps, rejoined.

    Aimed at the coding part: a head or tail that holds coding chromosomes (and not only
    copies of one), and the draw repeated (at most :data:`TRIES` times) while the expression
    stays the same."""
    _check(genome)
    return _mutated(genome, rng, _head_tail_rotation)


# ---- recombinations (section 3.3.2) -------------------------------------------------------

def _pairs(a: Genome, b: Genome, min_len: int = 1) -> list:
    _check(a, "a")
    _check(b, "b")
    keys = [k for k in _keys(a) if k in _keys(b)
            and len(_get(a, k)[0]) == len(_get(b, k)[0]) >= min_len
            and _get(a, k)[1] == _get(b, k)[1]]
    if not keys:
        shape = lambda g: [len(s) for s in g.strings]  # noqa: E731
        raise ValueError(f"parents have no pair of strings of equal length: string lengths "
                         f"{shape(a)} and {shape(b)}")
    return keys


def _differ(sa, sb) -> list[int]:
    return [i for i, (x, y) in enumerate(zip(sa, sb)) if x is not y and x != y]


def crossover(a: Genome, b: Genome, rng: np.random.Generator, splits: int = 1) -> tuple[Genome, Genome]:
    """One position splits a pair of strings; the parts after it are exchanged.

    Aimed at the coding part: a pair of strings that differ where either parent codes, a split
    with differing chromosomes on both sides of it (where there are such), and the draw
    repeated (at most :data:`TRIES` times) until both children's expressions differ from both
    parents'.

    Args:
        splits: how many times to repeat it on the same pair with a new position (>= 1).
    """
    if isinstance(splits, bool) or not isinstance(splits, (int, np.integer)) or splits < 1:
        raise ValueError(f"splits: {splits!r} must be an integer >= 1")
    keys = _pairs(a, b, min_len=2)
    act_a, act_b = _active(a), _active(b)
    differ = {k: _differ(_get(a, k)[0], _get(b, k)[0]) for k in keys}
    candidates = _first([k for k in keys if set(differ[k]) & (act_a[k] | act_b[k])],
                        [k for k in keys if differ[k]], keys)

    def splits_of(d, n):
        return _first(list(range(min(d) + 1, max(d) + 1)) if d else [], list(range(1, n)))
    first = {k: splits_of(differ[k], len(_get(a, k)[0])) for k in candidates}  # the first split's choices

    def draw(a, b, rng):
        k = _pick(rng, candidates)
        q = _pick(rng, first[k])
        sa, sb = _get(a, k)[0], _get(b, k)[0]
        sa, sb = sa[:q] + sb[q:], sb[:q] + sa[q:]
        for _ in range(splits - 1):
            q = _pick(rng, splits_of(_differ(sa, sb), len(sa)))
            sa, sb = sa[:q] + sb[q:], sb[:q] + sa[q:]
        return _put(a, k, sa), _put(b, k, sb)
    return _recombined(a, b, rng, draw)


def random_copy(a: Genome, b: Genome, rng: np.random.Generator) -> tuple[Genome, Genome]:
    """In each string pair, a chromosome at an arbitrary position of one parent is copied to
    an arbitrary position of the other's child (a tail position only takes a terminal).

    Aimed at the coding part: the target position is a coding one of the receiving parent and
    the copied chromosome differs from the one it replaces (where possible), and the draw is
    repeated (at most :data:`TRIES` times) until both children's expressions differ from both
    parents'."""
    keys = _pairs(a, b)
    active = (_active(a), _active(b))

    def draw(a, b, rng):
        children = [a, b]
        for k in keys:
            for c, donor in ((0, b), (1, a)):
                target, h = _get(children[c], k)
                source, _ = _get(donor, k)
                i = _pick(rng, _first(sorted(active[c][k]), list(range(len(target)))))
                valid = [j for j, ch in enumerate(source) if i < h or ch.arity == 0]
                target[i] = source[_pick(rng, _first([j for j in valid if source[j] != target[i]], valid))]
                children[c] = _put(children[c], k, target)
        return children[0], children[1]
    return _recombined(a, b, rng, draw)


def lerp_chromosome(c: Chromosome, d: Chromosome, u: float) -> Chromosome:
    """Linear interpolation of two chromosomes (see the module docstring)."""
    base = c if u < 0.5 else d
    other = d if base is c else c
    other_params = {s.name: v for s, v in zip(P.get(other.symbol).params, other.params)}
    out = []
    for spec, v in zip(P.get(base.symbol).params, base.params):
        if spec.name in other_params:
            pc = v if base is c else other_params[spec.name]
            pd = other_params[spec.name] if base is c else v
            v = (1.0 - u) * pc + u * pd
        out.append(v)
    return Chromosome(base.symbol, tuple(out))


def random_interpolation(a: Genome, b: Genome, rng: np.random.Generator) -> tuple[Genome, Genome]:
    """Two chromosomes (one aligned position of a string pair) are linearly interpolated with
    a random parameter u; the children get lerp(a, b, u) and lerp(b, a, u).

    Aimed at the coding part: the position is picked among those where the two chromosomes
    differ, share a parameter and at least one codes (else the first there is of: differ and
    one codes; differ and share; differ; any), and the draw is repeated (at most
    :data:`TRIES` times) until both children's expressions differ from both parents'."""
    keys = _pairs(a, b)
    act_a, act_b = _active(a), _active(b)

    def shared(x, y):
        px = {p.name for p in P.get(x.symbol).params}
        return any(p.name in px for p in P.get(y.symbol).params)
    spots = [(k, i) for k in keys for i in range(len(_get(a, k)[0]))]
    row = {k: (_get(a, k)[0], _get(b, k)[0]) for k in keys}
    differ = [(k, i) for k, i in spots if row[k][0][i] != row[k][1][i]]
    blend = [(k, i) for k, i in differ if shared(row[k][0][i], row[k][1][i])]
    codes = lambda k, i: i in act_a[k] or i in act_b[k]  # noqa: E731
    candidates = _first([(k, i) for k, i in blend if codes(k, i)], [(k, i) for k, i in differ if codes(k, i)],
                        blend, differ, spots)

    def draw(a, b, rng):
        k, i = _pick(rng, candidates)
        sa, sb = list(row[k][0]), list(row[k][1])
        u = float(rng.random())
        x, y = row[k][0][i], row[k][1][i]
        sa[i], sb[i] = lerp_chromosome(x, y, u), lerp_chromosome(y, x, u)
        return _put(a, k, sa), _put(b, k, sb)
    return _recombined(a, b, rng, draw)


MUTATIONS = {"transposition": transposition, "root_transposition": root_transposition,
             "substitution": substitution, "head_tail_rotation": head_tail_rotation}
RECOMBINATIONS = {"crossover": crossover, "random_copy": random_copy,
                  "random_interpolation": random_interpolation}
