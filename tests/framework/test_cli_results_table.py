"""The results table printed by ``trackfw run``: honest column names, paths printed whole."""

from __future__ import annotations

from pathlib import Path

import pytest
from rich.console import Console

from trackfw import cli
from trackfw_plugins.datasets.points import make_points_video

REPO = Path(__file__).resolve().parents[2]


def test_run_table_names_its_columns_and_keeps_long_paths_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    make_points_video(tmp_path / "data" / "clip", n_frames=30, intervals=[(10, 14)])
    # A path far longer than the 80 columns of a default terminal.
    out = tmp_path / ("a-rather-long-output-folder-name-" * 3) / "runs"
    monkeypatch.setattr(cli, "console", Console(width=80, force_terminal=False))
    pipeline = REPO / "pipelines" / "kalman1-tr-oracle.yaml"
    code = cli.main(["run", str(pipeline), "--input", str(tmp_path / "data"), "-o", str(out), "-q"])
    assert code == 0, capsys.readouterr().err
    printed = capsys.readouterr().out
    assert "…" not in printed and "..." not in printed, printed
    # The path may be folded over lines, never cut: joined back it is whole.
    joined = "".join(line.strip(" │┃|") for line in printed.splitlines())
    assert str(out / "clip") in joined.replace(" ", ""), printed
    assert "proc. fps" in printed and "detected intervals" in printed, printed
    assert " fps " not in printed.replace("proc. fps", ""), printed


def test_run_warns_before_replacing_another_pipelines_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    make_points_video(tmp_path / "data" / "clip", n_frames=30, intervals=[(10, 14)])
    out = tmp_path / "runs"
    arguments = ["--input", str(tmp_path / "data"), "-o", str(out), "-q"]
    first = REPO / "pipelines" / "kalman1-tr-oracle.yaml"
    assert cli.main(["run", str(first), *arguments]) == 0
    capsys.readouterr()
    # The same pipeline again: a plain re-run, no warning.
    assert cli.main(["run", str(first), *arguments]) == 0
    assert "warning" not in capsys.readouterr().err
    other = REPO / "pipelines" / "kalman1-ar-oracle.yaml"
    assert cli.main(["run", str(other), *arguments]) == 0
    error = " ".join(capsys.readouterr().err.split())
    assert "holds a run of pipeline 'kalman1-tr-oracle'" in error, error
    assert "'kalman1-ar-oracle' replaces it" in error, error
