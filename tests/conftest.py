"""Test-suite settings: on CI, hypothesis draws the same examples every run (``derandomize``);
MuJoCo's warnings go to the ``coursekit.mujoco`` logger (pytest shows them with a failure).

Locally every run explores new examples; a failure there is reproduced by its printed seed. CI
must not turn red on an example no one has seen, so it replays a fixed set -- the explicit
``@example`` cases plus the same generated ones each time.
"""

import os

from hypothesis import settings

from coursekit.creatures.mjcf import log_mujoco_warnings

log_mujoco_warnings()  # MuJoCo's warnings go to a logger, not into a MUJOCO_LOG.TXT in the checkout

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")
