"""The simulator's compiled kernels, compiled once for all the notebooks a grading run sandboxes.

numba compiles the swimmers' step (:mod:`coursekit.creatures.physics.compiled`) on its first
call and caches the machine code beside the source. The sandbox (:mod:`.sandbox`) shows the
package read-only, so without this module every graded notebook that simulates compiles the
kernels again, for 10-20 s. :func:`cache` compiles them once, outside any sandbox and from the
library's own code only, in a child process whose ``NUMBA_CACHE_DIR`` is a folder of the
grader's (:func:`folder`; a later grading run finds them there and only loads them).
:func:`copy_into` then gives each notebook a copy of its own, inside its box, so that nothing a
notebook writes there reaches another notebook or the grader.

The copy holds only code compiled from modules the sandbox shows as they are; those it shows
with functions withheld (:mod:`.withheld`) are left out. numba keys its cache by each source
file's path and content hash, so the copy serves the package the sandbox binds at the same
path, and a kernel the notebook calls with other types is compiled there as before. Where the
warm-up fails, grading goes on without it, only slower.

Run as ``python -m coursekit.grading.warm`` (with ``NUMBA_CACHE_DIR`` set), it is the warm-up:
short swims that call every kernel of the default step, of the numpy integrators' compiled
stages and of the limits' projection.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

#: Seconds the warm-up may take (compiling every kernel takes 10-20 s on a 2-core laptop).
TIMEOUT = 600.0
_READY: dict = {}


def folder() -> Path:
    """Where the grader keeps the compiled kernels: ``$XDG_CACHE_HOME/coursekit/numba/KEY``
    (default ``~/.cache/coursekit/numba/KEY``), the grading user's own; ``KEY`` is a hash of the
    kernels' sources, so that a notebook's copy never carries the code of other versions."""
    from coursekit.creatures.physics import compiled, kernels

    key = hashlib.sha256(b"".join(Path(m.__file__).read_bytes() for m in (kernels, compiled))).hexdigest()[:16]
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "coursekit" / "numba" / key


def cached() -> bool:
    """Whether :func:`folder` holds compiled kernels already (the warm-up then only loads them)."""
    try:
        return any(folder().rglob("*.nbi"))
    except (OSError, RuntimeError):
        return False


def cache() -> Path | None:
    """The folder of compiled kernels, warmed by a child process on the first call in this
    process; None where it could not be made (the notebooks then compile the kernels themselves)."""
    if "path" not in _READY:
        path, ok = None, False
        try:
            path = folder()
            path.mkdir(parents=True, exist_ok=True)
            env = {**os.environ, "NUMBA_CACHE_DIR": str(path), "PYTHONNOUSERSITE": "1"}
            ok = subprocess.run([sys.executable, "-m", __name__], env=env, stdin=subprocess.DEVNULL,
                                capture_output=True, timeout=TIMEOUT).returncode == 0
        except (OSError, RuntimeError, subprocess.SubprocessError):  # RuntimeError: no home folder
            pass
        _READY["path"] = path if ok else None
    return _READY["path"]


def copy_into(target: Path, withheld=()) -> Path | None:
    """A copy of :func:`cache`'s folder at ``target`` (for one notebook's ``NUMBA_CACHE_DIR``),
    without the code compiled from the modules ``withheld`` (their files); None without a cache."""
    source = cache()
    if source is None:
        return None
    stems = {Path(f).stem for f in withheld}
    # numba names a cache file "<module>.<function>-<line>.<python>.nbi" (or .nbc)
    shutil.copytree(source, target, ignore=lambda _, names: [n for n in names if n.split(".", 1)[0] in stems])
    return target


def main() -> None:
    """The warm-up: swims that call every kernel once (see the module docstring)."""
    import coursekit.data
    from coursekit.creatures import simulate
    from coursekit.creatures.champions import champions

    # the exploiters put joints back on their limits (the projection's kernel)
    creatures = champions() + [coursekit.data.creature(name) for name in ("limit_exploit_creature", "step_exploit_creature")]
    simulate(creatures, 1.0)  # the compiled step: contacts, limits, brains
    simulate(creatures[:1], 0.25, integrator="rk4", contacts=False)  # numpy's integrator around compiled stages


if __name__ == "__main__":
    main()
