"""Genotype of a genetic picture: chromosome strings, head/tail and the PreHeader (paper section 3.1).

A **genome** is several **chromosome strings** of constant length plus a **PreHeader**.

- A *chromosome* is one primitive with its parameter values (:class:`Chromosome`).
- A *string* has a head of ``h`` chromosomes (any primitive) followed by a tail of
  ``t = h (n - 1) + 1`` chromosomes (ZeroArgChrom only), ``n`` being the largest arity of the
  primitive set (2 here, so ``t = h + 1``). With that rule every string decodes to a complete
  tree whatever its chromosomes, so operators never need repair. Strings are ring lists: the
  operators rotate them.
- The *PreHeader* is a ring of head chromosomes, the root tree of the genome. It links any
  number ``s`` of strings: decoding reads the PreHeader followed by the ``s`` string roots as
  one more Karva string whose tail *is* the strings, so it holds ``(s - 1) / (n - 1)``
  chromosomes (``s - 1`` here). Unlike a fixed-arity linker (geppy) this works for any ``s``.

**Reading order (Karva, as in Gene Expression Programming).** A string is read breadth-first:
position 0 is the root; the arguments of the nodes of one level are the next chromosomes in
the string, left to right. Reading stops when every node has its arguments; the chromosomes
read form the *open reading frame* (the coding part), the rest are non-coding but kept, and
can become active after a mutation (:attr:`Genome.active`).

Example with ``h = 2`` (``t = 3``): ``plus sin | x y const`` decodes to
``(plus (sin y) x)``: ``plus`` takes ``sin`` and ``x``, then ``sin`` takes ``y``; ``const``
is non-coding.
"""

from __future__ import annotations

import json
import math
import operator
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, ClassVar, Iterable, Sequence

import numpy as np

from . import primitives as P

__all__ = ["Chromosome", "ChromosomeString", "Genome", "Node", "FORMAT", "random_chromosome"]

FORMAT = "coursekit.genome/1"
FLOAT32_MAX = float(np.finfo(np.float32).max)  # the evaluator's numbers are float32
MAX_DEPTH = 100  # levels of an expression tree (deeper ones would exhaust Python's stack)


class _CachedHash:
    """Hashes an immutable value once (genomes are dictionary keys again and again: the
    operators' caches, the gallery's). What is cached on the object (the hash, decoded trees:
    attributes starting with ``_``) never travels in a pickle: string hashes differ between
    processes, and the rest is made again where needed."""

    __slots__ = ()
    _FIELDS: ClassVar[Callable]  # operator.attrgetter of the dataclass fields, in their order

    def __hash__(self):
        try:
            return self.__dict__["_hash"]
        except KeyError:
            h = hash(self._FIELDS(self))
            object.__setattr__(self, "_hash", h)
            return h

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if not k.startswith("_")}


@dataclass(frozen=True)
class Chromosome(_CachedHash):
    """One primitive and its parameter values (floats, in the primitive's declared order)."""

    __hash__ = _CachedHash.__hash__  # in the body, so that dataclass keeps it
    _FIELDS = operator.attrgetter("symbol", "params")

    symbol: str
    params: tuple[float, ...] = ()

    def __post_init__(self):
        prim = P.get(self.symbol)
        raw = tuple(self.params)
        if len(raw) != len(prim.params):
            raise ValueError(f"chromosome {self.symbol!r}: params has {len(raw)} values, "
                             f"expected {len(prim.params)} ({', '.join(p.name for p in prim.params)})")
        params = []
        for spec, v in zip(prim.params, raw):
            try:
                f = float(v)
            except OverflowError:
                f = math.inf
            except (TypeError, ValueError):
                raise ValueError(f"chromosome {self.symbol!r}: {spec.name} = {v!r} is not a number") from None
            if not math.isfinite(f) or abs(f) > FLOAT32_MAX:
                shown = f"{v:.3g}" if isinstance(v, float) else (repr(v) if len(repr(v)) < 30 else f"{repr(v)[:20]}...")
                raise ValueError(f"chromosome {self.symbol!r}: {spec.name} = {shown} must be finite and at most "
                                 f"{FLOAT32_MAX:.4g} in size (the evaluator's float32; random values lie in "
                                 f"[{spec.low:g}, {spec.high:g}])")
            params.append(f)
        object.__setattr__(self, "params", tuple(params))

    @property
    def arity(self) -> int:
        """Number of arguments of this chromosome's primitive."""
        return P.arity(self.symbol)

    @classmethod
    def random(cls, rng: np.random.Generator, symbol: str) -> "Chromosome":
        """A chromosome of ``symbol`` with parameters drawn uniformly from their ranges."""
        return cls(symbol, tuple(float(rng.uniform(p.low, p.high)) for p in P.get(symbol).params))

    def param(self, name: str) -> float:
        """The value of the parameter called ``name``."""
        for spec, value in zip(P.get(self.symbol).params, self.params):
            if spec.name == name:
                return value
        raise KeyError(name)

    def label(self) -> str:
        """``symbol`` or ``(symbol p1 p2 ...)``, parameters with 4 significant digits."""
        if not self.params:
            return self.symbol
        return "(" + " ".join([self.symbol] + [f"{v:.4g}" for v in self.params]) + ")"


def _check_chromosomes(seq, where: str) -> tuple[Chromosome, ...]:
    seq = tuple(seq)
    for i, c in enumerate(seq):
        if not isinstance(c, Chromosome):
            raise TypeError(f"{where}[{i}]: expected a Chromosome, got {type(c).__name__}")
    return seq


@dataclass(frozen=True)
class ChromosomeString(_CachedHash):
    """A string of ``head_length + tail_length`` chromosomes; the tail holds terminals only."""

    __hash__ = _CachedHash.__hash__  # in the body, so that dataclass keeps it
    _FIELDS = operator.attrgetter("head_length", "chromosomes")

    head_length: int
    chromosomes: tuple[Chromosome, ...]

    def __post_init__(self):
        h = self.head_length
        if isinstance(h, bool) or not isinstance(h, (int, np.integer)) or h < 1:
            raise ValueError(f"head_length: {h!r} must be an integer >= 1")
        object.__setattr__(self, "head_length", int(h))
        chroms = _check_chromosomes(self.chromosomes, "chromosomes")
        expected = self.head_length + self.tail_length
        if len(chroms) != expected:
            raise ValueError(f"chromosomes: length {len(chroms)} but head_length {h} needs "
                             f"{expected} (head {h} + tail {self.tail_length})")
        for i, c in enumerate(chroms[self.head_length:], self.head_length):
            if c.arity != 0:
                raise ValueError(f"chromosomes[{i}]: {c.symbol!r} (arity {c.arity}) is in the "
                                 f"tail, which allows only ZeroArgChrom primitives")
        object.__setattr__(self, "chromosomes", chroms)

    @property
    def tail_length(self) -> int:
        """t = h (n - 1) + 1."""
        return self.head_length * (P.max_arity() - 1) + 1

    @property
    def symbols(self) -> list[str]:
        """The primitive names of the string, head then tail."""
        return [c.symbol for c in self.chromosomes]

    @property
    def head(self) -> tuple[Chromosome, ...]:
        """The first ``head_length`` chromosomes (any primitive)."""
        return self.chromosomes[: self.head_length]

    @property
    def tail(self) -> tuple[Chromosome, ...]:
        """The last ``tail_length`` chromosomes (ZeroArgChrom only)."""
        return self.chromosomes[self.head_length:]

    def __len__(self) -> int:
        return len(self.chromosomes)

    def replace(self, chromosomes: Sequence[Chromosome]) -> "ChromosomeString":
        """A new string of the same head length holding ``chromosomes``."""
        return ChromosomeString(self.head_length, tuple(chromosomes))

    @classmethod
    def random(cls, rng: np.random.Generator, head_length: int, symbols: Sequence[str] | None = None,
               function_rate: float = 0.75, root: str = "head") -> "ChromosomeString":
        """A random string (see :meth:`Genome.random` for the arguments); ``root`` is the
        place (:func:`random_chromosome`) its first chromosome is drawn for."""
        if isinstance(head_length, bool) or not isinstance(head_length, (int, np.integer)) or head_length < 1:
            raise ValueError(f"head_length: {head_length!r} must be an integer >= 1")
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
        t = head_length * (P.max_arity() - 1) + 1
        head = [random_chromosome(rng, root if i == 0 else "head", symbols, function_rate)
                for i in range(head_length)]
        tail = [random_chromosome(rng, "tail", symbols) for _ in range(t)]
        return cls(head_length, tuple(head + tail))


def _symbol_pools(symbols):
    if symbols is None:
        symbols = P.names()
    if isinstance(symbols, str):
        raise TypeError(f"symbols: expected a list of primitive names, got the string {symbols!r} (write [{symbols!r}])")
    symbols = list(symbols)
    for s in symbols:
        P.get(s)
    funcs = [s for s in symbols if P.arity(s) > 0]
    terms = [s for s in symbols if P.arity(s) == 0]
    if not terms:
        raise ValueError(f"symbols: {symbols} has no ZeroArgChrom primitive for the tail")
    return funcs, terms


def _weighted(rng: np.random.Generator, pool: Sequence[str], weights: Sequence[float]) -> str:
    """One of ``pool`` with probability proportional to ``weights`` (uniform when all equal)."""
    w = np.asarray(weights, dtype=float)
    if not np.any(w > 0):
        w = np.ones(len(pool))
    if np.all(w == w[0]):
        return pool[int(rng.integers(len(pool)))]
    return pool[int(rng.choice(len(pool), p=w / w.sum()))]


def random_chromosome(rng: np.random.Generator, place: str, symbols: Sequence[str] | None = None,
                      function_rate: float = 0.75) -> Chromosome:
    """A random chromosome valid for ``place``.

    Args:
        rng: the random generator.
        place: ``'tail'`` (ZeroArgChrom only), ``'head'`` (a function with probability
            ``function_rate``, else a terminal), ``'pre'`` (PreHeader: functions only when
            the set has any) or ``'root'`` (the root of a random genome: a function, drawn by
            the primitives' ``root`` weights).
        symbols: primitive names to draw from (default: all primitives). Within a kind
            (function or terminal) a primitive is drawn in proportion to its ``weight``
            (:mod:`.primitives`: colour leaves more often, stock photos and ``time`` less).
        function_rate: probability of a function at a head position.
    """
    funcs, terms = _symbol_pools(symbols)
    if place == "tail":
        pool = terms
    elif place == "head":
        if isinstance(function_rate, bool) or not isinstance(function_rate, (int, float, np.integer, np.floating)) or not 0.0 <= function_rate <= 1.0:
            raise ValueError(f"function_rate: {function_rate!r} must lie in [0, 1]")
        pool = funcs if funcs and rng.random() < function_rate else terms
    elif place == "pre":
        pool = funcs or terms
    elif place == "root":
        pool = funcs or terms
        return Chromosome.random(rng, _weighted(rng, pool, [P.get(s).root if funcs else P.get(s).weight
                                                            for s in pool]))
    else:
        raise ValueError(f"place: {place!r}; allowed: 'head', 'tail', 'pre', 'root'")
    return Chromosome.random(rng, _weighted(rng, pool, [P.get(s).weight for s in pool]))


@dataclass(frozen=True)
class Node:
    """A decoded expression-tree node; ``site`` is ``('pre', i)`` or ``(string, position)``."""

    chromosome: Chromosome
    children: tuple["Node", ...]
    site: tuple

    @property
    def symbol(self) -> str:
        return self.chromosome.symbol

    @property
    def params(self) -> tuple[float, ...]:
        return self.chromosome.params

    def sexpr(self) -> str:
        """This subtree as an s-expression."""
        if not self.children:
            return self.chromosome.label()
        head = " ".join([self.symbol] + [f"{v:.4g}" for v in self.params])
        return "(" + head + " " + " ".join(c.sexpr() for c in self.children) + ")"

    def structure(self) -> tuple:
        """The tree's shape and symbols without parameters (genomes sharing it batch together)."""
        return (self.symbol,) + tuple(c.structure() for c in self.children)

    def walk(self) -> Iterator[Node]:
        """All nodes of the subtree, depth first."""
        yield self
        for c in self.children:
            yield from c.walk()

    def size(self) -> int:
        """Number of nodes of the subtree."""
        return sum(1 for _ in self.walk())


def karva(items: Sequence, arity_of: Callable[[Any], int]) -> tuple[list[tuple[int, ...]], int]:
    """Breadth-first (Karva) reading: children index lists per item and the ORF length."""
    children: list[tuple[int, ...]] = [()] * len(items)
    level, nxt = [0], 1
    while level:
        new_level = []
        for i in level:
            a = arity_of(items[i])
            children[i] = tuple(range(nxt, nxt + a))
            new_level.extend(children[i])
            nxt += a
        level = new_level
    return children, nxt


def _levels(children: list[tuple[int, ...]]) -> int:
    """Depth of the Karva tree rooted at 0 given its children lists (iterative)."""
    depth, stack = 0, [(0, 1)]
    while stack:
        i, d = stack.pop()
        depth = max(depth, d)
        stack.extend((j, d + 1) for j in children[i])
    return depth


@dataclass(frozen=True)
class Genome(_CachedHash):
    """Chromosome strings linked by a PreHeader. Immutable: operators build new genomes."""

    __hash__ = _CachedHash.__hash__  # in the body, so that dataclass keeps it
    _FIELDS = operator.attrgetter("strings", "preheader")

    strings: tuple[ChromosomeString, ...]
    preheader: tuple[Chromosome, ...] = ()

    def __post_init__(self):
        if isinstance(self.strings, (ChromosomeString, str)) or not hasattr(self.strings, "__iter__"):
            raise TypeError(f"strings: expected a list of ChromosomeStrings (e.g. Genome([s])), got {type(self.strings).__name__}")
        strings = tuple(self.strings)
        if not strings:
            raise ValueError("strings: a genome needs at least one chromosome string")
        for i, s in enumerate(strings):
            if not isinstance(s, ChromosomeString):
                raise TypeError(f"strings[{i}]: expected a ChromosomeString, got {type(s).__name__}")
        pre = _check_chromosomes(self.preheader, "preheader")
        n = P.max_arity()
        if (len(strings) - 1) % (n - 1):
            raise ValueError(f"strings: {len(strings)} strings cannot be linked by a PreHeader of "
                             f"arity-{n} chromosomes; need 1 + k*{n - 1}")
        need = (len(strings) - 1) // (n - 1)
        if len(pre) != need:
            raise ValueError(f"preheader: {len(pre)} chromosomes but {len(strings)} strings need "
                             f"exactly {need}")
        object.__setattr__(self, "strings", strings)
        object.__setattr__(self, "preheader", pre)
        if len(pre) + max(s.head_length for s in strings) + 1 > MAX_DEPTH:  # else no tree can be deeper
            depth = self.depth()
            if depth > MAX_DEPTH:
                raise ValueError(f"genome: its expression is {depth} levels deep; at most {MAX_DEPTH} are allowed")

    def depth(self) -> int:
        """Levels of the expression tree (a terminal alone: 1), counted without recursion."""
        levels = {}
        for k, s in enumerate(self.strings):
            kids, _ = karva(s.chromosomes, lambda c: c.arity)
            levels[k] = _levels(kids)
        items = list(self.preheader) + list(range(len(self.strings)))
        kids, _ = karva(items, lambda it: 0 if isinstance(it, int) else it.arity)
        depth, stack = 0, [(0, 1)]
        while stack:
            i, d = stack.pop()
            it = items[i]
            if isinstance(it, int):
                depth = max(depth, d - 1 + levels[it])
            else:
                depth = max(depth, d)
                stack.extend((j, d + 1) for j in kids[i])
        return depth

    # ---- construction -------------------------------------------------------------------
    @classmethod
    def random(cls, rng: np.random.Generator, *, n_strings: int = 3, head_length: int = 4,
               symbols: Sequence[str] | None = None, function_rate: float = 0.75) -> "Genome":
        """A random genome.

        Args:
            rng: the random generator.
            n_strings: number of chromosome strings (>= 1); the PreHeader gets ``n_strings - 1``.
            head_length: h of every string (>= 1); the tail is ``h + 1``.
            symbols: primitive names to draw from (default: all); tails use its ZeroArgChrom
                members only.
            function_rate: probability that a head chromosome is a function (the rest are
                terminals). PreHeader chromosomes start as functions so every string links in;
                mutations may later put terminals there.
        Returns:
            A valid :class:`Genome`. Its root (the first PreHeader chromosome, or the root of
            the only string) is a function drawn by the primitives' ``root`` weights, the
            other chromosomes by their ``weight`` (:mod:`.primitives`), so that random
            pictures are mostly coloured and structured. For a first generation that is also
            never flat, black or one colour, use :func:`coursekit.pictures.variety.random_population`.
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
        if isinstance(n_strings, bool) or not isinstance(n_strings, (int, np.integer)) or n_strings < 1:
            raise ValueError(f"n_strings: {n_strings!r} must be an integer >= 1")
        n_pre = (n_strings - 1) // (P.max_arity() - 1)
        strings = tuple(ChromosomeString.random(rng, head_length, symbols, function_rate,
                                                root="root" if k == 0 and n_pre == 0 else "head")
                        for k in range(n_strings))
        pre = tuple(random_chromosome(rng, "root" if i == 0 else "pre", symbols) for i in range(n_pre))
        return cls(strings, pre)

    # ---- decoding -----------------------------------------------------------------------
    def _string_tree(self, k: int) -> Node:
        s = self.strings[k]
        # kept with the string: a child shares most of its strings with its parent
        trees = s.__dict__.get("_trees")
        if trees is None or trees[0] != P.REDEFINED:
            trees = (P.REDEFINED, {})
            object.__setattr__(s, "_trees", trees)
        tree = trees[1].get(k)
        if tree is None:
            kids, _ = karva(s.chromosomes, lambda c: c.arity)

            def build(i):
                return Node(s.chromosomes[i], tuple(build(j) for j in kids[i]), (k, i))
            tree = trees[1][k] = build(0)
        return tree

    def decode(self) -> Node:
        """The expression tree (PreHeader read first, then the string roots as its tail).

        Decoded once (trees are immutable): the genome keeps its tree, and each string the
        tree of it (shared by the genomes that hold the string), until a primitive is
        redefined (:func:`~.primitives.register_primitive` with ``replace=True``)."""
        cached = self.__dict__.get("_tree")
        if cached is not None and cached[0] == P.REDEFINED:
            return cached[1]
        items = list(self.preheader) + list(range(len(self.strings)))
        kids, _ = karva(items, lambda it: 0 if isinstance(it, int) else it.arity)

        def build(i):
            it = items[i]
            if isinstance(it, int):
                return self._string_tree(it)
            return Node(it, tuple(build(j) for j in kids[i]), ("pre", i))
        tree = build(0)
        object.__setattr__(self, "_tree", (P.REDEFINED, tree))
        return tree

    @property
    def active(self) -> dict:
        """Coding sites: ``{'pre': [i, ...], 0: [positions], 1: [...], ...}``, sorted."""
        out: dict = {"pre": []}
        for k in range(len(self.strings)):
            out[k] = []
        for node in self.decode().walk():
            out[node.site[0]].append(node.site[1])
        return {k: sorted(v) for k, v in out.items()}

    def expression(self) -> str:
        """Readable s-expression of the coding part, e.g. ``(plus (sin x) (const 0.42))``."""
        return self.decode().sexpr()

    def size(self) -> int:
        """Number of coding chromosomes (nodes of the expression tree)."""
        return self.decode().size()

    # ---- display ------------------------------------------------------------------------
    #: Side of the picture a notebook shows for a genome (``_repr_png_``), in pixels.
    REPR_SIZE = 160
    #: ``genome -> PNG bytes`` for notebooks, set by :mod:`.gallery` (the renderer sits above
    #: genomes: they do not import it); ``None``: no picture.
    picture_png: ClassVar = None

    def __repr__(self) -> str:
        """Short: the shape and the start of the expression (``to_json`` has everything).

        >>> Genome.random(np.random.default_rng(0), n_strings=1, head_length=1)
        Genome(1 string, head 1, 3 coding chromosomes: (divide y (const 0.01653)))
        """
        n, k = len(self.strings), self.size()
        expr = self.expression()
        if len(expr) > 60:
            expr = expr[:57] + "..."
        return (f"Genome({n} string{'s' * (n != 1)}, head {self.strings[0].head_length}, "
                f"{k} coding chromosome{'s' * (k != 1)}: {expr})")

    def _repr_png_(self) -> bytes | None:
        """The picture, for notebooks (``REPR_SIZE`` pixels square, rendered in this process)."""
        draw = type(self).picture_png
        return None if draw is None else draw(self)

    # ---- files --------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """The JSON-ready dict of :meth:`to_json`."""
        def chrom(c):
            return [c.symbol, list(c.params)]
        return {"format": FORMAT,
                "expression": self.expression(),  # for readers; ignored when loading
                "preheader": [chrom(c) for c in self.preheader],
                "strings": [{"head_length": s.head_length, "chromosomes": [chrom(c) for c in s.chromosomes]}
                            for s in self.strings]}

    def to_json(self, indent: int | None = None) -> str:
        """Versioned JSON (``"format": "coursekit.genome/1"``); floats round-trip exactly.

        Holds ``preheader`` and ``strings`` (each ``head_length`` and ``chromosomes`` as
        ``[symbol, [params]]``), plus the readable ``expression`` of the coding part.
        """
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_dict(cls, d: dict) -> "Genome":
        """Inverse of :meth:`to_dict`; ValueError naming the broken field otherwise."""
        if not isinstance(d, dict):
            raise ValueError(f"genome: expected a JSON object, got {type(d).__name__}")
        if d.get("format") != FORMAT:
            raise ValueError(f"genome: format {d.get('format')!r} is not {FORMAT!r}")

        def chrom(v, where):
            if (not isinstance(v, list) or len(v) != 2 or not isinstance(v[0], str)
                    or not isinstance(v[1], list)
                    or not all(isinstance(p, (int, float)) and not isinstance(p, bool) for p in v[1])):
                raise ValueError(f"genome: {where} = {v!r} is not [symbol, [numbers]]")
            try:
                return Chromosome(v[0], tuple(v[1]))
            except ValueError as e:
                raise ValueError(f"genome: {where}: {e}") from None

        strings_in, pre_in = d.get("strings"), d.get("preheader")
        if not isinstance(strings_in, list) or not isinstance(pre_in, list):
            raise ValueError("genome: 'strings' and 'preheader' must be lists")
        strings = []
        for k, s in enumerate(strings_in):
            if not isinstance(s, dict) or not isinstance(s.get("chromosomes"), list):
                raise ValueError(f"genome: strings[{k}] must be an object with 'chromosomes'")
            chroms = [chrom(v, f"strings[{k}].chromosomes[{i}]") for i, v in enumerate(s["chromosomes"])]
            try:
                strings.append(ChromosomeString(s.get("head_length"), tuple(chroms)))
            except (ValueError, TypeError) as e:
                raise ValueError(f"genome: strings[{k}]: {e}") from None
        pre = [chrom(v, f"preheader[{i}]") for i, v in enumerate(pre_in)]
        try:
            return cls(tuple(strings), tuple(pre))
        except (ValueError, TypeError) as e:
            raise ValueError(f"genome: {e}") from None

    @classmethod
    def from_json(cls, text: str | bytes) -> "Genome":
        """Parse :meth:`to_json` output; ValueError for truncated, foreign or invalid text."""
        try:
            d = json.loads(text)
        except (json.JSONDecodeError, UnicodeDecodeError, TypeError) as e:
            raise ValueError(f"genome: not valid JSON ({e})") from None
        except RecursionError:
            raise ValueError("genome: the JSON is nested too deeply to be a genome") from None
        return cls.from_dict(d)

    def replace_string(self, k: int, string: ChromosomeString | Iterable[Chromosome]) -> "Genome":
        """A new genome with string ``k`` (or ``'pre'`` for the PreHeader) replaced."""
        if k == "pre":
            return Genome(self.strings, tuple(string))
        n = len(self.strings)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not -n <= k < n:
            raise ValueError(f"k: {k!r} must be 'pre' or the index of one of the {n} strings")
        strings = list(self.strings)
        old = strings[k]
        strings[k] = string
        if (type(string) is ChromosomeString and string.head_length == old.head_length
                and type(self) is Genome and len(self.preheader) + old.head_length + 1 <= MAX_DEPTH):
            # the operators' case (thousands per gallery click): this genome is valid, and a
            # valid string of the same head length keeps it valid (the same shape, and no
            # tree can be too deep), so only the new string needed checking (it was, when made)
            g = object.__new__(Genome)
            object.__setattr__(g, "strings", tuple(strings))
            object.__setattr__(g, "preheader", self.preheader)
            return g
        return Genome(tuple(strings), self.preheader)
