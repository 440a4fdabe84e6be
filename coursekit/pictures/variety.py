"""Pictures worth a look: a first generation and children that never waste a slot (sections 3.3, 3.4).

With the user as the fitness function (paper section 3.4) every picture on the screen costs a
judgement, so a slot that shows a flat, black, one-colour, plain (a wash, a faint gradient), faint
or washed-out (a grey mist, a pale pastel), dark, static or noisy (snow) picture, or a copy of its
parent or of a sibling, is a wasted click. Two cheap previews
prevent that; both render low-resolution thumbnails (:data:`PREVIEW`, 32 x 32) and never change
what the genomes are:

- :func:`random_population` draws random genomes (:meth:`Genome.random`, whose draw weights
  already favour colour and structure) and redraws those with a tiny coding part, those whose
  preview is *dull* (flat, black, one colour almost everywhere, plain, faint, dark or static,
  :func:`dull`) or
  repeats another picture of the population, and a greyscale one once (grey pictures stay, as a
  minority). A preview with little coherence between neighbouring pixels is rendered again at
  :data:`NOISY_SIZE` (64 x 64) and redrawn when it is *noisy* there (:func:`noisy`: snow, grain
  finer than the preview can tell from a fine texture).
- :func:`distinct_children` takes children from an operator and redraws those whose preview
  is within :data:`SAME` (mean absolute difference, 2/255) of a parent's or of another child's,
  and those duller than their liveliest parent (a grey noise bred on by ``round``,
  ``mod`` or a bit operation easily gives flat children: ``benchmarks/picture_variety.py``
  measures them along chains of evolve clicks). When the parents have too few distinct
  children to give (two siblings, a tiny coding part), it mutates the rest once more.
  Children are not judged :func:`noisy` (that takes a second render, at 64 x 64, on every
  click); fewer are, with no noisy parents in the first generation.

The operators themselves (:mod:`.operators`) already aim at the coding part, and count swapped
arguments of a commutative primitive (``plus``, ``times`` ...) as no change, so most children
pass at once; the preview catches what the genome cannot tell, such as a changed constant under
a ``round``. Both redraw a bounded number of times, in slot order, from the given ``rng``: the
same seed gives the same population, bit for bit.
"""

from __future__ import annotations

from typing import Any, Callable, Iterator, Sequence

import numpy as np

from .evaluate import render
from .genome import Genome
from .operators import coding

__all__ = ["PREVIEW", "SAME", "BLACK", "FLAT", "ONE_COLOUR", "PLAIN", "FAINT", "WASHED", "STATIC", "DARK", "LEVELS",
           "NOISY", "NOISY_SIZE", "NOISY_SCREEN", "MIN_NODES", "preview", "dull", "dullness", "variation", "faint",
           "dark", "static", "coherence", "noisy", "greyscale",
           "random_population", "distinct_children"]

PREVIEW = 32  # pixels of a preview's side
SAME = 2.0 / 255.0  # mean absolute difference under which two pictures look the same (on contact sheets of near pairs)
BLACK = 1.0 / 255.0  # a picture with no value above this is black
FLAT = 0.02  # a picture whose every channel has a standard deviation below this is flat
ONE_COLOUR = 0.9  # a picture with one colour on this share of its pixels is that colour, a speck or a line aside
PLAIN = 0.7  # a picture whose colours change by less than this across it (variation) is a wash or a faint gradient
FAINT = 0.05  # a picture whose every channel has a standard deviation below this is faint (a grey mist, a pale wash)
WASHED = (0.08, 0.6)  # ... below this, with a mean luminance of at least this, it is washed out (a pale pastel)
DARK = (0.2, 0.4)  # a picture with 95 % of its pixels under this luminance and this brightest channel is dark
STATIC = 0.05  # a picture whose neighbouring pixels correlate less than this (across or down) is static
NOISY = 0.2  # a picture whose neighbouring pixels at NOISY_SIZE correlate less than this in every direction is noisy
NOISY_SIZE = 64  # pixels of the side at which a picture is judged noisy
NOISY_SCREEN = 0.3  # previews less coherent than this are rendered at NOISY_SIZE to be judged (those of 117 of
#                     118 noisy pictures measured; about 7 % of the previews, +10 % time: benchmarks/NOTES.md)
LEVELS = 16  # levels per channel at which two colours count as one
MIN_NODES = 5  # coding chromosomes a random genome of a first generation has at least


def preview(genomes: Sequence[Genome], size: int = PREVIEW) -> np.ndarray:
    """Low-resolution renders ``(N, size, size, 3)`` of ``genomes`` (in this process)."""
    return render(list(genomes), size, workers=1)


def dull(images: np.ndarray, flat: float = FLAT, one_colour: float = ONE_COLOUR, plain: float = PLAIN) -> np.ndarray:
    """Per picture of ``images`` ``(N, H, W, 3)``: flat (every channel's standard deviation
    below ``flat``), black (no value above :data:`BLACK`), one colour (:data:`LEVELS` levels per
    channel) on at least the share ``one_colour`` of its pixels (a black field with a few
    specks or one thin line has a high standard deviation and is still not worth a click),
    plain (its colours change by less than ``plain`` across it, :func:`variation`: a wash or a
    faint gradient), faint or washed out (:func:`faint`: little contrast, a fine texture in a
    grey mist or a pale pastel), dark (:func:`dark`: a dim shape on black, a murky field) or
    static (:func:`static`: pixels uncorrelated with their neighbours)."""
    return dullness(images, flat, one_colour, plain) > 0


def dullness(images: np.ndarray, flat: float = FLAT, one_colour: float = ONE_COLOUR, plain: float = PLAIN) -> np.ndarray:
    """Per picture of ``images``, how dull (:func:`dull`) it is: 2 when flat, black or one colour,
    1 when only plain, faint, dark or static, 0 when worth a look."""
    n = len(images)
    pixels = images.reshape(n, -1, 3)
    empty = ((pixels.std(axis=1).max(axis=1) < flat)
             | (pixels.reshape(n, -1).max(axis=1) <= BLACK)
             | (_commonest_share(pixels) >= one_colour))
    lesser = (variation(images) < plain) | faint(images) | dark(images) | static(images)
    return np.where(empty, 2, lesser.astype(np.int64))


def faint(images: np.ndarray, below: float = FAINT, washed: tuple[float, float] = WASHED) -> np.ndarray:
    """Per picture of ``images`` ``(N, H, W, 3)``: faint, too little contrast to show its
    structure. Every channel's standard deviation is below ``below`` (a grey mist, a pale
    wash with a fine texture, which :func:`variation` counts as busy), or below ``washed[0]``
    while its mean luminance (Rec. 601) is at least ``washed[1]``: washed out, a pale pastel
    (thresholds chosen on contact sheets of first generations: ``benchmarks/NOTES.md``)."""
    im = np.nan_to_num(np.asarray(images, dtype=np.float64)).reshape(len(images), -1, 3)
    if im.shape[1] == 0:
        return np.zeros(len(im), bool)
    spread = im.std(axis=1).max(axis=1)
    light = (im @ np.array([0.299, 0.587, 0.114])).mean(axis=1) >= washed[1]
    return (spread < below) | ((spread < washed[0]) & light)


def static(images: np.ndarray, below: float = STATIC) -> np.ndarray:
    """Per picture of ``images`` ``(N, H, W, 3)``: static, pixels that owe nothing to their
    neighbours (a ``dissolve`` of single cells, a ``round`` of noise). The correlation of
    neighbouring pixels, the better of across and down, weighted over the channels by their
    variance, is below ``below``; a texture, stripes or a swirl correlate along one direction at
    least (threshold chosen on a contact sheet of the 40 least correlated of 240 random pictures:
    ``benchmarks/NOTES.md``; independent noise at 32 x 32 scores about 0.02)."""
    c, var = _correlations(images)
    return (c[:, :2].max(axis=1) * var).sum(axis=1) / var.sum(axis=1) < below if c.size else np.zeros(len(c), bool)


def coherence(images: np.ndarray) -> np.ndarray:
    """Per picture of ``images`` ``(N, H, W, 3)``: how much its neighbouring pixels have in
    common, the correlation of each pixel with its neighbour in the best of four directions
    (across, down and the two diagonals), weighted over the channels by their variance. Near 1
    for a smooth picture, about 0 for independent noise (``1 - coherence`` is half the mean
    squared difference of neighbours over the variance: the share of the variance at the
    finest scale, in the direction where it is least); stripes, lines and a checkerboard of
    cells of a few pixels score high along one direction at least. 1 for a flat picture (no
    variance) and one of fewer than 2 x 2 pixels."""
    c, var = _correlations(images)
    if not c.size:
        return np.ones(len(c))
    best = ((c * var[:, None]).sum(axis=2) / var.sum(axis=1)[:, None]).max(axis=1)
    return np.where(var.sum(axis=1) > 1e-10, best, 1.0)


def noisy(images: np.ndarray, below: float = NOISY) -> np.ndarray:
    """Per picture of ``images`` ``(N, H, W, 3)``, rendered at :data:`NOISY_SIZE`: noisy, snow
    (grain at the scale of single pixels dominates it: its :func:`coherence` is under
    ``below``). Chosen on contact sheets at the gallery's 96 px of 1,200 first-generation
    pictures (60 seeds of 20) ranked by their coherence at 64 x 64: of the 44 under 0.2, 37
    were snow (pixel noise, a shape half drowned in it), 2 borderline and 5 not (ornamental
    rings, a fine grey texture, a few lines among specks); of the 42 from 0.2 to 0.3, 15 were
    snow and most others fine textures, swirls and line drawings worth a click
    (``benchmarks/NOTES.md``). Independent noise scores about 0, noise of cells of two pixels
    about 0.5 (coarser grain, which :func:`static` finds in the 32 x 32 preview); stripes, a
    checkerboard of cells of three pixels or more, and fine detail with a direction score
    higher. At 96 x 96 the
    same pictures score higher (grain of cells a little larger than a pixel there): the
    judgement is always made at :data:`NOISY_SIZE`, whatever the size shown."""
    return coherence(images) < below


def _correlations(images: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per picture and channel, the correlation of neighbouring pixels across, down and along
    the two diagonals ``(N, 4, 3)`` (``(N, 0, 3)`` for a picture of fewer than 2 x 2 pixels),
    and the channels' variances ``(N, 3)``."""
    im = np.nan_to_num(np.asarray(images, dtype=np.float64))
    if im.ndim != 4 or im.shape[1] < 2 or im.shape[2] < 2:
        return np.zeros((len(im), 0, 3)), np.ones((len(im), 3))
    x = im - im.mean(axis=(1, 2), keepdims=True)
    var = (x * x).mean(axis=(1, 2)) + 1e-12
    pairs = ((x[:, :, 1:], x[:, :, :-1]), (x[:, 1:], x[:, :-1]), (x[:, 1:, 1:], x[:, :-1, :-1]),
             (x[:, 1:, :-1], x[:, :-1, 1:]))
    return np.stack([(a * b).mean(axis=(1, 2)) / var for a, b in pairs], axis=1), var


def dark(images: np.ndarray, luminance: float = DARK[0], brightest: float = DARK[1]) -> np.ndarray:
    """Per picture of ``images`` ``(N, H, W, 3)``: dark, a dim shape on black or a murky field.
    Its 95th percentiles of luminance (Rec. 601) and of the brightest channel are below
    ``luminance`` and ``brightest``: a deep blue at full strength is dim by luminance only, and
    vivid (thresholds chosen on contact sheets of random pictures: ``benchmarks/NOTES.md``)."""
    im = np.nan_to_num(np.asarray(images, dtype=np.float32)).reshape(len(images), -1, 3)
    lum = im @ np.array([0.299, 0.587, 0.114], dtype=np.float32)
    return ((np.percentile(lum, 95, axis=1) < luminance)
            & (np.percentile(im.max(axis=2), 95, axis=1) < brightest)) if len(im) else np.zeros(0, bool)


def variation(images: np.ndarray) -> np.ndarray:
    """Per picture of ``images`` ``(N, H, W, 3)``: how much its busiest channel changes across and
    down it -- the mean absolute difference of neighbouring pixels times the side, horizontally
    plus vertically -- in full ranges per picture width. A ramp from black to white scores 1, a
    sharp edge between two colours their difference, a texture or a pattern many; it does not
    depend on the resolution for a smooth picture."""
    im = np.nan_to_num(np.asarray(images, dtype=np.float64))
    across = np.abs(np.diff(im, axis=2)).mean(axis=(1, 2)) * (im.shape[2] - 1) if im.shape[2] > 1 else 0.0
    down = np.abs(np.diff(im, axis=1)).mean(axis=(1, 2)) * (im.shape[1] - 1) if im.shape[1] > 1 else 0.0
    return np.max(across + down, axis=1)


def _commonest_share(pixels: np.ndarray) -> np.ndarray:
    """Per picture of ``pixels`` ``(N, P, 3)`` in [0, 1]: the share of its pixels in its commonest colour."""
    n, p = pixels.shape[:2]
    if p == 0:
        return np.zeros(n)
    q = np.clip(np.rint(np.nan_to_num(np.asarray(pixels, np.float64)) * (LEVELS - 1)), 0, LEVELS - 1).astype(np.int64)
    colour = (q[..., 0] * LEVELS + q[..., 1]) * LEVELS + q[..., 2] + LEVELS**3 * np.arange(n)[:, None]
    return np.bincount(colour.ravel(), minlength=n * LEVELS**3).reshape(n, -1).max(axis=1) / p


def greyscale(images: np.ndarray, tolerance: float = 0.02) -> np.ndarray:
    """Per picture: the mean over pixels of (largest - smallest channel) is below ``tolerance``."""
    n = len(images)
    return (images.max(axis=3) - images.min(axis=3)).reshape(n, -1).mean(axis=1) < tolerance


def _distance(pic: np.ndarray, refs: list[np.ndarray]) -> float:
    """Smallest mean absolute difference between ``pic`` and any of ``refs`` (inf if none)."""
    if not refs:
        return float("inf")
    return float(np.abs(np.stack(refs) - pic[None]).mean(axis=(1, 2, 3)).min())


def _previews(genomes: list[Genome], known: dict, size: int) -> np.ndarray:
    """Previews of ``genomes`` through ``known`` (expression -> preview): those of
    expressions not in it are rendered (each once) and added."""
    keys = [coding(g) for g in genomes]
    todo = {}
    for k, g in zip(keys, genomes):
        if k not in known:
            todo.setdefault(k, g)
    if todo:
        known.update(zip(todo, preview(list(todo.values()), size)))
    return np.stack([known[k] for k in keys]) if keys else np.empty((0, size, size, 3), np.float32)


def random_population(rng: np.random.Generator, n: int, *, tries: int = 8, size: int = PREVIEW,
                      min_nodes: int = MIN_NODES, **genome_params: Any) -> list[Genome]:
    """``n`` random genomes whose pictures are worth a look.

    Slot by slot, a genome (:meth:`Genome.random` with ``genome_params``) is redrawn while its
    coding part has fewer than ``min_nodes`` chromosomes (too small to breed: its mutants are
    few and mostly alike), or its preview at ``size`` is dull (:func:`dull`) or within
    :data:`SAME` of another slot's accepted picture, at
    most ``tries`` times; a greyscale preview (:func:`greyscale`) is redrawn once. A preview
    that passes with a :func:`coherence` under :data:`NOISY_SCREEN` is rendered again at
    :data:`NOISY_SIZE` and redrawn when it is :func:`noisy` there (a preview of 32 x 32 cannot
    tell snow from a fine texture: both alias into noise; a few noisy pictures, 5 of 8,000 over
    400 seeds, have a more coherent preview and stay). Redraws are
    batched per round, in slot order, so the result depends only on ``rng``'s state.

    Example:
        >>> pop = random_population(np.random.default_rng(0), 4)
        >>> bool(dull(preview(pop)).any())
        False
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"n: {n!r} must be an integer >= 0")
    if isinstance(tries, bool) or not isinstance(tries, (int, np.integer)) or tries < 0:
        raise ValueError(f"tries: {tries!r} must be an integer >= 0")
    if isinstance(min_nodes, bool) or not isinstance(min_nodes, (int, np.integer)) or min_nodes < 0:
        raise ValueError(f"min_nodes: {min_nodes!r} must be an integer >= 0")
    genomes = [Genome.random(rng, **genome_params) for _ in range(n)]
    accepted: dict[int, np.ndarray] = {}
    pending = list(range(n))
    for attempt in range(tries + 1):
        fresh = preview([genomes[i] for i in pending], size) if pending else []
        is_dull, is_grey = dull(np.asarray(fresh)), greyscale(np.asarray(fresh))
        if attempt < tries:  # snow: the passing previews that may be noise, judged at NOISY_SIZE
            screen = [k for k, (i, pic) in enumerate(zip(pending, fresh)) if not is_dull[k]
                      and not (is_grey[k] and attempt == 0) and genomes[i].size() >= min_nodes]
            screen = [k for k, c in zip(screen, coherence(np.asarray([fresh[k] for k in screen]))) if c < NOISY_SCREEN]
            if screen:
                is_dull[screen] |= noisy(preview([genomes[pending[k]] for k in screen], NOISY_SIZE))
        still = []
        for i, pic, bad, grey in zip(pending, fresh, is_dull, is_grey):
            if (bad or (grey and attempt == 0) or genomes[i].size() < min_nodes
                    or _distance(pic, list(accepted.values())) < SAME) and attempt < tries:
                still.append(i)
            else:
                accepted[i] = pic
        if not still:
            break
        for i in still:
            genomes[i] = Genome.random(rng, **genome_params)
        pending = still
    return genomes


def distinct_children(parents: Sequence[Genome], children: Iterator, n: int, *,
                      again: Callable[[Genome, list], Genome] | None = None,
                      mutate: Callable[[Genome], Genome] | None = None, tries: int = 8, draws: int = 4,
                      size: int = PREVIEW) -> list:
    """``n`` children from the iterator ``children`` that look different from ``parents`` and
    from each other.

    Each child is drawn (at most ``draws`` times, a cheap test on the genome) until its
    expression (:func:`~coursekit.pictures.operators.coding`) is not one already there: a
    parent's or another child's. The ``n`` children are then previewed at ``size``; slot by
    slot, one within :data:`SAME` (mean absolute difference) of a parent or of an already
    accepted child, or one duller than its liveliest parent (:func:`dullness`: flat, black or one
    colour, then plain, faint, dark or static), is drawn again, at most ``tries`` rounds (what is left then is
    the slot's best draw: a lively one before a flat one, then the most different); each
    distinct expression is previewed once (a picture depends on nothing else).

    When the parents have fewer distinct children than there are slots (two siblings, a small
    coding part), drawing from ``children`` again gives only copies. So a slot draws, in turn:

    1. from ``children``;
    2. ``again(c, accepted)``, when given, from round ``tries // 4`` on (``tries // 2`` without
       ``mutate``): the operator applied once more to the rejected child ``c``
       (``accepted``: the children kept so far). The gallery crosses ``c`` with a parent or an
       accepted sibling (more of the parents' material, with another split: the paper repeats
       crossover "with a different head and tail separation"), or repeats the mutation;
    3. ``mutate(c)``, when given, from round ``tries // 2`` on: the slot's child as it was
       then, mutated once more, new material when the parents' own is spent. Such a slot draws
       ``draws`` mutants of that child a round and keeps the first that passes (a mutation may
       well change a part of the tree the picture does not show).

    A slot goes on to the next of these at once when its ``draws`` draws gave only expressions
    already there. If anything drawn is not a :class:`Genome` (a student's operator gone wrong),
    the children are returned unchecked for the caller to report.
    """
    if not all(isinstance(p, Genome) for p in parents):
        return [next(children) for _ in range(n)]
    seen = {coding(p) for p in parents}
    accepted: list[Genome] = []
    stages = [lambda c: next(children)]
    if again is not None:
        stages.append(lambda c: again(c, list(accepted)))
    if mutate is not None:
        stages.append(mutate)
    starts = [0, tries // 4 if mutate is not None else tries // 2, tries // 2][:len(stages)]
    stage = [0] * n  # each slot's stage: an index into ``stages``

    base: dict[int, Genome] = {}  # slot -> the child its mutants are made from

    def draw(i: int, rejected):
        """A child for slot ``i``: at most ``draws`` draws of its stage for an expression not
        there yet, the next stage (on ``rejected``, else the last draw) when they give none."""
        while True:
            if mutate is not None and stage[i] == len(stages) - 1:
                rejected = base.setdefault(i, rejected)  # mutated once, not once more each round
            for _ in range(max(1, draws)):
                kid = stages[stage[i]](rejected)
                if not isinstance(kid, Genome):
                    return kid
                key = coding(kid)
                if key not in seen:
                    seen.add(key)
                    return kid
            if stage[i] + 1 == len(stages):
                return kid
            stage[i] += 1
            rejected = kid if rejected is None else rejected

    kids: list = []
    while len(kids) < n:
        kids.append(draw(len(kids), None))
        if not isinstance(kids[-1], Genome):
            return kids + [next(children) for _ in range(n - len(kids))]
    if not kids:
        return kids
    refs = list(preview(parents, size)) if parents else []
    level = int(dullness(np.asarray(refs)).min()) if parents else 0  # a child is no duller than its liveliest parent
    # a picture depends on the expression only: each distinct one is previewed once (a child
    # drawn again may repeat a rejected expression, or a parent's)
    previews = {coding(p): pic for p, pic in zip(parents, refs)}
    pending = list(range(n))
    candidates = {i: [kids[i]] for i in pending}  # each pending slot's draws this round, in order
    best: dict[int, tuple] = {}  # slot -> (lively, distance), child, preview: its best draw so far
    for attempt in range(tries + 1):
        drawn = [c for i in pending for c in candidates[i]]
        pics = _previews(drawn, previews, size)
        flat = dullness(pics) > level
        still, k = [], 0
        for i in pending:
            top = None  # the slot's best draw of this round
            for kid, pic, bad in zip(candidates[i], pics[k:], flat[k:]):
                score = (not bad, min(_distance(pic, refs), SAME))
                if top is None or score > top[0]:
                    top = score, kid, pic
                if score[0] and score[1] >= SAME:
                    break
            k += len(candidates[i])
            score, kids[i], pic = top
            if score[0] and score[1] >= SAME:
                refs.append(pic)
                accepted.append(kids[i])
            elif attempt < tries:
                if i not in best or score > best[i][0]:
                    best[i] = top
                still.append(i)
            else:  # out of tries: the slot's best draw (a lively near-copy rather than a flat one)
                if i in best:
                    (was_lively, _), kid, old = best[i]
                    if (was_lively, min(_distance(old, refs), SAME)) > score:
                        kids[i], pic = kid, old
                refs.append(pic)
                accepted.append(kids[i])
        if not still:
            break
        for i in still:
            stage[i] = max(stage[i], sum(attempt + 1 >= s for s in starts) - 1)
            mutating = mutate is not None and stage[i] == len(stages) - 1
            candidates[i] = [draw(i, kids[i]) for _ in range(max(1, draws) if mutating else 1)]
            if not all(isinstance(c, Genome) for c in candidates[i]):
                kids[i] = next(c for c in candidates[i] if not isinstance(c, Genome))
                return kids
        pending = still
    return kids
