"""Looking at creatures: off-screen pyvista pictures of expanded bodies (paper section 2.3, Fig. 1).

Parts are drawn as boxes coloured by their depth in the part tree (root dark, leaves bright,
matplotlib's ``viridis``), with every joint's axis as a short red line through its anchor
(prismatic joints in blue). Rendering is off-screen through VTK's EGL window (no X server);
``VTK_DEFAULT_OPENGL_WINDOW`` is set to ``vtkEGLRenderWindow`` unless the caller chose one.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")

from .body import PRISMATIC, BodyTree  # noqa: E402
from .phenotype import Phenotype, part_poses  # noqa: E402

_BOX_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)


def _body_of(obj) -> BodyTree:
    from .genotype import Creature

    if isinstance(obj, Creature):
        return obj.expand().body
    if isinstance(obj, Phenotype):
        return obj.body
    if isinstance(obj, BodyTree):
        return obj
    raise TypeError(f"render: expected a Creature, Phenotype or BodyTree, got {type(obj).__name__}")


def box_corners(body: BodyTree, q=None) -> np.ndarray:
    """(B, 8, 3) world corners of every part's box (root at the origin)."""
    R, t = part_poses(body, q)
    local = _BOX_CORNERS[None, :, :] * body.half_extents[:, None, :]
    return np.einsum("bij,bkj->bki", R, local) + t[:, None, :]


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
        >>> img = render(Creature.figure1_snake())  # doctest: +SKIP
    """
    import matplotlib
    import pyvista as pv

    body = _body_of(obj)
    if len(size) != 2 or not all(isinstance(s, (int, np.integer)) and 16 <= s <= 4096 for s in size):
        raise ValueError(f"render.size: need (width, height) integers in [16, 4096], got {size!r}")
    corners = box_corners(body, q)
    depth = body.depth
    cmap = matplotlib.colormaps["viridis"]
    top = max(int(depth.max()), 1)
    R, t = part_poses(body, q)
    pl = pv.Plotter(off_screen=True, window_size=list(size))
    try:
        pl.set_background(background)
        for b in range(body.n_bodies):
            box = pv.Box(bounds=(-1, 1, -1, 1, -1, 1))
            pts = np.asarray(box.points) * body.half_extents[b]
            box.points = pts @ R[b].T + t[b]
            colour = cmap(0.15 + 0.75 * depth[b] / top)[:3]
            pl.add_mesh(box, color=colour, show_edges=True, edge_color="black", line_width=1, smooth_shading=False)
        if joint_axes and body.n_bodies > 1:
            for b in range(1, body.n_bodies):
                L = 2.4 * float(body.half_extents[b].max())
                anchor = R[b] @ body.joint_pos_child[b] + t[b]
                a = R[b] @ body.joint_axis[b]
                colour = "blue" if body.joint_type[b] == PRISMATIC else "red"
                pl.add_mesh(pv.Line(anchor - 0.5 * L * a, anchor + 0.5 * L * a), color=colour, line_width=4)
        lo, hi = corners.reshape(-1, 3).min(0), corners.reshape(-1, 3).max(0)
        centre = 0.5 * (lo + hi)
        radius = max(float(np.linalg.norm(hi - lo)), 0.1)
        az, el = np.radians(azimuth), np.radians(elevation)
        eye = centre + radius * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        pl.camera_position = [tuple(eye), tuple(centre), (0.0, 0.0, 1.0)]
        pl.reset_camera()  # keep the direction, fit the distance to the bounds
        if path is None:
            return np.asarray(pl.screenshot(return_img=True))[..., :3].copy()
        path = Path(path)
        fd, tmp = tempfile.mkstemp(prefix=path.stem + ".", suffix=".png", dir=path.parent or ".")
        os.close(fd)
        try:
            pl.screenshot(tmp)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return path
    finally:
        pl.close()
