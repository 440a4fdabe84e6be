"""The shipped champions swim as recorded, steadily, and honestly (issue #11: champions ship with the kit)."""

import json

import numpy as np
import pytest

from coursekit.creatures import Creature, champions, simulate
from coursekit.creatures.audit import audit, body_length
from coursekit.creatures.champions import hall_of_fame


@pytest.fixture(scope="module")
def swims():
    fame = hall_of_fame()
    return fame, simulate([c.creature for c in fame], 10.0)


def test_every_champion_swims_at_its_recorded_pace_and_keeps_it(swims):
    fame, r = swims
    assert fame and len(champions()) == len(fame)
    for k, c in enumerate(fame):
        com = r.com[k]
        speed = np.linalg.norm(com[-1] - com[0]) / 10.0
        assert speed == pytest.approx(c.speed, rel=0.05), c.name
        assert body_length(c.creature.expand().body) == pytest.approx(c.body_length, rel=0.01)
        assert c.body_lengths_per_second >= 0.1, c.name  # a tenth of its length a second, or better
        half = len(com) // 2
        first, second = np.linalg.norm(com[half] - com[0]), np.linalg.norm(com[-1] - com[half])
        assert second >= 0.8 * first, (c.name, first, second)  # a stroke it repeats, not one push or one fold


def test_every_champion_passes_the_audit():
    reports = audit(champions(), 10.0)
    assert all(r.passed for r in reports), [str(r) for r in reports]


def test_a_broken_champions_file_names_the_entry_and_field(tmp_path, monkeypatch):
    import importlib
    from importlib import resources

    module = importlib.import_module("coursekit.creatures.champions")  # the package's champions() shadows the name

    good = json.loads((resources.files("coursekit.data") / "champions.json").read_text())
    bad = dict(good, champions=[dict(good["champions"][0], speed=-1.0)])
    (tmp_path / "champions.json").write_text(json.dumps(bad))
    monkeypatch.setattr(module.resources, "files", lambda package: tmp_path)
    with pytest.raises(ValueError, match="champion 0: field 'speed' must be a positive number"):
        hall_of_fame()
    (tmp_path / "champions.json").write_text(json.dumps({"format": "something else"}))
    with pytest.raises(ValueError, match="format"):
        hall_of_fame()
    assert isinstance(Creature.from_json(json.dumps(good["champions"][0]["creature"])), Creature)
