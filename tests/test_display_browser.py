"""End to end: a Genome, a Creature and a History displayed in a real notebook, in JupyterLab and in
Notebook 7, through headless Chromium (the browser test's machinery: ``tests/test_gallery_browser.py``).

The notebook is run from the Run menu as a student would; the test then reads the page: each
object shows its picture at its size, the creature with its summary. Screenshots of each output
go to the test's folder, and to ``$COURSEKIT_SCREENSHOTS`` when set (the docs' pictures,
``docs/_static/screenshots/``, are made that way).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import urllib.error
import urllib.request
from contextlib import ExitStack
from pathlib import Path

import pytest

from tests.test_gallery_browser import CHROMIUM_FLAGS, TIMEOUT_MS, chromium_executable, free_port

pytestmark = pytest.mark.browser

ROOT = Path(__file__).resolve().parent.parent
TOKEN = "coursekit-display-test"
CELLS = {
    "genome": "import numpy as np\nfrom coursekit.pictures import Genome\nGenome.random(np.random.default_rng(3))",
    "creature": "from coursekit.creatures import Creature\nCreature.figure1_snake()",
    "history": ("from coursekit.ga.history import History\nh = History()\n"
                "for g in range(8):\n    h.record(g, np.random.default_rng(g).random(10) * (1 + g), 1 / (1 + g), 10)\nh"),
}
WIDTHS = {"genome": 160, "creature": 400, "history": 600}
FRONTENDS = {"lab": ("jupyterlab", "/lab/tree/display.ipynb"), "notebook7": ("notebook", "/notebooks/display.ipynb")}


def write_notebook(folder: Path) -> None:
    nb = {"nbformat": 4, "nbformat_minor": 5,
          "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"},
                       "language_info": {"name": "python"}},
          "cells": [{"cell_type": "code", "id": k, "metadata": {}, "execution_count": None, "outputs": [], "source": v}
                    for k, v in CELLS.items()]}
    (folder / "display.ipynb").write_text(json.dumps(nb))


def start_server(module: str, tmp: Path, stack: ExitStack) -> str:
    root, home = tmp / "root", tmp / "jupyter"
    for plugin, values in {"apputils-extension/notification": {"fetchNews": "false", "checkForUpdates": False},
                           "notebook-extension/tracker": {"autoStartDefaultKernel": True}}.items():
        file = home / "settings" / "@jupyterlab" / f"{plugin}.jupyterlab-settings"
        file.parent.mkdir(parents=True, exist_ok=True)
        file.write_text(json.dumps(values))
    port = free_port()
    env = {**os.environ, "JUPYTER_RUNTIME_DIR": str(home / "runtime"), "JUPYTER_CONFIG_DIR": str(home / "config"),
           "JUPYTER_DATA_DIR": str(home / "data"), "IPYTHONDIR": str(home / "ipython"), "COURSEKIT_PROFILE": "ci",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    cmd = [sys.executable, "-m", module, "--no-browser", f"--ServerApp.root_dir={root}", f"--ServerApp.port={port}",
           "--ServerApp.port_retries=0", "--ServerApp.ip=127.0.0.1", f"--IdentityProvider.token={TOKEN}",
           f"--LabServerApp.user_settings_dir={home / 'settings'}", f"--LabServerApp.workspaces_dir={home / 'workspaces'}"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        cmd.append("--allow-root")
    log = open(tmp / "server.log", "wb")
    stack.callback(log.close)
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=root, start_new_session=True)

    def stop():
        for sig in (signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(proc.pid, sig)
                proc.wait(timeout=15)
                break
            except ProcessLookupError:
                break
            except subprocess.TimeoutExpired:
                continue

    stack.callback(stop)
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 60
    while True:
        try:
            urllib.request.urlopen(f"{base}/api/status?token={TOKEN}", timeout=5).close()
            return base
        except (urllib.error.URLError, ConnectionError, TimeoutError):
            assert proc.poll() is None, f"{module} exited early:\n{(tmp / 'server.log').read_text()[-3000:]}"
            assert time.monotonic() < deadline, f"{module} did not answer within 60 s"
            time.sleep(0.25)


def wait_kernel_idle(base: str, timeout: float = 120) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sessions = json.load(urllib.request.urlopen(f"{base}/api/sessions?token={TOKEN}", timeout=5))
        if sessions and all(s["kernel"]["execution_state"] == "idle" for s in sessions):
            return
        time.sleep(0.5)
    pytest.fail(f"the notebook's kernel was not idle within {timeout:.0f} s")


@pytest.mark.parametrize("frontend", sorted(FRONTENDS))
def test_objects_display_as_pictures_in_the_notebook(tmp_path, frontend):
    from playwright.sync_api import sync_playwright

    module, path = FRONTENDS[frontend]
    (tmp_path / "root").mkdir()
    write_notebook(tmp_path / "root")
    shots = [tmp_path] + ([Path(os.environ["COURSEKIT_SCREENSHOTS"])] if os.environ.get("COURSEKIT_SCREENSHOTS") else [])
    with ExitStack() as stack:
        base = start_server(module, tmp_path, stack)
        pw = stack.enter_context(sync_playwright())
        browser = pw.chromium.launch(executable_path=chromium_executable(), headless=True, args=CHROMIUM_FLAGS)
        stack.callback(browser.close)
        page = browser.new_page(viewport={"width": 1100, "height": 1400})
        page.set_default_timeout(TIMEOUT_MS)
        try:
            page.goto(f"{base}{path}?token={TOKEN}")
            page.locator(".jp-NotebookPanel .jp-Cell").first.wait_for()
            wait_kernel_idle(base)
            page.locator(".lm-MenuBar-itemLabel", has_text="Run").first.click()
            page.get_by_role("menuitem", name="Run All Cells", exact=True).click()
            cells = page.locator(".jp-NotebookPanel .jp-CodeCell")
            for k, (name, width) in enumerate(WIDTHS.items()):
                image = cells.nth(k).locator(".jp-OutputArea-output img")
                image.first.wait_for(state="visible", timeout=180_000)  # the first 3D picture starts VTK: slow
                page.wait_for_function("im => im.complete && im.naturalWidth > 0", arg=image.first.element_handle())
                assert image.count() == 1, f"{name}: {image.count()} pictures in its output"
                assert image.first.evaluate("im => im.naturalWidth") == width, name
                for folder in shots:
                    cells.nth(k).locator(".jp-OutputArea").screenshot(path=folder / f"{frontend}-{name}.png")
            caption = cells.nth(1).locator(".jp-OutputArea-output figcaption")
            assert "6 parts, 5 joints, 5 DOF" in caption.inner_text()
        except BaseException:
            try:
                page.screenshot(path=tmp_path / "failure.png", full_page=True)
                print(f"screenshot: {tmp_path / 'failure.png'}; server log: {tmp_path / 'server.log'}")
            except Exception:
                pass
            raise
