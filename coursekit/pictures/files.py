"""Picture files that carry their genome (paper section 3.4: every picture can be bred further).

Images are written with OpenImageIO as PNG (8 bit), TIFF (16 bit) or OpenEXR (32-bit float),
rendered at any size from the genome (re-evaluated, never upscaled). The genome's JSON
(``coursekit.genome/1``) travels in the file's metadata: in the ``coursekit:genome``
attribute (PNG text chunk, EXR header) and in ``ImageDescription`` (all three formats; the
only one TIFF keeps). The render settings (window, time) go in ``coursekit:render``.
Files are written atomically: a temporary file in the same folder, then ``os.replace``.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from .evaluate import render
from .genome import FORMAT, Genome

__all__ = ["save_image", "load_genome", "load_render_settings", "FORMATS"]

FORMATS = {".png": oiio.UINT8, ".tif": oiio.UINT16, ".tiff": oiio.UINT16, ".exr": oiio.FLOAT}
GENOME_KEY = "coursekit:genome"
RENDER_KEY = "coursekit:render"


def _format(path: Path):
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise ValueError(f"path: {str(path)!r} has extension {ext!r}; allowed: {', '.join(FORMATS)}")
    return FORMATS[ext]


def save_image(path, genome: Genome, size=(1024, 1024), *, window=(0.0, 0.0, 1.0, 1.0),
               time: float = 0.0, device=None) -> Path:
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
    spec = oiio.ImageSpec(w, h, 3, fmt)
    text = genome.to_json()
    spec.attribute(GENOME_KEY, text)
    spec.attribute("ImageDescription", text)
    spec.attribute(RENDER_KEY, json.dumps({"window": [float(v) for v in window], "time": float(time)}))
    spec.attribute("Software", "coursekit.pictures")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent or ".")
    os.close(fd)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the usual mode
        out = oiio.ImageOutput.create(tmp)
        if out is None or not out.open(tmp, spec):
            raise OSError(f"path: cannot write {str(path)!r}: {oiio.geterror() or (out and out.geterror())}")
        ok = out.write_image(np.ascontiguousarray(img))
        err = out.geterror()
        out.close()
        if not ok:
            raise OSError(f"path: writing {str(path)!r} failed: {err}")
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def _spec(path) -> oiio.ImageSpec:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"path: {str(path)!r} does not exist")
    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise ValueError(f"path: {str(path)!r} is not a readable image ({oiio.geterror()})")
    spec = inp.spec()
    inp.close()
    return spec


def load_genome(path) -> Genome:
    """The genome stored in an image written by :func:`save_image`.

    Raises:
        ValueError: the file is not an image, carries no genome, or the genome is broken.
    """
    spec = _spec(path)
    text = spec.getattribute(GENOME_KEY)
    if not text:
        desc = spec.getattribute("ImageDescription")
        if isinstance(desc, str) and FORMAT in desc:
            text = desc
    if not isinstance(text, str) or not text:
        raise ValueError(f"path: {str(path)!r} carries no coursekit genome in its metadata")
    try:
        return Genome.from_json(text)
    except ValueError as e:
        raise ValueError(f"path: {str(path)!r}: broken genome in metadata: {e}") from None


def load_render_settings(path) -> dict:
    """``{'window': [...], 'time': t}`` stored by :func:`save_image` (defaults if absent)."""
    text = _spec(path).getattribute(RENDER_KEY)
    settings = {"window": [0.0, 0.0, 1.0, 1.0], "time": 0.0}
    if isinstance(text, str) and text:
        try:
            settings.update(json.loads(text))
        except json.JSONDecodeError:
            raise ValueError(f"path: {str(path)!r}: broken {RENDER_KEY} metadata") from None
    return settings
