"""Fixtures for the core tests: point-only videos and test-only plugins."""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

from trackfw.hookspecs import hookimpl
from trackfw.records import Detections, FrameData
from trackfw.registry import Registry, load_registry
from trackfw.stages import Detector
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


class PixelCentreDetector(Detector):
    """Test detector that reads pixels: one detection at the image centre."""

    name = "pixel-centre"
    uses_pixels = True

    def detect(self, frame: FrameData) -> Detections:
        assert frame.image is not None
        height, width = frame.image.shape[:2]
        return Detections.from_points([[width / 2, height / 2]])


def registry_with(name: str, detector: type[Detector]) -> Registry:
    """The installed plugins plus one test detector, registered by the plugin ``name``."""
    module = ModuleType(f"{name}_plugin")

    @hookimpl
    def trackfw_register_stages(registry: Registry) -> None:
        registry.add_detector(detector)

    module.trackfw_register_stages = trackfw_register_stages  # type: ignore[attr-defined]
    return load_registry(extra_modules=[(name, module)])


def pixel_registry() -> Registry:
    """The installed plugins plus the test detector ``pixel-centre``."""
    return registry_with("pixel-centre", PixelCentreDetector)


PIXEL_PIPELINE = textwrap.dedent(
    """\
    name: pixels
    engine: {init: detections}
    stages:
      detector:    {type: pixel-centre}
      classifier:  {type: flow-threshold}
      tracker:     {type: kalman}
      gap_matcher: {type: assignment}
    """
)


@pytest.fixture
def pixel_pipeline(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A pipeline file whose detector reads pixels; ``trackfw`` commands see its test plugin."""
    monkeypatch.setattr("trackfw.cli.load_registry", pixel_registry)
    path = tmp_path / "pixels.yaml"
    path.write_text(PIXEL_PIPELINE, encoding="utf-8")
    return path
