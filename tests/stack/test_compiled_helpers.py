"""Functions decorated with ``compiled_helper`` have no entry point for Python (calling one from
Python crashes the interpreter), so only compiled code may refer to one: this test reads every
Python file of the package, the tests and the benchmarks and fails on any other reference."""

import ast
import pathlib

import numba

from mrta_drake.stack.compiled_helper import HELPER_OPTIONS

ROOT = pathlib.Path(__file__).resolve().parents[2]
FOLDERS = ("mrta_drake", "tests", "benchmarks")


def _compiled(function: ast.FunctionDef) -> bool:
    """Whether ``function`` is compiled by numba (``numba.njit`` or ``compiled_helper``)."""
    return any("njit" in ast.unparse(d) or "compiled_helper" in ast.unparse(d)
               for d in function.decorator_list)


def _trees() -> dict[pathlib.Path, ast.Module]:
    return {path: ast.parse(path.read_text(encoding="utf-8"))
            for folder in FOLDERS for path in sorted((ROOT / folder).rglob("*.py"))}


def helpers(trees) -> set[str]:
    """Names of the functions decorated with ``compiled_helper``."""
    return {node.name for tree in trees.values() for node in ast.walk(tree)
            if isinstance(node, ast.FunctionDef)
            and any(ast.unparse(d) == "compiled_helper" for d in node.decorator_list)}


def python_references(tree: ast.Module, names: set[str]) -> list[tuple[str, int]]:
    """(name, line) of each reference to one of ``names`` outside compiled functions (imports
    are not references: compiled code needs them)."""
    inside = {id(sub) for node in ast.walk(tree)
              if isinstance(node, ast.FunctionDef) and _compiled(node) for sub in ast.walk(node)}
    found = []
    for node in ast.walk(tree):
        name = (node.id if isinstance(node, ast.Name)
                else node.attr if isinstance(node, ast.Attribute) else None)
        if name in names and id(node) not in inside:
            found.append((name, node.lineno))
    return found


def test_the_check_sees_a_call_from_python():
    tree = ast.parse("@compiled_helper\ndef _h(x):\n    return x\n\n"
                     "@numba.njit(cache=True)\ndef k(x):\n    return _h(x)\n\n"
                     "def f(x):\n    return _h(x)\n")
    assert python_references(tree, helpers({None: tree})) == [("_h", 10)]


def test_only_compiled_code_refers_to_a_compiled_helper():
    trees = _trees()
    names = helpers(trees)
    assert len(names) > 20  # the helpers of the controller, the people, the planner
    found = [f"{path.relative_to(ROOT)}:{line} {name}" for path, tree in trees.items()
             for name, line in python_references(tree, names)]
    assert found == []



def test_a_helper_runs_inside_its_caller_and_its_library_is_only_linked():
    twice = numba.njit(**HELPER_OPTIONS)(lambda x: 2.0 * x)  # not cached: compiled here

    @numba.njit
    def twice_plus_one(x):
        return twice(x) + 1.0

    assert twice_plus_one(1.5) == 4.0
    (helper,) = [result.library for result in twice.overloads.values()]
    assert helper.serialize_using_object_code()[1] == "bitcode"  # no machine code of its own
    assert not any(helper.get_pointer_to_function(f.name) for f in helper.get_defined_functions())
