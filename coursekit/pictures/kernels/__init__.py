"""Whole-image kernels of the picture primitives (paper section 3.2), each bound to its primitive
in the registry (:func:`~coursekit.pictures.primitives.image_kernel`; forms and signatures are in
:mod:`~coursekit.pictures.primitives`): coordinates and constants (:mod:`.coordinates`), noise
(:mod:`.noise`), pixel maps (:mod:`.pixmaps`), pointwise functions (:mod:`.pointwise`), blurs
and gradients (:mod:`.neighbourhood`) and coordinate transforms (:mod:`.warps`), with numpy's
faster CPU functions in :mod:`.fast`.

**Types (section 3.2).** A value is a tensor ``(B, C, Hs, Ws)``: ``C`` is 1 (grey) or 3
(RGB) and ``Hs, Ws`` are 1 or the image size. A *scalar* is ``(B, 1, 1, 1)``, a *vector*
(colour) ``(B, 3, 1, 1)``, a *matrix* (pixel map) has ``Hs = H`` or ``Ws = W``. A function of
mixed inputs returns the most complex type of its inputs, which is exactly what broadcasting
gives: scalar + vector = vector, vector * matrix = colour matrix. ``x`` is ``(1, 1, 1, W)``
and ``y`` is ``(1, 1, H, 1)``, so a chain of pointwise operations on ``x`` alone costs ``W``
evaluations, not ``H W``.

**Coordinates.** Coordinate transforms (``swirl``, ``rotate``, ``warp-swirl``, ``warp-by``)
return the context in which their first argument is evaluated; neighbourhood operations
(``blur``, ``band-pass``, ``bump``, ``grad-mag``, ``grad-dir``) act on the pixel grid, sizes in
world units, their argument evaluated on the grid extended by their reach beyond the window
(:func:`~..tree.padded`: as a renderer filters, so a zoomed window is a crop of a larger
render).

**Speed.** Most of the time goes to a few primitives on whole images, so each picks the
cheapest exact method for the coordinates it gets. On :func:`~coursekit.pictures.context.separable` coordinates
noise interpolates lattice rows, then columns (small matrices for a few lattice cells, gathers
for many), pixel maps are sampled rows-then-columns and kept per (size, window) across renders
(a gallery renders every generation at one size), and dissolve looks its cells up per row and
column. Warped coordinates fall back to ``grid_sample``. Blurs multiply by banded matrices cut
into row tiles, touching only the band. Node values are never modified in place (cached
pictures and shared subtrees are handed to several parents); only fresh intermediates are. On
the CPU, transcendental functions and the blurs' matrix products go through numpy (faster there
than torch's: :func:`.fast.ufunc`).

**Batch invariance.** Every kernel computes each image of a batch as it would compute it
alone, bit for bit, so a picture never depends on what it was rendered with (batched, in waves,
in a worker): no reduction over a batch picks a method or a size, and no library kernel whose
rounding depends on an element's position in the tensor, or on whether it arrives compact or
broadcast, is used: torch's CPU transcendental functions round the elements past the last full
vector differently, and so does numpy for broadcast inputs (measured), so these go through
:func:`.fast.ufunc`, which computes each argument in its compact, contiguous form.
"""

from . import coordinates, neighbourhood, noise, pixmaps, pointwise, warps  # noqa: F401  (each binds its kernels)

__all__ = ["coordinates", "neighbourhood", "noise", "pixmaps", "pointwise", "warps"]
