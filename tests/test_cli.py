"""The `coursekit` command and the size profiles."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from coursekit import profile
from coursekit.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent


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


@pytest.mark.parametrize("command, opens", [(["lab", "{course}"], "/lab/tree/lessons"),
                                            (["demo", "pictures", "--dir", "{course}"], "/lab/tree/demos/picture_breeding.ipynb")])
def test_lab_serves_the_course_and_opens_the_lessons(tmp_path, command, opens):
    """`coursekit lab DIR` (the README's first command) copies the course into DIR and really
    serves JupyterLab there, opened on lessons/, with JupyterLab's news pop-up off; the pictures
    demo opens its notebook the same way. The solutions are not part of the student's copy."""
    import json
    import socket
    import time
    import urllib.error
    import urllib.request

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    course = tmp_path / "my course"
    command = [c.format(course=course) for c in command]
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
        assert "solutions" not in names
        assert sorted(p.name for p in (course / "lessons").glob("*.ipynb")) == sorted(
            p.name for p in (ROOT / "lessons").glob("*.ipynb"))
        page = urllib.request.urlopen(f"{base}/lab?token=t", timeout=5).read().decode()
        config = json.loads(re.search(r'<script id="jupyter-config-data" type="application/json">(.*?)</script>',
                                      page, re.S).group(1))
        assert config["news"] == {"disabled": True}  # no "get notified about Jupyter news?" pop-up

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
    assert {"best.json", "best.png", "best.gif", "best.mp4", "best-keyframes.png", "fitness.png"} <= set(summary["files"])
    assert set(summary["files"]) == {p.name for p in out.iterdir()}
    best = Creature.from_json((out / "best.json").read_text())
    assert best.expand().body.n_bodies == summary["best_parts"]
    assert summary["best_fitness"] == max(summary["history_best"])
    assert Image.open(out / "best.gif").n_frames > 1


def test_demo_without_a_name_writes_both_demos_and_a_page_that_opens_them(tmp_path):
    """`coursekit demo --out DIR`: the swimmers (film, key frames, fitness plot) and the bred
    pictures in one folder, and an index.html whose every link and picture is a file there."""
    import json
    import os
    from html.parser import HTMLParser

    import imageio_ffmpeg
    from PIL import Image

    env = {**os.environ, "COURSEKIT_PROFILE": "ci"}
    out = tmp_path / "demo"
    run = subprocess.run([sys.executable, "-m", "coursekit", "demo", "--out", str(out), "--seed", "1"],
                         env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    assert f"open {out / 'index.html'}" in run.stdout

    class Links(HTMLParser):
        def __init__(self):
            super().__init__()
            self.links = []

        def handle_starttag(self, tag, attrs):
            self.links += [(tag, v) for k, v in attrs if k in ("src", "href")]

    page = Links()
    page.feed((out / "index.html").read_text())
    targets = [v for _, v in page.links]
    assert targets and all((out / v).is_file() for v in targets), [v for v in targets if not (out / v).is_file()]
    assert ("video", "swimmers/best.mp4") in page.links and "swimmers/best.gif" in targets
    assert {"swimmers/best-keyframes.png", "swimmers/fitness.png", "pictures/gallery-0.png"} <= set(targets)
    assert any(v.startswith("pictures/favourite-") for v in targets)
    summary = json.loads((out / "swimmers" / "summary.json").read_text())
    frames = imageio_ffmpeg.count_frames_and_secs(str(out / "swimmers" / "best.mp4"))[0]
    assert frames == Image.open(out / "swimmers" / "best.gif").n_frames > 1
    strip = Image.open(out / "swimmers" / "best-keyframes.png")
    assert strip.size[0] > 3 * strip.size[1]  # key frames side by side
    from coursekit.creatures.champions import hall_of_fame

    fame = hall_of_fame()
    assert [c["name"] for c in summary["champions"]] == [c.name for c in fame] and fame  # every one shown, with its film
    assert all(f"swimmers/champion-{k}.mp4" in targets for k in range(len(fame)))
    pictures = json.loads((out / "pictures" / "summary.json").read_text())
    sheet = Image.open(out / "pictures" / "gallery-0.png")
    assert len(pictures["sheets"]) == pictures["generations"] + 1 and sheet.size[0] > sheet.size[1]  # 4 x 5 gallery
    from coursekit.pictures import Gallery, load_genome

    assert load_genome(out / "pictures" / "favourite-0.png").expression() == pictures["expressions"][0]
    gallery = Gallery.load(out / "pictures" / "gallery_session.json", size=16)  # breeding goes on from it
    assert gallery.state.generation == pictures["generations"]


def test_bench_help_lists_the_benchmarks_and_a_scripts_help_is_its_own():
    run = subprocess.run([sys.executable, "-m", "coursekit", "bench", "--help"], capture_output=True, text=True)
    assert run.returncode == 0 and "sims_scale" in run.stdout and "picture_variety" in run.stdout
    run = subprocess.run([sys.executable, "-m", "coursekit", "bench", "sims_scale", "--help"], capture_output=True, text=True)
    assert run.returncode == 0 and "--population" in run.stdout and "--generations" in run.stdout  # the script's options


def test_bench_names_what_it_has_and_what_it_needs():
    """`coursekit bench` runs the packaged (or checked-out) scripts; a wrong name is refused with the list."""
    run = subprocess.run([sys.executable, "-m", "coursekit", "bench", "no_such_bench"], capture_output=True, text=True)
    assert run.returncode == 2
    assert "no benchmark named 'no_such_bench'" in run.stderr
    for name in ("pictures", "swimmers", "brain"):
        assert name in run.stderr


def test_bench_runs_a_benchmark_and_passes_its_options():
    run = subprocess.run([sys.executable, "-m", "coursekit", "bench", "picture_variety", "--genomes", "2", "--sessions", "1"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "== benchmarks/picture_variety.py --genomes 2 --sessions 1" in run.stdout
    assert "children: 126 checked (1 sessions x 7 operators" in run.stdout  # the options reached the script


def test_bench_refuses_a_bad_option_by_name():
    """A count the benchmark divides by (``--reference-sample 0`` once ended in ZeroDivisionError after a
    minute of rendering) is refused at once, naming the option."""
    run = subprocess.run([sys.executable, "-m", "coursekit", "bench", "pictures", "--reference-sample", "0"],
                         capture_output=True, text=True)
    assert run.returncode != 0
    assert "argument --reference-sample: must be an integer >= 1, got 0" in run.stderr
    assert "Traceback" not in run.stderr


@pytest.mark.parametrize("argv, message", [
    (["gallery_click", "--clicks", "0"], "argument --clicks: must be an integer >= 1, got 0"),
    (["render", "--size", "0", "0"], "argument --size: must be an integer >= 16, got 0"),
    (["sims_scale", "--population", "1"], "argument --population: must be an integer >= 2, got 1"),
    (["sims_scale", "--rhythm", "2"], "argument --rhythm: must be a number from 0 to 1, got 2"),
    (["picture_variety", "--genomes", "0"], "argument --genomes: must be an integer >= 1, got 0"),
])
def test_bench_scripts_refuse_bad_sizes_by_name(argv, message):
    """--clicks 0 ended in an IndexError from numpy's quantile after the warm-up clicks, --size 0 0 and
    --population 1 in tracebacks from the library, --genomes 0 in a table of 0.0 % rows."""
    run = subprocess.run([sys.executable, "-m", "coursekit", "bench", *argv], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and message in run.stderr and "Traceback" not in run.stderr, run.stderr


def test_bench_says_what_a_benchmark_needs(monkeypatch, capsys):
    """Without MuJoCo the simulator benchmark is refused with the command that installs it."""
    import importlib.util

    from coursekit.cli import main

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "mujoco" else real(name, *a))
    assert main(["bench", "swimmers"]) == 2
    err = capsys.readouterr().err
    assert "swimmers needs mujoco" in err and "pip install 'coursekit[mujoco]'" in err


@pytest.mark.parametrize("workers", [1, 2])
def test_the_swimmer_demo_films_a_champion_that_is_its_own_best_once(tmp_path, monkeypatch, workers):
    """At its defaults the demo's run is the one that shipped as a champion: that champion is
    shown with the run's own films, not simulated and filmed a second time (with workers, the
    champions are filmed while evolution runs, and that one's films become the best's)."""
    import dataclasses
    import importlib
    import json

    from coursekit import demos
    from coursekit.creatures import Creature

    C = importlib.import_module("coursekit.creatures.champions")
    shipped = C.hall_of_fame()[0]
    monkeypatch.setenv("COURSEKIT_PROFILE", "ci")
    monkeypatch.setattr(C, "hall_of_fame", lambda: [])
    first = demos.swimmers(tmp_path / "first", seed=3, workers=1, progress=False)
    best = Creature.from_json((tmp_path / "first" / "best.json").read_text())
    fame = [dataclasses.replace(shipped, name="this run", creature=best), shipped]
    monkeypatch.setattr(C, "hall_of_fame", lambda: fame)
    second = demos.swimmers(tmp_path / "second", seed=3, workers=workers, progress=False)
    assert second["best_fitness"] == first["best_fitness"]  # the same run again
    own, theirs = second["champions"]
    assert {own[k] for k in ("mp4", "gif", "keyframes")} == set(second["films"].values())
    assert theirs["mp4"] == "champion-1.mp4" and (tmp_path / "second" / "champion-1.mp4").is_file()
    assert not list((tmp_path / "second").glob("champion-0*"))
    assert json.loads((tmp_path / "second" / "summary.json").read_text())["champions"][0]["mp4"] == "best.mp4"



def test_the_swimmer_demo_keeps_to_its_budget_by_breeding_fewer_generations_of_the_same_run(tmp_path, monkeypatch):
    """``budget``: no generation is begun that would end after it, so a slow laptop shows fewer
    generations, of the very same run, and says so; a budget the run fits in changes nothing."""
    import importlib
    import json

    from coursekit import demos

    monkeypatch.setenv("COURSEKIT_PROFILE", "ci")
    monkeypatch.setattr(importlib.import_module("coursekit.creatures.champions"), "hall_of_fame", lambda: [])
    full = demos.swimmers(tmp_path / "full", seed=2, generations=2, workers=1, progress=False)
    roomy = demos.swimmers(tmp_path / "roomy", seed=2, generations=2, workers=1, budget=1e9, progress=False)
    tight = demos.swimmers(tmp_path / "tight", seed=2, generations=2, workers=1, budget=1e-9, progress=False)
    assert full["generations"] == roomy["generations"] == 2 and not full["stopped_by_budget"] | roomy["stopped_by_budget"]
    assert roomy["history_best"] == full["history_best"]
    assert (tight["generations"], tight["generations_planned"], tight["stopped_by_budget"]) == (0, 2, True)
    assert tight["history_best"] == full["history_best"][:1]  # generation 0 of the same run
    assert json.loads((tmp_path / "tight" / "summary.json").read_text())["stopped_by_budget"] is True
    assert demos._bred(tight) == "0 generations of Sims' recipe (of 2: the next would have ended after the 1e-09 s budget)"
    with pytest.raises(ValueError, match="budget: must be a number of seconds >= 0"):
        demos.swimmers(tmp_path / "bad", budget=-1.0)
    with pytest.raises(ValueError, match="seconds: must be a number of seconds > 0, got 0"):
        demos.swimmers(tmp_path / "bad", seconds=0)  # not the default in disguise


@pytest.mark.parametrize("option, message", [("--budget=-1", "argument --budget: must be a number >= 0, got -1"),
                                             ("--population=1", "argument --population: must be an integer >= 2, got 1"),
                                             ("--seconds=0", "argument --seconds: must be a number > 0, got 0"),
                                             ("--seconds=inf", "argument --seconds: must be a number > 0, got inf"),
                                             ("--seed=-1", "argument --seed: must be an integer >= 0, got -1"),
                                             ("--workers=0", "argument --workers: must be an integer >= 1, got 0"),
                                             ("--workers=100000", "--workers: must be an integer from 1 to the population ("),
                                             ("--population=6 --workers=7", "--workers: must be an integer from 1 to the population (6), got 7"),
                                             ("--rhythm=1.5", "argument --rhythm: must be a number from 0 to 1, got 1.5"),
                                             ("--rhythm=-0.1", "argument --rhythm: must be a number >= 0, got -0.1")])
def test_the_demo_refuses_a_bad_size_by_name_before_it_starts(option, message, tmp_path):
    run = subprocess.run([sys.executable, "-m", "coursekit", "demo", "swimmers", *option.split(), "--out", str(tmp_path / "d")],
                         capture_output=True, text=True)
    assert run.returncode == 2 and message in run.stderr and "Traceback" not in run.stderr
    assert not (tmp_path / "d").exists()


def test_the_demo_refuses_an_out_folder_it_cannot_make(tmp_path):
    (tmp_path / "afile").write_text("")
    for out in (tmp_path / "afile", tmp_path / "afile" / "d"):
        run = subprocess.run([sys.executable, "-m", "coursekit", "demo", "swimmers", "--out", str(out)],
                             capture_output=True, text=True, timeout=120)
        assert run.returncode == 2 and "Traceback" not in run.stderr, run.stderr
        assert f"coursekit demo: --out {out}: cannot make this folder" in run.stderr


@pytest.mark.parametrize("option, message", [("--timeout=inf", "--timeout must be a positive finite number, got inf"),
                                             ("--cell-timeout=nan", "--cell-timeout must be a positive finite number, got nan"),
                                             ("--memory-mb=0", "--memory-mb must be a positive finite number, got 0"),
                                             ("--seed=-1", "argument --seed: must be an integer >= 0, got -1")])
def test_grade_refuses_a_bad_limit_by_name_before_grading(option, message, tmp_path):
    run = subprocess.run([sys.executable, "-m", "coursekit", "grade", str(tmp_path / "01_selection.ipynb"), option],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and message in run.stderr and "Traceback" not in run.stderr, run.stderr


def test_bench_runs_everything_but_what_this_machine_lacks(monkeypatch, capsys):
    """`coursekit bench` with no names runs every script but the GPU one where there is no GPU
    (named, it runs, and says itself that it has nothing to measure)."""
    import subprocess as sp

    from coursekit import cli

    ran = []
    monkeypatch.setitem(cli.BENCH_HARDWARE, "gpu", ("a CUDA GPU", lambda: False))
    monkeypatch.setattr(sp, "call", lambda argv, *a, **k: ran.append(argv[1]) or 0)
    assert cli.main(["bench"]) == 0
    names = {p.rsplit("/", 1)[-1] for p in ran}
    assert "gpu.py" not in names and {"swimmers.py", "pictures.py", "sims_scale.py"} <= names
    assert "leaving out gpu: it measures a CUDA GPU" in capsys.readouterr().err
    ran.clear()
    assert cli.main(["bench", "gpu"]) == 0 and [p.rsplit("/", 1)[-1] for p in ran] == ["gpu.py"]


def test_the_simulator_benchmark_runs_both_tables():
    """The simulator benchmark, tiny: the random-creature table and the realistic workload (the
    saved evolved population, every engine from one mid-swim state), each row next to MuJoCo."""
    run = subprocess.run([sys.executable, "-m", "coursekit", "bench", "swimmers", "--batches", "1", "--evolved-batches", "1",
                          "--seconds", "0.02", "--warmup", "0.02", "--cuda-batches"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    for row in ("mujoco RK4 (1 thread)", "ours numpy RKN +collisions", "mujoco RK4 +collisions +brains",
                "ours numpy RKN +collisions +brains", "our brains alone"):
        assert row in run.stdout, row


def test_the_grading_benchmark_grades_a_set_and_says_what_each_notebook_should_get(tmp_path):
    """`coursekit bench grading` through the grader an instructor runs: here the back-door set (the
    library's work handed in), each notebook 0 points, with its grading time."""
    table = tmp_path / "grading.md"
    run = subprocess.run([sys.executable, "-m", "coursekit", "bench", "grading", "--sets", "back-doors", "--markdown", str(table)],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    assert "every notebook got what it should" in run.stdout
    rows = [line.split("|")[1:-1] for line in table.read_text().splitlines() if line.startswith("| back-doors | cheats_")]
    assert len(rows) == len(list((ROOT / "tests" / "adversarial").glob("cheats_*.ipynb"))) == 6 and all(r[2].strip().startswith("0 / ") and r[4].strip() == "yes" and float(r[5]) > 0 for r in rows)
