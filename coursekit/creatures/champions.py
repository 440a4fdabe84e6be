"""Pre-evolved swimmers that ship with the kit: the hall of fame of real runs.

Students should see a good swimmer without waiting for evolution. ``coursekit/data/champions.json``
holds each champion's genotype with the command and seed that evolved it, the code it was evolved
with, and what it measured then: its speed over 10 s (m/s) and its body length (m), hence body
lengths per second. A run is deterministic for its seed, its code and the machine's floating-point
kernels, but evolution is chaotic: any change to the physics sends it down another path, and so
does a difference in the last bit of one function. Such differences exist between x86-64 machines
with the same packages: numpy's AVX-512 kernels of ``tan``, ``exp``, ``log`` and ``arctan`` round
differently from its AVX2 ones, and OpenBLAS's ``solve`` depends on the kernels it picks for the
processor. The Sims-scale runs were made with the compiled step
(:mod:`~coursekit.creatures.physics.compiled`) on x86-64 processors with AVX-512 (numpy's
``X86_V4``, OpenBLAS's ``SkylakeX`` kernels; seeds 0 and 2 on an Intel Xeon, seed 1 on an AMD
EPYC), where their commands follow them generation by generation; there, ``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" OPENBLAS_CORETYPE=Haswell``
(read when numpy loads) takes another path (benchmarks/NOTES.md). The demo's champion is the
demo's seed-0 run at its classroom sizes with ``--budget 0`` (all 40 generations), made with the
same step on the Intel Xeon. All four were bred from randomly wired creatures, as before random
creatures had a rhythm (:func:`~coursekit.creatures.generation.add_rhythm`): their commands say
``--rhythm 0``. So a champion is not re-derived on every change -- only when the physics it
exploited is gone: seed 1's first champion swam by passing its paddles through its arms, and was bred
again once self-contacts were held (:mod:`~coursekit.creatures.physics.contact_forces`); its successor
swam on stops at the joint limits that pulled a joint along (0.76 m/s; 0.08 once a stop may only take
energy, :meth:`~coursekit.creatures.physics.limits.Limits.release`), and was bred again too. What the tests
check is what a student sees now: every champion still swims at its recorded pace, steadily, and
passes the audit (:mod:`~coursekit.creatures.audit`).

>>> [round(c.body_lengths_per_second, 2) for c in hall_of_fame()]
[0.38, 0.74, 0.38, 1.22]
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib import resources

from .genotype import Creature

#: The format tag of ``champions.json``.
FORMAT = "coursekit.champions/1"
_FIELDS = {"name": str, "command": str, "seed": int, "evolved_with": str, "speed": float, "body_length": float, "creature": dict}


@dataclass(frozen=True)
class Champion:
    """One entry of the hall of fame: the creature, how it was evolved, what it measured."""

    name: str
    command: str
    seed: int
    evolved_with: str
    speed: float  #: m/s over 10 s, when it was evolved
    body_length: float  #: m (:func:`~coursekit.creatures.audit.body_length`)
    creature: Creature

    @property
    def body_lengths_per_second(self) -> float:
        return self.speed / self.body_length


def hall_of_fame() -> list[Champion]:
    """Every shipped champion, with its provenance (module docstring).

    Raises:
        ValueError: the data file is not a champions file, naming the entry and field at fault.
    """
    doc = json.loads((resources.files("coursekit.data") / "champions.json").read_text())  # a data file, not the module's code
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"champions.json: format must be {FORMAT!r}")
    out = []
    for i, entry in enumerate(doc.get("champions", [])):
        for name, kind in _FIELDS.items():
            value = entry.get(name) if isinstance(entry, dict) else None
            if not isinstance(value, kind) or isinstance(value, bool) or (kind is float and not value > 0):
                raise ValueError(f"champions.json: champion {i}: field {name!r} must be {'a positive number' if kind is float else kind.__name__}, got {value!r}")
        out.append(Champion(**{**entry, "creature": Creature.from_json(json.dumps(entry["creature"]))}))
    return out


def champions() -> list[Creature]:
    """The shipped champions' creatures, fittest first (see :func:`hall_of_fame`)."""
    return [c.creature for c in sorted(hall_of_fame(), key=lambda c: -c.speed)]
