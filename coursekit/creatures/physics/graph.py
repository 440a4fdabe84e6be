"""How :class:`~coursekit.creatures.physics.world.World` records its graph-ready step on CUDA.

Graph capture is hand-written because what a step hands the next (state, locks, contact anchors,
reused inertias) is this simulator's own (:meth:`World._carried
<coursekit.creatures.physics.world.World._carried>`); torch's
``torch.cuda.graphs.make_graphed_callables`` is for autograd modules with fixed inputs and outputs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from . import backend as bk


class CudaGraph:
    """How :class:`World` records its graph-ready step on CUDA: a ``torch.cuda.CUDAGraph``.

    The interface :meth:`World._graph_step` uses (:attr:`World.GRAPH`): ``applies(world)``, ``warm(world,
    step)`` for an eager step before the capture, ``CudaGraph(world)``, ``capture(record)`` and
    ``replay()``.
    """

    def __init__(self, world: Any):
        import torch

        self.graph = torch.cuda.CUDAGraph()

    @staticmethod
    def applies(world: Any) -> bool:
        return bk.is_torch(world.xp) and world.model.device is not None and str(world.model.device).startswith("cuda")

    @staticmethod
    def warm(world: Any, step: Callable[[], None]) -> None:
        """An eager step on a side stream (torch asks for a warm-up there before a capture)."""
        import torch

        device = world.model.device
        side = torch.cuda.Stream(device=device)
        side.wait_stream(torch.cuda.current_stream(device))
        with torch.cuda.stream(side):
            step()
        torch.cuda.current_stream(device).wait_stream(side)

    def capture(self, record: Callable[[], None]) -> None:
        import torch

        with torch.cuda.graph(self.graph):
            record()

    def replay(self) -> None:
        self.graph.replay()
