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

from typing import Sequence

import numpy as np

from . import primitives as P
from .genome import Chromosome, Genome, random_chromosome

__all__ = ["transposition", "root_transposition", "substitution", "head_tail_rotation",
           "crossover", "random_copy", "random_interpolation", "lerp_chromosome",
           "MUTATIONS", "RECOMBINATIONS"]


def _check(genome, name="genome"):
    if not isinstance(genome, Genome):
        raise TypeError(f"{name}: expected a Genome, got {type(genome).__name__}")


def _keys(g: Genome) -> list:
    return list(range(len(g.strings))) + (["pre"] if g.preheader else [])


def _get(g: Genome, k) -> tuple[list[Chromosome], int]:
    """Chromosomes of string ``k`` (or the PreHeader) and its head length."""
    if k == "pre":
        return list(g.preheader), len(g.preheader)
    s = g.strings[k]
    return list(s.chromosomes), s.head_length


def _put(g: Genome, k, chroms) -> Genome:
    if k == "pre":
        return g.replace_string("pre", chroms)
    return g.replace_string(k, g.strings[k].replace(chroms))


def _regions(g: Genome, k, with_root: bool) -> list[range]:
    chroms, h = _get(g, k)
    head = range(0 if with_root else 1, h)
    return [r for r in (head, range(h, len(chroms))) if len(r) >= 2]


def _pick(rng, seq):
    return seq[int(rng.integers(len(seq)))]


# ---- mutations (section 3.3.1) ------------------------------------------------------------

def transposition(genome: Genome, rng: np.random.Generator) -> Genome:
    """Two chromosomes of one string, both in the head (never the root) or both in the tail,
    are interchanged, or the first is replaced by a clone of the second."""
    _check(genome)
    keys = [k for k in _keys(genome) if _regions(genome, k, with_root=False)]
    k = _pick(rng, keys)
    region = _pick(rng, _regions(genome, k, with_root=False))
    i, j = (int(v) for v in rng.choice(np.asarray(region), size=2, replace=False))
    chroms, _ = _get(genome, k)
    if rng.random() < 0.5:
        chroms[i], chroms[j] = chroms[j], chroms[i]
    else:
        chroms[i] = chroms[j]
    return _put(genome, k, chroms)


def root_transposition(genome: Genome, rng: np.random.Generator) -> Genome:
    """The root of a string is interchanged with another head chromosome of the same string,
    or replaced by a clone of it. ValueError if no string has a head of length >= 2."""
    _check(genome)
    keys = [k for k in _keys(genome) if _get(genome, k)[1] >= 2]
    if not keys:
        raise ValueError("root_transposition: needs a string or PreHeader with head length >= 2")
    k = _pick(rng, keys)
    chroms, h = _get(genome, k)
    j = int(rng.integers(1, h))
    if rng.random() < 0.5:
        chroms[0], chroms[j] = chroms[j], chroms[0]
    else:
        chroms[0] = chroms[j]
    return _put(genome, k, chroms)


def substitution(genome: Genome, rng: np.random.Generator, symbols: Sequence[str] | None = None) -> Genome:
    """A chromosome is replaced by a new random one valid for its place (head or tail).

    Args:
        symbols: primitive names the new chromosome may use (default: all).
    """
    _check(genome)
    k = _pick(rng, _keys(genome))
    chroms, h = _get(genome, k)
    i = int(rng.integers(len(chroms)))
    chroms[i] = random_chromosome(rng, "head" if i < h else "tail", symbols)
    return _put(genome, k, chroms)


def head_tail_rotation(genome: Genome, rng: np.random.Generator) -> Genome:
    """A string is split into head and tail, one of them rotated several steps, rejoined."""
    _check(genome)
    keys = [k for k in _keys(genome) if _regions(genome, k, with_root=True)]
    k = _pick(rng, keys)
    region = _pick(rng, _regions(genome, k, with_root=True))
    chroms, _ = _get(genome, k)
    part = chroms[region.start:region.stop]
    steps = int(rng.integers(1, len(part)))
    chroms[region.start:region.stop] = part[steps:] + part[:steps]
    return _put(genome, k, chroms)


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


def crossover(a: Genome, b: Genome, rng: np.random.Generator, splits: int = 1) -> tuple[Genome, Genome]:
    """One position splits a pair of strings; the parts after it are exchanged.

    Args:
        splits: how many times to repeat it on the same pair with a new position (>= 1).
    """
    if isinstance(splits, bool) or not isinstance(splits, (int, np.integer)) or splits < 1:
        raise ValueError(f"splits: {splits!r} must be an integer >= 1")
    k = _pick(rng, _pairs(a, b, min_len=2))
    sa, sb = _get(a, k)[0], _get(b, k)[0]
    for _ in range(splits):
        q = int(rng.integers(1, len(sa)))
        sa, sb = sa[:q] + sb[q:], sb[:q] + sa[q:]
    return _put(a, k, sa), _put(b, k, sb)


def random_copy(a: Genome, b: Genome, rng: np.random.Generator) -> tuple[Genome, Genome]:
    """In each string pair, a chromosome at an arbitrary position of one parent is copied to
    an arbitrary position of the other's child (a tail position only takes a terminal)."""
    children = [a, b]
    for k in _pairs(a, b):
        for c, donor in ((0, b), (1, a)):
            target, h = _get(children[c], k)
            source, _ = _get(donor, k)
            i = int(rng.integers(len(target)))
            valid = [j for j, ch in enumerate(source) if i < h or ch.arity == 0]
            target[i] = source[_pick(rng, valid)]
            children[c] = _put(children[c], k, target)
    return children[0], children[1]


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
    a random parameter u; the children get lerp(a, b, u) and lerp(b, a, u)."""
    k = _pick(rng, _pairs(a, b))
    sa, sb = _get(a, k)[0], _get(b, k)[0]

    def shared(i):
        pa = {p.name for p in P.get(sa[i].symbol).params}
        return any(p.name in pa for p in P.get(sb[i].symbol).params)
    positions = [i for i in range(len(sa)) if shared(i)] or list(range(len(sa)))
    i = _pick(rng, positions)
    u = float(rng.random())
    ca, cb = lerp_chromosome(sa[i], sb[i], u), lerp_chromosome(sb[i], sa[i], u)
    sa[i], sb[i] = ca, cb
    return _put(a, k, sa), _put(b, k, sb)


MUTATIONS = {"transposition": transposition, "root_transposition": root_transposition,
             "substitution": substitution, "head_tail_rotation": head_tail_rotation}
RECOMBINATIONS = {"crossover": crossover, "random_copy": random_copy,
                  "random_interpolation": random_interpolation}
