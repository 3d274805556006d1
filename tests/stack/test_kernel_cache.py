"""kernel_cache: a kernel counts as cached only once numba has compiled and saved it, the CLI
announces compiling only then, a second process compiles its half into the shared cache, and
the manifest lists the argument types the quickstart's stack calls its kernels with."""

import importlib
import json
import os
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
    monkeypatch.setattr(kernel_cache, "FUNCTION_CPU_S",
                        {f"{k.module}.{k.name}": k.cpu_s for k in entries})
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


def test_the_halves_keep_the_first_kernel_and_the_building_ones_here():
    kernels = kernel_cache.ENTRY_KERNELS
    here, there = kernel_cache.split(kernels)
    assert here[0] == kernels[0] and all(k in here for k in kernels if k.building)
    assert sorted(here + there, key=kernels.index) == list(kernels)
    assert there and kernel_cache.cost(here) < kernel_cache.cost(kernels)


def test_the_split_weighs_a_helper_both_parts_would_compile_against_the_balance(monkeypatch):
    first, b, d = (EntryKernel("m", name, 0.0, (), helpers) for name, helpers in (
        ("a", ()), ("b", ("m.h",)), ("d", ("m.h",))))
    monkeypatch.setattr(kernel_cache, "CHILD_START_S", 0.0)
    monkeypatch.setattr(kernel_cache, "PARENT_AHEAD_S", 0.0)
    monkeypatch.setattr(kernel_cache, "FUNCTION_CPU_S", {"m.a": 8.0, "m.b": 4.0, "m.d": 4.0,
                                                         "m.h": 3.0})
    assert kernel_cache.cost((b, d)) == 11.0  # m.h once
    assert kernel_cache.split((first, b, d)) == ((first,), (b, d))  # 11 s, not 15 s apart
    monkeypatch.setitem(kernel_cache.FUNCTION_CPU_S, "m.a", 1.0)
    assert kernel_cache.split((first, b, d)) == ((first, b), (d,))  # 8 s, not 11 s together
    builds = EntryKernel("m", "e", 0.0, (), (), building=True)  # called before the run
    monkeypatch.setitem(kernel_cache.FUNCTION_CPU_S, "m.e", 20.0)
    assert kernel_cache.split((first, b, builds)) == ((first, builds), (b,))


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


def test_numba_imported_after_the_package_formats_its_messages_without_highlighting():
    """Highlighting re-initialises colorama for each of the thousands of messages numba
    formats (and drops) while typing a kernel: the package turns it off."""
    said = subprocess.run([sys.executable, "-c", "import mrta_drake, numba.core.errors as e; "
                           "print(type(e.termcolor()).__name__)"], capture_output=True,
                          text=True, check=True,
                          env={k: v for k, v in os.environ.items()
                               if k != "NUMBA_DISABLE_ERROR_MESSAGE_HIGHLIGHTING"})
    assert said.stdout.strip() == "NOPColorScheme"
