"""End to end: a student's real mouse clicks and keys in JupyterLab breed pictures in the gallery.

A real JupyterLab server serves a temporary folder holding a one-cell notebook that displays a
:class:`~coursekit.pictures.gallery.Gallery` of 20 pictures at 128 x 128 autosaving to a JSON
file; headless Chromium (driven by Playwright) opens the notebook, runs it from the Run menu and
then does what a student does: checks that evolve is greyed out with its reason, clicks
thumbnails, breeds with a mutation and a recombination, undoes and redoes, selects and evolves
from the keyboard, zooms, and branches from an ancestor in the lineage view. What the kernel saw
is read from the autosaved session on disk, not from the page.

It also measures what the issue asks of a click: **Evolve to screen**, from the press of the
mouse on the button (the page's ``pointerdown``) to the moment every new thumbnail is decoded
in the page, over :data:`EVOLVES` clicks (also from Playwright's click call, its own checks
before it clicks included); p50 and
p95 are printed and written with the screenshots to the artefacts folder
(``COURSEKIT_ARTEFACTS``, default ``test-artefacts/`` in the checkout, ignored by git). No
limit is asserted on them (a shared machine is not a stopwatch: ``benchmarks/gallery_click.py``).
Each timed Evolve follows a click on a picture and is pressed once the autosaved session shows
that pick, some 0.05-0.2 s later (quicker than a student moves to the button): by then the
gallery has usually bred the generation ahead, so the time is mostly the messages and the page
(``benchmarks/gallery_click.py`` times a press at once beside it).

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

import numpy as np
import pytest

pytestmark = pytest.mark.browser

ROOT = Path(__file__).resolve().parent.parent
ARTEFACTS = Path(os.environ.get("COURSEKIT_ARTEFACTS", ROOT / "test-artefacts")) / "gallery-browser"
TOKEN = "coursekit-browser-test"
N, SIZE = 20, 128  # pictures in the gallery (Sims' 4 x 5) and their size: the issue's case
CLICKS = [2, 0]  # thumbnails clicked, in this order (not sorted: the order is the parents' order)
MUTATION, RECOMBINATION = "transposition", "crossover"
EVOLVES = 12  # timed clicks on evolve
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage"]
TIMEOUT_MS = 60_000  # per wait in the page (the kernel imports torch on a busy 2-core machine)
OUT = ".jp-OutputArea-output"


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
        f"gallery = Gallery(np.random.default_rng(0), n={N}, columns=5, size={SIZE},\n"
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


def session_step(path: Path, before: int, what: str) -> dict:
    """The autosaved session once it has moved on from generation ``before``... or not at all."""
    return wait_for_session(path, lambda s: s["generation"] != before, what)


def test_real_clicks_and_keys_in_jupyterlab_breed_pictures(tmp_path, record_property):
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("the browser test needs the `playwright` package: pip install -e '.[test]'")
    exe = chromium_executable()
    (tmp_path / "root").mkdir()
    session = tmp_path / "root" / "session.json"
    write_notebook(tmp_path / "root", session)
    ARTEFACTS.mkdir(parents=True, exist_ok=True)
    latencies: list[float] = []

    with ExitStack() as stack:
        base = start_lab(tmp_path, stack)
        pw = stack.enter_context(sync_playwright())
        # Playwright gives the browser a new, empty profile (user data directory) of its own.
        browser = pw.chromium.launch(executable_path=exe, headless=True, args=CHROMIUM_FLAGS)
        stack.callback(browser.close)
        page = browser.new_page(viewport={"width": 1280, "height": 1400})
        page.set_default_timeout(TIMEOUT_MS)

        def shot(name):
            page.locator(f"{OUT} .widget-vbox").first.screenshot(path=ARTEFACTS / f"{name}.png")

        def button(name):
            return page.get_by_role("button", name=name, exact=True)

        def status(text):
            page.locator(f"{OUT} .widget-html", has_text=text).first.wait_for()

        images = page.locator(f"{OUT} .widget-gridbox img.widget-image")
        try:
            page.goto(f"{base}/lab/tree/gallery.ipynb?token={TOKEN}")
            page.locator(".jp-NotebookPanel .jp-Cell").first.wait_for()
            # The notebook's own kernel must be up first: Run All on a notebook still without one
            # starts a second kernel that races the first (JupyterLab 4), sometimes leaving none.
            page.locator(".jp-StatusBar-Item").filter(has_text=re.compile(r"^(?!No Kernel).+ \| Idle$")).wait_for()
            # Run > Run All Cells, as a student would.
            page.locator(".lm-MenuBar-itemLabel", has_text="Run").first.click()
            page.get_by_role("menuitem", name="Run All Cells", exact=True).click()

            images.nth(N - 1).wait_for(state="visible")
            assert images.count() == N, f"expected {N} thumbnails, the page shows {images.count()}"
            page.wait_for_function(
                "n => { const ims = [...document.querySelectorAll('.widget-gridbox img.widget-image')];"
                " return ims.length === n && ims.every(im => im.complete && im.naturalWidth > 0); }", arg=N)
            sizes = images.evaluate_all("ims => ims.map(im => [im.naturalWidth, im.naturalHeight])")
            assert sizes == [[SIZE, SIZE]] * N, f"thumbnails are not {SIZE}x{SIZE} pictures: {sizes}"
            status("generation 0")
            # Nothing selected: evolve and every operator are greyed out, and the reason is shown.
            assert button("evolve").is_disabled() and button(MUTATION).is_disabled()
            page.locator(f"{OUT} .widget-html", has_text="select a picture to breed from").first.wait_for()
            cut = page.locator(f"{OUT} button").evaluate_all(
                "bs => bs.filter(b => b.scrollWidth > b.clientWidth + 1).map(b => b.textContent.trim())")
            assert cut == [], f"button labels cut off: {cut}"
            shot("gallery")

            start = wait_for_session(session, lambda s: True, "autosave the new session")
            assert start["generation"] == 0 and start["selected"] == [], start
            for k, i in enumerate(CLICKS):
                images.nth(i).click()  # a real mouse click (move, press, release) on the thumbnail
                want = CLICKS[: k + 1]
                wait_for_session(session, lambda s: s["selected"] == want, f"select {want} after clicking #{i}")
            status("2 selected (#2, #0)")
            line = page.locator(f"{OUT} .widget-html", has_text="generation 0").first.inner_text()
            assert line.count("selected") == 1, f"the status line repeats itself: {line!r}"
            assert not button("evolve").is_disabled() and not button(RECOMBINATION).is_disabled()
            shot("gallery-selected")

            button(MUTATION).click()
            bred = session_step(session, 0, f"breed generation 1 after clicking {MUTATION!r}")
            status("generation 1")
            images.nth(3).click()
            images.nth(1).click()
            wait_for_session(session, lambda s: s["selected"] == [3, 1], "select #3 and #1")
            button(RECOMBINATION).click()
            crossed = session_step(session, 1, f"breed generation 2 after clicking {RECOMBINATION!r}")
            assert crossed["generation"] == 2
            button("undo").click()
            undone = session_step(session, 2, "undo")
            assert undone["generation"] == 1 and undone["population"] == bred["population"]
            button("redo").click()
            redone = session_step(session, 1, "redo")
            assert redone["population"] == crossed["population"] and redone["generation"] == 2
            shot("gallery-bred")

            # The keyboard, with the mouse over the gallery: the cursor is on #1 (the last click).
            images.nth(7).hover()
            page.keyboard.press("ArrowRight")
            page.keyboard.press("Space")
            wait_for_session(session, lambda s: s["selected"] == [2], "select #2 with the arrow and space keys")
            page.keyboard.press("e")
            keyed = session_step(session, 2, "evolve on the e key")
            assert keyed["history"][-1]["selected"] == [2] and keyed["population"][0] == redone["population"][2]

            # Evolve to screen: click a picture, then evolve; timed until every new thumbnail is decoded.
            requested = []  # from Playwright's click call: its own checks included
            for k in range(EVOLVES):
                images.nth(k % N).click()
                generation = keyed["generation"] + k
                wait_for_session(session, lambda s: s["selected"] == [k % N], f"select #{k % N}")
                # The clock starts when the button is pressed in the page (pointerdown), not when
                # Playwright is asked to click: its checks before the click (the button found,
                # visible, still, hit) took 18-95 ms here, which a student's click does not wait for.
                page.evaluate("() => { window.__asked = performance.now(); document.addEventListener("
                              "'pointerdown', () => { window.__t0 = performance.now(); }, {capture: true, once: true}); }")
                button("evolve").click()
                # The status line is set after the thumbnails, and the page applies the kernel's
                # messages in order: the new generation's line means every new picture has arrived;
                # then each must be decoded.
                handle = page.wait_for_function(
                    "g => { const line = [...document.querySelectorAll('.jp-OutputArea-output .widget-html')]"
                    ".some(h => h.textContent.startsWith('generation ' + g + ' '));"
                    " const ims = [...document.querySelectorAll('.widget-gridbox img.widget-image')];"
                    " return line && ims.every(im => im.complete && im.naturalWidth > 0)"
                    " ? [performance.now() - window.__t0, performance.now() - window.__asked] : false; }",
                    arg=generation + 1, polling="raf")
                pressed, asked = handle.json_value()
                latencies.append(float(pressed))
                requested.append(float(asked))
                session_step(session, generation, "evolve")

            # Zoom: every picture evaluated over a smaller window; reset brings them back.
            home = images.evaluate_all("ims => ims.map(im => im.src)")
            page.locator(f"{OUT} button[title^='zoom in']").click()
            status("view 2x")
            page.wait_for_function(
                "home => [...document.querySelectorAll('.widget-gridbox img.widget-image')]"
                ".every((im, i) => im.src !== home[i] && im.complete)", arg=home)
            shot("gallery-zoomed")
            page.get_by_role("button", name="reset view", exact=True).click()
            page.locator(f"{OUT} .widget-html", has_text="view reset").first.wait_for()

            # Lineage of the cursor picture; clicking its oldest ancestor branches from there.
            page.locator(f"{OUT} button[title^='lineage']").click()
            page.locator(f"{OUT} .widget-html", has_text="lineage of #").first.wait_for()
            shot("gallery-lineage")
            now = wait_for_session(session, lambda s: True, "autosave")
            ancestors = page.locator(f"{OUT} .widget-hbox .widget-vbox img.widget-image")  # not the grid's
            ancestors.first.click()  # the oldest generation is on the left
            branched = session_step(session, now["generation"], "branch from the oldest ancestor")
            assert branched["generation"] < now["generation"] and len(branched["selected"]) == 1
            assert branched["future"], "the generations after the branch point are not kept for redo"
            shot("gallery-branched")
        except BaseException:
            try:
                page.screenshot(path=ARTEFACTS / "failure.png", full_page=True)
                print(f"screenshot of the page: {ARTEFACTS / 'failure.png'}; server log: {tmp_path / 'jupyterlab.log'}")
            except Exception:
                pass
            raise

    # Exactly those clicks, in click order, then one generation bred from them.
    old = start["population"]
    first = bred["history"][0]
    assert first["selected"] == CLICKS, f"history holds selection {first['selected']}"
    assert first["population"] == old, "the bred-from generation is not the starting population"
    pop = bred["population"]
    assert len(pop) == N and pop[: len(CLICKS)] == [old[i] for i in CLICKS], \
        "the parents do not open the new generation in click order"
    assert pop != old, "the population did not change"

    p50, p95 = np.percentile(latencies, [50, 95])
    r50, r95 = np.percentile(requested, [50, 95])
    figure = {"clicks": len(latencies), "pictures": N, "size": SIZE, "p50_ms": round(float(p50), 1),
              "p95_ms": round(float(p95), 1), "max_ms": round(max(latencies), 1),
              "from_playwright_call_p50_ms": round(float(r50), 1), "from_playwright_call_p95_ms": round(float(r95), 1),
              "load_average": os.getloadavg()[0], "cores": os.cpu_count()}
    (ARTEFACTS / "latency.json").write_text(json.dumps(figure, indent=1))
    record_property("evolve_to_screen_ms", figure)
    print(f"\nEvolve to screen, {N} thumbnails at {SIZE}^2, {len(latencies)} clicks: p50 {p50:.0f} ms, "
          f"p95 {p95:.0f} ms, max {max(latencies):.0f} ms from the press (from Playwright's click call: "
          f"p50 {r50:.0f}, p95 {r95:.0f} ms; load average {figure['load_average']:.1f}); "
          f"screenshots in {ARTEFACTS}")
