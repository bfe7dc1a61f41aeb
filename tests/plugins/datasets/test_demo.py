"""builtin:demo is generated once, deterministically, into the cache, and reused."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackfw.dataset import load_video
from trackfw.registry import load_registry


def test_demo_is_generated_once_and_reused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TRACKFW_CACHE", str(tmp_path / "cache"))
    factory = load_registry().inputs["demo"].factory
    first = factory()
    video = load_video(first)
    assert video.name == "demo" and video.n_frames == 150
    assert video.ground_truth is not None and video.ground_truth.intervals
    assert len(video.ground_truth.targets[0]) == 6
    stamp = (first / "video.mp4").stat().st_mtime_ns
    assert factory() == first
    assert (first / "video.mp4").stat().st_mtime_ns == stamp
    assert not [p for p in first.parent.parent.iterdir() if p.name.startswith(".demo-")]
