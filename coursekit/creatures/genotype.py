"""The genotype of a swimming creature: :class:`Creature` (paper section 2.1).

A :class:`Creature` is the morphology graph — a list of :class:`~.morphology.Node` (node 0 is the
root) with its links, recursion and symmetry entries (:mod:`.morphology`, section 2.1.1) — plus a
central brain, a list of :class:`~coursekit.creatures.neural.Neuron` (section 2.1.2). It
validates itself, reads and writes its JSON file, expands into a phenotype
(:func:`.phenotype.expand`), shows itself in a notebook (:mod:`.render`) and is made at random or
by hand through :mod:`.generation` (``Creature.random``, ``Creature.figure1_snake``,
``Creature.paddle_turtle``). The names of :mod:`.morphology` and :mod:`.generation` (the
elements, the value lists, the random elements) are also importable from here.

Files are JSON with ``"format": "coursekit.creature/2"`` (version 2 adds each node's
``extra_limits``, the limits of multi-DOF joints), written atomically; version 1 files (1-DOF
joints only) are still read, as the same creatures.
"""

from __future__ import annotations

import base64
import copy
import html
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from coursekit.atomic import atomic_write

from . import generation
from .body import MAX_HALF_EXTENT, MIN_HALF_EXTENT
from .generation import (
    AXES,
    COORDS,
    DEFAULT_JOINT_TYPES,
    FACES,
    FORCES,
    PRISMATIC_LIMITS,
    REVOLUTE_LIMITS,
    ROTATIONS,
    SCALES,
    SIZES,
    choice,
    facing_rotation,
    limit_values,
    mirror_axis,
    random_face_point,
    random_link,
    random_node,
    random_recursion,
)
from .morphology import (
    IDENTITY,
    JOINT_AXES,
    JOINT_DOF,
    MAX_CHILDREN,
    MAX_FORCE,
    MAX_NODES,
    MAX_RECURSION_ENTRIES,
    MAX_RECURSIVE_LIMIT,
    MAX_SYMMETRY,
    SCALE_RANGE,
    ChildLink,
    Node,
    Recursion,
    Symmetry,
    has_cycle,
    node_from_dict,
    preorder,
    renumber,
    validate_node,
)
from .neural import MAX_BRAIN_NEURONS, Neuron, need_keys, validate_neuron
from .phenotype import MAX_PARTS, Phenotype, expand
from . import render as rendering  # the module (the package's name `render` is the function)

__all__ = ["FORMAT", "Creature", "ChildLink", "Node", "Recursion", "Symmetry", "JOINT_AXES", "JOINT_DOF",
           "DEFAULT_JOINT_TYPES", "limit_values", "MAX_HALF_EXTENT",
           "MIN_HALF_EXTENT", "MAX_NODES", "MAX_CHILDREN", "MAX_RECURSION_ENTRIES", "MAX_RECURSIVE_LIMIT",
           "MAX_SYMMETRY", "MAX_FORCE", "SCALE_RANGE", "IDENTITY", "SIZES", "COORDS", "FORCES", "REVOLUTE_LIMITS",
           "PRISMATIC_LIMITS", "SCALES", "AXES", "ROTATIONS", "FACES", "choice", "facing_rotation", "mirror_axis",
           "random_face_point", "random_link", "random_node", "random_recursion", "validate_node", "preorder",
           "renumber", "has_cycle"]

FORMAT = "coursekit.creature/2"
#: Every format version this module reads (the first had no multi-DOF joints).
READABLE_FORMATS = {"coursekit.creature/1": 1, FORMAT: 2}


@dataclass
class Creature:
    """A creature's genotype: morphology nodes (root first) and the central brain."""

    nodes: list
    brain: list = field(default_factory=list)

    def __post_init__(self) -> None:
        self.validate()

    # ------------------------------------------------------------------------ validity
    def validate(self) -> None:
        """Raise ``ValueError``/``TypeError`` naming the field when the genotype is invalid."""
        if not isinstance(self.nodes, list) or not 1 <= len(self.nodes) <= MAX_NODES:
            raise ValueError(f"Creature.nodes: need a list of 1..{MAX_NODES} nodes, got {self.nodes!r:.80}")
        if not isinstance(self.brain, list) or len(self.brain) > MAX_BRAIN_NEURONS:
            raise ValueError(f"Creature.brain: need a list of at most {MAX_BRAIN_NEURONS} neurons")
        for k, n in enumerate(self.brain):
            validate_neuron(n, f"Creature.brain[{k}]", brain=True, n_local=len(self.brain), n_brain=len(self.brain))
        for i, node in enumerate(self.nodes):
            validate_node(node, f"Creature.nodes[{i}]", len(self.nodes), len(self.brain))
        if has_cycle(self.nodes):
            raise ValueError("Creature.nodes: the child links form a cycle; use the recursion attribute for repetition")
        reach = preorder(self.nodes)
        if len(reach) != len(self.nodes):
            missing = sorted(set(range(len(self.nodes))) - set(reach))
            raise ValueError(f"Creature.nodes: nodes {missing} are unreachable from the root (collect garbage first)")

    def copy(self) -> "Creature":
        return copy.deepcopy(self)

    def unwired(self) -> "Creature":
        """A copy with the body alone: no neurons, no brain, every effector off (exercise 06 wires it)."""
        out = self.copy()
        for node in out.nodes:
            node.neurons = []
            node.effectors = [None] * node.dof
        out.brain = []
        return out

    # ------------------------------------------------------------------------ display
    #: (width, height) of the picture a notebook shows for a creature, in pixels.
    REPR_SIZE = (400, 300)

    def summary(self) -> dict:
        """What a person wants to know first, from the expanded body: ``parts``, ``joints``,
        ``dof`` (the joints' degrees of freedom; the free root adds 6 more), ``mass`` (kg),
        ``neurons`` (expanded, central brain included), and the genotype's ``nodes``.

        >>> Creature.figure1_snake().summary()["parts"]
        6
        """
        ph = self.expand()
        body = ph.body
        dof = body.n_joints  # one body-tree joint per DOF (multi-DOF joints are chains of hinges)
        return {"parts": body.n_parts, "joints": body.n_parts - 1, "dof": int(dof), "mass": float(body.mass.sum()),
                "neurons": int(ph.brain.n_neurons), "nodes": len(self.nodes)}

    def __repr__(self) -> str:
        """Short: the genotype's size (``to_json`` has everything).

        >>> Creature.figure1_snake()
        Creature(2 nodes, 1 brain neuron)
        """
        n, k = len(self.nodes), len(self.brain)
        return f"Creature({n} node{'s' * (n != 1)}, {k} brain neuron{'s' * (k != 1)})"

    def _repr_png_(self) -> bytes:
        """Its rendering (``REPR_SIZE``), for notebooks."""
        return self._repr_mimebundle_()["image/png"]

    def _repr_html_(self) -> str:
        """Its rendering with a one-line summary (parts, joints, DOF, mass, neurons), for notebooks."""
        return self._repr_mimebundle_()["text/html"]

    def _repr_mimebundle_(self, include=None, exclude=None) -> dict:
        """PNG, HTML (the PNG with its summary below) and text, from one rendering."""
        from coursekit.pictures.gallery import png_bytes  # not at import: it loads torch

        png = png_bytes(rendering.render(self, size=self.REPR_SIZE) / 255.0)
        s = self.summary()
        caption = (f"{s['parts']} parts, {s['joints']} joints, {s['dof']} DOF (+6 free root), "
                   f"{s['mass']:.3g} kg, {s['neurons']} neurons; genotype of {s['nodes']} nodes")
        data = base64.b64encode(png).decode("ascii")
        page = (f'<figure style="margin:0"><img src="data:image/png;base64,{data}" width="{self.REPR_SIZE[0]}" '
                f'alt="{html.escape(repr(self))}"><figcaption style="font-size:smaller">{html.escape(caption)}'
                "</figcaption></figure>")
        return {"image/png": png, "text/html": page, "text/plain": repr(self)}

    # --------------------------------------------------------------------------- files
    def to_dict(self) -> dict:
        return {"format": FORMAT, "nodes": [n.to_dict() for n in self.nodes], "brain": [n.to_dict() for n in self.brain]}

    def to_json(self) -> str:
        """Versioned JSON text (``"format": "coursekit.creature/2"``)."""
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_dict(cls, d: dict) -> "Creature":
        if not isinstance(d, dict):
            raise TypeError(f"creature: expected a JSON object, got {type(d).__name__}")
        fmt = d.get("format")
        if not isinstance(fmt, str) or fmt not in READABLE_FORMATS:
            raise ValueError(f"creature.format: expected one of {list(READABLE_FORMATS)}, got {fmt!r} (not a coursekit creature file?)")
        need_keys(d, ("nodes", "brain"), "creature")
        if not isinstance(d["nodes"], list) or not isinstance(d["brain"], list):
            raise TypeError("creature.nodes / creature.brain: expected lists")
        nodes = [node_from_dict(n, f"creature.nodes[{i}]", READABLE_FORMATS[fmt]) for i, n in enumerate(d["nodes"])]
        brain = [Neuron.from_dict(n, f"creature.brain[{k}]") for k, n in enumerate(d["brain"])]
        return cls(nodes, brain)

    @classmethod
    def from_json(cls, text: str) -> "Creature":
        """Parse :meth:`to_json` output; truncated or foreign text raises ``ValueError``."""
        if not isinstance(text, (str, bytes)):
            raise TypeError(f"Creature.from_json: expected str, got {type(text).__name__}")
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"Creature.from_json: not valid JSON (truncated file?): {e}") from None
        return cls.from_dict(d)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the JSON atomically (temporary file in the same folder, then ``os.replace``)."""
        atomic_write(path, self.to_json())

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> "Creature":
        """Read a file written by :meth:`save`."""
        try:
            text = Path(path).read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"Creature.load: {path} is not a text creature file") from None
        return cls.from_json(text)

    # ---------------------------------------------------------------------- phenotype
    def expand(self, max_parts: int | None = None) -> Phenotype:
        """The phenotype (body tree + flat brain); see :func:`coursekit.creatures.phenotype.expand`."""
        return expand(self, MAX_PARTS if max_parts is None else max_parts)

    # ------------------------------------------------------------------------- makers
    @classmethod
    def random(cls, rng: np.random.Generator, **params: Any) -> "Creature":
        """A random valid creature: see :func:`.generation.random_genotype` for ``params``
        (``n_nodes``, ``max_children``, ``neurons``, ``brain_neurons``, ``p_recursion``,
        ``p_symmetry``, ``max_parts``, ``joint_types``: e.g. ``["revolute", "spherical"]`` for
        multi-DOF joints). Nodes are numbered in LR pre-order, all reachable, acyclic."""
        return cls(*generation.random_genotype(rng, **params))

    @classmethod
    def figure1_snake(cls, segments: int = 4) -> "Creature":
        """The paper's Figure 1, a snake with two legs at the last limb (:func:`.generation.figure1_snake`)."""
        return cls(*generation.figure1_snake(segments))

    @classmethod
    def paddle_turtle(cls) -> "Creature":
        """A flat body rowing two feathering paddles (:func:`.generation.paddle_turtle`)."""
        return cls(*generation.paddle_turtle())
