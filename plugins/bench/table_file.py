"""Table files: a named list of pipelines, one table row each, with the paper's numbers beside.

``trackfw bench pipelines/tables/table1.yaml -d DATA`` runs the whole of the paper's Table 1 (and
our extra rows). A table file is YAML::

    table: table1
    description: ...
    rows:
      - pipeline: ../proposed.yaml            # relative to the table file
        paper: {MOTA: 88.9, MOTP: 3.3, MOTA-In: 76.8, MOTP-In: 3.4}
      - pipeline: ../bytetrack.yaml           # no paper figures: an extra row

It is told from a pipeline file by its ``rows`` key. Any argument of ``trackfw bench`` may be a
table file; its rows join the other pipelines in order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from trackfw.errors import UserError
from trackfw.yaml_loading import parse_yaml

#: Metrics a table file may quote from the paper.
PAPER_METRICS = ("MOTA", "MOTP", "MOTA-In", "MOTP-In")


@dataclass
class Expanded:
    """The pipeline files of a bench command, table files expanded.

    Attributes:
        files: pipeline files in order.
        paper: pipeline file (resolved) -> the paper's figures quoted for it.
    """

    files: list[Path] = field(default_factory=list)
    paper: dict[Path, dict[str, float]] = field(default_factory=dict)


def _read_mapping(path: Path) -> Any:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None  # not a readable text file: the pipeline loader says what is wrong
    try:
        return parse_yaml(text, str(path))
    except UserError:
        return None


def _paper_figures(path: Path, index: int, value: Any) -> dict[str, float]:
    where = f"{path}: rows[{index}].paper"
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise UserError(f"{where}: expected a mapping of {', '.join(PAPER_METRICS)} to numbers.")
    figures: dict[str, float] = {}
    for key, number in value.items():
        if key not in PAPER_METRICS:
            raise UserError(f"{where}: unknown metric {key!r}; expected one of {PAPER_METRICS}.")
        if isinstance(number, bool) or not isinstance(number, (int, float)):
            raise UserError(f"{where}.{key}: expected a number, got {number!r}.")
        if not math.isfinite(number):
            raise UserError(f"{where}.{key}: expected a finite number, got {number}.")
        figures[key] = float(number)
    return figures


def _rows(path: Path, document: dict[str, Any]) -> list[tuple[Path, dict[str, float]]]:
    rows = document.get("rows")
    if not isinstance(rows, list) or not rows:
        raise UserError(f"{path}: rows: expected a non-empty list of {{pipeline, paper}}.")
    unknown = sorted(set(document) - {"table", "description", "rows"})
    if unknown:
        raise UserError(f"{path}: unknown key {unknown[0]!r}; expected table, description, rows.")
    expanded = []
    for index, row in enumerate(rows):
        if not isinstance(row, dict) or not isinstance(row.get("pipeline"), str):
            raise UserError(f"{path}: rows[{index}]: expected a mapping with a pipeline path.")
        extra = sorted(set(row) - {"pipeline", "paper"})
        if extra:
            raise UserError(f"{path}: rows[{index}]: unknown key {extra[0]!r}.")
        pipeline = (path.parent / row["pipeline"]).resolve()
        if not pipeline.is_file():
            raise UserError(f"{path}: rows[{index}].pipeline: {row['pipeline']} not found.")
        expanded.append((pipeline, _paper_figures(path, index, row.get("paper"))))
    return expanded


def expand_tables(paths: list[Path]) -> Expanded:
    """Replace each table file among ``paths`` by its pipelines; others pass unchanged.

    Raises:
        UserError: a table file with a bad row (one line naming the file and the row).
    """
    result = Expanded()
    for path in paths:
        document = _read_mapping(path) if path.is_file() else None
        if isinstance(document, dict) and "rows" in document and "stages" not in document:
            for pipeline, figures in _rows(path, document):
                result.files.append(pipeline)
                if figures:
                    result.paper[pipeline] = figures
        else:
            result.files.append(path)
    return result


__all__ = ["PAPER_METRICS", "Expanded", "expand_tables"]
