"""kernel_cache: a kernel counts as cached only once numba has compiled and saved it, the CLI
announces compiling only then, a second process compiles its half into the shared cache, and
the manifest lists the argument types the quickstart's stack calls its kernels with."""

import importlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

from mrta_drake.stack import kernel_cache
from mrta_drake.stack.kernel_cache import EntryKernel
from mrta_drake.tools import cli

KERNEL = "import numba\n\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n"


@pytest.fixture
def fresh_kernels(tmp_path, monkeypatch):
    """Two packages, ``fresh_a_*`` and ``fresh_b_*``, each with a module ``kernels`` holding
    one never compiled ``njit(cache=True)`` kernel, ``twice``, registered as the entry
    kernels (5 s and 4 s to compile), importable here and in a child process."""
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    modules, entries = [], []
    for package, seconds in ((f"fresh_a_{tmp_path.name}", 5.0),
                             (f"fresh_b_{tmp_path.name}", 4.0)):
        (tmp_path / package).mkdir()
        (tmp_path / package / "__init__.py").write_text("")
        (tmp_path / package / "kernels.py").write_text(KERNEL)
        modules.append(importlib.import_module(f"{package}.kernels"))
        entries.append(EntryKernel(f"{package}.kernels", "twice", seconds, ("(int64,)",)))
    monkeypatch.setattr(kernel_cache, "ENTRY_KERNELS", tuple(entries))
    yield modules
    for module in modules:
        sys.modules.pop(module.__name__, None)


def test_a_kernel_is_cached_once_compiled(fresh_kernels):
    first, second = fresh_kernels
    assert not kernel_cache.is_cached(first.twice)
    assert kernel_cache.cold_kernel_seconds() == (_two_processes(5.0, 4.0)
                                                  if kernel_cache.processes() == 2 else 9.0)
    assert first.twice(2) == 4
    assert kernel_cache.is_cached(first.twice)
    assert kernel_cache.missing_kernels() == kernel_cache.ENTRY_KERNELS[1:]
    assert kernel_cache.cold_kernel_seconds() == 4.0
    assert second.twice(2) == 4
    assert kernel_cache.cold_kernel_seconds() == 0.0


def _two_processes(here: float, there: float) -> float:
    """The estimate for kernels of ``here`` and ``there`` CPU s compiled in two processes."""
    return max(here, there + kernel_cache.CHILD_START_S - kernel_cache.PARENT_AHEAD_S)


def test_the_halves_share_no_compiled_function_and_keep_the_first_kernel_here():
    here, there = kernel_cache.split(kernel_cache.ENTRY_KERNELS)
    assert here[0] == kernel_cache.ENTRY_KERNELS[0]
    assert sorted(here + there, key=kernel_cache.ENTRY_KERNELS.index) == list(
        kernel_cache.ENTRY_KERNELS)
    functions = [frozenset().union(*(k.functions for k in half)) for half in (here, there)]
    assert not functions[0] & functions[1]
    assert there  # the quickstart's kernels do not all share one helper


def test_kernels_sharing_a_helper_stay_together():
    first, shares, alone = (EntryKernel("m", name, seconds, (), helpers) for name, seconds,
                            helpers in (("a", 1.0, ("m.h",)), ("b", 9.0, ("m.h",)),
                                        ("c", 5.0, ())))
    assert kernel_cache.groups((first, alone, shares)) == [[first, shares], [alone]]
    assert kernel_cache.split((first, alone, shares)) == ((first, shares), (alone,))
    builds = EntryKernel("m", "d", 20.0, (), (), building=True)  # called before the run
    assert kernel_cache.split((first, alone, builds)) == ((first, builds), (alone,))


def test_the_cli_announces_a_cold_cache_and_compiles_in_two_processes(fresh_kernels, capsys):
    first, second = fresh_kernels
    compilation = cli._start_compiling()
    assert capsys.readouterr().err == ""  # said only once the input is found good
    cli._announce(compilation)
    seconds = round(_two_processes(5.0, 4.0)) if kernel_cache.processes() == 2 else 9
    assert capsys.readouterr().err == f"compiling kernels, once, ~{seconds} s\n"
    compilation.finish()
    assert kernel_cache.is_cached(first.twice) and kernel_cache.is_cached(second.twice)
    if kernel_cache.processes() == 2:  # the child compiled it: not compiled in this process
        assert second.twice.signatures == []
    warm = cli._start_compiling()
    cli._announce(warm)
    warm.finish()
    assert capsys.readouterr().err == ""


def test_every_signature_of_the_manifest_reads_back():
    for kernel in kernel_cache.ENTRY_KERNELS:
        for signature in kernel.signatures:
            assert str(kernel_cache.signature_types(signature)) == signature


QUICKSTART_SIGNATURES = """
import json
from mrta_drake.scenario.loading import load_scenario
from mrta_drake.stack import kernel_cache
from mrta_drake.stack.simulate import simulate
simulate(load_scenario(kernel_cache.QUICKSTART[0]), duration=10.0, plots=False)
print(json.dumps({f"{k.module}.{k.name}": [str(s) for s in k.dispatcher.signatures]
                  for k in kernel_cache.ENTRY_KERNELS}))
"""


def test_the_manifest_lists_what_the_quickstart_calls():
    """If this fails, a kernel's argument types changed: run ``python -m
    mrta_drake.stack.kernel_cache record`` (it rewrites ``kernel_signatures.json``). The
    quickstart runs in a process of its own: other tests call the kernels with other types."""
    result = subprocess.run([sys.executable, "-c", QUICKSTART_SIGNATURES], capture_output=True,
                            text=True, check=True, cwd=Path(kernel_cache.__file__).parents[2])
    called = json.loads(result.stdout.strip().splitlines()[-1])
    for kernel in kernel_cache.ENTRY_KERNELS:
        assert set(called[f"{kernel.module}.{kernel.name}"]) <= set(kernel.signatures), (
            kernel.module, kernel.name)
