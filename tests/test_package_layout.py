"""The package reads as the block diagram: domain packages, a few root modules, and no module
reaching into another's private names."""

import ast
import pathlib

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "mrta_drake"
ROOT_MODULES = {"__init__.py", "errors.py", "payloads.py"}


def _private_imports(path: pathlib.Path) -> list[str]:
    """``from X import _name`` and ``import X._name`` in ``path``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            found += [f"{node.module}.{a.name}" for a in node.names if a.name.startswith("_")]
            if node.module and any(p.startswith("_") for p in node.module.split(".")):
                found.append(node.module)
        elif isinstance(node, ast.Import):
            found += [a.name for a in node.names
                      if any(p.startswith("_") for p in a.name.split("."))]
    return found


def test_no_module_imports_another_modules_private_names():
    offences = {str(p.relative_to(PACKAGE)): names for p in sorted(PACKAGE.rglob("*.py"))
                if (names := _private_imports(p))}
    assert offences == {}


def test_the_root_holds_only_the_contract_and_the_error_type():
    assert {p.name for p in PACKAGE.glob("*.py")} == ROOT_MODULES
