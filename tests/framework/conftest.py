"""Fixtures for the core tests: point-only videos and test-only plugins."""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from pathlib import Path

import pytest

from trackfw_plugins.datasets.points import make_points_video

PIPELINE = textwrap.dedent(
    """\
    name: test-oracle
    description: oracle stages
    stages:
      detector:    {type: oracle}
      classifier:  {type: oracle}
      tracker:     {type: kalman, params: {association: hungarian}}
      gap_matcher: {type: assignment, params: {method: hungarian, predictor: {type: kalman}}}
    """
)


@pytest.fixture
def points_video(tmp_path: Path) -> Callable[..., Path]:
    """Factory for point-only videos under tmp_path."""

    def make(name: str = "video", **options: object) -> Path:
        return make_points_video(tmp_path / "data" / name, **options)  # type: ignore[arg-type]

    return make


@pytest.fixture
def pipeline_file(tmp_path: Path) -> Callable[[str], Path]:
    """Write pipeline text to a file and return its path."""

    def write(text: str = PIPELINE, name: str = "pipeline.yaml") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return write
