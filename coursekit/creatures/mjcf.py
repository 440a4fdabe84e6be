"""MuJoCo MJCF export of creature bodies (paper section 2.3; validation of section 2.4).

``to_mjcf`` writes the body tree of a creature (or several, side by side) as an MJCF model that
MuJoCo loads with ``mujoco.MjModel.from_xml_string``: one ``<body>`` per box with an explicit
``<inertial>`` (exact box mass and principal inertia at the centre), a free root joint, ``hinge``
and ``slide`` joints with their limits (a multi-DOF joint is its hinges in series, several
``<joint>`` of one ``<body>``: the body tree's massless frames are not bodies there), one ``<motor>`` per joint DOF (``gear`` = the joint's signed
gain, force range = its strength), gravity off. Box geoms are visual only (no MuJoCo contacts) unless ``contacts=True``, where
they collide under MuJoCo's own rules (every pair of boxes but parent and child; creatures are
then spaced apart so that they never touch one another); water is not exported. Its ``qpos``/``qvel`` layout is the one of
:func:`coursekit.creatures.physics.forward_dynamics`.

``mujoco_model`` loads the export into MuJoCo (the optional ``mujoco`` extra) and sends MuJoCo's
warnings ("Nan, Inf or huge value in QACC ...") to the Python logger ``coursekit.mujoco``, where
a notebook shows them and a test can catch them, instead of MuJoCo's default of printing them
and appending them to a ``MUJOCO_LOG.TXT`` in whatever folder the process runs in.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any
from xml.sax.saxutils import quoteattr

import numpy as np

from coursekit.creatures.body import REVOLUTE
from coursekit.creatures.physics.model import as_trees
from coursekit.creatures.physics.spatial import mat_to_quat

if TYPE_CHECKING:
    import mujoco

LOG = logging.getLogger("coursekit.mujoco")


def _f(values) -> str:
    return " ".join(repr(float(v)) for v in np.ravel(values))


def is_depth_first(parent: np.ndarray) -> bool:
    """True when ``parent`` lists a tree in depth-first pre-order (MuJoCo's body order)."""
    # in depth-first pre-order every body's parent is on the path from the root to body i-1
    path = [0]
    for i in range(1, len(parent)):
        while path and path[-1] != parent[i]:
            path.pop()
        if not path:
            return False
        path.append(i)
    return True


def _creature_xml(tree, prefix: str, pos, contacts: bool = False) -> tuple[list[str], list[str]]:
    if not is_depth_first(tree.parent):
        raise ValueError(
            f"BodyTree.parent: MJCF lists joints depth-first, so the tree must be in depth-first pre-order; got {tree.parent.tolist()}"
        )
    lines, motors = [], []
    quats = mat_to_quat(tree.joint_rot)
    children = [[] for _ in range(tree.n_bodies)]
    for i in range(1, tree.n_bodies):
        children[tree.parent[i]].append(i)

    def body(i: int, indent: str) -> None:
        """The part whose joint's first DOF is body ``i``: after massless frames, body ``b``."""
        chain = [i]
        while tree.massless[chain[-1]]:
            chain.append(children[chain[-1]][0])
        b = chain[-1]
        name = f"{prefix}b{b}"
        if i == 0:
            lines.append(f'{indent}<body name="{name}" pos="{_f(pos)}">')
            lines.append(f'{indent}  <freejoint name="{prefix}root"/>')
        else:
            # the part's pose at q = 0 (the massless frames' joints have no rotation or offset of their own)
            bpos = tree.joint_pos_parent[i] - tree.joint_rot[i] @ tree.joint_pos_child[b]
            lines.append(f'{indent}<body name="{name}" pos="{_f(bpos)}" quat="{_f(quats[i])}">')
            for j in chain:  # MuJoCo applies a body's joints in series, in order: one per DOF
                kind = "hinge" if tree.joint_type[j] == REVOLUTE else "slide"
                jname = f"{prefix}j{j}"
                lines.append(
                    f'{indent}  <joint name="{jname}" type="{kind}" pos="{_f(tree.joint_pos_child[b])}" '
                    f'axis="{_f(tree.joint_axis[j])}" limited="true" range="{_f(tree.limits[j])}"/>'
                )
                s = float(tree.strength[j])
                motors.append(
                    f'    <motor name="{prefix}m{j}" joint="{jname}" gear="{_f([tree.gain[j]])}" ctrllimited="true" '
                    f'ctrlrange="-1 1" forcelimited="true" forcerange="{_f([-s, s])}"/>'
                )
        lines.append(
            f'{indent}  <inertial pos="0 0 0" mass="{_f([tree.mass[b]])}" diaginertia="{_f(tree.inertia[b])}"/>'
        )
        collide = "" if contacts else ' contype="0" conaffinity="0"'
        lines.append(f'{indent}  <geom type="box" size="{_f(tree.half_extents[b])}"{collide}/>')
        for k in children[b]:
            body(k, indent + "  ")
        lines.append(f"{indent}</body>")

    body(0, "    ")
    return lines, motors


def reach(tree: Any) -> float:
    """An upper bound of how far any point of ``tree`` lies from its root's centre (m)."""
    return float(2.0 * np.linalg.norm(tree.half_extents, axis=1).sum())


def to_mjcf(creatures: Any, *, timestep: float = 1.0 / 60.0, integrator: str = "RK4", name: str = "coursekit",
            contacts: bool = False) -> str:
    """MJCF text of one creature or a list of creatures (each its own free-floating tree).

    Args:
        creatures: a BodyTree, an object with ``.expand().body`` (a creature), or a list of them.
        timestep: MuJoCo ``<option timestep>``.
        integrator: MuJoCo integrator name ("RK4", "Euler", "implicit", "implicitfast").
        name: model name.
        contacts: the boxes collide (MuJoCo's default filter: every pair but parent and child);
            the creatures' roots are then spaced along x by their :func:`reach` plus 1 m, so that
            two creatures never touch (the roots' ``qpos0``), instead of 2 m apart.

    Returns:
        The MJCF document. Bodies of creature ``c`` are named ``c{c}_b{i}``, joints ``c{c}_j{i}``
        (``i`` the body-tree index of the part, and of the body carrying the DOF).
    """
    if not (np.isfinite(timestep) and timestep > 0):
        raise ValueError(f"timestep: must be a positive number, got {timestep}")
    if integrator not in ("RK4", "Euler", "implicit", "implicitfast"):
        raise ValueError(f"integrator: got {integrator!r}; allowed: RK4, Euler, implicit, implicitfast")
    trees = as_trees(creatures)
    body_lines, motor_lines = [], []
    x = 0.0
    for c, tree in enumerate(trees):
        if contacts and c:
            x += reach(trees[c - 1]) + reach(tree) + 1.0
        b, m = _creature_xml(tree, f"c{c}_", [x if contacts else 2.0 * c, 0.0, 0.0], contacts)
        body_lines += b
        motor_lines += m
    out = [
        f"<mujoco model={quoteattr(name)}>",
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{_f([timestep])}" integrator="{integrator}" gravity="0 0 0"/>',
        "  <worldbody>",
        *body_lines,
        "  </worldbody>",
    ]
    if motor_lines:
        out += ["  <actuator>", *motor_lines, "  </actuator>"]
    out.append("</mujoco>")
    return "\n".join(out) + "\n"


def _warn(message: str) -> None:
    LOG.warning("MuJoCo: %s", message.strip())


def log_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to the logger ``coursekit.mujoco`` from now on (for the whole
    process: MuJoCo's warning handler is global), instead of printing them and writing them to
    ``MUJOCO_LOG.TXT`` in the current folder. Idempotent; needs ``mujoco``."""
    import mujoco

    if mujoco.get_mju_user_warning() is not _warn:
        mujoco.set_mju_user_warning(_warn)


def mujoco_model(creatures: Any, **options: Any) -> mujoco.MjModel:
    """A ``mujoco.MjModel`` of :func:`to_mjcf` ``(creatures, **options)``, with MuJoCo's warnings
    sent to the ``coursekit.mujoco`` logger (:func:`log_mujoco_warnings`).

    Raises:
        ModuleNotFoundError: when MuJoCo is not installed, naming the extra that brings it.
    """
    try:
        import mujoco
    except ModuleNotFoundError as exc:
        raise ModuleNotFoundError("mujoco_model needs MuJoCo: pip install 'coursekit[mujoco]'") from exc
    log_mujoco_warnings()
    return mujoco.MjModel.from_xml_string(to_mjcf(creatures, **options))
