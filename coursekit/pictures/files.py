"""Picture files that carry their genome (paper section 3.4: every picture can be bred further).

Images are written with OpenImageIO as PNG (8 bit), TIFF (16 bit) or OpenEXR (32-bit float),
rendered at any size from the genome (re-evaluated, never upscaled; up to
:data:`~coursekit.pictures.evaluate.MAX_PIXELS`, 4096 x 4096). The genome's JSON
(``coursekit.genome/1``) and the render settings (window, time) travel in the file's
metadata: together in ``ImageDescription`` (``coursekit.picture/1``: the one field all three
formats keep, TIFF included), and for PNG and EXR also in the ``coursekit:genome`` and
``coursekit:render`` attributes.

A file never lies. It is written to a temporary sibling (:func:`coursekit.atomic.atomic_path`)
and **read back** before it replaces the old file: the pixels must be those rendered (at the
format's precision) and the genome and settings those given, else :func:`save_image` raises
and the old file stays. This catches what a writer does not report: measured, OpenImageIO
returned normally from a PNG written onto a full disk, leaving an unreadable file.
"""

from __future__ import annotations

import os
from coursekit.atomic import atomic_path

import json
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from .evaluate import render
from .genome import FORMAT, Genome

PICTURE_FORMAT = "coursekit.picture/1"

__all__ = ["save_image", "load_genome", "load_render_settings", "FORMATS"]

FORMATS = {".png": oiio.UINT8, ".tif": oiio.UINT16, ".tiff": oiio.UINT16, ".exr": oiio.FLOAT}
GENOME_KEY = "coursekit:genome"
RENDER_KEY = "coursekit:render"


def _format(path: Path):
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise ValueError(f"path: {str(path)!r} has extension {ext!r}; allowed: {', '.join(FORMATS)}")
    return FORMATS[ext]


def save_image(path: str | os.PathLike[str], genome: Genome, size: int | tuple[int, int] = (1024, 1024), *,
               window: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0), time: float = 0.0,
               device: str | None = None) -> Path:
    """Render ``genome`` and write it with its genome in the metadata.

    Args:
        path: ``.png``, ``.tif``/``.tiff`` or ``.exr`` file to write.
        genome: the genome.
        size: ``(height, width)`` or one int (4096 and more work).
        window, time, device: as for :func:`coursekit.pictures.render`.
    Returns:
        The path written.
    """
    if not isinstance(genome, Genome):
        raise TypeError(f"genome: expected a Genome, got {type(genome).__name__}")
    path = Path(path)
    fmt = _format(path)
    img = render([genome], size, window=window, time=time, device=device)[0]
    h, w = img.shape[:2]
    settings = {"window": [float(v) for v in window], "time": float(time)}
    spec = oiio.ImageSpec(w, h, 3, fmt)
    spec.attribute(GENOME_KEY, genome.to_json())
    spec.attribute(RENDER_KEY, json.dumps(settings))
    spec.attribute("ImageDescription", json.dumps({"format": PICTURE_FORMAT, "genome": genome.to_dict(),
                                                   "render": settings}))
    spec.attribute("Software", "coursekit.pictures")
    with atomic_path(path, path.suffix) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise OSError(f"path: cannot write {str(path)!r}: {oiio.geterror() or (out and out.geterror())}")
        ok = out.write_image(np.ascontiguousarray(img))
        err = out.geterror()
        ok = out.close() and ok
        err = err or out.geterror()
        if not ok:
            raise OSError(f"path: writing {str(path)!r} failed: {err or oiio.geterror()}")
        _verify(tmp, path, img, fmt, genome, settings)
    return path


def _stored(img: np.ndarray, fmt) -> np.ndarray:
    """The pixels a file of ``fmt`` holds for the float image ``img``."""
    if fmt == oiio.UINT8:
        return np.round(img * 255).astype(np.uint8)
    if fmt == oiio.UINT16:
        return np.round(img * 65535).astype(np.uint16)
    return img


def _verify(tmp: Path, path: Path, img, fmt, genome: Genome, settings: dict) -> None:
    """Read the just-written ``tmp`` back; OSError unless it holds ``img``, the genome and the
    settings (so a full disk or a writer that drops metadata never replaces a good file)."""
    def fail(why):
        raise OSError(f"path: {str(path)!r} was not written correctly ({why}); the old file, if any, is kept")
    inp = oiio.ImageInput.open(str(tmp))
    if inp is None:
        fail(f"it cannot be read back: {oiio.geterror()}")
    try:
        spec = inp.spec()
        if (spec.width, spec.height, spec.nchannels) != (img.shape[1], img.shape[0], 3):
            fail(f"it reads back as {spec.width} x {spec.height} x {spec.nchannels}")
        back = inp.read_image(fmt)
        if back is None or not np.array_equal(np.asarray(back).reshape(img.shape), _stored(img, fmt)):
            fail(f"its pixels read back differently: {inp.geterror() or 'changed'}")
    finally:
        inp.close()
    try:
        if load_genome(tmp) != genome:
            fail("the genome in its metadata reads back differently")
        if load_render_settings(tmp) != settings:
            fail("the window and time in its metadata read back differently")
    except ValueError as e:
        fail(str(e))


def _spec(path) -> oiio.ImageSpec:
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"path: {str(path)!r} is a folder; give an image file")
    if not path.is_file():
        raise FileNotFoundError(f"path: {str(path)!r} does not exist")
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise ValueError(f"path: {str(path)!r} is not a readable image ({oiio.geterror()})")
    spec = inp.spec()
    inp.close()
    return spec


def load_genome(path: str | os.PathLike[str]) -> Genome:
    """The genome stored in an image written by :func:`save_image`.

    Raises:
        ValueError: the file is not an image, carries no genome, or the genome is broken.
    """
    spec = _spec(path)
    text = spec.getattribute(GENOME_KEY)
    if not text:
        picture = _picture(path, spec)
        text = picture.get("genome") if picture else None
        if isinstance(text, dict):
            text = json.dumps(text)
        elif picture and picture.get("format") == FORMAT:  # the genome itself (older files)
            text = spec.getattribute("ImageDescription")
    if not isinstance(text, str) or not text:
        raise ValueError(f"path: {str(path)!r} carries no coursekit genome in its metadata")
    try:
        return Genome.from_json(text)
    except ValueError as e:
        raise ValueError(f"path: {str(path)!r}: broken genome in metadata: {e}") from None


def _picture(path, spec) -> dict | None:
    """The JSON object in ``ImageDescription`` when it is coursekit's, else None."""
    desc = spec.getattribute("ImageDescription")
    if not isinstance(desc, str) or (PICTURE_FORMAT not in desc and FORMAT not in desc):
        return None
    try:
        d = json.loads(desc)
    except (json.JSONDecodeError, RecursionError):
        raise ValueError(f"path: {str(path)!r}: broken genome in metadata (ImageDescription is not JSON)") from None
    return d if isinstance(d, dict) else None


def load_render_settings(path: str | os.PathLike[str]) -> dict:
    """``{'window': [...], 'time': t}`` stored by :func:`save_image` (defaults if absent)."""
    spec = _spec(path)
    text = spec.getattribute(RENDER_KEY)
    settings = {"window": [0.0, 0.0, 1.0, 1.0], "time": 0.0}
    if isinstance(text, str) and text:
        try:
            stored = json.loads(text)
        except json.JSONDecodeError:
            raise ValueError(f"path: {str(path)!r}: broken {RENDER_KEY} metadata") from None
    else:
        picture = _picture(path, spec)
        stored = picture.get("render", {}) if picture else {}
    if not isinstance(stored, dict):
        raise ValueError(f"path: {str(path)!r}: broken render settings in metadata")
    settings.update({k: stored[k] for k in ("window", "time") if k in stored})
    return settings
