"""Picture files with the genome in their metadata (OpenImageIO: PNG, TIFF, EXR)."""

import os

import numpy as np
import OpenImageIO as oiio
import pytest

from coursekit.pictures import Genome, load_genome, render, save_image
from coursekit.pictures.files import load_render_settings
from coursekit.pictures import primitives as P


def read_pixels(path, fmt):
    inp = oiio.ImageInput.open(str(path))
    data = inp.read_image(fmt)
    inp.close()
    return data


@pytest.fixture
def genome():
    return Genome.random(np.random.default_rng(42), n_strings=3, head_length=5)


def test_png_reloads_identical_genome_and_same_pixels(tmp_path, genome):
    path = save_image(tmp_path / "pic.png", genome, (48, 40), window=(0.1, 0.0, 0.9, 1.2), time=0.5)
    back = load_genome(path)
    assert back == genome and back.to_json() == genome.to_json()
    settings = load_render_settings(path)
    again = render(back, (48, 40), **settings)[0]
    stored = read_pixels(path, oiio.UINT8)
    assert stored.shape == (48, 40, 3)
    assert np.array_equal(stored, np.round(again * 255).astype(np.uint8))
    assert os.listdir(tmp_path) == ["pic.png"]  # the temporary file is gone


def test_exr_reloads_identical_genome_and_bit_identical_pixels(tmp_path, genome):
    path = save_image(tmp_path / "pic.exr", genome, 32)
    assert load_genome(path) == genome
    assert np.array_equal(read_pixels(path, oiio.FLOAT), render(load_genome(path), 32)[0])


def test_tiff_keeps_the_genome_in_image_description(tmp_path, genome):
    path = save_image(tmp_path / "pic.tif", genome, 16)
    assert load_genome(path) == genome
    stored = read_pixels(path, oiio.UINT16)
    assert np.array_equal(stored, np.round(render(genome, 16)[0] * 65535).astype(np.uint16))


def test_save_overwrites_atomically(tmp_path, genome):
    path = tmp_path / "pic.png"
    save_image(path, genome, 8)
    other = Genome.random(np.random.default_rng(1))
    save_image(path, other, 8)
    assert load_genome(path) == other
    assert sorted(os.listdir(tmp_path)) == ["pic.png"]


def test_files_without_or_with_broken_genome_are_refused(tmp_path, genome):
    plain = tmp_path / "plain.png"
    spec = oiio.ImageSpec(4, 4, 3, oiio.UINT8)
    out = oiio.ImageOutput.create(str(plain))
    out.open(str(plain), spec)
    out.write_image(np.zeros((4, 4, 3), np.uint8))
    out.close()
    with pytest.raises(ValueError, match="carries no coursekit genome"):
        load_genome(plain)
    with pytest.raises(IsADirectoryError, match="path: .* is a folder; give an image file"):
        load_genome(tmp_path)
    with pytest.raises(FileNotFoundError, match="the folder '.*nowhere' does not exist"):
        save_image(tmp_path / "nowhere" / "a.png", genome, 8)
    broken = tmp_path / "broken.exr"
    spec = oiio.ImageSpec(4, 4, 3, oiio.FLOAT)
    spec.attribute("coursekit:genome", genome.to_json()[:-20])
    out = oiio.ImageOutput.create(str(broken))
    out.open(str(broken), spec)
    out.write_image(np.zeros((4, 4, 3), np.float32))
    out.close()
    with pytest.raises(ValueError, match="broken genome"):
        load_genome(broken)
    text = tmp_path / "notes.png"
    text.write_text("not an image")
    with pytest.raises(ValueError, match="not a readable image"):
        load_genome(text)
    with pytest.raises(FileNotFoundError):
        load_genome(tmp_path / "missing.png")
    with pytest.raises(ValueError, match="extension '.jpg'"):
        save_image(tmp_path / "pic.jpg", genome, 8)


@pytest.mark.slow
def test_4096_square_exr_renders_at_full_resolution(tmp_path):
    pointwise = [n for n in P.names() if n not in ("blur", "band-pass", "bump", "grad-mag", "grad-dir")]
    g = Genome.random(np.random.default_rng(3), n_strings=2, head_length=5, symbols=pointwise)
    path = save_image(tmp_path / "big.exr", g, 4096)
    assert load_genome(path) == g
    pixels = read_pixels(path, oiio.FLOAT)
    assert pixels.shape == (4096, 4096, 3)
    # re-evaluated, not upscaled: a 64x64 corner equals a zoomed render of that window
    corner = render(g, 64, window=(0.0, 0.0, 64 / 4096, 64 / 4096))[0]
    assert float((np.abs(pixels[:64, :64] - corner) > 1e-4).mean()) <= 0.01


# ---- files that never lie ---------------------------------------------------------------------

def test_every_format_keeps_the_window_and_time(tmp_path):
    # measured before: TIFF lost them in 156 of 160 files (only ImageDescription survives there)
    rng = np.random.default_rng(7)
    for k in range(12):
        g = Genome.random(rng, n_strings=2, head_length=4)
        window = tuple(float(v) for v in np.round(rng.uniform(-2, 2, 4), 3))
        window = (min(window[0], window[2]) - 0.1, min(window[1], window[3]) - 0.1, max(window[0], window[2]), max(window[1], window[3]))
        time = float(rng.uniform(0, 3))
        for ext in (".png", ".tif", ".exr"):
            path = save_image(tmp_path / f"p{k}{ext}", g, 8, window=window, time=time)
            assert load_genome(path) == g
            assert load_render_settings(path) == {"window": list(window), "time": time}, (ext, k)


FULL_DISK = r"""
import resource, signal, sys
import numpy as np
from coursekit.pictures import Genome, save_image
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)       # a write past the limit fails (EFBIG), as on a full disk
resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))
g = Genome.random(np.random.default_rng(3), n_strings=3, head_length=6)
try:
    save_image(sys.argv[1], g, 256)
except OSError as e:
    print("OSError:", e)
else:
    print("returned normally")
"""


@pytest.mark.parametrize("ext", [".png", ".tif", ".exr"])
def test_a_full_disk_raises_and_keeps_the_good_file(tmp_path, genome, ext):
    import subprocess
    import sys

    path = tmp_path / f"good{ext}"
    save_image(path, genome, 16)
    before = path.read_bytes()
    run = subprocess.run([sys.executable, "-c", FULL_DISK, str(path)], capture_output=True, text=True)
    assert "OSError:" in run.stdout and str(path) in run.stdout, run.stdout + run.stderr
    assert path.read_bytes() == before and load_genome(path) == genome
    assert sorted(os.listdir(tmp_path)) == [path.name]  # no temporary file left behind


KILLED = r"""
import os, signal, sys
from coursekit.atomic import atomic_path
with atomic_path(sys.argv[1], ".png") as tmp:
    tmp.write_bytes(b"half a picture")
    os.kill(os.getpid(), signal.SIGKILL)            # the kernel dies in the middle of a save
"""


def test_temporaries_of_a_killed_save_are_removed_by_the_next(tmp_path, genome):
    import subprocess
    import sys

    path = tmp_path / "pic.png"
    save_image(path, genome, 8)
    subprocess.run([sys.executable, "-c", KILLED, str(path)])
    left = [n for n in os.listdir(tmp_path) if n != "pic.png"]
    assert len(left) == 1 and left[0].startswith(".pic.png.")  # what the kill left
    save_image(path, genome, 8)
    assert os.listdir(tmp_path) == ["pic.png"]

