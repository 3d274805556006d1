"""Whether numba's on-disk cache already holds the stack's compiled kernels, and compiling them
in two processes at once when it does not.

The first run after installing (or with an empty ``NUMBA_CACHE_DIR``, or after a kernel's source
changed) compiles the kernels, which takes tens of seconds once; later runs load them from the
cache in well under a second. The entry kernels of the quickstart's stack (those Python calls;
they compile the helpers they call), their argument types, the CPU s each took to compile and
the compiled functions each calls (directly or not) are listed in ``kernel_signatures.json``,
in the order the quickstart first calls them, with the CPU s each compiled function took
itself (``functions``: what compiling it alone, its callees already compiled, costs),
written by ``python -m mrta_drake.stack.kernel_cache record`` (run it again when a kernel's
argument types change: ``tests/stack/test_kernel_cache.py`` says when).

``cold_kernel_seconds`` reads the cache index of each entry kernel (one small file read each,
nothing compiled) and estimates how long compiling the missing ones will take, so that the
CLI can say so before the run starts. ``Compilation`` forks a second process
that compiles part of the missing kernels (``split``) into the shared cache while this one
loads the scenario and builds the diagram (compiling what that calls) and then compiles the
rest of its part (``compile_kernels``); the run then loads everything from the cache. Numba
writes each cache entry whole, and a function compiled twice (one of numba's own both parts
call) is the same machine code, so nothing depends on which process compiled what.
"""

import dataclasses
import gc
import importlib
import itertools
import json
import os
import pathlib
import pickle
import signal
import sys

MANIFEST = pathlib.Path(__file__).with_name("kernel_signatures.json")
QUICKSTART = ("scenarios/hospital_6_robots.yaml", "--duration", "60")
# CPU s the second process spends besides compiling its kernels (forked with numba and the
# kernels' modules imported: copying pages it writes, compiling numba's own helpers again):
# its CPU time less its kernels' (the manifest's) in the quickstart, on the benchmark host
# (docs/benchmarks.md, "The first run"; both constants measured at the manifest's load).
CHILD_START_S = 1.0
# CPU s this process spends, once the second has started, on work other than compiling before
# the run (loading the scenario, building the diagram): its CPU time from starting the second
# process to the end of ``Compilation.finish`` less its kernels', measured alike.
PARENT_AHEAD_S = 1.8


@dataclasses.dataclass(frozen=True)
class EntryKernel:
    """An entry kernel: ``module``'s ``njit(cache=True)`` function ``name``, the argument
    types it is called with (numba's spelling of each signature), the CPU s compiling it
    (with every helper it compiled first) took on the benchmark host, the compiled
    functions (``module.name``) it calls, directly or through others, and whether loading
    the scenario or building the diagram calls it (``building``: before the run)."""

    module: str
    name: str
    cpu_s: float
    signatures: tuple[str, ...]
    helpers: tuple[str, ...] = ()
    building: bool = False

    @property
    def functions(self) -> frozenset[str]:
        """The compiled functions compiling this kernel compiles: its own and its helpers."""
        return frozenset((f"{self.module}.{self.name}", *self.helpers))

    @property
    def dispatcher(self):
        return getattr(importlib.import_module(self.module), self.name)


def _read_manifest(path: pathlib.Path) -> tuple[tuple[EntryKernel, ...], dict[str, float]]:
    manifest = json.loads(path.read_text(encoding="utf-8"))
    return tuple(EntryKernel(k["module"], k["name"], k["cpu_s"], tuple(k["signatures"]),
                             tuple(k["helpers"]), k["building"])
                 for k in manifest["kernels"]), manifest["functions"]


ENTRY_KERNELS, FUNCTION_CPU_S = _read_manifest(MANIFEST)


def is_cached(dispatcher) -> bool:
    """Whether numba's cache holds a compiled version of ``dispatcher`` (an ``njit(cache=True)``
    function) for its current source and numba version. Reads numba's cache index through its
    internal ``_cache`` attribute; a numba without it counts as cached (nothing announced)."""
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if cache_file is None:
        return True
    try:
        return bool(cache_file._load_index())
    except (OSError, EOFError, ValueError, pickle.UnpicklingError):  # numba then recompiles
        return False


def missing_kernels() -> tuple[EntryKernel, ...]:
    """The entry kernels the cache lacks, in the manifest's order."""
    return tuple(k for k in ENTRY_KERNELS if not is_cached(k.dispatcher))


def cost(kernels) -> float:
    """CPU s compiling ``kernels`` in one process takes: every compiled function they call
    (``EntryKernel.functions``) once, at its ``FUNCTION_CPU_S``."""
    return sum(FUNCTION_CPU_S.get(f, 0.0) for f in frozenset().union(*(
        k.functions for k in kernels)))


def added_seconds(here, there) -> float:
    """Estimated wall s compiling the kernels ``here`` in this process and ``there`` in a
    second one adds to the run: the ``cost`` of this process's part, or of the second's
    with its start-up (``CHILD_START_S``) less this process's other work meanwhile
    (``PARENT_AHEAD_S``) when that ends later (0.0 for none)."""
    return max(cost(here), cost(there) + CHILD_START_S - PARENT_AHEAD_S if there else 0.0)


def parts(kernels: tuple[EntryKernel, ...]) -> tuple[tuple[EntryKernel, ...],
                                                     tuple[EntryKernel, ...]]:
    """``kernels`` as compiled here and in a second process: ``split`` on 2 cores or more,
    else all here."""
    return split(kernels) if processes() > 1 else (kernels, ())


def split(kernels: tuple[EntryKernel, ...]) -> tuple[tuple[EntryKernel, ...],
                                                     tuple[EntryKernel, ...]]:
    """``kernels`` in two parts that finish soonest: the one compiled here and the one for a
    second process. The first kernel and those loading the scenario or building the diagram
    call stay here (this process calls them before the second could have compiled them);
    of every way to place the others (the manifest lists a dozen kernels: a few thousand
    ways at most), the first whose later part finishes soonest (``added_seconds``), this
    process starting ``PARENT_AHEAD_S`` behind with its other work, the second
    ``CHILD_START_S`` behind with its start-up. Each part costs ``cost``: a helper both
    parts call is compiled in both, which the split weighs against the balance (kernels
    that share only a cheap helper may go apart; before, any shared helper kept them
    together)."""
    pinned = [k for i, k in enumerate(kernels) if i == 0 or k.building]
    free = [k for k in kernels if k not in pinned]
    best = None
    for places in itertools.product((0, 1), repeat=len(free)):
        there = [k for k, place in zip(free, places, strict=True) if place]
        here = pinned + [k for k, place in zip(free, places, strict=True) if not place]
        added = added_seconds(here, there)
        if best is None or added < best[0]:
            best = (added, here, there)
    order = {kernel: i for i, kernel in enumerate(kernels)}
    here, there = (tuple(sorted(h, key=order.__getitem__)) for h in best[1:])
    return here, there


def processes() -> int:
    """How many processes compile at once: 2 when this process may use 2 cores or more and
    can fork (``_fork_compiling``)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return 2 if (cores or 1) >= 2 and hasattr(os, "fork") else 1


def cold_kernel_seconds() -> float:
    """Estimated wall s of compiling the entry kernels missing from the cache (0.0 when the
    cache is warm): see ``Compilation.seconds``."""
    return Compilation.estimate(missing_kernels())


def signature_types(signature: str) -> tuple:
    """The numba argument types spelled ``signature`` (``str`` of a numba signature)."""
    from numba.core import types

    return eval(signature, {**vars(types), "bool": types.boolean})  # our own manifest's spelling


def compile_kernels(kernels) -> None:
    """Compiles (or loads from the cache) every signature of ``kernels`` not compiled yet (a
    kernel given its signatures in its decorator compiled them as its module was imported)."""
    for kernel in kernels:
        dispatcher = kernel.dispatcher
        for signature in map(signature_types, kernel.signatures):
            if signature not in dispatcher.signatures:
                dispatcher.compile(signature)


def _fork_compiling(kernels: tuple[EntryKernel, ...]) -> int:
    """Forks a child process that compiles ``kernels`` into the shared cache (its output
    discarded, the collector off: it compiles and exits, ``os._exit``, without the parent's
    clean-up) and returns its process id. Forked, it starts with this process's imports
    (numba, the kernels' modules) done: the second process's start-up is a fork's."""
    child = os.fork()
    if child == 0:
        code = 1
        try:
            devnull = os.open(os.devnull, os.O_RDWR)
            for stream in (0, 1, 2):
                os.dup2(devnull, stream)
            gc.disable()
            compile_kernels(kernels)
            code = 0
        finally:
            os._exit(code)  # never back into the parent's code, whatever happened
    return child


class Compilation:
    """Compiling ``kernels`` (entry kernels missing from the cache) before a run: on 2 cores
    or more, the later half (``split``) starts at once in a child process, compiling into the
    shared cache (its output discarded: a kernel it fails to compile is compiled by the run,
    as without it); ``finish`` compiles the earlier half here and waits for the child."""

    def __init__(self, kernels: tuple[EntryKernel, ...]):
        self._here, there = parts(kernels)
        self.seconds = added_seconds(self._here, there)
        self._child = _fork_compiling(there) if there else None

    @staticmethod
    def estimate(kernels: tuple[EntryKernel, ...]) -> float:
        """Estimated wall s compiling ``kernels`` adds to the run (``added_seconds`` of
        their ``parts``)."""
        return added_seconds(*parts(kernels))

    def finish(self) -> None:
        """Compiles this process's half and waits for the child's."""
        compile_kernels(self._here)
        if self._child is not None:
            os.waitpid(self._child, 0)
            self._child = None

    def cancel(self) -> None:
        """Stops the child, unless ``finish`` waited for it (the run will not happen)."""
        if self._child is not None:
            os.kill(self._child, signal.SIGKILL)
            os.waitpid(self._child, 0)


def _record(out: pathlib.Path) -> None:
    """Runs the quickstart's simulation here (one process) with numba's cache in an empty
    folder and writes the entry kernels it compiled (in order, with their signatures, compile
    CPU s, the compiled functions each calls and whether it was called before the run) to
    ``out``."""
    import tempfile
    import time

    with tempfile.TemporaryDirectory() as cache:
        os.environ["NUMBA_CACHE_DIR"] = cache
        from numba.core import event

        from mrta_drake.scenario.loading import load_scenario
        from mrta_drake.stack.simulate import simulate

        entries, open_, compiled, begun, building = {}, [], set(), set(), set()
        own = {}  # "module.name": CPU s of compiling the function less the ours it compiled

        class Listener(event.Listener):
            def on_start(self, ev):
                if not open_:  # an entry kernel (numba compiles one function at a time)
                    function = ev.data["dispatcher"].py_func
                    begun.add((function.__module__, function.__name__))
                open_.append([time.process_time(), 0.0])

            def on_end(self, ev):
                start, inner = open_.pop()
                seconds = time.process_time() - start
                function = ev.data["dispatcher"].py_func
                if function.__module__.startswith("mrta_drake."):  # numba's own: its caller's
                    compiled.add(ev.data["dispatcher"])
                    key = f"{function.__module__}.{function.__name__}"
                    own[key] = own.get(key, 0.0) + seconds - inner
                    if open_:
                        open_[-1][1] += seconds
                    else:
                        key = (function.__module__, function.__name__)
                        entries[key] = entries.get(key, 0.0) + seconds

        event.register("numba:compile", Listener())
        scenario = pathlib.Path(__file__).resolve().parents[2] / QUICKSTART[0]
        simulate(load_scenario(str(scenario)), duration=float(QUICKSTART[2]), plots=False,
                 before_run=lambda: building.update(begun))
    names = {id(result.library): f"{d.py_func.__module__}.{d.py_func.__name__}"
             for d in compiled for result in d.overloads.values()}
    kernels = []
    for (module, name), seconds in entries.items():
        dispatcher = getattr(importlib.import_module(module), name)
        libraries = [result.library for result in dispatcher.overloads.values()]
        helpers, seen = set(), set()
        while libraries:  # every library linked into the kernel's, directly or not
            library = libraries.pop()
            if id(library) not in seen:
                seen.add(id(library))
                helpers.add(names.get(id(library)))
                libraries.extend(library._linking_libraries)  # numba's, as ``_cache`` above
        helpers -= {None, f"{module}.{name}"}
        kernels.append({"module": module, "name": name, "cpu_s": round(seconds, 2),
                        "signatures": [str(s) for s in dispatcher.signatures],
                        "helpers": sorted(helpers), "building": (module, name) in building})
    out.write_text(json.dumps({"command": "python -m mrta_drake.stack.kernel_cache record",
                               "run": "mrta-sim run " + " ".join(QUICKSTART),
                               "kernels": kernels,
                               "functions": {name: round(seconds, 3)
                                             for name, seconds in sorted(own.items())}},
                              indent=1) + "\n", encoding="utf-8")


def main(argv=None) -> int:
    """``record``: rewrite the manifest (see the module docstring)."""
    argv = sys.argv[1:] if argv is None else argv
    # ``record`` measures the kernels as the CLI compiles them: without collecting garbage
    # (numba's compiler makes cycles by the million; collecting them only costs time).
    gc.disable()
    if argv == ["record"]:
        _record(MANIFEST)
        return 0
    print("usage: python -m mrta_drake.stack.kernel_cache record", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
