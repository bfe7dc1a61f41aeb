"""Table files: the whole of Table 1 in one ``trackfw bench`` command, paper figures beside ours."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from trackfw.cli import main
from trackfw.errors import UserError
from trackfw_plugins.bench.table_file import expand_tables

REPO = Path(__file__).resolve().parents[3]
TABLES = REPO / "pipelines" / "tables"
PAPER_ROWS = [
    "proposed", "kalman1-tr", "kalman1-ar", "kalman2-tr", "kalman2-ar", "kalman3-tr",
    "kalman3-ar", "lomo", "gog", "dpnms", "smot", "cem", "gtcsa",
]  # fmt: skip
BATCH_ROWS = {"dpnms", "smot", "cem", "gtcsa", "bytetrack"}


def test_the_two_table_files_list_the_thirteen_paper_rows_then_ours() -> None:
    real = expand_tables([TABLES / "table1.yaml"])
    oracle = expand_tables([TABLES / "table1-oracle.yaml"])
    names = [path.stem for path in real.files]
    assert names[:13] == PAPER_ROWS and "bytetrack" in names[13:]
    assert [path.stem for path in oracle.files] == [f"{name}-oracle" for name in names]
    # The paper's row for DPNMS, and none for our rows.
    assert real.paper[REPO / "pipelines" / "dpnms.yaml"] == {
        "MOTA": 47.1, "MOTP": 4.6, "MOTA-In": 19.9, "MOTP-In": 7.7,
    }  # fmt: skip
    assert REPO / "pipelines" / "bytetrack.yaml" not in real.paper


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("rows: []", "rows: expected a non-empty list"),
        ("rows: [{pipeline: missing.yaml}]", "rows[0].pipeline: missing.yaml not found"),
        (
            "rows: [{pipeline: p.yaml, paper: {MOTA: .nan}}]",
            "rows[0].paper.MOTA: expected a finite",
        ),
        ("rows: [{pipeline: p.yaml, paper: {IDF1: 3}}]", "unknown metric 'IDF1'"),
        ("rows: [{pipeline: p.yaml, note: x}]", "rows[0]: unknown key 'note'"),
        ("rows: [{pipeline: p.yaml}]\ncolumns: 3", "unknown key 'columns'"),
    ],
)
def test_a_bad_table_file_is_one_line(text: str, message: str, tmp_path: Path) -> None:
    (tmp_path / "p.yaml").write_text("name: p\nstages: {}\n")
    table = tmp_path / "t.yaml"
    table.write_text(text + "\n")
    with pytest.raises(UserError) as raised:
        expand_tables([table])
    assert len(raised.value.lines) == 1 and message in raised.value.lines[0], raised.value.lines


def test_pipeline_files_pass_through_unchanged(tmp_path: Path) -> None:
    pipeline = REPO / "pipelines" / "dpnms-oracle.yaml"
    expanded = expand_tables([pipeline, tmp_path / "missing.yaml"])
    assert expanded.files == [pipeline, tmp_path / "missing.yaml"] and not expanded.paper


@pytest.mark.slow
def test_bench_runs_the_whole_oracle_table_on_a_tiny_dataset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dataset, out = tmp_path / "data", tmp_path / "bench"
    synth = ["dataset", "synth", "--out", str(dataset), "--videos", "1", "--frames", "60"]
    assert main([*synth, "--size", "320x180", "--jobs", "1", "--no-preview", "--seed", "2"]) == 0
    table = TABLES / "table1-oracle.yaml"
    assert main(["bench", str(table), "-d", str(dataset), "-o", str(out), "-q"]) == 0
    printed = capsys.readouterr().out
    assert "paper MOTA %" in printed and "| cem-oracle | 1/1 |" in printed
    with (out / "table.csv").open() as stream:
        rows = {row["pipeline"]: row for row in csv.DictReader(stream)}
    assert list(rows) == [path.stem for path in expand_tables([table]).files]
    assert rows["dpnms-oracle"]["paper MOTA"] == "47.1"
    assert rows["bytetrack-oracle"]["paper MOTA"] == ""
    for name, row in rows.items():
        assert row["videos_done"] == "1" and float(row["fps"]) > 0, name
        assert math.isfinite(float(row["MOTA"])), name
        # Batch trackers classify no frame: IL-F1 is not applicable, not 0.
        assert (row["IL-F1"] == "") == (name.removesuffix("-oracle") in BATCH_ROWS), name
    assert (out / "table.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
