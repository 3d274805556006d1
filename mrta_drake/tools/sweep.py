"""Sweeps: many runs of one scenario over a grid of variations, in parallel, resumable.

A sweep spec is a YAML file::

    scenario: ../hospital_6_robots.yaml   # required: the base scenario, relative to this file
    grid:                                 # required: every combination of values is one run
      seed: [0, 1, 2]                     # any scenario field, by dotted name
      duration: [60.0]                    # s
      blocks.controller.kind: [cluster_cbf, go_to_goal]
      robots: [2, 4, 6]                   # special: the first k robots of the scenario
      humans: [true, false]               # special: false drops every person
    fixed:                                # optional: fields set the same way in every run
      tasks.service_time: 2.0
    plugins: [my_blocks.py, my_package.rules]  # optional: see below

``plugins`` are Python files (relative to the spec) or importable module names that register
your own block kinds or leader rules (``blocks.register_block``,
``control.register_leader_rule``) when imported. They are imported when the spec is loaded
and again in every worker process (which imports nothing of yours otherwise), so the grid
can name your kinds: ``blocks.allocator.kind: [smt, mine]``.

Dotted fields are set in the scenario before it is loaded and checked (``load_scenario``'s
``overrides``), so a generated task stream and a Scenic scene follow the run's seed (a scene
keeps clear of the run's robots, so it follows ``robots`` too). Setting
``blocks.<slot>.kind`` keeps the base's ``params`` for that slot. A value the scenario
loader rejects is a spec error (``InputError`` naming the spec file and field); a run that
fails later (an unknown block kind, parameters its block refuses, a crash) becomes an error
row and the sweep goes on.

``run_sweep`` runs every combination once: each in a fresh local process
(``ProcessPoolExecutor``), or as a task on a Ray cluster (the ``distributed`` extra; the
cluster's workers need mrta-drake installed). A run writes its files (timeline, events,
``summary.json``) to ``OUT/runs/<run_id>/``; a run whose ``summary.json`` exists, and does
not say it was interrupted, is not run again, its row is rebuilt from the file, so a sweep
stopped half way, or one given more grid values, resumes. Run names come from the grid
values only: after changing ``fixed`` or the base scenario, use a new ``OUT``. The results
table, one row per run, goes to ``OUT/results.csv`` (and ``OUT/results.parquet`` when
pyarrow is installed): the run's grid values, ``status`` (ok or error), the summary's task
figures (``tasks_*``), smallest clearances (``min_*``, m) and contact counts, the deadlock
count, planner and controller failures, real-time factor, wall time (s) and the error
message.
"""

import csv
import dataclasses
import importlib
import importlib.util
import itertools
import json
import os
import re
import sys
import traceback
import typing
import warnings
from dataclasses import dataclass, field

from mrta_drake.errors import InputError
from mrta_drake.scenario.schema import Scenario
from mrta_drake.scenario.typed_yaml import load_typed, read_yaml

ROBOTS = "robots"  # grid key: the number of robots, the scenario's first ones
HUMANS = "humans"  # grid key: true keeps the scenario's people, false drops them


@dataclass(frozen=True)
class SweepSpec:
    """A sweep spec (see the module docstring). ``grid`` maps a field to its list of values;
    ``fixed`` a field to its value; ``plugins`` are files (absolute once loaded) or module
    names to import first; ``source`` is the spec file."""

    scenario: str = ""
    grid: dict = field(default_factory=dict)
    fixed: dict = field(default_factory=dict)
    plugins: list[str] = field(default_factory=list)
    source: str = ""

    def runs(self) -> list["SweepRun"]:
        """Every combination of the grid's values, the first key varying slowest."""
        keys = list(self.grid)
        runs = []
        for combination in itertools.product(*(self.grid[key] for key in keys)):
            values = dict(zip(keys, combination, strict=True))
            runs.append(SweepRun(_run_id(values), values, dict(self.fixed) | values))
        return runs


@dataclass(frozen=True)
class SweepRun:
    """One run: ``run_id`` names it (and its folder), ``values`` are its grid values and
    ``settings`` everything set in its scenario (fixed fields and grid values)."""

    run_id: str
    values: dict
    settings: dict


@dataclass(frozen=True)
class SweepResult:
    """What ``run_sweep`` did: ``rows`` of the results table in grid order, how many runs
    it ``ran`` and how many it ``reused`` from an earlier sweep, and the ``table`` files."""

    rows: list[dict]
    ran: int
    reused: int
    table: list[str]


def load_sweep(path: str) -> SweepSpec:
    """Read and check the sweep spec at ``path``; errors name the spec file and field."""
    path = os.fspath(path)
    raw = read_yaml(path, "sweep spec")
    if not isinstance(raw, dict):
        raise InputError(path, None, "expected a mapping with `scenario:` and `grid:`")
    raw = {key: value for key, value in raw.items() if key != "source"}
    spec = load_typed(raw, SweepSpec, path)
    if not spec.scenario:
        raise InputError(path, "scenario", "is required (the base scenario file)")
    scenario = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)),
                                             spec.scenario))
    if not os.path.isfile(scenario):
        raise InputError(path, "scenario", f"file not found: {spec.scenario!r}")
    if not spec.grid:
        raise InputError(path, "grid", "give at least one field with a list of values")
    plugins = [_plugin_path(plugin, path, f"plugins[{k}]")
               for k, plugin in enumerate(spec.plugins)]
    for k, plugin in enumerate(plugins):
        try:
            import_plugin(plugin)
        except Exception as error:  # the user's code: whatever it raises is a spec error
            raise InputError(path, f"plugins[{k}]", f"{spec.plugins[k]!r} failed to import: "
                             f"{type(error).__name__}: {error}") from None
    from mrta_drake.scenario.loading import load_scenario

    robot_count = len(load_scenario(scenario, check_world=False).robots)
    for section, entries in (("grid", spec.grid), ("fixed", spec.fixed)):
        for key, value in entries.items():
            where = f"{section}.{key}"
            _check_key(key, path, where)
            if section == "grid" and (not isinstance(value, list) or not value):
                raise InputError(path, where, f"expected a non-empty list of values, got "
                                 f"{value!r}")
            values = value if section == "grid" else [value]
            for k, item in enumerate(values):
                here = f"{where}[{k}]" if section == "grid" else where
                if key == ROBOTS:
                    if isinstance(item, bool) or not isinstance(item, int) or not (
                            1 <= item <= robot_count):
                        raise InputError(path, here, f"expected a robot count from 1 to the "
                                         f"scenario's {robot_count}, got {item!r}")
                elif key == HUMANS:
                    if not isinstance(item, bool):
                        raise InputError(path, here, f"expected true or false, got {item!r}")
                else:
                    overrides = _plain(spec.fixed) | {key: item}
                    try:
                        load_scenario(scenario, check_world=False, overrides=overrides)
                    except InputError as error:
                        raise InputError(path, here, f"{item!r} does not load: {error}"
                                         ) from None
    spec = dataclasses.replace(spec, scenario=scenario, plugins=plugins,
                               source=os.path.abspath(path))
    ids = [run.run_id for run in spec.runs()]
    if len(set(ids)) != len(ids):
        duplicate = next(i for i in ids if ids.count(i) > 1)
        raise InputError(path, "grid", f"two runs would be named {duplicate!r}; are values "
                         "repeated?")
    return spec


def run_sweep(spec: SweepSpec, out_dir: str, *, workers: int | None = None,
              ray_address: str | None = None, plots: bool = False,
              progress: bool = False) -> SweepResult:
    """Run every run of ``spec`` not already done in ``out_dir`` (``workers`` local
    processes, default one per CPU; or on the Ray cluster at ``ray_address``), then write
    the results table. Failed runs become error rows. ``plots``: each run also writes its
    PNG plots; ``progress``: show a progress bar."""
    runs = spec.runs()
    rows: dict[str, dict] = {}
    todo = []
    for run in runs:
        summary_file = os.path.join(out_dir, "runs", run.run_id, "summary.json")
        summary = None
        if os.path.isfile(summary_file):
            with open(summary_file, encoding="utf-8") as f:
                summary = json.load(f)
        if summary is not None and not summary.get("interrupted"):
            rows[run.run_id] = _row(run, summary, None)
        else:  # not run yet, or stopped part way (Ctrl-C): run again
            todo.append(run)
    reused = len(rows)
    if ray_address:
        outcomes = _on_ray(spec.scenario, todo, out_dir, plots, spec.plugins, ray_address)
    else:
        outcomes = _on_processes(spec.scenario, todo, out_dir, plots, spec.plugins, workers)
    bar = _progress_bar(len(runs), reused, progress)
    try:
        for run, (summary, error) in outcomes:
            if summary is not None:
                _write_summary(out_dir, run, summary)
            rows[run.run_id] = _row(run, summary, error)
            bar.update(1)
    finally:
        bar.close()
    ordered = [rows[run.run_id] for run in runs if run.run_id in rows]
    return SweepResult(ordered, len(todo), reused, write_table(ordered, out_dir))


def run_one(scenario_path: str, run: SweepRun, run_dir: str, plots: bool = False,
            plugins: tuple[str, ...] = ()) -> tuple[dict | None, str | None]:
    """Run ``run`` of the base scenario, writing its files (with ``plots``, its PNG plots
    too) to ``run_dir``: (summary, None), or (None, the error in one line) when it fails,
    the traceback going to ``error.txt``. ``plugins`` are imported first."""
    from mrta_drake.stack.simulate import simulate

    os.makedirs(run_dir, exist_ok=True)
    with open(os.path.join(run_dir, "run.json"), "w", encoding="utf-8") as f:
        json.dump({"run_id": run.run_id, "scenario": scenario_path,
                   "settings": run.settings, "plugins": list(plugins)}, f, indent=2)
    try:
        for plugin in plugins:
            import_plugin(plugin)
        result = simulate(sweep_scenario(scenario_path, run.settings), out_dir=run_dir,
                          plots=plots)
    except Exception as error:  # a failed run is a row of the table, not the sweep's end
        with open(os.path.join(run_dir, "error.txt"), "w", encoding="utf-8") as f:
            f.write(traceback.format_exc())
        lines = str(error).strip().splitlines()
        return None, f"{type(error).__name__}: {lines[0] if lines else ''}"
    if result.summary["interrupted"]:  # Ctrl-C stopped it part way: so ends the sweep
        raise KeyboardInterrupt
    return result.summary, None


def sweep_scenario(scenario_path: str, settings: dict) -> Scenario:
    """The base scenario with a run's ``settings``: dotted fields set before loading, then
    only the first ``robots`` robots and, with ``humans`` false, no people."""
    from mrta_drake.scenario.loading import load_scenario

    scenario = load_scenario(scenario_path, overrides=_plain(settings))
    if ROBOTS in settings:
        scenario = dataclasses.replace(scenario, robots=scenario.robots[:settings[ROBOTS]])
    if settings.get(HUMANS) is False:
        scenario = dataclasses.replace(
            scenario, humans=dataclasses.replace(scenario.humans, walkers=[], groups=[]))
    return scenario


def import_plugin(plugin: str) -> None:
    """Import ``plugin``, a ``.py`` file (its folder goes on ``sys.path`` for its own
    imports) or a module name, once per process."""
    if not plugin.endswith(".py"):
        importlib.import_module(plugin)
        return
    name = "mrta_sweep_plugin_" + re.sub(r"\W", "_", os.path.splitext(plugin)[0])
    if name in sys.modules:
        return
    folder = os.path.dirname(plugin)
    if folder not in sys.path:
        sys.path.insert(0, folder)
    module_spec = importlib.util.spec_from_file_location(name, plugin)
    module = importlib.util.module_from_spec(module_spec)
    sys.modules[name] = module
    try:
        module_spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise


def _plugin_path(plugin: str, spec_file: str, where: str) -> str:
    """A plugin file made absolute (relative to the spec), or a module name as it is."""
    if not plugin.endswith(".py"):
        return plugin
    found = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(spec_file)), plugin))
    if not os.path.isfile(found):
        raise InputError(spec_file, where, f"file not found: {plugin!r}")
    return found


def _plain(settings: dict) -> dict:
    """The settings that are scenario fields (not ``robots`` or ``humans``)."""
    return {key: value for key, value in settings.items() if key not in (ROBOTS, HUMANS)}


def write_table(rows: list[dict], out_dir: str) -> list[str]:
    """Write ``rows`` to ``out_dir``/results.csv, and results.parquet when pyarrow is
    installed; returns the files written."""
    os.makedirs(out_dir, exist_ok=True)
    columns = table_columns(rows)
    written = [os.path.join(out_dir, "results.csv")]
    with open(written[0], "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, columns)
        writer.writeheader()
        writer.writerows(rows)
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        return written
    try:
        table = pyarrow.Table.from_pylist([{c: row.get(c) for c in columns} for row in rows])
    except (pyarrow.ArrowInvalid, pyarrow.ArrowTypeError) as error:  # e.g. mixed-type values
        warnings.warn(f"results.parquet not written: {error}", stacklevel=2)
        return written
    written.append(os.path.join(out_dir, "results.parquet"))
    pyarrow.parquet.write_table(table, written[1])
    return written


def table_columns(rows: list[dict]) -> list[str]:
    """Every column of ``rows`` in first-seen order, ``error`` last."""
    columns = list(dict.fromkeys(key for row in rows for key in row if key != "error"))
    return columns + ["error"]


def format_table(rows: list[dict]) -> str:
    """The main columns of ``rows`` as plain text, one line per run."""
    wanted = ["run_id", "status", "tasks_completed", "tasks_on_time", "min_robot_robot",
              "robot_robot_contacts", "robot_wall_contacts", "deadlocks", "real_time_factor",
              "error"]
    columns = [c for c in wanted if any(row.get(c) is not None for row in rows)]
    cells = [[_cell(row.get(c)) for c in columns] for row in rows]
    widths = [max([len(c)] + [len(line[k]) for line in cells]) for k, c in enumerate(columns)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(columns, widths, strict=True))]
    lines += ["  ".join(v.ljust(w) for v, w in zip(line, widths, strict=True)).rstrip()
              for line in cells]
    return "\n".join(lines)


def _cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.3g}" if abs(value) < 1000 else f"{value:.0f}"
    text = str(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _row(run: SweepRun, summary: dict | None, error: str | None) -> dict:
    """A table row: the run, its grid values and the key figures of its summary."""
    row = {"run_id": run.run_id} | run.values | {"status": "ok" if summary else "error"}
    if summary:
        for key, value in (summary.get("tasks") or {}).items():
            if _is_number(value):
                row[f"tasks_{key}"] = value
        for key, value in (summary.get("safety") or {}).items():
            clearance = key.startswith("min_") and not key.endswith(("_time", "_between"))
            if clearance or key.endswith("_contacts"):
                row[key] = value
        deadlocks = summary.get("deadlocks")
        if isinstance(deadlocks, dict):
            deadlocks = deadlocks.get("count")
        if _is_number(deadlocks):
            row["deadlocks"] = deadlocks
        for key in ("planner_failures", "controller_failures", "real_time_factor",
                    "wall_time"):
            row[key] = summary.get(key)
    row["error"] = error
    return row


def _is_number(value) -> bool:
    return isinstance(value, int | float)


def _write_summary(out_dir: str, run: SweepRun, summary: dict) -> None:
    """Keep the run's summary.json next to the table (a Ray worker may have written it on
    another machine)."""
    path = os.path.join(out_dir, "runs", run.run_id, "summary.json")
    if not os.path.isfile(path):
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w", encoding="utf-8") as f:
            json.dump(summary, f, indent=2)


def _on_processes(scenario_path: str, runs: list[SweepRun], out_dir: str, plots: bool,
                  plugins: list[str], workers: int | None):
    """Yield (run, outcome) as runs finish, each run in a fresh spawned process."""
    if not runs:
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    workers = min(workers or os.cpu_count() or 1, len(runs))
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                             max_tasks_per_child=1) as pool:
        futures = {pool.submit(run_one, scenario_path, run, _run_dir(out_dir, run), plots,
                               tuple(plugins)): run for run in runs}
        for future in as_completed(futures):
            try:
                outcome = future.result()
            except Exception as error:  # the worker process died (e.g. a crash in C++)
                outcome = (None, f"{type(error).__name__}: worker process failed: {error}")
            yield futures[future], outcome


def _on_ray(scenario_path: str, runs: list[SweepRun], out_dir: str, plots: bool,
            plugins: list[str], address: str):
    """Yield (run, outcome) as runs finish on the Ray cluster at ``address``."""
    try:
        import ray
    except ImportError:
        raise InputError(None, "--ray", "needs Ray: pip install 'mrta-drake[distributed]'"
                         ) from None
    if not runs:
        return
    ray.init(address=address, ignore_reinit_error=True, log_to_driver=False)
    remote = ray.remote(num_cpus=1)(run_one)
    pending = {remote.remote(scenario_path, run, _run_dir(out_dir, run), plots,
                             tuple(plugins)): run for run in runs}
    while pending:
        (done,), _ = ray.wait(list(pending), num_returns=1)
        run = pending.pop(done)
        try:
            outcome = ray.get(done)
        except Exception as error:  # the task or its worker died
            outcome = (None, f"{type(error).__name__}: {str(error).splitlines()[0]}")
        yield run, outcome


def _run_dir(out_dir: str, run: SweepRun) -> str:
    return os.path.abspath(os.path.join(out_dir, "runs", run.run_id))


def _progress_bar(total: int, done: int, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, initial=done, unit="run", disable=not enabled)


def _run_id(values: dict) -> str:
    """A folder name for a run from its grid values, e.g. ``seed=0__robots=2``."""
    parts = []
    for key, value in values.items():
        text = json.dumps(value) if isinstance(value, bool | None) else str(value)
        parts.append(f"{key}={text}")
    return re.sub(r"[^A-Za-z0-9._=+-]", "_", "__".join(parts))


def _check_key(key, file: str, where: str) -> None:
    """A grid or fixed key must be ``robots``, ``humans`` or a scenario field's dotted name
    (through dataclass fields; anything below a free-form ``params``-like mapping)."""
    if not isinstance(key, str) or not key:
        raise InputError(file, where, f"expected a field name, got {key!r}")
    if key in (ROBOTS, HUMANS):
        return
    schema = Scenario
    names = key.split(".")
    for depth, name in enumerate(names):
        inner = _optional_inner(schema)
        schema = inner if inner is not None else schema
        if schema is dict or typing.get_origin(schema) is dict:
            return
        if not dataclasses.is_dataclass(schema):
            raise InputError(file, where, f"cannot set a field inside "
                             f"{'.'.join(names[:depth])}: it is not a mapping")
        hints = typing.get_type_hints(schema)
        known = [f.name for f in dataclasses.fields(schema) if f.name != "source"]
        if name not in known:
            raise InputError(file, where, f"unknown field {name!r} (known: "
                             f"{', '.join(known)})")
        schema = hints[name]


def _optional_inner(schema):
    args = typing.get_args(schema)
    if len(args) == 2 and type(None) in args:
        return next(a for a in args if a is not type(None))
    return None
