"""Every function of the core, the plugins and the benchmarks: a body of at most 60 lines.

The body is counted from its first statement after the docstring to its last line: the
signature (keyword-heavy commands and solvers) and the Google docstring (arguments, shapes) are
not logic. Nested functions count inside their parent and on their own.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("framework", "plugins", "benchmarks")
MAX_BODY_LINES = 60

#: Functions allowed to be longer, by "path:name" with their body lines. Empty: add one only
#: with a reason beside it, and the test below asks to remove it once it is short.
ALLOWED: dict[str, int] = {}


def body_lines(function: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines from the first statement after the docstring to the end of ``function``."""
    body = function.body
    first = body[0]
    has_docstring = (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
    )
    if has_docstring and len(body) > 1:
        first = body[1]
    end = function.end_lineno or function.lineno
    return end - first.lineno + 1


def long_functions() -> dict[str, int]:
    """``{"path:name": body lines}`` of every function over :data:`MAX_BODY_LINES`."""
    found: dict[str, int] = {}
    for folder in FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
            for node in ast.walk(tree):
                if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                    length = body_lines(node)
                    if length > MAX_BODY_LINES:
                        found[f"{path.relative_to(ROOT).as_posix()}:{node.name}"] = length
    return found


def test_functions_are_at_most_60_lines() -> None:
    found = long_functions()
    new = {name: length for name, length in found.items() if name not in ALLOWED}
    assert not new, "split these functions (body lines over 60):\n" + "\n".join(
        f"  {name}: {length}" for name, length in sorted(new.items())
    )


def test_the_allow_list_holds_only_functions_still_too_long() -> None:
    shortened = sorted(set(ALLOWED) - set(long_functions()))
    assert not shortened, f"remove from ALLOWED, now short enough or gone: {shortened}"


def test_the_scan_sees_the_code() -> None:
    # A broken walk (wrong root, no files) would pass the tests above without looking.
    assert sum(1 for folder in FOLDERS for _ in (ROOT / folder).rglob("*.py")) > 50
