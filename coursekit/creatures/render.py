"""Looking at creatures: off-screen pyvista pictures of expanded bodies (paper section 2.3, Fig. 1).

Parts are drawn as boxes coloured by their depth in the part tree (root dark, leaves bright,
matplotlib's ``viridis``), with every joint's axis as a short red line through its anchor
(prismatic joints in blue). Rendering is off-screen through VTK's EGL window (no X server);
``VTK_DEFAULT_OPENGL_WINDOW`` is set to ``vtkEGLRenderWindow`` unless the caller chose one.

Mesa's software renderer and triton (which CUDA builds of torch import on first use of
``torch._dynamo``) each load their own LLVM, and triton loaded after Mesa crashes the process
(a segmentation fault, measured with torch 2.14.1+cu130). So before its first plotter this
module imports ``torch._dynamo`` when triton is installed: loaded in that order, both work.
"""

from __future__ import annotations

import importlib.util
import os
import warnings
from pathlib import Path

import numpy as np

os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

from coursekit.atomic import atomic_path  # noqa: E402

from .body import PRISMATIC, BodyTree  # noqa: E402
from .phenotype import Phenotype, part_poses  # noqa: E402

_BOX_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)


def _body_of(obj) -> BodyTree:
    if isinstance(obj, Phenotype):
        return obj.body
    if isinstance(obj, BodyTree):
        return obj
    if callable(getattr(obj, "expand", None)) and hasattr(obj, "nodes"):  # a Creature (genotype.py sits above)
        return obj.expand().body
    raise TypeError(f"render: expected a Creature, Phenotype or BodyTree, got {type(obj).__name__}")


def box_corners(body: BodyTree, q=None) -> np.ndarray:
    """(B, 8, 3) world corners of every part's box (root at the origin)."""
    R, t = part_poses(body, q)
    local = _BOX_CORNERS[None, :, :] * body.half_extents[:, None, :]
    return np.einsum("bij,bkj->bki", R, local) + t[:, None, :]


def world_poses(body: BodyTree, qpos) -> tuple[np.ndarray, np.ndarray]:
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


def frame(points, azimuth: float, elevation: float, aspect: float, *, view_angle: float = 30.0,
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


def _check_size(size):
    if len(size) != 2 or not all(isinstance(s, (int, np.integer)) and 16 <= s <= 4096 for s in size):
        raise ValueError(f"render.size: need (width, height) integers in [16, 4096], got {size!r}")


def _triton_before_mesa() -> None:
    """Load triton's LLVM before Mesa's (see the module docstring); once, and only where triton is installed."""
    if importlib.util.find_spec("triton") is not None:
        import torch._dynamo  # noqa: F401  (imports triton)


class _Scene:
    """One off-screen plotter with a creature's boxes and joint axes, re-posable for animation."""

    def __init__(self, body: BodyTree, size, background, joint_axes, notebook: bool = False):
        _triton_before_mesa()
        import matplotlib
        import pyvista as pv

        self.body = body
        self.pl = pv.Plotter(off_screen=True, notebook=notebook, window_size=list(size))
        self.pl.set_background(background)
        depth = body.depth
        cmap = matplotlib.colormaps["viridis"]
        top = max(int(depth.max()), 1)
        self.unit = np.asarray(pv.Box(bounds=(-1, 1, -1, 1, -1, 1)).points)
        self.boxes, self.axes = [], []
        for b in range(body.n_bodies):
            box = pv.Box(bounds=(-1, 1, -1, 1, -1, 1))
            colour = cmap(0.15 + 0.75 * depth[b] / top)[:3]
            self.pl.add_mesh(box, color=colour, show_edges=True, edge_color="black", line_width=1, smooth_shading=False)
            self.boxes.append(box)
        if joint_axes:
            for b in range(1, body.n_bodies):
                line = pv.Line((0, 0, 0), (1, 0, 0))
                self.pl.add_mesh(line, color="blue" if body.joint_type[b] == PRISMATIC else "red", line_width=4)
                self.axes.append((b, line))

    def pose(self, R, t) -> np.ndarray:
        """Move every part to its pose; returns the (B * 8, 3) box corners for framing."""
        body = self.body
        for b, box in enumerate(self.boxes):
            box.points = (self.unit * body.half_extents[b]) @ R[b].T + t[b]
        for b, line in self.axes:
            L = 2.4 * float(body.half_extents[b].max())
            anchor = R[b] @ body.joint_pos_child[b] + t[b]
            a = R[b] @ body.joint_axis[b]
            line.points = np.array([anchor - 0.5 * L * a, anchor + 0.5 * L * a])
        local = _BOX_CORNERS[None, :, :] * body.half_extents[:, None, :]
        return (np.einsum("bij,bkj->bki", R, local) + t[:, None, :]).reshape(-1, 3)

    def look(self, centre, radius, azimuth, elevation):
        """Look at ``centre`` from ``radius`` away (animation: the same distance every frame)."""
        az, el = np.radians(azimuth), np.radians(elevation)
        eye = centre + radius * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        self.pl.camera_position = [tuple(eye), tuple(centre), (0.0, 0.0, 1.0)]


def _framed_scene(obj, size, q, joint_axes, background, azimuth, elevation, notebook=False) -> _Scene:
    """A scene of ``obj`` in pose ``q``, the camera framing it (:func:`frame`)."""
    body = _body_of(obj)
    _check_size(size)
    scene = _Scene(body, size, background, joint_axes and body.n_bodies > 1, notebook)
    corners = scene.pose(*part_poses(body, q))
    points = np.concatenate([corners] + [np.asarray(line.points) for _, line in scene.axes])
    eye, centre, up = frame(points, azimuth, elevation, size[0] / size[1], view_angle=scene.pl.camera.view_angle)
    scene.pl.camera_position = [tuple(eye), tuple(centre), tuple(up)]
    scene.pl.renderer.reset_camera_clipping_range()
    return scene


def render(obj, path=None, *, size=(480, 360), q=None, joint_axes: bool = True, background: str = "white",
           azimuth: float = 30.0, elevation: float = 25.0):
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
        if path is None:
            return np.asarray(scene.pl.screenshot(return_img=True))[..., :3].copy()
        with atomic_path(path, ".png") as tmp:
            scene.pl.screenshot(str(tmp))
        return Path(path)
    finally:
        scene.pl.close()


class View:
    """What :func:`view` returns: the picture, and (opt-in) a rotatable 3D widget over it.

    A notebook with a widget front-end shows the widget; any other (a notebook viewer, an HTML
    export, a front-end without ipywidgets) shows the static picture that travels with it.

    Attributes:
        png: the static picture (PNG bytes).
        widget: pyvista's notebook widget, or ``None`` for the static picture alone.
    """

    def __init__(self, png: bytes, widget=None):
        self.png, self.widget = png, widget

    def _repr_mimebundle_(self, include=None, exclude=None) -> dict:
        bundle = {"image/png": self.png, "text/plain": "<creature view>"}
        if self.widget is not None:
            data = self.widget._repr_mimebundle_()
            bundle.update(data[0] if isinstance(data, tuple) else data)
        return bundle


def view(obj, *, interactive: bool = False, size=(480, 360), q=None, joint_axes: bool = True,
         background: str = "white", azimuth: float = 30.0, elevation: float = 25.0) -> View:
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


def animate(obj, trajectory, path, *, fps: int = 20, size=(480, 360), joint_axes: bool = False,
            background: str = "white", azimuth: float = 30.0, elevation: float = 25.0) -> Path:
    """Write a GIF of a creature swimming along a recorded trajectory.

    The camera keeps its direction and distance and follows the centre of the body, over a grid
    that stays put in the water, so forward motion shows.

    Args:
        obj: the creature (or Phenotype / BodyTree) that was simulated.
        trajectory: (F, nq) MuJoCo-layout ``qpos`` frames, e.g. ``simulate(...,
            record_every=k).trajectory[i]``.
        path: the GIF to write (atomically).
        fps: frames per second of the GIF.
        size, joint_axes, background, azimuth, elevation: as for :func:`render`.

    Returns:
        The written path.
    """
    import pyvista as pv

    body = _body_of(obj)
    _check_size(size)
    frames = np.asarray(trajectory, dtype=np.float64)
    if frames.ndim != 2 or len(frames) < 1:
        raise ValueError(f"trajectory: expected an (F, nq) array of qpos frames, got shape {frames.shape}")
    if not (isinstance(fps, (int, np.integer)) and 1 <= fps <= 60):
        raise ValueError(f"fps: must be an integer in [1, 60], got {fps!r}")
    poses = [world_poses(body, f) for f in frames]
    scene = _Scene(body, size, background, joint_axes and body.n_bodies > 1)
    try:
        extent = np.concatenate([scene.pose(*p) for p in (poses[0], poses[-1])])
        lo, hi = extent.min(0), extent.max(0)
        reach = float(np.ptp(np.concatenate([scene.pose(*p) for p in poses[:: max(1, len(poses) // 8)]]), axis=0).max())
        floor_z = float(lo[2]) - 0.3 * reach
        size_xy = 3.0 * max(reach, float(np.linalg.norm(hi - lo)), 0.5)
        centre0 = 0.5 * (lo + hi)
        grid = pv.Plane(center=(centre0[0], centre0[1], floor_z), direction=(0, 0, 1), i_size=size_xy, j_size=size_xy,
                        i_resolution=12, j_resolution=12)
        scene.pl.add_mesh(grid, style="wireframe", color="#7fa7c9", line_width=1)
        radius = max(float(np.linalg.norm(np.ptp(scene.pose(*poses[0]), axis=0))), 0.1) * 1.6

        with atomic_path(path, ".gif") as tmp:
            scene.pl.open_gif(str(tmp), fps=fps)
            for R, t in poses:
                c = scene.pose(R, t)
                scene.look(0.5 * (c.min(0) + c.max(0)), radius, azimuth, elevation)
                scene.pl.write_frame()
            scene.pl.mwriter.close()  # flush the GIF before it is moved into place
            scene.pl.mwriter = None
        return Path(path)
    finally:
        scene.pl.close()
