"""Tests of the ``train detector`` command registration."""

from __future__ import annotations

from pathlib import Path

import typer
from typer.testing import CliRunner

from trackfw.errors import UserError
from trackfw_plugins.detectors.cli import register


def _app() -> typer.Typer:
    app = typer.Typer()
    train = typer.Typer()
    register(train)
    app.add_typer(train, name="train")
    return app


def test_command_is_registered_with_its_options() -> None:
    result = CliRunner().invoke(_app(), ["train", "detector", "--help"])
    assert result.exit_code == 0
    for option in ("--dataset", "--mot", "--out", "--epochs", "--seed"):
        assert option in result.output


def test_without_training_data_it_is_a_user_error(tmp_path: Path) -> None:
    result = CliRunner().invoke(_app(), ["train", "detector", "--out", str(tmp_path / "m.onnx")])
    assert isinstance(result.exception, UserError)
    assert "--dataset" in str(result.exception)
    assert not (tmp_path / "m.onnx").exists()
