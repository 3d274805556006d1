"""kernel_cache: a kernel counts as cached only once numba has compiled and saved it, and the
CLI announces compiling only then."""

import importlib.util
import sys

import pytest

from mrta_drake.stack import kernel_cache
from mrta_drake.tools import cli

KERNEL = "import numba\n\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n"


@pytest.fixture
def fresh_kernel(tmp_path, monkeypatch):
    """A module with one never compiled ``njit(cache=True)`` kernel, ``twice``, registered
    as the only entry kernel (5 s to compile)."""
    name = f"fresh_kernel_{tmp_path.name}"
    path = tmp_path / f"{name}.py"
    path.write_text(KERNEL)
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, name, module)
    spec.loader.exec_module(module)
    monkeypatch.setattr(kernel_cache, "ENTRY_KERNELS", {(name, "twice"): 5.0})
    return module


def test_a_kernel_is_cached_once_compiled(fresh_kernel):
    assert not kernel_cache.is_cached(fresh_kernel.twice)
    assert kernel_cache.cold_kernel_seconds() == 5.0
    assert fresh_kernel.twice(2) == 4
    assert kernel_cache.is_cached(fresh_kernel.twice)
    assert kernel_cache.cold_kernel_seconds() == 0.0


def test_the_cli_announces_a_cold_cache_only(fresh_kernel, capsys):
    cli._announce_compiling()
    assert capsys.readouterr().err == "compiling kernels, once, ~5 s\n"
    fresh_kernel.twice(1)
    cli._announce_compiling()
    assert capsys.readouterr().err == ""


def test_every_entry_kernel_exists():
    for (module, name) in kernel_cache.ENTRY_KERNELS:
        assert hasattr(importlib.import_module(module), name), (module, name)
