"""Sphinx configuration of coursekit's documentation: the course, and the API reference built
from the docstrings (``python -m sphinx -b html docs docs/_build/html``; the test suite builds it)."""

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
os.environ.setdefault("COURSEKIT_PROFILE", "ci")

project = "coursekit"
author = "the coursekit authors"
copyright = "2026, the coursekit authors"
from coursekit import __version__ as release  # noqa: E402

version = release
extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",  # the docstrings' Args/Returns/Raises sections (Google and NumPy style)
    "sphinx.ext.viewcode",
]
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
napoleon_numpy_docstring = True
napoleon_google_docstring = True
templates_path = ["_templates"]
exclude_patterns = ["_build"]
html_theme = "alabaster"
html_static_path = ["_static"]
html_title = f"coursekit {release}"
suppress_warnings = ["autosummary.import_cycle"]
