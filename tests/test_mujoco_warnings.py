"""MuJoCo's warnings reach the ``coursekit.mujoco`` logger and leave no MUJOCO_LOG.TXT behind."""

import logging

import mujoco  # in the [test] extra: the cross-check must run, never skip
import numpy as np
import pytest

from coursekit.creatures import Creature
from coursekit.creatures.mjcf import mujoco_model, to_mjcf


def test_an_unstable_state_is_logged_not_written_to_a_file(tmp_path, monkeypatch, caplog):
    monkeypatch.chdir(tmp_path)  # MuJoCo's own handler appends to MUJOCO_LOG.TXT in the working folder
    model = mujoco_model(Creature.random(np.random.default_rng(3)))
    data = mujoco.MjData(model)
    data.qvel[:] = np.nan  # MuJoCo resets the state and warns: "Nan, Inf or huge value in QVEL"
    with caplog.at_level(logging.WARNING, logger="coursekit.mujoco"):
        mujoco.mj_step(model, data)
    assert data.warning[mujoco.mjtWarning.mjWARN_BADQVEL].number == 1
    messages = [r.getMessage() for r in caplog.records if r.name == "coursekit.mujoco"]
    assert len(messages) == 1 and "QVEL" in messages[0], messages
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def test_the_model_is_the_export():
    creature = Creature.random(np.random.default_rng(5))
    a = mujoco_model(creature, timestep=0.01)
    b = mujoco.MjModel.from_xml_string(to_mjcf(creature, timestep=0.01))
    assert (a.nbody, a.njnt, a.nu, a.opt.timestep) == (b.nbody, b.njnt, b.nu, 0.01)
    np.testing.assert_array_equal(a.body_mass, b.body_mass)


def test_bad_options_are_refused_by_name():
    with pytest.raises(ValueError, match="integrator"):
        mujoco_model(Creature.random(np.random.default_rng(5)), integrator="Verlet")
