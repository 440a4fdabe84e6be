"""Film files: the frames of a clip written as an endlessly looping GIF (Pillow) or an H.264 MP4
(imageio-ffmpeg's own ffmpeg binary), each read back before it replaces an old file; and single
pictures as PNG (:func:`write_png`), read back the same way.

A writer is made on a temporary path with ``(tmp, fps, size)``, takes frames with ``add``, and
``finish`` (or ``abort``) closes it; ``check(path, n, size)`` reads the file back and raises
``OSError`` unless it holds ``n`` frames of ``size``. :func:`~coursekit.creatures.render.animate`
drives them, one per file, from a single rendering pass.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from coursekit.atomic import atomic_path


def write_png(img: np.ndarray, path: str | os.PathLike[str]) -> Path:
    """Write a ``(H, W, 3)`` uint8 image as a PNG, atomically, read back before it replaces an old file."""
    from PIL import Image

    if Path(path).suffix.lower() != ".png":
        raise ValueError(f"path: a picture is written as PNG; give a file name ending in .png, got {str(path)!r}")
    with atomic_path(path, ".png") as tmp:
        Image.fromarray(img).save(tmp, format="PNG")
        with Image.open(tmp) as check:  # read back before it replaces an old file
            if check.size != (img.shape[1], img.shape[0]):
                raise OSError(f"{path}: the PNG read back is {check.size}, not {img.shape[1]}x{img.shape[0]}")
    return Path(path)


class GifFile:
    """Frames kept as palette images, written as one endlessly looping GIF at ``fps``."""

    def __init__(self, tmp: Path, fps: int, size):
        self.tmp, self.fps, self.frames = tmp, fps, []

    def add(self, img: np.ndarray) -> None:
        from PIL import Image

        self.frames.append(Image.fromarray(img).quantize(colors=255, method=Image.Quantize.FASTOCTREE))

    def finish(self) -> None:
        self.frames[0].save(self.tmp, format="GIF", save_all=True, append_images=self.frames[1:],
                            duration=round(1000 / self.fps), loop=0)

    def abort(self) -> None:
        self.frames.clear()

    @staticmethod
    def check(path: Path, n: int, size) -> None:
        from PIL import Image

        with Image.open(path) as g:
            if g.n_frames != n or g.size != tuple(size):
                raise OSError(f"{path}: the GIF read back has {g.n_frames} frames of {g.size}, not {n} of {tuple(size)}")


#: imageio-ffmpeg's quality (0-10) of the MP4s: 6 is x264's constant rate factor 20, which looks like
#: 8 (factor 10) at half the file (a 10 s champion film at 480 x 360: 2.8 against 6.3 MB).
MP4_QUALITY = 6


class Mp4File:
    """Frames streamed to ffmpeg (imageio-ffmpeg's own binary): H.264 in yuv420p, which browsers play."""

    def __init__(self, tmp: Path, fps: int, size):
        import imageio_ffmpeg

        self.out = imageio_ffmpeg.write_frames(str(tmp), tuple(size), fps=fps, codec="libx264", pix_fmt_out="yuv420p",
                                               quality=MP4_QUALITY, macro_block_size=2, output_params=["-preset", "veryfast", "-movflags", "+faststart"])
        self.out.send(None)

    def add(self, img: np.ndarray) -> None:
        self.out.send(np.ascontiguousarray(img))

    def finish(self) -> None:
        self.out.close()  # waits for ffmpeg to write the file

    abort = finish

    @staticmethod
    def check(path: Path, n: int, size) -> None:
        import imageio_ffmpeg

        reader = imageio_ffmpeg.read_frames(str(path))
        try:
            meta = next(reader)  # the stream's header (no frame decoded)
        finally:
            reader.close()
        count = imageio_ffmpeg.count_frames_and_secs(str(path))[0]  # packets counted, not decoded
        if count != n or tuple(meta["size"]) != tuple(size):
            raise OSError(f"{path}: the MP4 read back has {count} frames of {meta['size']}, not {n} of {tuple(size)}")


WRITERS = {".gif": GifFile, ".mp4": Mp4File}
