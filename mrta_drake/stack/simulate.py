"""Running a scenario: ``simulate(scenario)`` returns a ``SimulationResult``."""

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator

from mrta_drake.results.summary import summarize
from mrta_drake.scenario.schema import Scenario
from mrta_drake.stack.diagram import Stack, build_diagram

SLICE = 10.0  # s of simulated time at most between two checks for a stop request


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """What a run produced. ``times`` (T,) s; ``robot_states`` (T, N, 4) [x, y, theta, v];
    ``human_positions`` (T, M, 2); ``events`` as noted by the recorder; ``summary`` the
    figures printed and written to ``summary.json``."""

    scenario: Scenario
    times: np.ndarray
    robot_states: np.ndarray
    human_positions: np.ndarray
    events: list
    summary: dict
    stack: Stack = field(repr=False)


def simulate(scenario: Scenario, *, duration: float | None = None,
             meshcat: Meshcat | None = None, record_html: str | None = None,
             out_dir: str | None = None, progress: bool = False,
             realtime_rate: float = 0.0, plots: bool = True,
             before_run: Callable[[], None] | None = None,
             stop_requested: Callable[[], bool] | None = None) -> SimulationResult:
    """Run ``scenario`` for ``duration`` s (default: the scenario's), headless unless a
    ``meshcat`` is given. ``record_html`` writes a self-contained replay page;
    ``out_dir`` receives timeline.csv and events.jsonl as the run goes and summary.json
    (and, with ``plots``, the PNG plots of ``mrta_drake.results.plots``) at the end, also
    when the run stops early: ``stop_requested()`` true (asked between slices of at most
    ``SLICE`` s; the CLI's answer to Ctrl-C and SIGTERM), or a ``KeyboardInterrupt``. The
    results then cover the simulated time reached (summary ``interrupted``); ``progress``
    shows a progress bar; ``realtime_rate`` > 0 paces the run. ``before_run`` is called once
    the diagram is built, before the simulator initializes (the CLI finishes compiling the
    kernels there: ``kernel_cache.Compilation``)."""
    duration = scenario.duration if duration is None else duration
    if record_html and meshcat is None:
        meshcat = Meshcat()
    stack = build_diagram(scenario, meshcat=meshcat, out_dir=out_dir)
    if before_run is not None:
        before_run()
    simulator = Simulator(stack.diagram)
    simulator.set_target_realtime_rate(realtime_rate)
    if record_html:
        meshcat.StartRecording(frames_per_second=min(scenario.rates.meshcat, 30.0))
    start_cpu, start_wall = time.process_time(), time.perf_counter()
    simulator.Initialize()
    bar = _progress_bar(duration) if progress else None
    interrupted = False
    try:
        # Advance in slices so the progress bar moves and a stop is heard; results do not
        # depend on the slicing.
        step = min(max(1.0, duration / 200.0), SLICE)
        t = 0.0
        while t < duration:
            if stop_requested is not None and stop_requested():
                interrupted = True
                break
            t = min(duration, t + step)
            simulator.AdvanceTo(t)
            if bar is not None:
                bar.update(t - bar.n)
        if not interrupted:
            stack.diagram.ForcedPublish(simulator.get_context())
    except KeyboardInterrupt:  # a long run never loses its results: keep what ran
        interrupted = True
    finally:
        if bar is not None:
            bar.close()
        stack.recorder.close()
    wall = time.perf_counter() - start_wall
    cpu = time.process_time() - start_cpu
    if record_html:
        meshcat.StopRecording()
        meshcat.PublishRecording()
        os.makedirs(os.path.dirname(os.path.abspath(record_html)), exist_ok=True)
        with open(record_html, "w") as f:
            f.write(meshcat.StaticHtml())
    times, states, humans = stack.recorder.arrays()
    if interrupted:  # up to the last sample recorded
        duration = float(times[-1]) if len(times) else 0.0
    summary = summarize(stack, duration, wall, cpu) | {"interrupted": interrupted}
    if out_dir:
        os.makedirs(out_dir, exist_ok=True)
        with open(os.path.join(out_dir, "summary.json"), "w") as f:
            json.dump(summary, f, indent=2)
        if plots:
            from mrta_drake.results.plots import write_plots

            write_plots(out_dir, stack, summary)
    return SimulationResult(scenario, times, states, humans, list(stack.recorder.events),
                            summary, stack)


def _progress_bar(duration: float):
    from tqdm import tqdm

    return tqdm(total=duration, unit="sim s", bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} "
                "sim s [{elapsed}<{remaining}]")
