"""Pictures of one run, as PNG files (matplotlib's Agg canvas; no pyplot, no display).

- ``trajectories.png``: every robot's path over the floor plan's occupancy raster, with the
  locations, the people's paths (faint) and where robots were deadlocked; a path breaks
  where a lift ride moved its robot to another level.
- ``gantt.png``: each robot's stops over time, coloured by task, with the task deadlines.
- ``legs.png``: predicted against actual duration of every completed stop.
- ``drift.png``: actual minus predicted drop-off time of every completed task over time,
  with the re-plans on drift.
- ``clearances.png``: the smallest robot-robot, robot-wall and robot-human clearance over
  time.

World frame (x east, y north), metres, seconds of simulation time.
"""

import os

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from mrta_drake.payloads import DROPOFF, PICKUP
from mrta_drake.results.clearances import clearances
from mrta_drake.results.summary import RELOCATION_STEP

RASTER_RESOLUTION = 0.1  # m per cell of the drawn floor plan


def write_plots(out_dir: str, stack, summary: dict) -> list[str]:
    """Write the five plots of the run recorded by ``stack.recorder`` (summarized as
    ``summary``) to ``out_dir``; returns the files written."""
    recorder, scenario = stack.recorder, stack.scenario
    times, states, humans = recorder.arrays()
    names = list(recorder.robot_names)
    floor_plan = stack.world.floor_plan
    grid = (floor_plan.raw_grid if floor_plan.raw_grid is not None
            else floor_plan.occupancy(RASTER_RESOLUTION))
    locations = {loc.id: tuple(loc.point) for loc in scenario.locations if loc.point}
    radii = [r.radius for r in scenario.robots]
    human_radii = [] if stack.humans is None else stack.humans.human_radii
    gaps = clearances(floor_plan.obstacles, states[..., :2], radii, humans, human_radii)
    deadlocks = summary["deadlocks"]["episodes"]
    os.makedirs(out_dir, exist_ok=True)
    paths = [os.path.join(out_dir, name) for name in
             ("trajectories.png", "gantt.png", "legs.png", "clearances.png", "drift.png")]
    plot_trajectories(paths[0], grid, names, states[..., :2], humans, locations, deadlocks)
    plot_gantt(paths[1], names, summary["legs"], summary["tasks"]["per_task"],
               float(times[-1]) if len(times) else 0.0)
    plot_legs(paths[2], names, summary["legs"])
    plot_clearances(paths[3], times, *gaps.smallest(), deadlocks)
    plot_drift(paths[4], summary["predictions"])
    return paths


def plot_trajectories(path: str, grid, names, robot_xy, human_xy, locations: dict,
                      deadlocks=()) -> None:
    """Robot paths ``robot_xy`` (T, N, 2) over the occupancy ``grid`` (an
    ``OccupancyGrid``), human paths ``human_xy`` (T, M, 2) faint, ``locations`` (id ->
    (x, y)) labelled, ``deadlocks`` (summary episodes) marked."""
    x0, x1, y0, y1 = grid.extent
    figure = Figure(figsize=(6.0, 6.0 * (y1 - y0) / max(x1 - x0, 1e-9) * 0.9 + 0.8))
    axes = figure.add_subplot()
    axes.imshow(grid.occupied, origin="lower", extent=grid.extent, cmap="Greys",
                vmin=0, vmax=1.6, interpolation="nearest")
    for j in range(human_xy.shape[1]):
        axes.plot(human_xy[:, j, 0], human_xy[:, j, 1], color="0.55", lw=0.6, alpha=0.6)
    colours = _colours(len(names))
    for k, name in enumerate(names):
        xy = robot_xy[:, k]
        rides = np.flatnonzero(np.linalg.norm(np.diff(xy, axis=0), axis=1) > RELOCATION_STEP)
        drawn = np.insert(np.asarray(xy, dtype=float), rides + 1, np.nan, axis=0)
        axes.plot(drawn[:, 0], drawn[:, 1], color=colours[k], lw=1.4, label=name)
        if len(xy):
            axes.plot(*xy[0], "o", color=colours[k], ms=5)
            axes.plot(*xy[-1], "s", color=colours[k], ms=5, mec="black", mew=0.5)
    for location, (x, y) in locations.items():
        axes.plot(x, y, "*", color="black", ms=8)
        axes.annotate(str(location), (x, y), xytext=(4, 4), textcoords="offset points",
                      fontsize=8)
    for d in deadlocks:
        axes.plot(*d["position"], "X", color="red", ms=11, mec="black")
    axes.set(xlim=(x0, x1), ylim=(y0, y1), xlabel="x (m)", ylabel="y (m)", aspect="equal",
             title="Trajectories (o start, \u25a0 end, * locations, X deadlocks)")
    axes.legend(fontsize=7, loc="upper right")
    _save(figure, path)


def plot_gantt(path: str, names, legs, tasks, end_time: float) -> None:
    """Each robot's stops (``legs``, from start to completion) as bars coloured by task,
    labelled P/D + task id for pickup/drop-off (grey, @ + location, without a task); each
    task's deadline
    as a vertical tick on the row of the robot that had it, red when missed."""
    figure = Figure(figsize=(9.0, 1.2 + 0.5 * len(names)))
    axes = figure.add_subplot()
    row = {name: k for k, name in enumerate(names)}
    palette = _colours(max(len(tasks), 1), "tab20")
    for leg in legs:
        task = leg["task"]
        colour = "0.7" if task is None else palette[task % len(palette)]
        axes.barh(row[leg["robot"]], leg["end"] - leg["start"], left=leg["start"],
                  height=0.6, color=colour, edgecolor="black", lw=0.4)
        mark = {PICKUP: "P", DROPOFF: "D"}.get(leg["action"], "")
        label = f"{mark}{task}" if task is not None else f"@{leg['location']}"
        axes.text(0.5 * (leg["start"] + leg["end"]), row[leg["robot"]], label,
                  ha="center", va="center", fontsize=6)
    for task in tasks:
        if task["robot"] is None:
            continue
        missed = task["deadline_met"] is False
        axes.plot([task["deadline"]] * 2, [row[task["robot"]] - 0.4, row[task["robot"]] + 0.4],
                  color="red" if missed else palette[task["id"] % len(palette)], lw=2)
    axes.set(yticks=range(len(names)), yticklabels=names, xlim=(0, max(end_time, 1.0)),
             xlabel="time (s)", title="Stops per robot (P pickup, D drop-off; | deadline, "
             "red when missed)")
    axes.invert_yaxis()
    _save(figure, path)


def plot_legs(path: str, names, legs) -> None:
    """Left: predicted against actual duration per completed stop, with y = x. Right: the
    actual (filled) and predicted (hollow) durations against completion time."""
    figure = Figure(figsize=(10.0, 4.5))
    left, right = figure.subplots(1, 2)
    colours = dict(zip(names, _colours(len(names)), strict=True))
    predicted = [leg for leg in legs if leg["predicted"] is not None]
    for leg in predicted:
        left.plot(leg["predicted"], leg["actual"], "o", color=colours[leg["robot"]], ms=4)
    if predicted:
        top = max(max(leg["predicted"], leg["actual"]) for leg in predicted) * 1.05
        left.plot([0, top], [0, top], "k--", lw=0.8)
    else:
        left.text(0.5, 0.5, "no predicted times\n(the allocator made none)",
                  ha="center", va="center", transform=left.transAxes)
    left.set(xlabel="predicted (s)", ylabel="actual (s)", title="Stop duration")
    for leg in legs:
        colour = colours[leg["robot"]]
        right.plot(leg["end"], leg["actual"], "o", color=colour, ms=4)
        if leg["predicted"] is not None:
            right.plot(leg["end"], leg["predicted"], "o", mfc="none", color=colour, ms=6)
            right.plot([leg["end"]] * 2, [leg["predicted"], leg["actual"]], color=colour,
                       lw=0.6)
    right.set(xlabel="completed at (s)", ylabel="duration (s)",
              title="Actual (filled) and predicted (hollow)")
    for name, colour in colours.items():
        right.plot([], [], "o", color=colour, label=name)
    right.legend(fontsize=7)
    _save(figure, path)


def plot_drift(path: str, predictions: dict) -> None:
    """Actual minus predicted drop-off time (s) of each completed task against its actual
    drop-off (s), with a vertical line at each re-plan on drift (``summary["predictions"]``)."""
    figure = Figure(figsize=(9.0, 4.0))
    axes = figure.add_subplot()
    drift = np.array(predictions["drift"], dtype=float).reshape(-1, 2)
    axes.plot(drift[:, 0], drift[:, 1], "o", ms=4, label="task drop-off")
    for k, event in enumerate(predictions["replans"]["events"]):
        axes.axvline(event["time"], color="grey", lw=0.6,
                     label="re-plan on drift" if k == 0 else None)
    axes.axhline(0.0, color="black", lw=0.8)
    axes.set(xlabel="drop-off at (s)", ylabel="actual - predicted (s)",
             title="Drift of the predicted drop-offs (positive: later than predicted)")
    axes.legend(fontsize=8)
    _save(figure, path)


def plot_clearances(path: str, times, robot_robot, robot_wall, robot_human,
                    deadlocks=()) -> None:
    """The smallest clearances (T,) each over ``times``, m; contact below 0; deadlocked
    stretches shaded."""
    figure = Figure(figsize=(9.0, 4.0))
    axes = figure.add_subplot()
    for values, label in ((robot_robot, "robot-robot"), (robot_wall, "robot-wall"),
                          (robot_human, "robot-human")):
        if np.isfinite(values).any():
            axes.plot(times, np.where(np.isfinite(values), values, np.nan), lw=1, label=label)
    axes.axhline(0.0, color="red", lw=0.8)
    end = times[-1] if len(times) else 0.0
    for d in deadlocks:
        axes.axvspan(d["start"], end if d["end"] is None else d["end"], color="red",
                     alpha=0.12)
    axes.set(xlabel="time (s)", ylabel="clearance (m)", ylim=(min(-0.1, axes.get_ylim()[0]),
             None), title="Smallest clearance (surface to surface; red: contact, "
             "shaded: deadlock)")
    axes.legend(fontsize=8)
    _save(figure, path)


def _colours(count: int, map_name: str = "tab10") -> list:
    cmap = colormaps[map_name]
    return [cmap(k % cmap.N) for k in range(count)]


def _save(figure: Figure, path: str) -> None:
    FigureCanvasAgg(figure)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
