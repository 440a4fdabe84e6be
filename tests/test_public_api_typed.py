"""The public API is typed: ``py.typed`` ships with the package (tests/test_course.py checks the
wheel), so every function the public packages export, and every public method of the classes
they export, annotates all its parameters and its return, and every annotation names a real type."""

import importlib
import importlib.resources
import inspect
import typing

import matplotlib.axes
import matplotlib.figure
import mujoco  # in the [test] extra
import pytest
from matplotlib.animation import FuncAnimation

from coursekit.creatures import BodyTree, Creature, Phenotype

PUBLIC = ["coursekit.pictures", "coursekit.pictures.operators", "coursekit.pictures.primitives",
          "coursekit.pictures.figures", "coursekit.creatures", "coursekit.creatures.operators",
          "coursekit.creatures.physics", "coursekit.creatures.render", "coursekit.creatures.mjcf",
          "coursekit.creatures.figures", "coursekit.ga", "coursekit.grading", "coursekit.data", "coursekit.profile",
          "coursekit.atomic"]
# names modules import only for type checkers (``if TYPE_CHECKING:``), to resolve their annotations
CHECKER_ONLY = {"matplotlib": matplotlib, "mujoco": mujoco, "FuncAnimation": FuncAnimation, "Creature": Creature, "Phenotype": Phenotype,
                "BodyTree": BodyTree}


def public_callables():
    seen = {}
    for name in PUBLIC:
        module = importlib.import_module(name)
        for attr in getattr(module, "__all__", [n for n in vars(module) if not n.startswith("_")]):
            obj = getattr(module, attr)
            if inspect.isfunction(obj) and obj.__module__.startswith("coursekit"):
                seen.setdefault(f"{obj.__module__}.{obj.__qualname__}", obj)
            elif inspect.isclass(obj) and obj.__module__.startswith("coursekit"):
                for key, value in vars(obj).items():
                    if isinstance(value, (classmethod, staticmethod)):
                        value = value.__func__
                    if inspect.isfunction(value) and (not key.startswith("_") or key == "__init__"):
                        seen.setdefault(f"{obj.__module__}.{value.__qualname__}", value)
    return seen


CALLABLES = public_callables()


def test_the_package_is_marked_typed():
    assert (importlib.resources.files("coursekit") / "py.typed").is_file()


def test_the_public_api_is_found():
    # the contract's names (shared/DESIGN.md) are among the callables checked below
    for name in ["coursekit.pictures.evaluate.render", "coursekit.ga.selection.tournament",
                 "coursekit.creatures.simulate.simulate", "coursekit.creatures.genotype.Creature.random",
                 "coursekit.pictures.genome.Genome.random", "coursekit.grading.formative.check",
                 "coursekit.creatures.physics.dynamics.forward_dynamics", "coursekit.pictures.files.save_image"]:
        assert name in CALLABLES
    assert len(CALLABLES) > 150


@pytest.mark.parametrize("qualname", sorted(CALLABLES))
def test_every_parameter_and_return_is_annotated_with_a_real_type(qualname):
    fn = inspect.unwrap(CALLABLES[qualname])
    signature = inspect.signature(fn)
    missing = [p for p, v in signature.parameters.items() if v.annotation is inspect.Parameter.empty
               and p not in ("self", "cls")]
    if signature.return_annotation is inspect.Signature.empty and fn.__name__ != "__init__":
        missing.append("return")
    assert not missing, f"{qualname}: no annotation for {missing}"
    typing.get_type_hints(fn, globalns={**vars(importlib.import_module(fn.__module__)), **CHECKER_ONLY})
