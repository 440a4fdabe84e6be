"""Size profiles: lessons and demos scale their heavy cells, never skip them.

``COURSEKIT_PROFILE=classroom`` (the default) sizes work for a live session on a 2-core laptop;
``COURSEKIT_PROFILE=ci`` shrinks populations, generations and resolutions so every notebook runs
top to bottom in CI. The same code runs in both; only the sizes change.
"""

from __future__ import annotations

import os
from typing import TypeVar

PROFILES = ("classroom", "ci")
T = TypeVar("T")


def current() -> str:
    """The active profile name, from ``COURSEKIT_PROFILE``."""
    name = os.environ.get("COURSEKIT_PROFILE", "classroom").strip().lower() or "classroom"
    if name not in PROFILES:
        raise ValueError(f"COURSEKIT_PROFILE: unknown profile {name!r}; allowed: {', '.join(PROFILES)}")
    return name


def sized(classroom: T, ci: T) -> T:
    """Pick a size by profile: ``generations = sized(classroom=40, ci=5)``."""
    return ci if current() == "ci" else classroom
