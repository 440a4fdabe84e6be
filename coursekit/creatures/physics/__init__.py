"""The batched swimmer simulator (paper section 2.4): spatial algebra, ABA, water, contact, integration.

Public entry points: :func:`forward_dynamics` (MuJoCo-layout validation interface),
:class:`Model` (a packed population) and :func:`random_body_tree` (test bodies).
"""

from .dynamics import forward_dynamics
from .model import Model, as_trees
from .samples import random_body_tree, random_state

__all__ = ["forward_dynamics", "Model", "as_trees", "random_body_tree", "random_state"]
