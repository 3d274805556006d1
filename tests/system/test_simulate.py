"""End to end: the hospital scenario runs, is reproducible, and its replay page renders."""

import json
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from mrta_drake import load_scenario, simulate
from mrta_drake.tools.cli import main

ROOT = pathlib.Path(__file__).resolve().parents[2]
ROUTES = ROOT / "scenarios/hospital_routes_6_robots.yaml"


@pytest.fixture(scope="module")
def routes_scenario():
    return load_scenario(ROUTES)


def test_same_scenario_twice_gives_bit_identical_trajectories(routes_scenario):
    first = simulate(routes_scenario, duration=20.0)
    second = simulate(routes_scenario, duration=20.0)
    assert first.robot_states.shape == (201, 6, 4)
    assert np.array_equal(first.robot_states, second.robot_states)
    moved = np.linalg.norm(first.robot_states[-1, :, :2] - first.robot_states[0, :, :2], axis=1)
    assert (moved > 1.0).all()


def test_cli_run_duration_is_the_scenarios_so_a_generated_stream_runs_to_it(tmp_path):
    # The scenario lasts 2 s; --duration 6 runs 6 s and its tasks keep arriving after 2 s,
    # as a sweep's duration does (before, the stream stopped at the scenario's 2 s).
    text = (ROOT / "scenarios/hospital_6_robots.yaml").read_text()
    text = text.replace("../models", str(ROOT / "models"))
    text = text.replace("  file: tasks/hospital_paper_stream.json\n",
                        "  generate: {rate: 2.0, batch_size: [1, 1], deadline_range: [60, 90]}\n")
    text = text.replace("  travel_times: travel_times/hospital.yaml", "").replace(
        "duration: 600.0", "duration: 2.0")
    scenario = tmp_path / "short.yaml"
    scenario.write_text(text)
    out = tmp_path / "run"
    assert main(["run", str(scenario), "--duration", "6", "--out", str(out), "--quiet",
                 "--no-plots"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    arrivals = [task["arrival"] for task in summary["tasks"]["per_task"]]
    assert summary["duration"] == pytest.approx(6.0)
    assert max(arrivals) > 2.0 and all(arrival < 6.0 for arrival in arrivals)


def test_cli_run_prints_summary_and_writes_results(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", str(ROUTES), "--duration", "5", "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "real-time factor" in printed and "robot6" in printed
    assert (out / "summary.json").is_file()
    rows = (out / "timeline.csv").read_text().splitlines()
    assert rows[0] == "time,robot,x,y,theta,v"
    assert len(rows) == 1 + 6 * 51


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGINT])
def test_a_run_stopped_by_a_signal_writes_its_results_so_far(tmp_path, stop):
    # A batch system's stop (SIGTERM) or Ctrl-C (SIGINT) ends the run after its current
    # slice: the summary covers the simulated time reached and says it was interrupted; the
    # exit code is 130.
    out = tmp_path / "run"
    run = subprocess.Popen([sys.executable, "-m", "mrta_drake.tools.cli", "run", str(ROUTES),
                            "--duration", "1e6", "--out", str(out), "--no-plots", "--quiet"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    timeline = out / "timeline.csv"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and run.poll() is None and (
            not timeline.is_file() or timeline.stat().st_size < 20_000):
        time.sleep(0.5)
    assert run.poll() is None, run.communicate()
    run.send_signal(stop)
    printed, err = run.communicate(timeout=120)
    assert run.returncode == 130, err
    summary = json.loads((out / "summary.json").read_text())
    last = float(timeline.read_text().splitlines()[-1].split(",")[0])
    assert summary["interrupted"] and 0 < summary["duration"] == pytest.approx(last)
    assert "(interrupted)" in printed and "Traceback" not in err


def _chromium():
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(_chromium() is None, reason="chromium is not installed")
def test_recorded_replay_page_renders_in_headless_chromium(routes_scenario, tmp_path):
    from PIL import Image

    page = tmp_path / "replay.html"
    simulate(routes_scenario, duration=3.0, record_html=str(page))
    html = page.read_text()
    assert html.startswith("<!DOCTYPE html>") or "<html" in html[:200]
    shot = tmp_path / "shot.png"
    done = subprocess.run(
        [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}",
         "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
         "--enable-logging=stderr", "--v=0", "--window-size=1024,768",
         # --timeout, not --virtual-time-budget: the replay animates forever, so virtual
         # time never runs out of work and the budget is never reached.
         "--timeout=8000", f"--screenshot={shot}", page.as_uri()],
        capture_output=True, text=True, timeout=120)
    console = [line for line in done.stderr.splitlines() if "CONSOLE" in line]
    assert not [line for line in console if "Uncaught" in line or "Error" in line], console
    pixels = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    # Not blank: the floor plan and robots make the picture far from uniform.
    assert pixels.std() > 10.0
    assert len(np.unique(pixels.reshape(-1, 3), axis=0)) > 50


@pytest.mark.parametrize("flags", [
    ["run", str(ROUTES), "--out", "{blocked}/out"],
    ["run", str(ROUTES), "--record", "{blocked}/replay.html"],
    ["diagram", str(ROUTES), "{blocked}/diagram.dot"],
    ["travel-times", str(ROUTES), "--out", "{blocked}/times.yaml"],
    ["sweep", str(ROOT / "scenarios/sweeps/hospital_20_seeds.yaml"), "--out", "{blocked}/s"],
])
def test_output_that_cannot_be_written_is_one_line_before_any_run(tmp_path, capsys, flags):
    blocked = tmp_path / "a_file"  # a file where a folder should be
    blocked.write_text("")
    code = main([flag.format(blocked=blocked) for flag in flags])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert err.startswith("error: ") and "cannot write to" in err and str(blocked) in err


@pytest.mark.skipif(shutil.which("dot") is None, reason="graphviz is not installed")
def test_diagram_in_a_format_graphviz_lacks_is_one_line(tmp_path, capsys):
    assert main(["diagram", str(ROUTES), str(tmp_path / "diagram.nosuchformat")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "graphviz cannot write" in err
