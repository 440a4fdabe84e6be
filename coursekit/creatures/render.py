"""Looking at creatures: off-screen pyvista pictures and films of expanded bodies (paper section 2.3, Figs. 1 and 3).

Parts are drawn as boxes coloured by their depth in the part tree (root dark, leaves bright,
matplotlib's ``viridis``), with every joint's axis as a short red line through its anchor
(prismatic joints in blue) and a grey rod along every prismatic joint, so a part that slides
out stays joined to its parent on screen as in the physics.

- :func:`render`, :func:`view`: one picture, the camera fitted to the projected body (:func:`frame`);
- :class:`Clip`, :func:`frames`, :func:`animate`: a recorded swim filmed with a camera that
  follows the smoothed centre of mass and keeps every part in the picture over the whole clip,
  with the centre of mass's trail, over a grid fixed in the water, on :data:`WATER` blue; GIF (Pillow) and MP4
  (H.264 through imageio-ffmpeg's ffmpeg) from one pass;
- :func:`keyframes`: the paper's Figure 3, key frames side by side with their times.

Rendering is off-screen through VTK's EGL window (no X server); ``VTK_DEFAULT_OPENGL_WINDOW``
is set to ``vtkEGLRenderWindow`` unless the caller chose one. Every picture of a process is
drawn by one plotter, made on first use and emptied between pictures: making a GL context
costs more than drawing a small creature.

Mesa's software renderer and triton (which CUDA builds of torch import on first use of
``torch._dynamo``) each load their own LLVM, and triton loaded after Mesa crashes the process
(a segmentation fault, measured with torch 2.14.1+cu130). So before its first plotter this
module imports ``triton`` where it is installed (0.3 s; ``torch._dynamo`` took 4 s): both then work.
"""

from __future__ import annotations

import atexit
import contextlib
import importlib.util
import os
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

from coursekit.atomic import atomic_path  # noqa: E402

from .body import PRISMATIC, BodyTree  # noqa: E402
from .film import WRITERS, write_png  # noqa: E402
from .neural import is_real  # noqa: E402
from .phenotype import Phenotype, part_poses  # noqa: E402
from .stroke import keyframe_picks, stroke_phase  # noqa: E402

_BOX_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)


def _body_of(obj) -> BodyTree:
    if isinstance(obj, Phenotype):
        return obj.body
    if isinstance(obj, BodyTree):
        return obj
    if callable(getattr(obj, "expand", None)) and hasattr(obj, "nodes"):  # a Creature (genotype.py sits above)
        return obj.expand().body
    raise TypeError(f"render: expected a Creature, Phenotype or BodyTree, got {type(obj).__name__}")


def box_corners(body: BodyTree, q: ArrayLike | None = None) -> np.ndarray:
    """(B, 8, 3) world corners of every part's box (root at the origin)."""
    R, t = part_poses(body, q)
    local = _BOX_CORNERS[None, :, :] * body.half_extents[:, None, :]
    return np.einsum("bij,bkj->bki", R, local) + t[:, None, :]


def world_poses(body: BodyTree, qpos: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """World rotations ``(B, 3, 3)`` and centres ``(B, 3)`` from a MuJoCo-layout ``qpos``
    (root position, root quaternion w, x, y, z, then the joint coordinates)."""
    qpos = np.asarray(qpos, dtype=np.float64)
    if qpos.shape != (7 + body.n_joints,):
        raise ValueError(f"qpos: expected shape ({7 + body.n_joints},) for this body, got {qpos.shape}")
    w, x, y, z = qpos[3:7] / np.linalg.norm(qpos[3:7])
    R0 = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])
    R, t = part_poses(body, qpos[7:])
    return R0 @ R, t @ R0.T + qpos[:3]


def frame(points: ArrayLike, azimuth: float, elevation: float, aspect: float, *, view_angle: float = 30.0,
          margin: float = 0.9) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A perspective camera looking from ``azimuth``/``elevation`` (degrees) at ``points`` that
    they fill: their projection spans ``margin`` of the frame's width or height, whichever binds.

    A bounding-sphere fit (VTK's ``reset_camera``) leaves a long thin creature small in a large
    empty frame; this fits the projected extent instead, with the view centred on it.

    Args:
        points: (N, 3) world points to frame (e.g. every box corner).
        aspect: width / height of the picture.
        view_angle: the camera's vertical view angle (VTK's default: 30 degrees).
        margin: fraction of the frame the points may span.

    Returns:
        ``(eye, focal_point, view_up)``, as pyvista's ``camera_position`` takes them.
    """
    for name, angle in (("azimuth", azimuth), ("elevation", elevation)):
        if not is_real(angle):
            raise ValueError(f"{name}: must be a finite number of degrees, got {angle!r}")
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    az, el = np.radians(azimuth), np.radians(elevation)
    back = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])  # centre -> eye
    world_up = np.array([0.0, 0.0, 1.0]) if abs(back[2]) < 0.999 else np.array([0.0, 1.0, 0.0])
    right = np.cross(-back, world_up)
    right /= np.linalg.norm(right)
    up = np.cross(right, -back)
    # Exactly: move the camera by (sx, sy) in its image plane and to ``distance`` from the box
    # centre; point i lands at (x_i - sx) / (distance - z_i) horizontally. The smallest distance
    # with every point inside +-m on both axes is the largest (max_i(x_i/m + z_i) +
    # max_j(z_j - x_j/m)) / 2 over the axes; the shift then centres the points on the binding axis.
    # (Box corners seen from outside never bind the near limit below.)
    centre = 0.5 * (pts.min(0) + pts.max(0))
    p = pts - centre
    z = p @ back
    t = np.tan(np.radians(view_angle) / 2) * margin
    axes = [(right, p @ right, t * aspect), (up, p @ up, t)]
    distance = max(float(np.max(x / m + z) + np.max(z - x / m)) / 2 for _, x, m in axes)
    # Nothing closer to the eye than a quarter of the points' radius (a near point along the line
    # of sight would otherwise let the camera come up to it).
    near = 0.25 * max(float(np.linalg.norm(p, axis=1).max()), 1e-3)
    distance = max(distance, float(z.max()) + near)
    for direction, x, m in axes:
        lo, hi = np.max(x - m * (distance - z)), np.min(x + m * (distance - z))
        centre = centre + direction * 0.5 * (lo + hi)
    return centre + distance * back, centre, up


def _check_size(size, *, even: bool = False):
    if not isinstance(size, (tuple, list, np.ndarray)) or len(size) != 2 or not all(isinstance(s, (int, np.integer)) and 16 <= s <= 4096 for s in size):
        raise ValueError(f"render.size: need (width, height) integers in [16, 4096], got {size!r}")
    if even and any(s % 2 for s in size):
        raise ValueError(f"size: an MP4 (H.264, yuv420p) needs an even width and height, got {tuple(size)!r}")


def _triton_before_mesa() -> None:
    """Load triton's LLVM before Mesa's (see the module docstring); once, and only where triton is installed."""
    if importlib.util.find_spec("triton") is not None:
        import triton  # noqa: F401  (loads its LLVM, libtriton)


_SHARED: dict[int, object] = {}  # process id -> the off-screen plotter every picture of that process reuses


def _close_shared() -> None:
    pl = _SHARED.pop(os.getpid(), None)
    if pl is not None:
        pl.close()


def _shared_plotter(size, background):
    """This process's one off-screen plotter (its EGL context made once), emptied and resized.

    A forked child gets its own: a GL context is not shared across processes."""
    _triton_before_mesa()
    import pyvista as pv

    pl = _SHARED.get(os.getpid())
    if pl is None or getattr(pl, "_closed", False) or pl.render_window is None:
        if not _SHARED:
            atexit.register(_close_shared)
        pl = _SHARED[os.getpid()] = pv.Plotter(off_screen=True, window_size=list(size))
    else:
        pl.clear_actors()
        pl.window_size = list(size)
    pl.set_background(background)
    return pl


def _line_width(size) -> int:
    """Line widths in pixels that read at this picture size (3 at 360 pixels high)."""
    return max(2, round(min(size) / 120))


class _Scene:
    """A creature's boxes, joint axes and sliders in a plotter, re-posable for animation.

    Prismatic joints get a grey slider rod from the anchor on the parent to the anchor on the
    child: a slid-out part is joined to its parent on screen as it is in the physics."""

    def __init__(self, body: BodyTree, size, background, joint_axes, plotter=None, notebook: bool = False):
        import matplotlib
        import pyvista as pv

        self.body = body
        if plotter is None and not notebook:
            plotter = _shared_plotter(size, background)
        elif plotter is None:
            _triton_before_mesa()
            plotter = pv.Plotter(off_screen=True, notebook=True, window_size=list(size))
            plotter.set_background(background)
        self.pl, self.shared = plotter, plotter is _SHARED.get(os.getpid())
        cube = pv.Box(bounds=(-1, 1, -1, 1, -1, 1))  # 8 corners, 6 quads
        self.unit = np.asarray(cube.points)
        B, P = body.n_bodies, len(self.unit)
        self.parts = np.flatnonzero(~body.massless)  # a multi-DOF joint's massless frames have no box
        quads = np.asarray(cube.faces).reshape(-1, 5)
        faces = np.concatenate([quads + np.array([0, 1, 1, 1, 1]) * b * P for b in range(len(self.parts))])
        # All parts are one mesh (one actor: the scene builds and draws in a fraction of the time
        # of an actor per part), coloured per face by the part's depth.
        self.boxes = pv.PolyData(np.zeros((len(self.parts) * P, 3)), faces=faces.ravel())
        depth = body.part_depth[self.parts]
        colours = matplotlib.colormaps["viridis"](0.15 + 0.75 * depth / max(int(depth.max()), 1))[:, :3]
        self.boxes.cell_data["colour"] = np.repeat((255 * colours).round().astype(np.uint8), len(quads), axis=0)
        self.pl.add_mesh(self.boxes, scalars="colour", rgb=True, show_edges=True, edge_color="black", line_width=1,
                         smooth_shading=False, render=False)
        # Joint axes (red, prismatic blue) and slider rods (grey): one line mesh each.
        width = _line_width(size)
        self.sliders = [b for b in range(1, B) if body.joint_type[b] == PRISMATIC]
        self.axes = list(range(1, B)) if joint_axes else []
        self.lines = []
        for joints, colours, w in ((self.sliders, lambda b: (110, 110, 110), width + 2),
                                   (self.axes, lambda b: (0, 0, 255) if body.joint_type[b] == PRISMATIC else (255, 0, 0), width + 1)):
            if joints:
                mesh = pv.PolyData(np.zeros((2 * len(joints), 3)), lines=np.array([[2, 2 * k, 2 * k + 1] for k in range(len(joints))]).ravel())
                mesh.cell_data["colour"] = np.array([colours(b) for b in joints], dtype=np.uint8)
                self.pl.add_mesh(mesh, scalars="colour", rgb=True, line_width=w, render=False)
            self.lines.append(mesh if joints else None)

    def pose(self, R, t) -> np.ndarray:
        """Move every part to its pose; returns the points to frame: box corners, lines' ends."""
        body = self.body
        k = self.parts
        corners = (np.einsum("bij,bkj->bki", R[k], self.unit[None] * body.half_extents[k][:, None, :]) + t[k][:, None, :]).reshape(-1, 3)
        self.boxes.points = corners
        sliders, axes = self.lines
        if sliders is not None:
            b = np.array(self.sliders)
            p = body.parent[b]
            ends = np.stack([np.einsum("bij,bj->bi", R[p], body.joint_pos_parent[b]) + t[p],
                             np.einsum("bij,bj->bi", R[b], body.joint_pos_child[b]) + t[b]], axis=1)
            sliders.points = ends.reshape(-1, 3)
        if axes is not None:
            b = np.array(self.axes)
            anchor = np.einsum("bij,bj->bi", R[b], body.joint_pos_child[b]) + t[b]
            part = body.part_of()[b]  # a massless frame's axis is drawn at its part's scale
            half = 1.2 * body.half_extents[part].max(axis=1, keepdims=True) * np.einsum("bij,bj->bi", R[b], body.joint_axis[b])
            axes.points = np.stack([anchor - half, anchor + half], axis=1).reshape(-1, 3)
        return np.concatenate([corners] + [np.asarray(m.points) for m in self.lines if m is not None])

    def camera(self, eye, centre, up) -> None:
        self.pl.camera_position = [tuple(eye), tuple(centre), tuple(up)]
        self.pl.renderer.reset_camera_clipping_range()

    def image(self) -> np.ndarray:
        self.pl.render()  # (a screenshot alone renders only a plotter's first picture)
        return np.asarray(self.pl.screenshot(return_img=True))[..., :3].copy()

    def close(self) -> None:
        """Empty the shared plotter (it stays for the next picture); close one of its own."""
        if self.shared:
            self.pl.clear_actors()
        else:
            self.pl.close()


def _framed_scene(obj, size, q, joint_axes, background, azimuth, elevation, notebook=False, plotter=None) -> _Scene:
    """A scene of ``obj`` in pose ``q``, the camera framing it (:func:`frame`)."""
    body = _body_of(obj)
    _check_size(size)
    scene = _Scene(body, size, background, joint_axes and body.n_bodies > 1, plotter, notebook)
    points = scene.pose(*part_poses(body, q))
    scene.camera(*frame(points, azimuth, elevation, size[0] / size[1], view_angle=scene.pl.camera.view_angle))
    return scene


def render(obj: Any, path: str | os.PathLike[str] | None = None, *, size: tuple[int, int] = (480, 360),
           q: ArrayLike | None = None, joint_axes: bool = True, background: str = "white", azimuth: float = 30.0,
           elevation: float = 25.0) -> np.ndarray | Path:
    """Render a creature off-screen.

    Args:
        obj: a :class:`~coursekit.creatures.genotype.Creature`, :class:`Phenotype` or BodyTree.
        path: where to write a PNG (atomically); ``None`` returns the image instead.
        size: (width, height) in pixels.
        q: (B - 1,) joint coordinates (default: the rest pose).
        joint_axes: draw every joint's axis.
        background: background colour.
        azimuth, elevation: camera angles (degrees) around the body's centre.

    Returns:
        The ``(height, width, 3)`` uint8 image when ``path`` is None, else the written path.

    Example:
        >>> from coursekit.creatures import Creature
        >>> render(Creature.figure1_snake()).shape
        (360, 480, 3)
    """
    scene = _framed_scene(obj, size, q, joint_axes, background, azimuth, elevation)
    try:
        img = scene.image()
    finally:
        scene.close()
    if path is None:
        return img
    return write_png(img, path)


class View:
    """What :func:`view` returns: the picture, and (opt-in) a rotatable 3D widget over it.

    A notebook with a widget front-end shows the widget; any other (a notebook viewer, an HTML
    export, a front-end without ipywidgets) shows the static picture that travels with it.

    Attributes:
        png: the static picture (PNG bytes).
        widget: pyvista's notebook widget, or ``None`` for the static picture alone.
    """

    def __init__(self, png: bytes, widget: Any | None = None) -> None:
        self.png, self.widget = png, widget

    def _repr_mimebundle_(self, include=None, exclude=None) -> dict:
        bundle = {"image/png": self.png, "text/plain": "<creature view>"}
        if self.widget is not None:
            data = self.widget._repr_mimebundle_()
            bundle.update(data[0] if isinstance(data, tuple) else data)
        return bundle


def view(obj: Any, *, interactive: bool = False, size: tuple[int, int] = (480, 360), q: ArrayLike | None = None,
         joint_axes: bool = True, background: str = "white", azimuth: float = 30.0, elevation: float = 25.0) -> View:
    """A creature for a notebook to display: its picture, or (opt-in) a 3D view the mouse rotates.

    The interactive view is pyvista's notebook backend (``client``: the geometry is sent to the
    page once and turns there; ``pip install 'coursekit[interactive]'``). Without that backend
    the view is the static picture, with a warning saying what to install; with it, the picture
    still travels with the widget for front-ends that cannot show widgets.

    Args:
        obj: a :class:`~coursekit.creatures.genotype.Creature`, :class:`Phenotype` or BodyTree.
        interactive: ask for the rotatable view.
        size, q, joint_axes, background, azimuth, elevation: as for :func:`render`.

    Returns:
        A :class:`View`.
    """
    from coursekit.pictures.gallery import png_bytes

    options = dict(size=size, q=q, joint_axes=joint_axes, background=background, azimuth=azimuth, elevation=elevation)
    png = png_bytes(render(obj, **options) / 255.0)
    if not interactive:
        return View(png)
    if importlib.util.find_spec("trame_pyvista") is None:
        warnings.warn("view(interactive=True) needs pyvista's notebook backend "
                      "(pip install 'coursekit[interactive]'); showing the static picture", stacklevel=2)
        return View(png)
    scene = _framed_scene(obj, size, q, joint_axes, background, azimuth, elevation, notebook=True)
    return View(png, scene.pl.show(jupyter_backend="client", return_viewer=True))


def centre_of_mass(body: BodyTree, qpos: ArrayLike) -> np.ndarray:
    """The ``(3,)`` world centre of mass of ``body`` in the MuJoCo-layout pose ``qpos``."""
    _, t = world_poses(body, qpos)
    return (body.mass @ t) / body.mass.sum()


def _nice_step(length: float) -> float:
    """1, 2 or 5 times a power of ten, close to ``length`` (grid spacing that reads as a scale)."""
    e = 10.0 ** np.floor(np.log10(max(length, 1e-6)))
    return float(min((1.0, 2.0, 5.0, 10.0), key=lambda k: abs(np.log(k * e / length))) * e)


#: Frames from which :func:`animate` and :func:`keyframes` show a bar by default (about 3 s of filming at 480 x 360).
BAR_FRAMES = 60
WATER = "#d6e9f5"  # the films' background: pale water blue, under which the grid and the trail still show


class Clip:
    """A recorded swim ready to film: the poses, a follow camera for the whole clip, the floor grid
    and the centre-of-mass trail. :func:`frames`, :func:`animate` and :func:`keyframes` film it.

    The camera keeps its direction and follows the centre of mass smoothed over time (a Gaussian
    of ``follow`` seconds, centred, so it neither lags nor shakes with each stroke); its distance and
    offset are fitted once (:func:`frame`) to the union over the clip of every part relative to the
    followed point, so every part of every frame is inside the picture and the creature keeps
    one size on screen. The strokes show against a grid that stays put in the water.

    Args:
        obj: the creature (or Phenotype / BodyTree) that was simulated.
        trajectory: (F, nq) MuJoCo-layout ``qpos`` frames, e.g. ``simulate(...,
            record_every=k).trajectory[i]``.
        frame_times: (F,) simulated time of every frame in seconds (``SimulationResult.frame_times``);
            default ``1 / fps`` apart.
        fps: frames per second, for the default ``frame_times`` and for files.
        size, joint_axes, background, azimuth, elevation: as for :func:`render`.
        follow: seconds the camera's path is smoothed over (0: it follows the centre of mass exactly).
        trail: draw the path of the centre of mass so far.
        floor: draw the grid fixed in the water: below the creature, or behind it when it rises or
            sinks out of a floor's view (its spacing in metres is 1, 2 or 5 times a power of ten).
        label: write the time (and the grid spacing) in a corner of every frame.
        margin: fraction of the picture's height or width the creature may span.
    """

    def __init__(self, obj: Any, trajectory: ArrayLike, *, frame_times: ArrayLike | None = None, fps: int = 20,
                 size: tuple[int, int] = (480, 360), joint_axes: bool = False, background: str = WATER,
                 azimuth: float = 30.0, elevation: float = 25.0, follow: float = 1.0, trail: bool = True,
                 floor: bool = True, label: bool = True, margin: float = 0.8) -> None:
        from scipy.ndimage import gaussian_filter1d

        body = _body_of(obj)
        _check_size(size)
        qpos = np.asarray(trajectory, dtype=np.float64)
        if qpos.ndim != 2 or len(qpos) < 1:
            raise ValueError(f"trajectory: expected an (F, nq) array of qpos frames, got shape {qpos.shape}")
        if not (isinstance(fps, (int, np.integer)) and 1 <= fps <= 60):
            raise ValueError(f"fps: must be an integer in [1, 60], got {fps!r}")
        times = np.arange(len(qpos)) / fps if frame_times is None else np.asarray(frame_times, dtype=np.float64)
        if times.shape != (len(qpos),) or not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
            raise ValueError(f"frame_times: expected {len(qpos)} increasing times (one per frame), got shape {times.shape}")
        if not (np.isfinite(follow) and follow >= 0):
            raise ValueError(f"follow: must be a number of seconds >= 0, got {follow!r}")
        if not 0.1 <= margin <= 1.0:
            raise ValueError(f"margin: must be in [0.1, 1], got {margin!r}")
        self.body, self.times, self.fps, self.size, self.background, self.label = body, times, int(fps), tuple(size), background, label
        self.poses = [world_poses(body, f) for f in qpos]
        self.com = np.stack([(body.mass @ t) / body.mass.sum() for _, t in self.poses])
        dt = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
        self.follow = gaussian_filter1d(self.com, follow / dt, axis=0, mode="nearest") if follow > 0 and len(times) > 1 else self.com.copy()
        self._options = (size, background, joint_axes and body.n_bodies > 1)
        scene = _Scene(body, *self._options)
        try:
            self.points = [scene.pose(R, t) for R, t in self.poses]  # what must stay in the picture, frame by frame
            relative = np.concatenate([p - s for p, s in zip(self.points, self.follow)])
            self.eye, self.centre, self.up = frame(relative, azimuth, elevation, size[0] / size[1],
                                                   view_angle=scene.pl.camera.view_angle, margin=margin)
        finally:
            scene.close()
        self.reach = float(max(np.ptp(np.concatenate(self.points[:1]), axis=0).max(), 0.05))
        self.grid_step = _nice_step(self.reach / 3)
        self.floor = self._grid() if floor else None
        self.trail = trail

    def _grid(self) -> tuple[np.ndarray, np.ndarray, float]:
        """``(centre, normal, side)`` of the square grid fixed in the water, just beyond every part of
        the swim along ``normal``: a floor below it or, for a swimmer that rises or sinks by more than
        its own size (out of a floor's view), a wall behind it holding its path, facing the camera."""
        everything = np.concatenate(self.points)
        path, view = self.com[-1] - self.com[0], self.centre - self.eye  # view: from the camera into the picture
        across = view - view.dot(path) * path / max(float(path @ path), 1e-18)
        rises = np.ptp(self.com[:, 2]) > self.reach and np.linalg.norm(across) > 1e-9
        normal = across / np.linalg.norm(across) if rises else np.array([0.0, 0.0, -1.0])
        mid, depth = 0.5 * (self.com[0] + self.com[-1]), float((everything @ normal).max()) + 0.3 * self.reach
        return mid + (depth - mid @ normal) * normal, normal, float(np.ptp(everything, axis=0).max() + 3 * self.reach)

    def __len__(self) -> int:
        return len(self.poses)

    def _text(self, i: int) -> str:
        return f"t = {self.times[i]:.2f} s" + (f"   grid {self.grid_step:g} m" if self.floor is not None else "")

    def film(self, indices: Sequence[int] | None = None, progress: bool | None = False) -> Iterator[np.ndarray]:
        """Yield ``(i, image)`` for the frames ``indices`` (default all), one plotter for them all;
        ``progress``: a tqdm bar (``None``: when there are at least :data:`BAR_FRAMES` frames)."""
        import pyvista as pv
        from tqdm.auto import tqdm

        indices = range(len(self)) if indices is None else [int(i) for i in indices]
        for i in indices:
            if not 0 <= i < len(self):
                raise ValueError(f"frame index {i} is outside the clip's {len(self)} frames")
        scene = _Scene(self.body, *self._options)
        bar = tqdm(total=len(indices), desc="filming", unit="frame", leave=True,
                   disable=not (len(indices) >= BAR_FRAMES if progress is None else progress))
        try:
            width = _line_width(self.size)
            if self.floor is not None:
                centre, normal, side = self.floor
                n = max(int(np.ceil(side / self.grid_step)), 1)
                grid = pv.Plane(center=centre, direction=normal, i_size=n * self.grid_step, j_size=n * self.grid_step,
                                i_resolution=n, j_resolution=n)
                scene.pl.add_mesh(grid, style="wireframe", color="#7fa7c9", line_width=1, render=False)
            trail = None
            if self.trail and len(self) > 1:
                trail = pv.PolyData(self.com.copy())
                trail.verts = np.empty(0, dtype=np.int64)  # the path so far only, not every point of it
                trail.lines = np.array([2, 0, 0])
                scene.pl.add_mesh(trail, color="#e6550d", line_width=width, render=False)
            text = None
            if self.label:
                font = max(6, self.size[1] // 40)
                text = scene.pl.add_text(self._text(0), position=(4, self.size[1] - 4 - 2 * font), font_size=font, color="black", render=False)
            for i in indices:
                scene.pose(*self.poses[i])
                if trail is not None:
                    trail.lines = np.concatenate([[i + 1], np.arange(i + 1)]) if i else np.array([2, 0, 0])
                if text is not None:
                    text.SetInput(self._text(i))
                s = self.follow[i]
                scene.camera(self.eye + s, self.centre + s, self.up)
                yield i, scene.image()
                bar.update()
        finally:
            bar.close()
            scene.close()


def frames(obj: Any, trajectory: ArrayLike, **options: Any) -> Iterator[np.ndarray]:
    """The frames of a swim, one ``(height, width, 3)`` uint8 image per ``qpos`` frame (a generator).

    Args:
        obj, trajectory, options: as for :class:`Clip` (``size``, ``follow``, ``trail`` ...).
    """
    for _, img in Clip(obj, trajectory, **options).film():
        yield img


def animate(obj: Any, trajectory: ArrayLike, path: str | os.PathLike[str] | Sequence[str | os.PathLike[str]], *,
            fps: int = 20, size: tuple[int, int] = (480, 360), joint_axes: bool = False, background: str = WATER,
            azimuth: float = 30.0, elevation: float = 25.0, progress: bool | None = None, **options: Any) -> Path | list[Path]:
    """Film a creature swimming along a recorded trajectory: a GIF, an MP4, or both from one pass.

    The camera follows the creature and keeps all of it in the picture for the whole clip, over
    a grid that stays put in the water, with the path of its centre of mass drawn behind it
    (:class:`Clip`). Every file is written atomically and read back (frame count and size)
    before it replaces an old one.

    Args:
        obj: the creature (or Phenotype / BodyTree) that was simulated.
        trajectory: (F, nq) MuJoCo-layout ``qpos`` frames, e.g. ``simulate(...,
            record_every=k).trajectory[i]``.
        path: the file to write, ``.gif`` or ``.mp4`` (H.264, even ``size`` only); or a list of them.
        fps: frames per second of the files.
        size, joint_axes, background, azimuth, elevation: as for :func:`render`.
        progress: a tqdm bar of the frames filmed; ``None``: for :data:`BAR_FRAMES` frames or more.
        **options: :class:`Clip`'s ``frame_times``, ``follow``, ``trail``, ``floor``, ``label``, ``margin``.

    Returns:
        The written path (a list of them when ``path`` was a list).
    """
    paths = [Path(p) for p in path] if isinstance(path, (list, tuple)) else [Path(path)]
    for p in paths:
        if p.suffix.lower() not in WRITERS:
            raise ValueError(f"path: {str(p)!r} must end in one of {', '.join(WRITERS)}")
    _check_size(size, even=any(p.suffix.lower() == ".mp4" for p in paths))
    clip = Clip(obj, trajectory, fps=fps, size=size, joint_axes=joint_axes, background=background,
                azimuth=azimuth, elevation=elevation, **options)
    with contextlib.ExitStack() as stack:
        tmps = [stack.enter_context(atomic_path(p, p.suffix.lower())) for p in paths]
        writers = []
        try:
            for p, t in zip(paths, tmps):
                writers.append(WRITERS[p.suffix.lower()](t, fps, size))
            for _, img in clip.film(progress=progress):
                for w in writers:
                    w.add(img)
        except BaseException:
            for w in writers:
                w.abort()
            raise
        for w, p, t in zip(writers, paths, tmps):
            w.finish()
            w.check(t, len(clip), size)
    return paths if isinstance(path, (list, tuple)) else paths[0]


def keyframes(obj: Any, trajectory: ArrayLike, path: str | os.PathLike[str] | None = None, *, n: int = 4,
              size: tuple[int, int] = (320, 240), gap: int = 4, gap_colour: tuple[int, int, int] = (200, 200, 200),
              stroke: bool = True, progress: bool | None = None, **options: Any) -> np.ndarray | Path:
    """The paper's Figure 3: ``n`` key frames of a swim side by side, time increasing left to right.

    The frames are spread from the first to the last and, with ``stroke``, shifted (each by less
    than one stroke) so that the panels after the first show the stroke at successive phases of one
    cycle (:func:`~coursekit.creatures.stroke.keyframe_picks`; without ``stroke``, or with no stroke
    to show, evenly spaced). They are filmed with the clip's follow camera (:class:`Clip`: the same
    size on screen, the centre-of-mass trail showing the way come so far, the grid the motion
    against the water), each labelled with its time.

    Args:
        obj, trajectory: as for :func:`animate`.
        path: where to write the PNG (atomically); ``None`` returns the image instead.
        n: key frames (at most the trajectory's frames).
        size: (width, height) of one key frame.
        gap: pixels between key frames, in ``gap_colour``.
        progress: as for :func:`animate`.
        **options: :class:`Clip`'s options (``frame_times``, ``follow``, ``azimuth`` ...).

    Returns:
        The ``(height, n * width + (n - 1) * gap, 3)`` uint8 strip, or the written path.
    """
    F = len(np.asarray(trajectory))
    if not (isinstance(n, (int, np.integer)) and 1 <= n <= max(F, 1)):
        raise ValueError(f"n: must be an integer in [1, {F}] (the trajectory's frames), got {n!r}")
    if not (isinstance(gap, (int, np.integer)) and gap >= 0):
        raise ValueError(f"gap: must be an integer >= 0 (pixels), got {gap!r}")
    clip = Clip(obj, trajectory, size=size, **options)
    picks = keyframe_picks(clip.times, n, stroke_phase(trajectory, clip.times) if stroke else None)
    if len(np.unique(picks)) != n:
        raise ValueError(f"n: {n} key frames do not fit in {len(clip)} frames")
    w, h = size
    strip = np.empty((h, n * w + (n - 1) * gap, 3), dtype=np.uint8)
    strip[:] = np.asarray(gap_colour, dtype=np.uint8)
    for k, (_, img) in enumerate(clip.film(picks, progress)):
        strip[:, k * (w + gap): k * (w + gap) + w] = img
    return strip if path is None else write_png(strip, path)
