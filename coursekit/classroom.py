"""Notebook helpers for the classroom: demo cells that survive Run All, and the setup check.

The seed paper's teaching model (section 4) has students implement the operators and then see
their own code drive the real systems. In an exercise notebook the demo cells between the tasks
call the student's functions; before a function is written they would stop Run All with a raw
``NotImplementedError`` traceback. :func:`demo` wraps such a cell: a function that is not
written yet (or a result an earlier, skipped demo would have made) gives one friendly line saying
what to do, and the notebook runs on to its end. Every other error still raises.

:func:`setup_check` tells a student in one line per item whether 3D rendering, widgets, torch and
the swimmers' compiled physics work on this machine, and what to install if not (lesson 00); the
physics item compiles the simulator's step, which numba then caches, so the first swim of the
course does not sit still for its compile time.
"""

from __future__ import annotations

import contextlib
import importlib
import sys
import traceback
from collections.abc import Iterator
from typing import TextIO

__all__ = ["demo", "setup_check"]


def _unwritten(exc: BaseException) -> str | None:
    """The name of the function whose body raised ``exc`` (the innermost frame), if any."""
    frames = traceback.extract_tb(exc.__traceback__)
    return frames[-1].name if frames else None


@contextlib.contextmanager
def demo(uses: str | None = None) -> Iterator[None]:
    """Run a demo cell; if a function it needs is not written yet, say so instead of failing.

    Use it around the code of a demo cell of an exercise (``with demo():``). A
    ``NotImplementedError`` (a function still holding ``raise NotImplementedError()``) or a
    ``NameError`` (a result of an earlier demo that could not run yet) ends the cell with one
    line naming what is missing and what to do; Run All goes on with the next cell. Any other
    exception propagates as usual: a bug in a written function still shows its traceback.

    Args:
        uses: optional, the task(s) the cell needs, for the message (e.g. ``"section 2"``).

    Example:
        >>> with demo():  # doctest: +ELLIPSIS
        ...     raise NotImplementedError()
        ⏸ This demo needs a function you have not written yet...
    """
    where = f" ({uses})" if uses else ""
    try:
        yield
    except NotImplementedError as exc:
        name = _unwritten(exc)
        what = f"`{name}`" if name and not name.startswith("<") else "a function"
        print(f"⏸ This demo needs a function you have not written yet{where}: {what} still raises "
              f"NotImplementedError. Write it, run its cell and its check, then run this cell again. "
              f"(The notebook goes on below.)")
    except NameError as exc:
        missing = getattr(exc, "name", None) or str(exc)
        print(f"⏸ This demo needs `{missing}`, which an earlier demo makes once your functions work{where}. "
              f"Run the cells above again when they do. (The notebook goes on below.)")


# ------------------------------------------------------------------------------- setup check

_FIX = {
    "3D rendering": "pip install pyvista vtk; on Linux without a display also the system's Mesa EGL "
                    "(Debian/Ubuntu: sudo apt-get install libegl1 libegl-mesa0 libgl1)",
    "widgets": "pip install ipywidgets jupyterlab_widgets ipyevents, then restart JupyterLab",
    "torch": "pip install torch (CPU is enough: pip install torch --index-url https://download.pytorch.org/whl/cpu)",
    "swimmers' physics": "pip install numba (the simulator's compiled step; without it the swimmers run on numpy, "
                         "several times slower)",
}


def _check_rendering():
    import numpy as np

    from coursekit.creatures import Creature
    from coursekit.creatures.render import render

    image = render(Creature.figure1_snake(), size=(96, 72))
    if image.ndim != 3 or image.shape[:2] != (72, 96) or float(np.ptp(image)) == 0.0:
        raise RuntimeError("the off-screen picture came back empty")
    pv, vtk = importlib.import_module("pyvista"), importlib.import_module("vtk")
    return f"pyvista {pv.__version__}, VTK {vtk.vtkVersion.GetVTKVersion()}"


def _check_widgets():
    widgets = importlib.import_module("ipywidgets")
    try:
        lab = importlib.import_module("jupyterlab_widgets")
    except ImportError:
        raise RuntimeError("ipywidgets is installed but jupyterlab_widgets (the JupyterLab side) is not") from None
    importlib.import_module("ipyevents")
    widgets.ToggleButton(description="test")
    return f"ipywidgets {widgets.__version__}, jupyterlab_widgets {lab.__version__}"


def _check_torch():
    torch = importlib.import_module("torch")
    x = torch.ones(3, dtype=torch.float64)
    if float((x * 2).sum()) != 6.0:
        raise RuntimeError("a small computation gave a wrong result")
    device = "CUDA " + torch.cuda.get_device_name(0) if torch.cuda.is_available() else "CPU"
    return f"torch {torch.__version__}, {device}"


def _check_physics():
    import time

    import numba

    from coursekit.creatures import Creature, simulate

    start = time.perf_counter()  # the first run compiles the step (once: numba caches it for later sessions)
    run = simulate([Creature.figure1_snake(), Creature.paddle_turtle()], 0.25, settle=0.0, compiled=True)
    if not (run.fitness >= 0).all() or run.diverged.any():
        raise RuntimeError("a short swim went wrong")
    return f"numba {numba.__version__}, a short swim in {time.perf_counter() - start:.1f} s, compiling included the first time"


CHECKS = {"3D rendering": _check_rendering, "widgets": _check_widgets, "torch": _check_torch,
          "swimmers' physics": _check_physics}


def setup_check(file: TextIO | None = None, progress: bool = False) -> dict:
    """Check 3D rendering, widgets, torch and the swimmers' physics; print one line each (with the fix
    when one fails).

    Args:
        file: where the lines go (default: standard output).
        progress: a tqdm bar over the checks, naming the one running (the first imports take
            seconds, so a notebook shows it is working).

    Returns:
        ``{item: (ok, detail)}`` for ``"3D rendering"``, ``"widgets"``, ``"torch"`` and
        ``"swimmers' physics"``.
    """
    file = sys.stdout if file is None else file
    results = {}
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(CHECKS), desc="checking", unit="check", leave=True)
    for item, fn in CHECKS.items():  # each line as soon as its check is done
        if bar is not None:
            bar.set_postfix_str(item)
        try:
            results[item] = (True, fn())
        except Exception as exc:  # any failure is reported, never raised: this is a diagnosis
            results[item] = (False, f"{type(exc).__name__}: {exc}"[:200])
        ok, detail = results[item]
        line = f"✔ {item}: works ({detail})" if ok else f"✘ {item}: does not work ({detail}). To fix: {_FIX[item]}"
        print(line, file=file, flush=True)
        if bar is not None:
            bar.update()
    if bar is not None:
        bar.set_postfix_str("done")
        bar.close()
    return results
