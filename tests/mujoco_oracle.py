"""MuJoCo as the oracle: ``mj_forward``'s accelerations for exported creatures (shared by the cross-check tests)."""

import numpy as np

import mujoco  # in the [test] extra: the cross-check must run, never skip

from coursekit.creatures.mjcf import to_mjcf


def mujoco_qacc(trees, states, tau):
    """MuJoCo's ``qacc`` (flat, MuJoCo layout) for ``trees`` in ``states`` with generalised forces ``tau``."""
    model = mujoco.MjModel.from_xml_string(to_mjcf(trees))
    data = mujoco.MjData(model)
    data.qpos[:] = np.concatenate([s[0] for s in states])
    data.qvel[:] = np.concatenate([s[1] for s in states])
    data.qfrc_applied[:] = np.concatenate(tau)
    mujoco.mj_forward(model, data)
    assert data.nefc == 0, "states must be inside limits (no active constraints)"
    return data.qacc.copy()
