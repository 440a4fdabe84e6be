"""End to end: a student's real mouse clicks in JupyterLab select pictures in the gallery.

A real JupyterLab server serves a temporary folder holding a one-cell notebook that displays a
small :class:`~coursekit.pictures.gallery.Gallery` autosaving to a JSON file; headless Chromium
(driven by Playwright) opens the notebook, runs it from the Run menu, clicks two thumbnails and
then a mutation button. What the kernel saw is read from the autosaved session on disk, not from
the page.

Marked ``browser`` and deselected by default (a laptop may lack Chromium): run it with
``python -m pytest -m browser``. It needs Chromium (Debian: ``apt-get install chromium``; another
binary through ``COURSEKIT_CHROMIUM``) and the ``playwright`` Python package (no Playwright
browser download). It fails, rather than skips, when it cannot run.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from contextlib import ExitStack
from pathlib import Path

import pytest

pytestmark = pytest.mark.browser

ROOT = Path(__file__).resolve().parent.parent
TOKEN = "coursekit-browser-test"
N = 4  # pictures in the gallery
CLICKS = [2, 0]  # thumbnails clicked, in this order (not sorted: the order is the parents' order)
MUTATION = "transposition"
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage"]
TIMEOUT_MS = 60_000  # per wait in the page (the kernel imports torch on a busy 2-core machine)


def chromium_executable() -> str:
    exe = os.environ.get("COURSEKIT_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, ("no Chromium found: install it (Debian/Ubuntu: `apt-get install chromium`) or point "
                 "COURSEKIT_CHROMIUM at a Chromium/Chrome binary")
    return exe


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def write_notebook(folder: Path, session: Path) -> Path:
    source = (
        "import numpy as np\n"
        "from coursekit.pictures.gallery import Gallery\n"
        f"gallery = Gallery(np.random.default_rng(0), n={N}, columns={N}, size=64,\n"
        "                  genome_params={'n_strings': 2, 'head_length': 3},\n"
        f"                  autosave={str(session)!r})\n"
        "gallery.widget"
    )
    nb = {"nbformat": 4, "nbformat_minor": 5,
          "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"},
                       "language_info": {"name": "python"}},
          "cells": [{"cell_type": "code", "id": "gallery", "metadata": {}, "execution_count": None,
                     "outputs": [], "source": source}]}
    path = folder / "gallery.ipynb"
    path.write_text(json.dumps(nb))
    return path


def start_lab(tmp: Path, stack: ExitStack) -> str:
    """JupyterLab on ``tmp/root``; returns its base URL. Stopped (kernels included) by ``stack``."""
    root, home = tmp / "root", tmp / "jupyter"
    # Settings of a fresh JupyterLab, less what would stand between the page and the clicks: no
    # news/update toasts, no "Select Kernel" dialog (the notebook's kernelspec starts at once).
    for plugin, values in {"apputils-extension/notification": {"fetchNews": "false", "checkForUpdates": False},
                           "notebook-extension/tracker": {"autoStartDefaultKernel": True}}.items():
        file = home / "settings" / "@jupyterlab" / f"{plugin}.jupyterlab-settings"
        file.parent.mkdir(parents=True, exist_ok=True)
        file.write_text(json.dumps(values))
    port = free_port()
    env = {**os.environ, "JUPYTER_RUNTIME_DIR": str(home / "runtime"), "JUPYTER_CONFIG_DIR": str(home / "config"),
           "JUPYTER_DATA_DIR": str(home / "data"),
           "IPYTHONDIR": str(home / "ipython"), "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
           "COURSEKIT_PROFILE": "ci"}
    cmd = [sys.executable, "-m", "jupyterlab", "--no-browser", f"--ServerApp.root_dir={root}",
           f"--ServerApp.port={port}", "--ServerApp.port_retries=0", "--ServerApp.ip=127.0.0.1",
           f"--IdentityProvider.token={TOKEN}", f"--LabApp.user_settings_dir={home / 'settings'}",
           f"--LabApp.workspaces_dir={home / 'workspaces'}"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        cmd.append("--allow-root")
    log = open(tmp / "jupyterlab.log", "wb")
    stack.callback(log.close)
    # Its own session: the kernels it starts are in its process group, which teardown ends.
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=root, start_new_session=True)
    base = f"http://127.0.0.1:{port}"

    def stop():
        if proc.poll() is None:
            try:  # a clean shutdown stops its kernels too
                req = urllib.request.Request(f"{base}/api/shutdown", method="POST",
                                             headers={"Authorization": f"token {TOKEN}"})
                urllib.request.urlopen(req, timeout=5).close()
                proc.wait(timeout=15)
            except Exception:
                pass
        for sig in (signal.SIGTERM, signal.SIGKILL):  # then whatever is left of its process group
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                break
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                continue
            time.sleep(0.5)  # let its kernels exit on SIGTERM before the SIGKILL round

    stack.callback(stop)
    deadline = time.monotonic() + 60
    while True:
        try:
            urllib.request.urlopen(f"{base}/api/status?token={TOKEN}", timeout=5).close()
            return base
        except (urllib.error.URLError, ConnectionError, TimeoutError):
            assert proc.poll() is None, f"JupyterLab exited early:\n{(tmp / 'jupyterlab.log').read_text()[-3000:]}"
            assert time.monotonic() < deadline, "JupyterLab did not answer within 60 s"
            time.sleep(0.25)


def wait_for_session(path: Path, done, what: str, timeout: float = 60) -> dict:
    """Poll the autosaved session until ``done(session)``; fail with the last one seen."""
    deadline, last = time.monotonic() + timeout, None
    while True:
        try:
            last = json.loads(path.read_text())
        except (FileNotFoundError, json.JSONDecodeError):
            pass
        if last is not None and done(last):
            return last
        if time.monotonic() > deadline:
            brief = None if last is None else {k: last[k] for k in ("generation", "selected")}
            pytest.fail(f"the kernel did not {what} within {timeout:.0f} s; autosave {path} holds {brief}")
        time.sleep(0.1)


def test_real_clicks_in_jupyterlab_select_pictures_and_breed(tmp_path):
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("the browser test needs the `playwright` package: pip install -e '.[test]'")
    exe = chromium_executable()
    (tmp_path / "root").mkdir()
    session = tmp_path / "root" / "session.json"
    write_notebook(tmp_path / "root", session)

    with ExitStack() as stack:
        base = start_lab(tmp_path, stack)
        pw = stack.enter_context(sync_playwright())
        # Playwright gives the browser a new, empty profile (user data directory) of its own.
        browser = pw.chromium.launch(executable_path=exe, headless=True, args=CHROMIUM_FLAGS)
        stack.callback(browser.close)
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        page.set_default_timeout(TIMEOUT_MS)
        try:
            page.goto(f"{base}/lab/tree/gallery.ipynb?token={TOKEN}")
            page.locator(".jp-NotebookPanel .jp-Cell").first.wait_for()
            # The notebook's own kernel must be up first: Run All on a notebook still without one
            # starts a second kernel that races the first (JupyterLab 4), sometimes leaving none.
            page.locator(".jp-StatusBar-Item").filter(has_text=re.compile(r"^(?!No Kernel).+ \| Idle$")).wait_for()
            # Run > Run All Cells, as a student would.
            page.locator(".lm-MenuBar-itemLabel", has_text="Run").first.click()
            page.get_by_role("menuitem", name="Run All Cells", exact=True).click()

            images = page.locator(".jp-OutputArea-output img.widget-image")
            images.nth(N - 1).wait_for(state="visible")
            assert images.count() == N, f"expected {N} thumbnails, the page shows {images.count()}"
            page.wait_for_function(
                "n => { const ims = [...document.querySelectorAll('.jp-OutputArea-output img.widget-image')];"
                " return ims.length === n && ims.every(im => im.complete && im.naturalWidth > 0); }", arg=N)
            widths = images.evaluate_all("ims => ims.map(im => [im.naturalWidth, im.naturalHeight])")
            assert widths == [[64, 64]] * N, f"thumbnails are not 64x64 pictures: {widths}"
            status = page.locator(".jp-OutputArea-output .widget-html", has_text="generation 0")
            status.wait_for()
            page.locator(".jp-OutputArea-output .widget-vbox").first.screenshot(path=tmp_path / "gallery.png")

            start = wait_for_session(session, lambda s: True, "autosave the new session")
            assert start["generation"] == 0 and start["selected"] == [], start
            for k, i in enumerate(CLICKS):
                images.nth(i).click()  # a real mouse click (move, press, release) on the thumbnail
                want = CLICKS[: k + 1]
                wait_for_session(session, lambda s: s["selected"] == want, f"select {want} after clicking #{i}")
            page.locator(".jp-OutputArea-output .widget-html", has_text=f"{len(CLICKS)} selected").wait_for()
            page.locator(".jp-OutputArea-output .widget-vbox").first.screenshot(path=tmp_path / "gallery-selected.png")

            page.get_by_role("button", name=MUTATION, exact=True).click()
            after = wait_for_session(session, lambda s: s["generation"] == 1,
                                     f"breed generation 1 after clicking {MUTATION!r}")
            page.locator(".jp-OutputArea-output .widget-html", has_text="generation 1").wait_for()
            page.locator(".jp-OutputArea-output .widget-vbox").first.screenshot(path=tmp_path / "gallery-bred.png")
        except BaseException:
            try:
                page.screenshot(path=tmp_path / "failure.png", full_page=True)
                print(f"screenshot of the page: {tmp_path / 'failure.png'}; server log: {tmp_path / 'jupyterlab.log'}")
            except Exception:
                pass
            raise

    # Exactly those clicks, in click order, then one generation bred from them.
    old = start["population"]
    assert len(after["history"]) == 1, f"{len(after['history'])} generations in the history, not 1"
    assert after["history"][-1]["selected"] == CLICKS, f"history holds selection {after['history'][-1]['selected']}"
    assert after["history"][-1]["population"] == old, "the bred-from generation is not the starting population"
    assert after["selected"] == [], f"selection not cleared after breeding: {after['selected']}"
    pop = after["population"]
    assert len(pop) == N
    assert pop[: len(CLICKS)] == [old[i] for i in CLICKS], "the parents do not open the new generation in click order"
    assert pop != old, "the population did not change"
