"""The stage cache: replay equals computation, keys, damaged files, no pickle."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from trackfw.dataset import load_video
from trackfw.engine import Engine
from trackfw.formats.run import frames_text, gaps_data, tracks_text
from trackfw.pipeline import Pipeline, validate_pipeline
from trackfw.records import VideoContext
from trackfw.registry import Registry, load_registry
from trackfw.stage_cache import StageCache, cache_key

PIPELINE: dict[str, Any] = {
    "name": "cache-test",
    "stages": {
        "detector": {"type": "bench-test"},
        "classifier": {"type": "oracle"},
        "tracker": {"type": "kalman", "params": {"association": "hungarian"}},
        "gap_matcher": {"type": "assignment", "params": {"predictor": {"type": "kalman"}}},
    },
}


def _without_timings(text: str) -> list[list[str]]:
    """frames.csv rows without the tracker and gap-matcher milliseconds (they are measured)."""
    return [line.split(",")[:-2] for line in text.splitlines()]


def _one_video_and_a_cache(
    small_dataset: Any, tmp_path: Path
) -> tuple[Registry, Pipeline, VideoContext, StageCache]:
    """The registry, the test pipeline, one video of the small dataset and an empty cache."""
    registry = load_registry()
    pipeline = validate_pipeline(PIPELINE, registry)
    video = load_video(small_dataset(count=1) / "v0")
    return registry, pipeline, video, StageCache(tmp_path / "cache")


def test_a_hit_replays_detector_and_classifier_exactly(
    bench_plugin, small_dataset, tmp_path: Path
) -> None:
    registry, pipeline, video, cache = _one_video_and_a_cache(small_dataset, tmp_path)
    counter = sys.modules["trackfw_benchtest"]
    engine = Engine(pipeline, registry)

    computed = engine.run_video(video, cache=cache)
    calls = counter.CALLS
    assert (cache.hits, cache.misses, cache.stores) == (0, 1, 1)
    replayed = engine.run_video(video, cache=cache)
    assert calls == counter.CALLS, "the detector ran on a cache hit"
    assert (cache.hits, cache.misses) == (1, 1)

    assert tracks_text(replayed, 80) == tracks_text(computed, 80)
    strip = [{k: v for k, v in gap.items() if k != "milliseconds"} for gap in gaps_data(computed)]
    assert [
        {k: v for k, v in g.items() if k != "milliseconds"} for g in gaps_data(replayed)
    ] == strip
    # Detections, decisions and the recorded detector/classifier milliseconds are replayed.
    assert _without_timings(frames_text(replayed)) == _without_timings(frames_text(computed))
    assert any(frame.infoless for frame in replayed.frames)


def test_the_key_follows_detector_classifier_and_video_only(
    bench_plugin, small_dataset, tmp_path: Path
) -> None:
    registry = load_registry()
    video_dir = small_dataset(count=1) / "v0"
    video = load_video(video_dir)
    base = validate_pipeline(PIPELINE, registry)
    key = cache_key(base, video, registry)

    def variant(kind: str, params: dict[str, Any]) -> str:
        data: dict[str, Any] = {**PIPELINE, "stages": {**PIPELINE["stages"]}}
        data["stages"][kind] = {**data["stages"][kind], "params": params}
        return cache_key(validate_pipeline(data, registry), video, registry)

    assert variant("gap_matcher", {"method": "nearest"}) == key
    assert variant("tracker", {"association": "nearest"}) == key
    assert variant("detector", {"sleep_ms": 1.0}) != key
    stat = (video_dir / "gt.csv").stat()
    os.utime(video_dir / "gt.csv", ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    assert cache_key(base, video, registry) != key


def test_a_damaged_cache_file_is_a_miss_and_is_rewritten(
    bench_plugin, small_dataset, tmp_path: Path
) -> None:
    registry, pipeline, video, cache = _one_video_and_a_cache(small_dataset, tmp_path)
    Engine(pipeline, registry).run_video(video, cache=cache)
    (path,) = (tmp_path / "cache").glob("*.npz")
    # Stored without pickled objects: it loads with allow_pickle=False.
    with np.load(path, allow_pickle=False) as archive:
        assert archive["points"].dtype == np.float64 and archive["status"].shape == (
            video.n_frames,
        )
    path.write_bytes(path.read_bytes()[:100])
    again = StageCache(tmp_path / "cache")
    assert again.load(cache_key(pipeline, video, registry), video.n_frames, video.name) is None
    Engine(pipeline, registry).run_video(video, cache=again)
    assert again.stores == 1
    assert (
        StageCache(tmp_path / "cache").load(
            cache_key(pipeline, video, registry), video.n_frames, video.name
        )
        is not None
    )


def test_key_follows_files_a_stage_reads_without_naming_them(small_dataset, tmp_path: Path) -> None:
    from types import ModuleType

    from trackfw.hookspecs import hookimpl
    from trackfw.records import ClassifierDecision
    from trackfw.stages import Classifier, StageParams

    shipped = tmp_path / "shipped.json"
    shipped.write_text("{}")

    class ShippedModelClassifier(Classifier):
        """Reads a model file that no parameter names (like a shipped model)."""

        name = "shipped-model"

        @classmethod
        def resource_files(cls, params: StageParams) -> list[Path]:
            return [shipped]

        def classify(self, frame, detections):  # type: ignore[no-untyped-def]
            return ClassifierDecision(0.0, False)

    module = ModuleType("shipped_plugin")

    @hookimpl
    def trackfw_register_stages(registry):  # type: ignore[no-untyped-def]
        registry.add_classifier(ShippedModelClassifier)

    module.trackfw_register_stages = trackfw_register_stages  # type: ignore[attr-defined]
    registry = load_registry(extra_modules=[("shipped", module)])
    spec = {
        **PIPELINE,
        "stages": {
            **PIPELINE["stages"],
            "detector": {"type": "oracle"},
            "classifier": {"type": "shipped-model"},
        },
    }
    pipeline = validate_pipeline(spec, registry)
    video = load_video(small_dataset(count=1) / "v0")
    before = cache_key(pipeline, video, registry)
    assert cache_key(pipeline, video, registry) == before
    shipped.write_text('{"retrained": true}')
    assert cache_key(pipeline, video, registry) != before
