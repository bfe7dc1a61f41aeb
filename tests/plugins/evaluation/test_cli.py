"""The ``trackfw eval`` command, mounted on a bare typer app."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from trackfw.errors import UserError
from trackfw_plugins.evaluation.cli import register

from ...conftest import ORACLE_PIPELINE


def _app() -> typer.Typer:
    app = typer.Typer()
    register(app)

    @app.command()
    def other() -> None:  # a second command keeps typer in multi-command mode
        """Placeholder."""

    return app


def test_eval_prints_table_and_writes_reports(
    tmp_path: Path, make_video: Callable[..., Path], make_run: Callable[..., Path]
) -> None:
    truth = {t: {1: (100.0 + t, 200.0), 2: (600.0, 300.0)} for t in range(20) if not 5 < t < 9}
    make_video(tmp_path / "data", "walk", truth, n_frames=20, intervals=[(5, 9)])
    make_run(tmp_path / "runs", "walk", truth, n_frames=20, infoless_frames=[6, 7, 8])
    result = CliRunner().invoke(
        _app(), ["eval", "--dataset", str(tmp_path / "data"), "--runs", str(tmp_path / "runs"),
                 "--out", str(tmp_path / "out"), "--dist", "30", "--sensitivity"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "MOTA" in result.output and "pooled" in result.output
    header = (tmp_path / "out" / "eval.csv").read_text(encoding="utf-8").splitlines()[0]
    assert "MOTA@60" in header
    assert (tmp_path / "out" / "eval.json").is_file()
    assert not (tmp_path / "runs" / "eval.csv").exists()


def test_eval_defaults_to_the_runs_folder_and_raises_user_errors(
    tmp_path: Path, make_video: Callable[..., Path], make_run: Callable[..., Path]
) -> None:
    truth = {t: {1: (100.0, 200.0)} for t in range(5)}
    make_video(tmp_path / "data", "a", truth, n_frames=5)
    make_run(tmp_path / "runs", "a", truth, n_frames=5)
    runner = CliRunner()
    # -d as for trackfw bench: one spelling of the dataset option across the commands.
    ok = runner.invoke(
        _app(), ["eval", "-d", str(tmp_path / "data"), "--runs", str(tmp_path / "runs")]
    )
    assert ok.exit_code == 0, ok.output
    assert (tmp_path / "runs" / "eval.csv").is_file()
    bad = runner.invoke(
        _app(), ["eval", "--dataset", str(tmp_path / "data"), "--runs", str(tmp_path / "none")]
    )
    assert isinstance(bad.exception, UserError)
    assert "no such folder" in str(bad.exception)


def _eval_main(dataset: Path, runs: Path) -> int:
    from trackfw.cli import main

    return main(["eval", "--dataset", str(dataset), "--runs", str(runs)])


def _kill_one_run_before_its_summary(
    data: Path, runs: Path, make_video: Callable[..., Path], make_run: Callable[..., Path]
) -> None:
    truth = {t: {1: (100.0, 200.0)} for t in range(5)}
    for name in ("a", "killed"):
        make_video(data, name, truth, n_frames=5)
        make_run(runs, name, truth, n_frames=5)
    # summary.json is written last: without it the run was interrupted.
    (runs / "killed" / "summary.json").unlink()


def _cut_frames_csv_short(
    data: Path, runs: Path, make_video: Callable[..., Path], make_run: Callable[..., Path]
) -> None:
    truth = {t: {1: (100.0, 200.0)} for t in range(10)}
    make_video(data, "cut", truth, n_frames=10)
    run = make_run(runs, "cut", truth, n_frames=10)
    frames = (run / "frames.csv").read_text().splitlines()
    (run / "frames.csv").write_text("\n".join(frames[:5]) + "\n")  # header and 4 of 10 rows


@pytest.mark.parametrize(
    ("damage", "fragments"),
    [
        (_kill_one_run_before_its_summary, ["'killed'", "summary.json"]),
        (_cut_frames_csv_short, ["frames.csv", "'cut'", "4 of 10"]),
    ],
    ids=["no-summary", "cut-frames-csv"],
)
def test_eval_refuses_a_damaged_run_naming_the_video(
    damage: Callable[..., None],
    fragments: list[str],
    tmp_path: Path,
    make_video: Callable[..., Path],
    make_run: Callable[..., Path],
    capsys: pytest.CaptureFixture[str],
) -> None:
    damage(tmp_path / "data", tmp_path / "runs", make_video, make_run)
    assert _eval_main(tmp_path / "data", tmp_path / "runs") == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert all(fragment in lines[0] for fragment in fragments), lines
    assert not (tmp_path / "runs" / "eval.csv").exists()


def _two_configurations(tmp_path: Path) -> tuple[Path, Path, str, str]:
    """Runs of v1 and v2 with the default, then v1 again with another --set (as if v2 was killed)."""
    from trackfw.cli import main
    from trackfw_plugins.datasets.points import make_points_video

    dataset, runs = tmp_path / "data", tmp_path / "runs"
    for name in ("v1", "v2"):
        make_points_video(dataset / name, n_frames=40, intervals=[(15, 20)], n_others=0)
    pipeline = tmp_path / "oracle.yaml"
    pipeline.write_text(ORACLE_PIPELINE)
    base = ["run", str(pipeline), "--output", str(runs), "-q"]
    assert main([*base, "--input", str(dataset)]) == 0
    changed = "stages.tracker.params.gate_px_at_1080=80"
    assert main([*base, "--input", str(dataset / "v1"), "--set", changed]) == 0
    first = json.loads((runs / "v2" / "summary.json").read_text())["pipeline_hash"]
    second = json.loads((runs / "v1" / "summary.json").read_text())["pipeline_hash"]
    return dataset, runs, first, second


def test_eval_refuses_runs_of_two_configurations(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dataset, runs, first, second = _two_configurations(tmp_path)
    assert first != second
    capsys.readouterr()
    assert _eval_main(dataset, runs) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert first in lines[0] and second in lines[0] and "v1" in lines[0] and "v2" in lines[0]
    assert not (runs / "eval.json").exists()


def test_eval_json_records_the_pipeline_hash(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dataset, runs, first, _ = _two_configurations(tmp_path)
    from trackfw.cli import main

    # Running v1 again with the first configuration makes the folder consistent.
    pipeline = tmp_path / "oracle.yaml"
    assert (
        main(["run", str(pipeline), "--input", str(dataset / "v1"), "--output", str(runs), "-q"])
        == 0
    )
    assert _eval_main(dataset, runs) == 0, capsys.readouterr().err
    document = json.loads((runs / "eval.json").read_text())
    assert document["pipeline_hash"] == first
    assert document["pipeline"] == "oracle"


def test_eval_refuses_ground_truth_that_dataset_check_rejects(
    tmp_path: Path,
    make_video: Callable[..., Path],
    make_run: Callable[..., Path],
    capsys: pytest.CaptureFixture[str],
) -> None:
    from trackfw_plugins.datasets.check import check_dataset

    truth = {t: {1: (100.0, 200.0)} for t in range(10)}
    truth[4][7] = (300.0, 200.0)  # id 7 appears on frame 5 only, never on frame 1
    video = make_video(tmp_path / "data", "late", truth, n_frames=10)
    make_run(tmp_path / "runs", "late", truth, n_frames=10)
    # The dataset's frames are not the point here; check_dataset's ground-truth lines are.
    problems = [p for p in check_dataset(tmp_path / "data").problems if "gt.csv" in p]
    assert len(problems) == 1 and "id 7 is not on frame 1" in problems[0], problems
    assert _eval_main(tmp_path / "data", tmp_path / "runs") == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [f"error: {problems[0]}"], lines
    assert not (tmp_path / "runs" / "eval.csv").exists()
    assert str(video) in lines[0]
