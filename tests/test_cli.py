"""The `coursekit` command and the size profiles."""

import subprocess
import sys

import pytest

from coursekit import profile
from coursekit.cli import build_parser


def test_help_lists_every_subcommand():
    out = subprocess.run([sys.executable, "-m", "coursekit", "--help"], capture_output=True, text=True, check=True).stdout
    for sub in ("lab", "grade", "exercises", "bench"):
        assert sub in out


def test_grade_requires_notebooks():
    with pytest.raises(SystemExit):
        build_parser().parse_args(["grade"])


def test_profiles(monkeypatch):
    monkeypatch.setenv("COURSEKIT_PROFILE", "ci")
    assert profile.sized(classroom=40, ci=3) == 3
    monkeypatch.setenv("COURSEKIT_PROFILE", "classroom")
    assert profile.sized(classroom=40, ci=3) == 40
    monkeypatch.setenv("COURSEKIT_PROFILE", "huge")
    with pytest.raises(ValueError, match="COURSEKIT_PROFILE"):
        profile.current()
