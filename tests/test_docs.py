"""The documentation site builds (Sphinx, from the docstrings), with a page for every module."""

from __future__ import annotations

import pkgutil
import subprocess
import sys
from pathlib import Path

import coursekit

ROOT = Path(__file__).resolve().parent.parent


def test_the_api_reference_builds_with_a_page_per_module(tmp_path):
    run = subprocess.run([sys.executable, "-m", "sphinx", "-b", "html", "-q", "-E", "-d", str(tmp_path / "doctrees"),
                          str(ROOT / "docs"), str(tmp_path / "html")], capture_output=True, text=True, cwd=tmp_path,
                         env={**__import__("os").environ, "COURSEKIT_PROFILE": "ci"})
    assert run.returncode == 0, run.stderr[-3000:]
    broken = [line for line in run.stderr.splitlines() if "failed to import" in line or "autodoc: failed" in line]
    assert not broken, "\n".join(broken)
    modules = {m.name for m in pkgutil.walk_packages(coursekit.__path__, "coursekit.")
               if not m.name.endswith("__main__") and "._course" not in m.name}
    pages = {p.stem for p in (tmp_path / "html" / "api").glob("*.html")}
    assert modules <= pages, f"modules without a page: {sorted(modules - pages)}"
    index = (tmp_path / "html" / "api" / "coursekit.pictures.genome.html").read_text()
    assert "Genome" in index and "to_json" in index  # the docstrings made it in
