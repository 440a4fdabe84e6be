"""The grading sandbox (issue 13, parts 2-3): bubblewrap, or no grading without --unsafe.

What a notebook cannot do inside it, end to end: tests/test_grading_integrity.py (escape.ipynb).
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from coursekit.grading import sandbox

ROOT = Path(__file__).resolve().parent.parent
HAVE = sandbox.available() is None


def test_without_a_sandbox_grading_is_refused_unless_unsafe(tmp_path):
    bad = tmp_path / "01_selection.ipynb"
    bad.write_text('{"cells": [')  # graded at once: no kernel needed
    env = {"PATH": str(tmp_path), "PYTHONPATH": str(ROOT)}  # no bwrap on this PATH
    proc = subprocess.run([sys.executable, "-m", "coursekit", "grade", str(bad), "--json", "r.json"], cwd=tmp_path,
                          capture_output=True, text=True, env=env)
    assert proc.returncode == 2 and "cannot sandbox the notebooks: bubblewrap (bwrap) is not installed" in proc.stderr
    assert "--unsafe" in proc.stderr and proc.stdout == "" and not (tmp_path / "r.json").exists()
    proc = subprocess.run([sys.executable, "-m", "coursekit", "grade", str(bad), "--json", "r.json", "--unsafe"],
                          cwd=tmp_path, capture_output=True, text=True, env=env)
    assert proc.returncode == 0 and "graded without a sandbox (--unsafe)" in proc.stdout


@pytest.mark.skipif(not HAVE, reason=f"no sandbox here: {sandbox.available()}")
def test_inside_the_sandbox_files_are_read_only_hidden_or_private(tmp_path):
    box = tmp_path / "box"
    (box / "work").mkdir(parents=True)
    other = tmp_path / "other_submission.ipynb"
    other.write_text("answers")
    marker = Path("/tmp") / f"coursekit-host-file-{tmp_path.name}"
    marker.write_text("the host's /tmp")
    script = f"""
cat {ROOT}/solutions/01_selection.ipynb 2>/dev/null | wc -c
cat {other} | wc -c
touch {ROOT}/coursekit/PWNED 2>/dev/null && echo wrote-package
echo box > {box}/work/mine && cat {box}/work/mine
test -e {marker} && echo seen || echo unseen
ls /proc | grep -c '^[0-9]'
ls -A {ROOT}/.git {ROOT}/tests {ROOT}/lessons 2>/dev/null | grep -vc ':$'
test -r {ROOT}/coursekit/grading/sandbox.py && echo package
echo x 2>/dev/null > /dev/coursekit-x && echo wrote-dev || echo dev-read-only
head -c 100000000 /dev/zero 2>/dev/null > /dev/shm/big && echo shm-unbounded || echo shm-full
"""
    try:
        run = subprocess.run(sandbox.command(box, show=[ROOT / "coursekit"], hide_dirs=[ROOT / "solutions"], hide_files=[other])
                             + ["/bin/sh", "-c", script],
                             capture_output=True, text=True, timeout=120)
    finally:
        marker.unlink()
    lines = run.stdout.split()
    assert run.returncode == 0, run.stderr
    assert lines[:4] == ["0", "0", "box", "unseen"], lines  # solutions hidden, other submission empty, box writable, /tmp private
    assert int(lines[4]) < 10  # its own PID namespace: a handful of processes, not the machine's
    # nothing of the checkout but the package (its git history holds the solutions)
    assert lines[5:7] == ["0", "package"], lines
    # /dev holds device nodes only, and /dev/shm is small (red team, round 6: 700 MB written there counted nowhere)
    assert lines[7:] == ["dev-read-only", "shm-full"], lines
    assert not (ROOT / "coursekit" / "PWNED").exists() and (ROOT / "solutions" / "01_selection.ipynb").stat().st_size > 0


PROBE = '''import glob, json, os
ppid = os.getppid()
seen = {"parent": open(f"/proc/{ppid}/cmdline", "rb").read().split(b"\\0")[2].decode(), "fds": {}}
for fd in os.listdir(f"/proc/{ppid}/fd"):
    try:
        with open(f"/proc/{ppid}/fd/{fd}", "a"):
            seen["fds"][fd] = "opened"
    except OSError as exc:
        seen["fds"][fd] = type(exc).__name__
seen["box"] = sorted(os.path.relpath(p, "..") for p in glob.glob("../**", recursive=True))
json.dump(seen, open("probe.json", "w"))'''


@pytest.mark.skipif(not HAVE, reason=f"no sandbox here: {sandbox.available()}")
def test_the_kernel_cannot_reach_the_grading_child_nor_find_the_cases(tmp_path):
    """The grading child is undumpable: the kernel (same user) opens none of its descriptors (the
    results pipe among them), and the plan with the cases is gone before the notebook's cells run."""
    import nbformat
    from nbformat.v4 import new_code_cell, new_notebook

    nb = new_notebook(cells=[new_code_cell(PROBE)])
    nb.metadata["coursekit"] = {"exercise": "01_selection"}
    nbformat.write(nb, tmp_path / "probe.ipynb")
    env = {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT), "COURSEKIT_PROFILE": "ci", "TMPDIR": str(tmp_path),
           "COURSEKIT_GRADE_KEEP": "1"}
    subprocess.run([sys.executable, "-m", "coursekit", "grade", "probe.ipynb", "--timeout", "5"], cwd=tmp_path,
                   capture_output=True, text=True, env=env, timeout=600)
    probes = list(tmp_path.glob("coursekit-grade-*/box/work/probe.json"))
    assert len(probes) == 2  # exercise 01 runs twice (withheld.runs): each run is probed
    import json

    for probe in probes:
        seen = json.loads(probe.read_text())
        assert seen["parent"] == "coursekit.grading.executor"
        assert len(seen["fds"]) > 3 and set(seen["fds"].values()) == {"PermissionError"}, seen["fds"]
        assert "submission.ipynb" in seen["box"] and not {"calls.json", "spec.json", "channel.jsonl"} & set(seen["box"]), seen["box"]


#: The probe run inside the sandbox by a user who is not root: the sandbox's own limit, then a fork
#: bomb of 200 sleeping children. sandbox.py is shipped as text (only the standard library).
_FORK_BOMB = """
import os, sys, time
ns = {"__name__": "sandbox"}
exec(compile(sys.stdin.read(), "sandbox.py", "exec"), ns)
why = ns["limit_processes"](24)
started = 0
for _ in range(200):
    try:
        pid = os.fork()
    except OSError:
        break
    if pid == 0:
        time.sleep(5)
        os._exit(0)
    started += 1
print(why, started)
"""


@pytest.mark.skipif(not HAVE, reason=f"no sandbox here: {sandbox.available()}")
def test_a_fork_bomb_stops_at_the_process_limit_for_a_grader_who_is_not_root(tmp_path):
    """bubblewrap gives a non-root grader a user namespace of its own, in which RLIMIT_NPROC counts
    only the sandbox's processes (Linux >= 5.14): 30 processes the same user runs outside do not
    count, and the bomb gets 24 children, not 200. As root this runs as `nobody`; the system
    Python is used (the test's own Python may live where `nobody` cannot read)."""
    user = 65534 if os.geteuid() == 0 else None
    python = "/usr/bin/python3" if user is not None else sys.executable
    if not Path(python).exists():
        pytest.skip("no system Python for the user nobody")
    outside = [subprocess.Popen(["sleep", "60"], user=user) for _ in range(30)]
    try:
        run = subprocess.run(sandbox.command(None, python=user is None) + [python, "-c", _FORK_BOMB], user=user, capture_output=True,
                             text=True, timeout=120, input=(ROOT / "coursekit" / "grading" / "sandbox.py").read_text())
    finally:
        for p in outside:
            p.kill()
            p.wait()
    assert run.returncode == 0, run.stderr
    why, started = run.stdout.split()[-2:]
    if sandbox._counts_per_namespace():
        assert why == "None" and int(started) == 24, run.stdout
    else:  # an older kernel: nothing is set (it would count the user's other processes), and it says why
        assert "per user, not per namespace" in run.stdout and int(started) == 200


def test_outside_a_user_namespace_of_its_own_the_limit_is_not_set_and_it_says_why():
    """Here (no sandbox) the limit would bind root not at all and any other user across all their processes."""
    why = sandbox.limit_processes(10)
    assert why == ("running as root, whom RLIMIT_NPROC does not bind" if os.geteuid() == 0 else
                   "no user namespace of its own: RLIMIT_NPROC would count the user's other processes")
