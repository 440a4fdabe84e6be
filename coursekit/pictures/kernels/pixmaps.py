"""The stock pictures as a primitive, ``pixmap`` (paper section 3.2).

On coordinates shared by the batch and :func:`~coursekit.pictures.context.separable` a picture
is sampled rows, then columns, and kept for the render (and across renders of one size and
window); otherwise ``grid_sample``, bilinear with border padding, on folded coordinates.
"""

from __future__ import annotations

import torch

from .. import textures as T
from ..context import fold, host
from ..primitives import image_kernel

__all__: list[str] = []  # reached through the registry

def _bilinear_axis(f: torch.Tensor, n: int):
    """Source indices and weights of grid_sample's bilinear sampling (align_corners=False,
    border padding) at unit coordinates f along an axis of n pixels."""
    t = (f * n - 0.5).clamp_(0.0, n - 1.0)
    i0 = torch.floor(t)
    return i0.long(), (i0 + 1.0).clamp_(max=n - 1.0).long(), t - i0


def _pixmap_separable(img: torch.Tensor, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """Bilinear sampling of img (1, 3, h, w) at fold(x) (W,) and fold(y) (H,): rows, then columns."""
    r0, r1, wy = _bilinear_axis(fold(y), img.shape[2])
    c0, c1, wx = _bilinear_axis(fold(x), img.shape[3])
    rows = torch.lerp(img[:, :, r0], img[:, :, r1], wy[:, None])  # (1, 3, H, w)
    return torch.lerp(rows[..., c0], rows[..., c1], wx)


def _pixmap(ctx, p):
    idx = [T.pixmap_index(v) for v in host(p[0])]
    B = len(idx)
    if ctx.separable:
        # separable coordinates (an unwarped context): sample rows then columns, and keep the
        # result for the whole render (and across renders of the same size and window)
        key = None if ctx.key is None else ("pixmap", ctx.key)
        pics = [ctx.res.sampled((key, i) if key else None,
                                lambda i=i: _pixmap_separable(ctx.res.pixmap(i), ctx.x[0, 0, 0], ctx.y[0, 0, :, 0]))
                for i in idx]
        return pics[0] if B == 1 else torch.cat(pics)
    x, y = torch.broadcast_tensors(fold(ctx.x), fold(ctx.y))
    grid = torch.empty(x.shape[0], ctx.H, ctx.W, 2, dtype=x.dtype, device=x.device)
    torch.mul(x[:, 0], 2.0, out=grid[..., 0])
    torch.mul(y[:, 0], 2.0, out=grid[..., 1])
    grid.sub_(1.0)
    if B == 1:  # one picture (a uniform node may see per-genome coordinates)
        return torch.nn.functional.grid_sample(ctx.res.pixmap(idx[0]).expand(grid.shape[0], -1, -1, -1), grid,
                                               mode="bilinear", padding_mode="border", align_corners=False)
    grid = grid.expand(B, ctx.H, ctx.W, 2)
    out = torch.empty(B, 3, ctx.H, ctx.W, dtype=x.dtype, device=x.device)
    for i in sorted(set(idx)):
        sel = [b for b in range(B) if idx[b] == i]
        img = ctx.res.pixmap(i).expand(len(sel), -1, -1, -1)
        out[sel] = torch.nn.functional.grid_sample(img, grid[sel].contiguous(), mode="bilinear",
                                                   padding_mode="border", align_corners=False)
    return out


image_kernel("pixmap")(_pixmap)
