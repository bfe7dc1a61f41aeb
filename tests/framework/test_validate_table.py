"""``trackfw validate`` on a bench table file: says what the file is and validates its pipelines."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackfw.cli import main

from ..conftest import assert_one_error_line
from .conftest import PIPELINE

REPOSITORY = Path(__file__).resolve().parents[2]
TABLE_SENTENCE = "is a bench table file (it has `rows`), not a pipeline"


def run_cli(capsys: pytest.CaptureFixture[str], *arguments: object) -> tuple[int, str, str]:
    code = main([str(argument) for argument in arguments])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def write_table(folder: Path, *pipelines: str) -> Path:
    tables = folder / "tables"
    tables.mkdir()
    rows = "".join(f"  - pipeline: ../{name}\n" for name in pipelines)
    table = tables / "table.yaml"
    table.write_text(f"table: t\nrows:\n{rows}", encoding="utf-8")
    return table


def test_a_table_of_valid_pipelines_is_valid(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "a.yaml").write_text(PIPELINE, encoding="utf-8")
    (tmp_path / "b.yaml").write_text(PIPELINE.replace("test-oracle", "test-b"), encoding="utf-8")
    table = write_table(tmp_path, "a.yaml", "b.yaml")
    code, out, err = run_cli(capsys, "validate", table)
    assert code == 0, err
    assert f"{table} {TABLE_SENTENCE}: run it with `trackfw bench`" in out
    assert out.count("ok ") == 2 and "'test-b'" in out
    assert err == ""


def test_an_invalid_listed_pipeline_fails_the_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "a.yaml").write_text(PIPELINE, encoding="utf-8")
    broken = PIPELINE.replace("{type: oracle}", "{type: no-such-detector}", 1)
    (tmp_path / "b.yaml").write_text(broken, encoding="utf-8")
    table = write_table(tmp_path, "a.yaml", "b.yaml")
    code, out, err = run_cli(capsys, "validate", table)
    assert code == 2
    assert out.count("ok ") == 1
    errors = err.strip().splitlines()
    assert len(errors) == 2
    assert "b.yaml" in errors[0] and "no-such-detector" in errors[0]
    assert errors[1] == f"error: {table}: 1 of the 2 pipelines it lists are not valid."


def test_a_table_without_pipeline_paths_is_one_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    table = tmp_path / "table.yaml"
    table.write_text("table: t\nrows:\n  - paper: {MOTA: 1.0}\n", encoding="utf-8")
    code, _, err = run_cli(capsys, "validate", table)
    assert_one_error_line(code, err, TABLE_SENTENCE, "rows[0]")


def test_the_paper_table_validates(capsys: pytest.CaptureFixture[str]) -> None:
    # The file of the report: two pipeline errors (name, stages) before.
    table = REPOSITORY / "pipelines" / "tables" / "table1.yaml"
    code, out, err = run_cli(capsys, "validate", table)
    assert code == 0, err
    listed = table.read_text(encoding="utf-8").count("- pipeline:")
    assert out.count("ok ") == listed > 10
