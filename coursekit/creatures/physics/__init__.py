"""The batched swimmer simulator (paper section 2.4): spatial algebra, ABA, water, contact, integration.

Modules: :mod:`.spatial` (spatial vectors), :mod:`.model` (a population packed by tree depth),
:mod:`.aba` (Featherstone's articulated-body algorithm), :mod:`.water` (Sims' drag),
:mod:`.limits` (joint limits as constraints), :mod:`.contact` (OBB self-collisions), :mod:`.integrate`
(RKN / RK4), :mod:`.world` (stepping a batch with guards), :mod:`.compiled` and :mod:`.kernels`
(the default step, compiled with numba), :mod:`.graph` (the step as a CUDA graph), :mod:`.jcalc`
(joint transforms), :mod:`.reference` (the book's ABA), :mod:`.dynamics` (MuJoCo-layout forward
dynamics), :mod:`.backend` (numpy / torch), :mod:`.samples` (random bodies).
"""

from .dynamics import forward_dynamics
from .model import Model, as_trees
from .samples import random_body_tree, random_state
from .water import DRAG_COEFFICIENT
from .world import World

__all__ = ["DRAG_COEFFICIENT", "Model", "World", "as_trees", "forward_dynamics", "random_body_tree", "random_state"]
