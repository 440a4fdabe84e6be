"""Grading works on any install and says so when it cannot (issue 13, part 0).

- Memory is bounded by what the notebook's processes hold, not by address space: a notebook
  that reserves 3.5 GiB of address space it never touches (what a CUDA build of torch does on
  import) grades normally under the default ``--memory-mb 4096``; one that really fills memory
  is reported NOT GRADED, with the reason, and ``coursekit grade`` exits with status 3.
- Private ``coursekit-grade-*`` folders are removed after a ``SIGTERM``, and after a
  ``SIGKILL`` by the next run; nothing the notebook started survives.
- The ``--json`` path is refused before anything is graded.
- Terminal escapes never reach the summary or the results.
"""

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import nbformat
import psutil
import pytest
from nbformat.v4 import new_code_cell, new_notebook

from coursekit.grading import supervisor
from coursekit.grading.supervisor import Watch, held_files
from coursekit.grading.report import clean

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "adversarial"))
from make_notebooks import HONEST  # noqa: E402

sys.path.pop(0)

RESERVE = '''import ctypes
libc = ctypes.CDLL(None, use_errno=True)
libc.mmap.restype = ctypes.c_void_p
libc.mmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_long]
# 3.5 GiB of address space: 2 GiB PROT_NONE (a reservation) and 1.5 GiB read-write never touched
none = libc.mmap(None, 2048 * 2**20, 0, 0x22, -1, 0)        # PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS
untouched = libc.mmap(None, 1536 * 2**20, 0x3, 0x22, -1, 0)  # PROT_READ | PROT_WRITE
assert none not in (None, 2**64 - 1) and untouched not in (None, 2**64 - 1), f"mmap failed: errno {ctypes.get_errno()}"
'''


def notebook(path, *cells):
    nb = new_notebook(cells=[new_code_cell("import json, math, os, sys\nimport numpy as np"), *map(new_code_cell, cells)])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nbformat.write(nb, path)
    return path


def env(tmp):
    (tmp / "tmp").mkdir(exist_ok=True)
    return {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT), "COURSEKIT_PROFILE": "ci", "TMPDIR": str(tmp / "tmp")}


def grade(tmp, paths, *extra):
    cmd = [sys.executable, "-m", "coursekit", "grade", *map(str, paths), *extra]
    return subprocess.run(cmd, cwd=tmp, capture_output=True, text=True, timeout=900, env=env(tmp))


def leftovers(tmp):
    return sorted(p.name for p in (tmp / "tmp").glob("coursekit-grade-*"))


@pytest.mark.slow
def test_reserved_address_space_is_not_memory_use(tmp_path):
    # the functions are defined in the cell that reserves: under an address-space limit the mmap
    # fails, the cell stops and everything scores 0 (measured before this change: 0 / 10)
    nb = notebook(tmp_path / "01_selection.ipynb", RESERVE + "\n\n" + "\n\n".join(HONEST.values()))
    proc = grade(tmp_path, [nb], "--json", "r.json", "--timeout", "20", "--cell-timeout", "120")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    results = json.loads((tmp_path / "r.json").read_text())
    assert results["score"] == 10.0 and results["extra_data"]["notebooks"][0]["graded"], results["output"]
    assert "error" not in results["output"] and leftovers(tmp_path) == []


@pytest.mark.slow
def test_a_notebook_that_fills_memory_is_not_graded_and_the_command_fails(tmp_path):
    hog = "hog = bytearray(1536 * 2**20)  # zero-filled: every page touched\nhog[::4096] = b'x' * len(hog[::4096])"
    nb = notebook(tmp_path / "hog.ipynb", hog, *HONEST.values())
    ok = notebook(tmp_path / "ok.ipynb", *HONEST.values())
    proc = grade(tmp_path, [nb, ok], "--exercise", "01_selection", "--json", "r.json", "--memory-mb", "700",
                 "--timeout", "20", "--cell-timeout", "120")
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "hog.ipynb: NOT GRADED: " in proc.stdout and "over the limit of 700 MiB (--memory-mb)" in proc.stdout
    assert "ok.ipynb: 10 / 10 points" in proc.stdout  # the rest of the batch is graded as usual
    results = json.loads((tmp_path / "r.json").read_text())  # results are written for every notebook
    hog_nb, ok_nb = results["extra_data"]["notebooks"]
    assert not hog_nb["graded"] and any("memory" in why for why in hog_nb["not_graded"])
    assert any(re.match(r"cells? 2\b[\d, ]*: skipped", why) for why in hog_nb["not_graded"])  # one line per reason
    assert ok_nb["graded"] and ok_nb["not_graded"] == []
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("where, why", [("dir", "is a directory"), ("missing/r.json", "does not exist"),
                                        ("file/r.json", "does not exist")])
def test_an_unusable_results_path_is_refused_before_grading(tmp_path, where, why):
    (tmp_path / "dir").mkdir()
    (tmp_path / "file").write_text("")
    nb = notebook(tmp_path / "01_selection.ipynb", "import time\ntime.sleep(3600)")  # would take an hour to grade
    proc = grade(tmp_path, [nb], "--json", where)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.startswith(f"coursekit grade: --json {where}: ") and why in proc.stderr


def _wait_for_kernel(grader: subprocess.Popen):
    for _ in range(6000):  # the kernel starts within seconds; the loop only bounds a broken run
        try:
            kids = psutil.Process(grader.pid).children(recursive=True)
            if any("ipykernel" in " ".join(k.cmdline()) for k in kids):
                return kids
        except psutil.Error:
            pass
        assert grader.poll() is None, grader.communicate()
        time.sleep(0.1)
    raise AssertionError("no kernel started")


@pytest.mark.slow
def test_sigterm_removes_the_private_folder_and_every_process(tmp_path):
    nb = notebook(tmp_path / "01_selection.ipynb", "import time\ntime.sleep(3600)")
    grader = subprocess.Popen([sys.executable, "-m", "coursekit", "grade", str(nb), "--json", "r.json"], cwd=tmp_path,
                              env=env(tmp_path), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    kids = _wait_for_kernel(grader)
    assert len(leftovers(tmp_path)) == 1
    grader.send_signal(signal.SIGTERM)
    _, err = grader.communicate(timeout=300)
    assert grader.returncode == 128 + signal.SIGTERM and "stopped by signal SIGTERM" in err
    assert leftovers(tmp_path) == [] and not (tmp_path / "r.json").exists()
    assert not [k for k in kids if k.is_running() and k.status() != psutil.STATUS_ZOMBIE]


@pytest.mark.slow
def test_after_a_sigkill_the_next_run_removes_the_folder(tmp_path):
    nb = notebook(tmp_path / "01_selection.ipynb", "import time\ntime.sleep(3600)")
    grader = subprocess.Popen([sys.executable, "-m", "coursekit", "grade", str(nb)], cwd=tmp_path,
                              env=env(tmp_path), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    kids = _wait_for_kernel(grader)
    grader.kill()
    grader.wait()
    for k in kids:  # a SIGKILL leaves the notebook's processes behind: the test ends them itself
        try:
            k.kill()
        except psutil.Error:
            pass
    stale = leftovers(tmp_path)
    assert len(stale) == 1 and stale[0].startswith(f"coursekit-grade-{grader.pid}-")
    bad = tmp_path / "02_picture_mutations.ipynb"
    bad.write_text('{"cells": [')  # graded in a moment: no kernel starts
    proc = grade(tmp_path, [bad])
    assert proc.returncode == 0, proc.stderr
    assert leftovers(tmp_path) == []


def test_remove_stale_spares_live_processes_and_foreign_names(tmp_path):
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead = int(done.stdout)
    alive = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    try:
        for name in (f"coursekit-grade-{dead}-abc", f"coursekit-grade-{alive.pid}-abc", "coursekit-grade-xyz", "other"):
            (tmp_path / name).mkdir()
        (tmp_path / f"coursekit-grade-{dead}-file").write_text("not a folder")
        removed = supervisor.remove_stale(tmp_path) if not psutil.pid_exists(dead) else pytest.skip("pid reused")
        assert removed == [f"coursekit-grade-{dead}-abc"]
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
            [f"coursekit-grade-{alive.pid}-abc", "coursekit-grade-xyz", "other", f"coursekit-grade-{dead}-file"])
    finally:
        alive.kill()
        alive.wait()


@pytest.mark.parametrize("attack", [
    "\x1b[2J\x1b[H",  # clear the screen, cursor home
    "\x1b]52;c;Y3VybCBldmlsLnNo\x07",  # OSC 52: set the clipboard
    "\x1b]0;owned\x1b\\",  # OSC window title, ST-terminated
    "\x1b[1A\r\x1b[2K",  # cursor up, return, erase line: overwrite the previous line
    "\x9b31m",  # 8-bit CSI
    "\x1bP1$r\x1b\\",  # DCS
    "\u202e",  # right-to-left override
    "\ud800",  # a lone surrogate: printing it raised UnicodeEncodeError, and the batch's results were lost
])
def test_clean_strips_terminal_escapes_and_control_characters(attack):
    text = clean(f"before {attack}ga.tournament 2.00 / 2 all properties hold\tafter\nnext")
    assert text == "before ga.tournament 2.00 / 2 all properties hold\tafter ⏎ next"
    assert all(ch == "\t" or (ord(ch) >= 32 and not 0x7f <= ord(ch) <= 0x9f) for ch in text)
    text.encode("utf-8")


JITTED_TOURNAMENT = """import numba


@numba.njit
def best_of(fitness, contestants):
    out = np.empty(contestants.shape[0], dtype=np.int64)
    for i in range(contestants.shape[0]):
        out[i] = contestants[i, 0]
        for j in range(1, contestants.shape[1]):
            if fitness[contestants[i, j]] > fitness[out[i]]:
                out[i] = contestants[i, j]
    return out


def tournament(fitness, k, rng, size=3):
    return best_of(np.asarray(fitness, dtype=float), rng.integers(0, len(fitness), size=(k, size)))"""


def test_honest_numba_code_first_compiled_while_graded_gets_its_marks(tmp_path):
    # red team, round 6: numba compiles through ctypes, which the graded function's process refused (0 / 2)
    nb = notebook(tmp_path / "01_selection.ipynb", *[JITTED_TOURNAMENT if name == "tournament" else source
                                                      for name, source in HONEST.items()])
    proc = grade(tmp_path, [nb], "--json", "r.json", "--seed", "7")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert json.loads((tmp_path / "r.json").read_text())["score"] == 10, proc.stdout


def test_files_without_a_name_count_as_memory_and_disk(tmp_path):
    # red team, round 6: memfd shared memory never mapped, and a deleted file kept open, counted nowhere
    code = ("import os, time\nfd = os.memfd_create('x')\nos.write(fd, b'x' * 8 * 2**20)\n"
            f"f = open({str(tmp_path / 'gone')!r}, 'wb')\nf.write(b'y' * 4 * 2**20)\nf.flush()\nos.unlink(f.name)\n"
            "print('ready', flush=True)\ntime.sleep(60)")
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE)
    try:
        assert child.stdout.readline() == b"ready\n"
        memory, disk = held_files([child.pid, child.pid])  # each file once
        assert list(memory) == [child.pid] and 8 * 2**20 <= memory[child.pid] < 9 * 2**20, memory
        assert 4 * 2**20 <= disk < 5 * 2**20, disk
        watch = Watch(limit_mb=10**6, disk_mb=3)
        watch.poll()
        assert child.wait(10) == -signal.SIGKILL and "MiB of files, over the limit of 3 MiB" in watch.events[0]
    finally:
        child.kill()
        child.wait()


IN_FLIGHT = """import os, socket, time
a, b = socket.socketpair(socket.AF_UNIX)
{make}
os.write(fd, b"x" * 64 * 2**20)
socket.send_fds(a, [b"x"], [fd])  # the file's only reference is now in flight, in no process's fds
os.close(fd)
print("ready", flush=True)
time.sleep(60)"""


@pytest.mark.parametrize("make, limit", [
    ("fd = os.memfd_create('hidden')", "shared memory"),
    ("fd = os.open('gone', os.O_CREAT | os.O_RDWR)\nos.unlink('gone')", "free space"),
])
def test_what_no_process_holds_is_stopped_by_the_machine_wide_backstop(tmp_path, monkeypatch, make, limit):
    # red team, round 7: a memfd or a deleted file whose only reference is in flight in a socket, counted nowhere
    disk = limit == "free space"
    # one backstop at a time, each with 2 MiB to spare: what other programs do cannot stop this one first
    monkeypatch.setattr(supervisor, "BACKSTOP_SLACK", 2**20 if disk else 2**20 - supervisor.TMP_BYTES - supervisor.SHM_BYTES)
    if disk:
        monkeypatch.setattr(supervisor, "machine_shared_memory", lambda: 1)
    watch = Watch(limit_mb=1, folder=tmp_path if disk else None, disk_mb=1)
    watch.poll()
    assert watch.events == []
    child = subprocess.Popen([sys.executable, "-c", IN_FLIGHT.format(make=make)], cwd=tmp_path, stdout=subprocess.PIPE)
    try:
        assert child.stdout.readline() == b"ready\n"
        assert held_files([child.pid]) == ({}, 0)  # nothing to see per process
        watch._next_disk = 0.0
        watch.poll()
        assert child.wait(10) == -signal.SIGKILL and limit in watch.events[0], watch.events
    finally:
        child.kill()
        child.wait()


@pytest.mark.slow
def test_shared_memory_a_notebook_never_maps_counts_against_its_memory(tmp_path):
    hoard = "import os, time\nfd = os.memfd_create('hoard')\nfor _ in range(600):\n    os.write(fd, b'x' * 2**20)\ntime.sleep(5)"
    nb = notebook(tmp_path / "01_selection.ipynb", hoard, *HONEST.values())
    proc = grade(tmp_path, [nb], "--memory-mb", "500", "--seed", "7")
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "NOT GRADED: the notebook's kernel was stopped" in proc.stdout and "over the limit of 500 MiB" in proc.stdout


def test_a_student_error_text_cannot_cost_the_batch_its_results(tmp_path):
    forged = ('def tournament(fitness, k, rng, size=3):\n'
              '    raise ValueError("lone \\ud800 surrogate\\nga.tournament              2.00 / 2   all properties hold")')
    honest = notebook(tmp_path / "honest.ipynb", *HONEST.values())
    odd = notebook(tmp_path / "odd.ipynb", *HONEST.values(), forged)
    for nb in (honest, odd):
        nb_json = json.loads(nb.read_text())
        nb_json["metadata"]["coursekit"] = {"exercise": "01_selection"}
        nb.write_text(json.dumps(nb_json))
    proc = grade(tmp_path, [honest, odd], "--json", "r.json", "--seed", "7")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    results = json.loads((tmp_path / "r.json").read_text())["extra_data"]["notebooks"]
    assert [r["score"] for r in results] == [10, 8], results
    assert len(re.findall(r"^\s*ga\.tournament\s+2\.00 / 2\s+all properties hold$", proc.stdout, re.M)) == 1, proc.stdout


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\u2028", "\u2029", "\x85"])
def test_a_message_cannot_fake_a_line_of_the_summary(newline):
    fake = f"boom{newline}physics.rkn_step           6.00 / 6   all properties hold"
    assert clean(fake) in ("boom ⏎ physics.rkn_step 6.00 / 6   all properties hold",
                           "boomphysics.rkn_step 6.00 / 6   all properties hold")
    assert len(clean(fake).splitlines()) == 1


@pytest.mark.slow
def test_a_notebook_past_its_total_time_is_stopped_and_not_graded(tmp_path):
    sleeps = ["import time\ntime.sleep(20)"] * 3  # 60 s of cells, each well within its own timeout
    nb = notebook(tmp_path / "01_selection.ipynb", *HONEST.values(), *sleeps)
    proc = grade(tmp_path, [nb], "--json", "r.json", "--cell-timeout", "60", "--notebook-timeout", "15")
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "NOT GRADED: grading stopped after 15 s (--notebook-timeout 15 s)" in proc.stdout
    assert leftovers(tmp_path) == []


def test_notebook_timeout_must_be_positive(tmp_path):
    proc = grade(tmp_path, [tmp_path / "01_selection.ipynb"], "--notebook-timeout", "0")
    assert proc.returncode == 2 and "--notebook-timeout must be a positive finite number, got 0.0" in proc.stderr


@pytest.mark.parametrize("hidden", ["\u061c", "\ufeff", "\u2060", "\u00ad", "\U000e0041", "\ue000", "\U0010ffff"])
def test_clean_drops_invisible_and_bidirectional_characters(hidden):
    # red team, round 7: format, private-use and tag characters passed, and long runs of spaces (which a terminal
    # wraps into what looks like a line of its own)
    assert clean(f"a{hidden}b" + " " * 300 + "ga.tournament 2.00 / 2") == "ab ga.tournament 2.00 / 2"
