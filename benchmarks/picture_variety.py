"""Benchmark: are random pictures worth a look, and does every gallery slot show something new?

Prints one table for the two measurements of issue 12 (findings 1 and 2), on fixed seeds:

**Random pictures** (``--genomes`` genomes, default 600; genome ``i`` is the first genome drawn
from ``numpy.random.default_rng(i)``), rendered at 64 x 64 over the unit square, for
``Genome.random`` at its defaults and, when the library has one, for the gallery's first
generation (:func:`coursekit.pictures.variety.random_population`, one genome per seed):

- *flat*: every channel's standard deviation over the picture is below 0.02;
- *black*: no value above 1/255;
- *one colour*: one colour (16 levels per channel) covers at least 90 % of the pixels (a black
  field with specks or a thin line; flat pictures are one colour too);
- *greyscale*: the mean over pixels of (largest channel - smallest channel) is below 0.02;
- *plain*: its busiest channel changes by less than 0.7 full ranges across the picture (the mean
  absolute difference of neighbouring pixels times the side, across plus down): a pale wash or
  a faint gradient;
- *photo-dominated*: the picture's luminance correlates (``|Pearson r| > 0.5``) with the
  luminance of one of the scikit-image stock photos (each rendered alone as a ``pixmap``
  chromosome at the same size and window);
- *photo in tree*: the coding part holds a ``pixmap`` chromosome (an ingredient, seen or not);
- *dark*: 95 % of the pixels under 0.2 in luminance (Rec. 601) and under 0.4 in their brightest
  channel;
- *aliased*: the picture differs from a 4x supersampled render of it (256 x 256, box-averaged to
  64 x 64) by more than 0.1 (mean absolute difference): detail finer than its pixels, pixel
  noise at this size or, more often, a fine texture (this column was called *noisy* before
  2026-12-06);
- *noisy*: snow, grain at the scale of single pixels dominates the picture: the correlation of
  neighbouring pixels, in the best of four directions (across, down, the two diagonals),
  weighted over the channels by their variance, is below 0.2 (independent noise scores about 0,
  stripes and smooth pictures near 1);
- *pale*: every channel's standard deviation is below 0.05 (a grey mist, a faint wash), or
  below 0.08 with a mean luminance of at least 0.6 (washed out, a pale pastel).

**Children identical** (``--sessions`` sessions, default 30): session ``s`` starts a widget-free
gallery (:class:`~coursekit.pictures.gallery.Evolution`, 20 pictures, first generation as the
gallery makes it, ``default_rng(s)``), selects pictures ``s mod 20`` and ``(s + 7) mod 20`` and
clicks each of the seven operators once (undo in between, so every operator breeds from the same
two parents). Each of the 18 children per click is rendered at 64 x 64; it *repeats* when its
mean absolute difference to a parent or to an earlier child of the same click is below 1/255
(a wasted slot), and it is *identical to a parent or a sibling* when that holds for a parent or
for any other child of the click (the issue's definition: both children of a duplicate pair count).

**Children of siblings** (the same number of sessions): session ``s`` selects picture ``s mod 20``
of its first generation, mutates it by substitution, then selects two of those children (drawn
by ``default_rng(s)``) and recombines them by crossover, then (undo in between) by random
interpolation: the children *identical* to a parent or any sibling (1/255, as above) and *alike*
(3/255).

**Flat children** (the same sessions): the fraction of those children that are flat or black,
that are one colour, that are pale and that are noisy, and along a *chain*: session ``s`` evolves
(mixed operators) from one random picture, then from one random child of that, four times; the
same four fractions over the chain, and the plain children of the chain. These yardsticks are the benchmark's own, so that one script measures any version of the
library.

Usage: ``python benchmarks/picture_variety.py [--genomes 600] [--sessions 30]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from coursekit.cli import number
from coursekit.pictures import Genome, primitives, render
from coursekit.pictures.gallery import Evolution, GalleryState
from coursekit.pictures.genome import Chromosome, ChromosomeString

SIZE = 64
SAME = 1.0 / 255.0
ALIKE = 3.0 / 255.0  # mean absolute difference under which two pictures look alike on a contact sheet


def flat_or_black(images):
    """Per picture of ``images`` (N, H, W, 3): every channel's standard deviation below 0.02, or
    no value above 1/255."""
    n = len(images)
    return (images.reshape(n, -1, 3).std(axis=1).max(axis=1) < 0.02) | (images.reshape(n, -1).max(axis=1) <= SAME)


def plain_pictures(images, below=0.7):
    """Per picture: its busiest channel changes by less than ``below`` full ranges across it."""
    im = np.asarray(images, dtype=np.float64)
    across = np.abs(np.diff(im, axis=2)).mean(axis=(1, 2)) * (im.shape[2] - 1)
    down = np.abs(np.diff(im, axis=1)).mean(axis=(1, 2)) * (im.shape[1] - 1)
    return (across + down).max(axis=1) < below


def pale_pictures(images):
    """Per picture: every channel's standard deviation under 0.05, or under 0.08 with a mean
    luminance (Rec. 601) of at least 0.6."""
    n = len(images)
    spread = images.reshape(n, -1, 3).std(axis=1).max(axis=1)
    light = _luminance(images).reshape(n, -1).mean(axis=1) >= 0.6
    return (spread < 0.05) | ((spread < 0.08) & light)


def one_colour(images, share=0.9, levels=16):
    """Per picture: one colour (``levels`` per channel) on at least ``share`` of the pixels."""
    q = np.clip(np.rint(images * (levels - 1)), 0, levels - 1).astype(np.int64).reshape(len(images), -1, 3)
    colour = (q[..., 0] * levels + q[..., 1]) * levels + q[..., 2]
    return np.array([np.bincount(c).max() / c.size >= share for c in colour], dtype=bool)


def _render(genomes):
    return render(list(genomes), SIZE, workers=1)


def _luminance(images):
    return images @ np.array([0.299, 0.587, 0.114], dtype=np.float32)


def _photos():
    pics = [Genome((ChromosomeString(1, (Chromosome("pixmap", (i + 0.5,)), Chromosome("x"), Chromosome("y"))),))
            for i in range(len(primitives.PIXMAPS))]
    return _luminance(_render(pics)).reshape(len(pics), -1)


def picture_figures(images, photos):
    """Fractions (flat, black, one colour, greyscale, plain, photo-dominated) of ``images`` (N, H, W, 3)."""
    n = len(images)
    if n == 0:
        return [float("nan")] * 6
    flat = images.reshape(n, -1, 3).std(axis=1).max(axis=1) < 0.02
    black = images.reshape(n, -1).max(axis=1) <= SAME
    grey = (images.max(axis=3) - images.min(axis=3)).reshape(n, -1).mean(axis=1) < 0.02
    lum = _luminance(images).reshape(n, -1)
    lum = lum - lum.mean(axis=1, keepdims=True)
    ph = photos - photos.mean(axis=1, keepdims=True)
    norm = np.linalg.norm(lum, axis=1)[:, None] * np.linalg.norm(ph, axis=1)[None, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(norm > 1e-9, (lum @ ph.T) / np.maximum(norm, 1e-30), 0.0)
    photo = np.abs(r).max(axis=1) > 0.5
    return [float(v.mean()) for v in (flat, black, one_colour(images), grey, plain_pictures(images), photo)]


def with_photo(genomes):
    """Fraction of ``genomes`` whose coding part holds a ``pixmap`` (a stock photo)."""
    return float(np.mean([any(n.symbol == "pixmap" for n in g.decode().walk()) for g in genomes]))


def dark_pictures(images):
    """Per picture: 95 % of its pixels under 0.2 in luminance and under 0.4 in their brightest channel."""
    n = len(images)
    lum = _luminance(images).reshape(n, -1)
    return (np.percentile(lum, 95, axis=1) < 0.2) & (np.percentile(images.max(axis=3).reshape(n, -1), 95, axis=1) < 0.4)


def aliased_pictures(genomes, images):
    """Per picture: more than 0.1 (mean absolute difference) from a 4x supersampled render."""
    fine = render(list(genomes), 4 * SIZE, workers=1).reshape(len(genomes), SIZE, 4, SIZE, 4, 3).mean(axis=(2, 4))
    return np.abs(images - fine).mean(axis=(1, 2, 3)) > 0.1


def noisy_pictures(images, below=0.2):
    """Per picture: the correlation of neighbouring pixels, best of across, down and the two
    diagonals, weighted over the channels by their variance, is below ``below``."""
    x = np.asarray(images, dtype=np.float64)
    x = x - x.mean(axis=(1, 2), keepdims=True)
    var = (x * x).mean(axis=(1, 2)) + 1e-12
    pairs = ((x[:, :, 1:], x[:, :, :-1]), (x[:, 1:], x[:, :-1]), (x[:, 1:, 1:], x[:, :-1, :-1]), (x[:, 1:, :-1], x[:, :-1, 1:]))
    best = np.max([(a * b).mean(axis=(1, 2)).sum(axis=1) / var.sum(axis=1) for a, b in pairs], axis=0)  # the channels' correlations weighted by their variances
    return (best < below) & (var.sum(axis=1) > 1e-10)


def first_generation(rng, n):
    """The gallery's first generation, as this version of the library makes it."""
    try:
        from coursekit.pictures.variety import random_population
    except ImportError:
        return [Genome.random(rng) for _ in range(n)]
    return random_population(rng, n)


def children_figures(sessions, n=20):
    """(children checked, fraction repeating, fraction identical to a parent or sibling, and
    per operator the fraction identical)."""
    checked = repeats = identical = flat = single = alike = pale = noisy = 0
    per_op: dict = {}
    for s in range(sessions):
        rng = np.random.default_rng(s)
        ev = Evolution(GalleryState(first_generation(rng, n)), rng)
        picks = [s % n, (s + 7) % n]
        for name in list(ev.mutations) + list(ev.recombinations):
            for i in picks:
                ev.select(i, True)
            msg = ev.mutate(name) if name in ev.mutations else ev.recombine(name)
            assert msg.startswith("generation"), msg
            pics = _render(ev.state.population)
            parents, kids = pics[:2], pics[2:]
            for j, kid in enumerate(kids):
                d_par = [np.abs(kid - p).mean() for p in parents]
                d_sib = [np.abs(kid - k).mean() for m, k in enumerate(kids) if m != j]
                d_earlier = [np.abs(kid - k).mean() for k in kids[:j]]
                checked += 1
                repeats += min(d_par + d_earlier) < SAME
                identical += min(d_par + d_sib) < SAME
                alike += min(d_par + d_sib) < ALIKE
                flat += bool(flat_or_black(kid[None])[0])
                single += bool(one_colour(kid[None])[0])
                pale += bool(pale_pictures(kid[None])[0])
                noisy += bool(noisy_pictures(kid[None])[0])
                per_op.setdefault(name, []).append(min(d_par + d_sib) < SAME)
            ev.undo()
            ev.state.selected.clear()
    return (checked, repeats / checked, identical / checked, {k: float(np.mean(v)) for k, v in per_op.items()},
            flat / checked, single / checked, alike / checked, pale / checked, noisy / checked)


def sibling_figures(sessions, n=20):
    """(children checked, fraction identical to a parent or a sibling, fraction alike), per
    recombination, when the parents are two children of one substitution click."""
    out = {}
    for s in range(sessions):
        rng = np.random.default_rng(s)
        ev = Evolution(GalleryState(first_generation(rng, n)), rng)
        ev.select(s % n, True)
        assert ev.mutate("substitution").startswith("generation")
        a, b = (int(v) for v in np.random.default_rng(s).choice(np.arange(1, n), 2, replace=False))
        for name in ("crossover", "random_interpolation"):
            ev.select(a, True)
            ev.select(b, True)
            assert ev.recombine(name).startswith("generation")
            pics = _render(ev.state.population)
            d = np.abs(pics[:, None] - pics[None]).mean(axis=(2, 3, 4))
            np.fill_diagonal(d, np.inf)
            near = d.min(axis=1)[2:]
            c = out.setdefault(name, [0, 0, 0])
            c[0] += len(near)
            c[1] += int((near < SAME).sum())
            c[2] += int((near < ALIKE).sum())
            ev.undo()
            ev.state.selected.clear()
    return {k: (c[0], c[1] / c[0], c[2] / c[0]) for k, c in out.items()}


def chain_figures(sessions, n=20, depth=4):
    """Flat or black children, one-colour children and plain children, over chains of ``depth``
    evolve clicks, each from one random picture of the generation before (children checked, the
    three fractions)."""
    checked = flat = single = plain = pale = noisy = 0
    for s in range(sessions):
        rng = np.random.default_rng(1000 + s)
        ev = Evolution(GalleryState(first_generation(rng, n)), rng)
        for _ in range(depth):
            ev.select(int(rng.integers(1, n)) if ev.state.generation else int(rng.integers(n)), True)
            assert ev.next_generation().startswith("generation")
            kids = _render(ev.state.population[1:])
            checked += len(kids)
            flat += int(flat_or_black(kids).sum())
            single += int(one_colour(kids).sum())
            plain += int(plain_pictures(kids).sum())
            pale += int(pale_pictures(kids).sum())
            noisy += int(noisy_pictures(kids).sum())
    return checked, flat / checked, single / checked, plain / checked, pale / checked, noisy / checked


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--genomes", type=number(int, 1), default=600)
    ap.add_argument("--sessions", type=number(int, 0), default=30)
    args = ap.parse_args(argv)
    photos = _photos()
    rows = []
    t0 = time.perf_counter()
    plain = [Genome.random(np.random.default_rng(i)) for i in range(args.genomes)]
    pics = _render(plain)
    rows.append(("Genome.random (defaults)", picture_figures(pics, photos) + [with_photo(plain)]
                 + [float(dark_pictures(pics).mean()), float(aliased_pictures(plain, pics).mean()),
                    float(pale_pictures(pics).mean()), float(noisy_pictures(pics).mean())]))
    t1 = time.perf_counter()
    try:
        from coursekit.pictures.variety import random_population
    except ImportError:
        random_population = None
    if random_population is not None:
        first = [random_population(np.random.default_rng(i), 1)[0] for i in range(args.genomes)]
        t_first = time.perf_counter() - t1
        pics = _render(first)
        rows.append(("first generation (random_population)",
                     picture_figures(pics, photos) + [with_photo(first)]
                     + [float(dark_pictures(pics).mean()), float(aliased_pictures(first, pics).mean()),
                        float(pale_pictures(pics).mean()), float(noisy_pictures(pics).mean())]))
    t2 = time.perf_counter()
    children = children_figures(args.sessions) if args.sessions > 0 else None
    chain = chain_figures(args.sessions) if args.sessions > 0 else None
    sib = sibling_figures(args.sessions) if args.sessions > 0 else None
    t3 = time.perf_counter()
    print(f"random pictures: {args.genomes} genomes (seeds 0..{args.genomes - 1}) at {SIZE}^2")
    print(f"{'':38s} {'flat':>6s} {'black':>6s} {'1 col.':>6s} {'grey':>6s} {'plain':>6s} {'photo':>6s} {'photo in tree':>14s}"
          f" {'dark':>6s} {'alias.':>6s} {'pale':>6s} {'noisy':>6s}")
    for name, (flat, black, single, grey, plain_, photo, tree, dark, aliased, pale, noisy) in rows:
        print(f"{name:38s} {flat:6.1%} {black:6.1%} {single:6.1%} {grey:6.1%} {plain_:6.1%} {photo:6.1%} {tree:14.1%}"
              f" {dark:6.1%} {aliased:6.1%} {pale:6.1%} {noisy:6.1%}")
    if children is not None:
        _print_children(args.sessions, *children[:4], children[6])
        print(f"  flat or black: {children[4]:.1%}, one colour: {children[5]:.1%}, pale: {children[7]:.1%}, noisy: "
              f"{children[8]:.1%}; over chains of 4 evolve clicks ({chain[0]} children): {chain[1]:.1%}, {chain[2]:.1%}, "
              f"{chain[4]:.1%} and {chain[5]:.1%}; plain over the chains: {chain[3]:.1%}")
        print("children of two siblings: " + ", ".join(f"{k} ({c} children) identical {same:.1%}, alike {alike:.1%}"
                                                       for k, (c, same, alike) in sib.items()))
    first_s = f"{t_first:.1f}" if random_population is not None else "-"
    print(f"(seconds: Genome.random and its figures {t1 - t0:.1f}, random_population {first_s} (its figures "
          f"{t2 - t1 - (t_first if random_population is not None else 0):.1f}), sessions {t3 - t2:.1f})")


def _print_children(sessions, checked, repeats, identical, per_op, alike):
    print(f"children: {checked} checked ({sessions} sessions x 7 operators x 18 children) at {SIZE}^2:")
    print(f"  repeat a parent or an earlier child: {repeats:.1%}")
    print(f"  identical to a parent or a sibling:  {identical:.1%}")
    print(f"  alike (within {ALIKE * 255:.0f}/255):               {alike:.1%}")
    print("  identical, per operator: " + ", ".join(f"{k} {v:.1%}" for k, v in per_op.items()))


if __name__ == "__main__":
    main()
