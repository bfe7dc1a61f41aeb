"""The project's docs are the reference its code cites, and they agree with the code.

* Every ``docs/<page>.md#<anchor>`` cited anywhere in the repository (docstrings, comments,
  Markdown) names a page that exists and a heading of that page; every ``docs/<page>.md`` cited
  without an anchor names a page that exists.
* Every relative Markdown link inside ``docs/`` and README.md points at an existing file and, when
  it has one, an existing heading.
* Nothing cites the design brief outside the repository (``../shared/docs``): users of the
  package cannot read it.
* Every parameter table in the algorithm pages (``<!-- params: KIND/NAME -->`` before the table)
  gives the defaults the stage's ``Params`` model has, and the tables of a stage list all of its
  parameters; every built-in stage with parameters has a table.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from pydantic import BaseModel

from trackfw.pipeline import EngineOptions
from trackfw.registry import load_registry

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: Folders and files whose text may cite the docs.
SCANNED = ("framework", "plugins", "benchmarks", "tests", "examples", "docs", "pipelines")
SCANNED_FILES = ("README.md", "pyproject.toml", "setup.py")
SUFFIXES = {".py", ".md", ".yaml", ".yml", ".toml", ".txt", ".cfg"}
#: The brief's file names, assembled so that this file does not cite them itself.
BRIEF_FILES = ("ALGORITHMS" + ".md", "DESIGN" + ".md")

CITATION = re.compile(r"docs/((?:[\w.-]+/)*[\w.-]+\.md)#([\w-]+)")
PAGE_CITATION = re.compile(r"\bdocs/((?:[\w.-]+/)*[\w.-]+\.md)")
MARKDOWN_LINK = re.compile(r"\]\(([^)\s]+)\)")
HEADING = re.compile(r"^(#{1,6})\s+(.+?)\s*#*\s*$")
PARAMS_MARKER = re.compile(r"<!--\s*params:\s*(\S+)\s*-->")
CODE_CELL = re.compile(r"^`(.*)`$")


def _text_files() -> Iterator[Path]:
    for name in SCANNED:
        folder = ROOT / name
        if folder.is_dir():
            for path in sorted(folder.rglob("*")):
                if path.is_file() and path.suffix in SUFFIXES and ".venv" not in path.parts:
                    yield path
    for name in SCANNED_FILES:
        if (ROOT / name).is_file():
            yield ROOT / name


def slug(heading: str) -> str:
    """GitHub's anchor for a Markdown heading.

    >>> slug("Kalman TR predictor"), slug("`rpm.*` keys: TPS-RPM")
    ('kalman-tr-predictor', 'rpm-keys-tps-rpm')
    """
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """The anchors of every heading of a Markdown page (duplicates numbered as GitHub does)."""
    seen: dict[str, int] = {}
    found: set[str] = set()
    fenced = False
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        match = HEADING.match(line)
        if fenced or not match:
            continue
        base = slug(match.group(2))
        count = seen.get(base, 0)
        seen[base] = count + 1
        found.add(base if count == 0 else f"{base}-{count}")
    return found


def _check_target(page: Path, anchor: str | None, where: str) -> str | None:
    if not page.is_file():
        return f"{where}: {page.relative_to(ROOT)} does not exist"
    if anchor and page.suffix == ".md" and anchor not in anchors(page):
        return f"{where}: {page.relative_to(ROOT)} has no heading with anchor #{anchor}"
    return None


def test_slug_follows_github() -> None:
    assert slug("Re-initialisation at b") == "re-initialisation-at-b"
    assert slug("CLEAR MOT for points") == "clear-mot-for-points"
    assert slug("Window cost ψ") == "window-cost-ψ"


def test_cited_docs_anchors_exist() -> None:
    problems = []
    citations = 0
    for path in _text_files():
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            for match in CITATION.finditer(line):
                citations += 1
                where = f"{path.relative_to(ROOT)}:{number}"
                problem = _check_target(DOCS / match.group(1), match.group(2), where)
                if problem:
                    problems.append(problem)
    assert citations > 0, "no docs anchor citation found: the scan itself is broken"
    assert not problems, "\n".join(problems)


def test_cited_docs_pages_exist() -> None:
    missing = [
        f"{path.relative_to(ROOT)}:{number}: docs/{match.group(1)} does not exist"
        for path in _text_files()
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)
        for match in PAGE_CITATION.finditer(line)
        if not (DOCS / match.group(1)).is_file()
    ]
    assert not missing, "\n".join(missing)


def test_nothing_cites_the_design_brief() -> None:
    here = Path(__file__).resolve()
    offenders = [
        f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
        for path in _text_files()
        if path.resolve() != here
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)
        if any(name in line for name in BRIEF_FILES)
    ]
    assert not offenders, (
        "cite the repository's docs (docs/algorithms/*.md#anchor) instead of the design brief:\n"
        + "\n".join(offenders)
    )


def test_markdown_links_resolve() -> None:
    pages = [*sorted(DOCS.rglob("*.md")), ROOT / "README.md"]
    problems = []
    for page in pages:
        for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), start=1):
            for match in MARKDOWN_LINK.finditer(line):
                target = match.group(1)
                if re.match(r"^[a-z]+:", target):
                    continue  # http:, mailto:, ...
                file_part, _, anchor = target.partition("#")
                resolved = page if not file_part else (page.parent / file_part).resolve()
                where = f"{page.relative_to(ROOT)}:{number}"
                if resolved.is_dir():
                    continue
                problem = _check_target(resolved, anchor or None, where)
                if problem:
                    problems.append(problem)
    assert not problems, "\n".join(problems)


# --- parameter tables -------------------------------------------------------------------------


def _tables() -> dict[str, list[tuple[str, str, str]]]:
    """``marker -> [(key, default cell, where)]`` over every page of docs/algorithms."""
    tables: dict[str, list[tuple[str, str, str]]] = {}
    for page in sorted((DOCS / "algorithms").glob("*.md")):
        marker: str | None = None
        in_table = False
        for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), start=1):
            found = PARAMS_MARKER.search(line)
            if found:
                marker, in_table = found.group(1), False
                tables.setdefault(marker, [])
                continue
            if marker is None:
                continue
            if not line.startswith("|"):
                if in_table:
                    marker, in_table = None, False
                continue
            in_table = True
            cells = [cell.strip() for cell in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
            key_cell = CODE_CELL.match(cells[0]) if cells else None
            if key_cell is None:
                continue  # header or separator row
            where = f"{page.relative_to(ROOT)}:{number}"
            tables[marker].append((key_cell.group(1), cells[1], where))
    return tables


def _model_for(marker: str) -> tuple[type[BaseModel], dict[str, Any]]:
    """The parameter model of a marker and its defaults (nested stages as ``{type: ...}``)."""
    if marker == "engine":
        return EngineOptions, EngineOptions().model_dump()
    kind, _, name = marker.partition("/")
    entry = load_registry().get(kind, name)
    model: type[BaseModel] = entry.cls.Params
    defaults = model().model_dump()
    for key in getattr(entry.cls, "nested", {}):
        defaults[key] = {"type": getattr(entry.cls, f"default_{key}", None)}
    return model, defaults


def _same(documented: Any, actual: Any) -> bool:
    if isinstance(actual, tuple | list):
        return (
            isinstance(documented, list)
            and len(documented) == len(actual)
            and all(_same(d, a) for d, a in zip(documented, actual, strict=True))
        )
    if isinstance(actual, dict):
        return (
            isinstance(documented, dict)
            and documented.keys() == actual.keys()
            and all(_same(documented[k], actual[k]) for k in actual)
        )
    if isinstance(actual, bool) or actual is None or isinstance(actual, str):
        return bool(documented == actual and type(documented) is type(actual))
    if isinstance(actual, int | float) and isinstance(documented, int | float):
        if math.isinf(actual) or math.isinf(documented):
            return bool(documented == actual)
        return math.isclose(documented, actual, rel_tol=1e-9, abs_tol=0.0)
    return bool(documented == actual)


def _lookup(defaults: dict[str, Any], key: str) -> tuple[bool, Any]:
    value: Any = defaults
    for part in key.split("."):
        if not isinstance(value, dict) or part not in value:
            return False, None
        value = value[part]
    return True, value


TABLES = _tables()


def test_parameter_tables_exist() -> None:
    assert {"engine", "tracker/kalman", "gap_matcher/window-tps-rpm", "predictor/ar"} <= set(TABLES)


@pytest.mark.parametrize("marker", sorted(TABLES))
def test_parameter_table_matches_code(marker: str) -> None:
    _, defaults = _model_for(marker)
    problems = []
    listed: set[str] = set()
    for key, cell, where in TABLES[marker]:
        top = key.split(".")[0]
        listed.add(top)
        if key.endswith(".*"):
            continue  # documented on another page
        known, actual = _lookup(defaults, key)
        if not known:
            problems.append(f"{where}: {marker} has no parameter {key!r}")
            continue
        code = CODE_CELL.match(cell)
        documented = yaml.safe_load(code.group(1)) if code else None
        if code is None or not _same(documented, actual):
            problems.append(f"{where}: {key} is documented as {cell}, the code says {actual!r}")
    missing = sorted(set(defaults) - listed)
    if missing:
        problems.append(f"{marker}: parameters missing from the docs tables: {missing}")
    assert not problems, "\n".join(problems)


def test_every_built_in_stage_has_a_parameter_table() -> None:
    registry = load_registry()
    missing = [
        f"{entry.kind}/{entry.name}"
        for entry in registry.stages.values()
        if entry.source.builtin
        and (entry.cls.Params.model_fields or getattr(entry.cls, "nested", {}))
        and f"{entry.kind}/{entry.name}" not in TABLES
    ]
    assert not missing, (
        "built-in stages without a parameter table in docs/algorithms/ (add one after a"
        f" '<!-- params: KIND/NAME -->' line on the stage kind's page): {sorted(missing)}"
    )
