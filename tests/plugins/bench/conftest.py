"""Fixtures for the benchmark tests: a small point-only dataset and a test-only detector plugin.

The plugin is installed like a third-party distribution (a dist-info folder with an entry point
on ``sys.path`` and ``PYTHONPATH``), so worker processes and subprocesses discover it too.
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from pathlib import Path

import pytest

from trackfw_plugins.datasets.points import make_points_video

PLUGIN_SOURCE = textwrap.dedent(
    '''
    import os
    import time

    from pydantic import Field

    from trackfw.hookspecs import hookimpl
    from trackfw.records import Detections
    from trackfw.stages import Detector, StageParams

    CALLS = 0


    class BenchTestParams(StageParams):
        fail_on: str = Field("", description="video name on which detect raises")
        crash_on: str = Field("", description="video name on which the process exits")
        sleep_ms: float = Field(0.0, description="sleep per frame, milliseconds")


    class BenchTestDetector(Detector):
        """Ground-truth targets as detections; counts calls, may fail, crash or sleep."""

        name = "bench-test"
        Params = BenchTestParams
        uses_pixels = False
        needs_ground_truth = True

        def start(self, video):
            self.targets = video.ground_truth.targets

        def detect(self, frame):
            global CALLS
            CALLS += 1
            name = frame.video.name
            if self.params.fail_on == name:
                raise RuntimeError(f"boom on {name}")
            if self.params.crash_on == name:
                os._exit(17)
            if self.params.sleep_ms:
                time.sleep(self.params.sleep_ms / 1000)
            return Detections.from_points(list(self.targets.get(frame.t, {}).values()))


    @hookimpl
    def trackfw_register_stages(registry):
        registry.add_detector(BenchTestDetector)
    '''
)

PIPELINE = textwrap.dedent(
    """\
    name: {name}
    stages:
      detector:    {{type: bench-test, params: {detector}}}
      classifier:  {{type: oracle}}
      tracker:     {{type: kalman, params: {{association: hungarian}}}}
      gap_matcher: {{type: assignment, params: {{method: {method}, predictor: {{type: kalman}}}}}}
    """
)


@pytest.fixture
def bench_plugin(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Install the ``bench-test`` detector; returns the site folder (also put on PYTHONPATH)."""
    site = tmp_path / "site"
    dist_info = site / "trackfw_benchtest-0.1.0.dist-info"
    dist_info.mkdir(parents=True)
    (dist_info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: trackfw-benchtest\nVersion: 0.1.0\n"
    )
    (dist_info / "entry_points.txt").write_text("[trackfw]\nbenchtest = trackfw_benchtest\n")
    (site / "trackfw_benchtest.py").write_text(PLUGIN_SOURCE)
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv("PYTHONPATH", str(site))
    return site


@pytest.fixture
def bench_pipeline(tmp_path: Path) -> Callable[..., Path]:
    """Write a pipeline that uses the ``bench-test`` detector."""

    def write(name: str = "counting", method: str = "hungarian", **detector: object) -> Path:
        params = "{" + ", ".join(f"{key}: {value!r}" for key, value in detector.items()) + "}"
        path = tmp_path / "pipelines" / f"{name}.yaml"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(PIPELINE.format(name=name, detector=params, method=method))
        return path

    return write


@pytest.fixture
def small_dataset(tmp_path: Path) -> Callable[..., Path]:
    """A dataset of point-only videos ``v0, v1, ...`` with two intervals each."""

    def make(count: int = 2, n_frames: int = 120) -> Path:
        root = tmp_path / "dataset"
        for index in range(count):
            make_points_video(
                root / f"v{index}",
                n_frames=n_frames,
                n_targets=5,
                n_others=3,
                intervals=[(30, 45), (80, 95)],
                seed=index,
            )
        return root

    return make
