"""trackfw bench: the table, skipping finished jobs, stage caching, failures, timeouts."""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import pytest

from trackfw.cli import main
from trackfw_plugins.evaluation.report import evaluate_dataset

REPO = Path(__file__).resolve().parents[3]
ORACLE_PIPELINES = [
    REPO / "pipelines" / "kalman1-tr-oracle.yaml",
    REPO / "pipelines" / "kalman2-ar-oracle.yaml",
]


def _table(out: Path) -> dict[str, dict[str, str]]:
    with (out / "table.csv").open() as stream:
        return {row["pipeline"]: row for row in csv.DictReader(stream)}


def _manifest(out: Path) -> dict:
    return json.loads((out / "manifest.json").read_text())


def test_bench_writes_the_table_and_a_rerun_skips_every_job(
    small_dataset, tmp_path: Path, capsys
) -> None:
    dataset = small_dataset()
    out = tmp_path / "out"
    arguments = [
        "bench",
        *map(str, ORACLE_PIPELINES),
        "--dataset",
        str(dataset),
        "--out",
        str(out),
        "-q",
    ]
    assert main(arguments) == 0
    printed = capsys.readouterr().out
    assert "| kalman1-tr-oracle | 2/2 |" in printed and "MOTA-In %" in printed
    for name in ("table.md", "table.csv", "table.png"):
        assert (out / name).stat().st_size > 0
    assert (out / "table.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((out / "failures.json").read_text()) == []
    table = _table(out)
    assert set(table) == {"kalman1-tr-oracle", "kalman2-ar-oracle"}
    # Each row is the evaluation plugin's mean over videos of that pipeline's runs folder.
    for name, row in table.items():
        runs = next((out / "runs").glob(f"{name}-*"))
        mean = evaluate_dataset(dataset, runs).mean_row()
        for metric in ("MOTA", "MOTP", "MOTA-In", "MOTP-In", "IDF1", "HOTA", "IL-F1"):
            assert float(row[metric]) == pytest.approx(mean[metric], rel=1e-5), (name, metric)
        assert row["videos_done"] == "2" and float(row["fps"]) > 0
        assert float(row["ms tracker"]) > 0
    counts = _manifest(out)["counts"]
    assert counts == {"done": 4, "skipped": 0, "failed": 0}
    # The two pipelines share detector and classifier: detection ran once per video.
    caches = sorted(job["cache"] for job in _manifest(out)["jobs"])
    assert caches == ["hit", "hit", "miss", "miss"]
    assert len(list((out / "cache").glob("*.npz"))) == 2

    summaries = sorted((out / "runs").glob("*/*/summary.json"))
    stamps = [path.stat().st_mtime_ns for path in summaries]
    assert main(arguments) == 0
    assert _manifest(out)["counts"] == {"done": 0, "skipped": 4, "failed": 0}
    assert [path.stat().st_mtime_ns for path in summaries] == stamps
    assert _table(out) == table


def test_changing_the_gap_matcher_replays_detection_from_the_cache(
    bench_plugin, bench_pipeline, small_dataset, tmp_path: Path
) -> None:
    dataset = small_dataset()
    pipeline = bench_pipeline("counting")
    out = tmp_path / "out"
    base = ["bench", str(pipeline), "--dataset", str(dataset), "--out", str(out), "-q"]
    assert main(base) == 0
    counter = sys.modules["trackfw_benchtest"]
    first_calls = counter.CALLS
    assert first_calls > 0
    assert [job["cache"] for job in _manifest(out)["jobs"]] == ["miss", "miss"]

    changed = [*base, "--set", "stages.gap_matcher.params.method=nearest"]
    assert main(changed) == 0
    assert first_calls == counter.CALLS  # the detector was not called again
    jobs = _manifest(out)["jobs"]
    assert [(job["status"], job["cache"]) for job in jobs] == [("done", "hit"), ("done", "hit")]
    assert len(list((out / "runs").glob("counting-*"))) == 2  # a new hash, a new runs folder

    # The replay gives what a run without the cache gives.
    fresh = tmp_path / "fresh"
    assert main([*changed[:5], str(fresh), "-q", "--no-cache", *changed[-2:]]) == 0
    assert not (fresh / "cache").exists()
    replayed_runs = max((out / "runs").glob("counting-*"), key=lambda p: p.stat().st_mtime_ns)
    fresh_runs = next((fresh / "runs").glob("counting-*"))
    assert replayed_runs.name == fresh_runs.name
    for video in ("v0", "v1"):
        assert (replayed_runs / video / "tracks.txt").read_text() == (
            fresh_runs / video / "tracks.txt"
        ).read_text()
    assert _table(out)["counting"]["MOTA"] == _table(fresh)["counting"]["MOTA"]


def test_a_failing_job_is_recorded_and_the_sweep_goes_on(
    bench_plugin, bench_pipeline, small_dataset, tmp_path: Path, capsys
) -> None:
    dataset = small_dataset()
    failing = bench_pipeline("failing", fail_on="v1")
    healthy = bench_pipeline("healthy")
    out = tmp_path / "out"
    code = main(
        ["bench", str(failing), str(healthy), "--dataset", str(dataset), "--out", str(out), "-q"]
    )
    assert code == 2
    failures = json.loads((out / "failures.json").read_text())
    assert [(f["pipeline"], f["video"], f["error_type"]) for f in failures] == [
        ("failing", "v1", "RuntimeError")
    ]
    assert "boom on v1" in failures[0]["error_message"]
    assert _manifest(out)["counts"] == {"done": 3, "skipped": 0, "failed": 1}
    table = _table(out)
    assert table["failing"]["videos_done"] == "1" and table["healthy"]["videos_done"] == "2"
    assert "| failing | 1/2 |" in capsys.readouterr().out
    # The failed job left no completion marker, so a rerun tries it again.
    assert not any((out / "runs").glob("failing-*/v1/summary.json"))


def test_a_job_past_its_time_limit_fails_with_a_timeout(
    bench_plugin, bench_pipeline, small_dataset, tmp_path: Path
) -> None:
    dataset = small_dataset(count=1, n_frames=200)
    slow = bench_pipeline("slow", sleep_ms=5)
    out = tmp_path / "out"
    code = main(
        ["bench", str(slow), "--dataset", str(dataset), "--out", str(out), "-q", "--timeout", "0.2"]
    )
    assert code == 2
    failures = json.loads((out / "failures.json").read_text())
    assert [f["error_type"] for f in failures] == ["JobTimeoutError"]
    assert "0.2 s" in failures[0]["error_message"]


def test_bad_input_is_reported_before_anything_is_written(
    small_dataset, tmp_path: Path, capsys
) -> None:
    dataset = small_dataset(count=1)
    out = tmp_path / "out"
    pipeline = str(ORACLE_PIPELINES[0])
    code = main(
        [
            "bench",
            pipeline,
            "--dataset",
            str(dataset),
            "--out",
            str(out),
            "--set",
            "nosuch:engine.box_size=3",
        ]
    )
    assert code == 2
    assert "no pipeline is named 'nosuch'" in capsys.readouterr().err
    code = main(
        ["bench", pipeline, "--dataset", str(dataset), "--out", str(out), "--executor", "dsak"]
    )
    assert code == 2
    assert "did you mean 'dask'" in capsys.readouterr().err
    assert not out.exists()


def test_per_pipeline_overrides_apply_to_the_named_pipeline_only(
    small_dataset, tmp_path: Path
) -> None:
    from trackfw.registry import load_registry
    from trackfw_plugins.bench.sweep import plan_sweep

    dataset = small_dataset(count=1)
    plan = plan_sweep(
        load_registry(),
        [*ORACLE_PIPELINES, REPO / "pipelines" / "proposed-oracle.yaml"],
        dataset,
        tmp_path / "out",
        [
            "proposed-oracle:stages.gap_matcher.params.lambda2=0",
            "proposed-oracle:stages.tracker.params.appearance.descriptor=none",
            "engine.box_size=60",
        ],
    )
    configs = {entry.pipeline.name: entry.pipeline for entry in plan.pipelines}
    assert configs["proposed-oracle"].stages["gap_matcher"].params.lambda2 == 0
    assert all(pipeline.engine.box_size == 60 for pipeline in configs.values())
    assert len(plan.jobs) == 3 and not (tmp_path / "out").exists()


def test_a_shared_cache_dir_serves_another_output_folder(small_dataset, tmp_path: Path) -> None:
    dataset = small_dataset(count=1)
    cache = tmp_path / "shared-cache"
    pipeline = str(ORACLE_PIPELINES[0])
    for out in (tmp_path / "first", tmp_path / "second"):
        arguments = ["bench", pipeline, "--dataset", str(dataset), "--out", str(out), "-q"]
        assert main([*arguments, "--cache-dir", str(cache)]) == 0
        assert not (out / "cache").exists()
    assert [job["cache"] for job in _manifest(tmp_path / "first")["jobs"]] == ["miss"]
    assert [job["cache"] for job in _manifest(tmp_path / "second")["jobs"]] == ["hit"]
    assert len(list(cache.glob("v0-*.npz"))) == 1


def test_a_batch_row_replays_the_detections_a_segment_row_recorded(
    bench_plugin, bench_pipeline, small_dataset, tmp_path: Path
) -> None:
    # Table 1 puts batch trackers (no classifier) beside segment pipelines with the same
    # detector: the detector runs once per video, and the batch row replays what it found.
    dataset = small_dataset(count=2)
    segment = bench_pipeline("counting")
    batch = tmp_path / "pipelines" / "batch.yaml"
    batch.write_text(
        "name: batch\nstages:\n  detector: {type: bench-test}\n  batch_tracker: {type: dpnms}\n"
    )
    together, alone = tmp_path / "together", tmp_path / "alone"
    arguments = ["--dataset", str(dataset), "-q", "--jobs", "1"]
    assert main(["bench", str(batch), str(segment), "--out", str(together), *arguments]) == 0
    states = {(job["pipeline"], job["cache"]) for job in _manifest(together)["jobs"]}
    assert states == {("batch", "hit"), ("counting", "miss")}
    assert main(["bench", str(batch), "--out", str(alone), *arguments]) == 0
    assert [job["cache"] for job in _manifest(alone)["jobs"]] == ["miss", "miss"]
    for video in ("v0", "v1"):
        replayed = next((together / "runs").glob(f"batch-*/{video}/tracks.txt")).read_text()
        computed = next((alone / "runs").glob(f"batch-*/{video}/tracks.txt")).read_text()
        assert replayed == computed and replayed
