"""The ``trackfw eval`` command, mounted on a bare typer app."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import typer
from typer.testing import CliRunner

from trackfw.errors import UserError
from trackfw_plugins.evaluation.cli import register


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
    ok = runner.invoke(
        _app(), ["eval", "--dataset", str(tmp_path / "data"), "--runs", str(tmp_path / "runs")]
    )
    assert ok.exit_code == 0, ok.output
    assert (tmp_path / "runs" / "eval.csv").is_file()
    bad = runner.invoke(
        _app(), ["eval", "--dataset", str(tmp_path / "data"), "--runs", str(tmp_path / "none")]
    )
    assert isinstance(bad.exception, UserError)
    assert "no such folder" in str(bad.exception)
