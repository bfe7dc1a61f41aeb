"""The core stands alone: it imports no plugin, and plugins reach it by its import name only."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _imports(path: Path) -> list[tuple[int, str]]:
    """Every module ``path`` imports, anywhere in the file (functions included), with its line."""
    found: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
    return found


def _offenders(folder: str, forbidden: str) -> list[str]:
    return [
        f"{path.relative_to(ROOT)}:{line}: imports {module}"
        for path in sorted((ROOT / folder).rglob("*.py"))
        for line, module in _imports(path)
        if module == forbidden or module.startswith(f"{forbidden}.")
    ]


def test_the_core_imports_no_plugin() -> None:
    assert _offenders("framework", "trackfw_plugins") == []


def test_plugins_never_import_the_core_by_its_folder_name() -> None:
    assert _offenders("plugins", "framework") == []


def test_the_scan_sees_imports_inside_functions(tmp_path: Path) -> None:
    module = tmp_path / "module.py"
    module.write_text("def f():\n    from trackfw_plugins.evaluation import report\n")
    assert _imports(module) == [(2, "trackfw_plugins.evaluation")]
