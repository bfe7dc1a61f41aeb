"""The array aliases are defined once, in trackfw.arrays, and imported everywhere else."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ALIAS_DEFINITION = re.compile(r"^\w*Array(\s*:\s*TypeAlias)?\s*=\s*(npt\.)?NDArray\[", re.MULTILINE)


def test_no_module_but_trackfw_arrays_defines_an_array_alias() -> None:
    offenders = [
        str(path.relative_to(ROOT))
        for folder in ("framework", "plugins", "benchmarks", "examples")
        for path in sorted((ROOT / folder).rglob("*.py"))
        if path.name != "arrays.py" and ALIAS_DEFINITION.search(path.read_text(encoding="utf-8"))
    ]
    assert offenders == []
