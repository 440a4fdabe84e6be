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


@pytest.mark.parametrize("command, opens", [(["lab"], "/lab/tree/lessons"),
                                            (["demo", "pictures"], "/lab/tree/demos/picture_breeding.ipynb")])
def test_lab_serves_the_course_and_opens_the_lessons(tmp_path, command, opens):
    """`coursekit lab` (the README's first command) really serves JupyterLab on lessons/; the
    pictures demo opens its notebook the same way."""
    import json
    import socket
    import time
    import urllib.error
    import urllib.request

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {**__import__("os").environ, "JUPYTER_RUNTIME_DIR": str(tmp_path), "JUPYTER_CONFIG_DIR": str(tmp_path)}
    proc = subprocess.Popen(
        [sys.executable, "-m", "coursekit", *command, "--no-browser", f"--ServerApp.port={port}", "--ServerApp.token=t", "--ServerApp.ip=127.0.0.1"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    try:
        base = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 60
        while True:
            try:
                listing = json.load(urllib.request.urlopen(f"{base}/api/contents?token=t", timeout=5))
                break
            except (urllib.error.URLError, ConnectionError):
                assert proc.poll() is None, "JupyterLab exited early"
                assert time.monotonic() < deadline, "JupyterLab did not come up within 60 s"
                time.sleep(0.5)
        names = {c["name"] for c in listing["content"]}
        assert {"lessons", "exercises"} <= names  # lessons link to ../exercises: both must be reachable

        class NoRedirect(urllib.request.HTTPRedirectHandler):
            def redirect_request(self, *a, **k):
                return None

        try:
            urllib.request.build_opener(NoRedirect).open(f"{base}/?token=t", timeout=5)
            location = ""
        except urllib.error.HTTPError as e:
            location = e.headers["Location"]
        assert location.split("?")[0].endswith(opens)
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    with socket.socket() as s:  # stopping `coursekit lab` stopped the server itself (no orphan)
        assert s.connect_ex(("127.0.0.1", port)) != 0, "JupyterLab still serves after coursekit stopped"


def test_swimmers_demo_writes_what_a_lecture_shows(tmp_path):
    import json
    import os

    from PIL import Image

    from coursekit.creatures import Creature

    env = {**os.environ, "COURSEKIT_PROFILE": "ci"}
    out = tmp_path / "demo"
    subprocess.run([sys.executable, "-m", "coursekit", "demo", "swimmers", "--out", str(out), "--seed", "3"],
                   check=True, env=env, capture_output=True)
    summary = json.loads((out / "summary.json").read_text())
    assert {"best.json", "best.png", "best.gif", "fitness.png"} <= set(summary["files"])
    best = Creature.from_json((out / "best.json").read_text())
    assert best.expand().body.n_bodies == summary["best_parts"]
    assert summary["best_fitness"] == max(summary["history_best"])
    assert Image.open(out / "best.gif").n_frames > 1
