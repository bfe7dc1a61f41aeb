"""A job that kills its worker process fails alone; the other jobs complete (local pool)."""

from __future__ import annotations

from pathlib import Path

from trackfw.registry import load_registry
from trackfw_plugins.bench.executor import ExecutorOptions, make_executor
from trackfw_plugins.bench.sweep import plan_sweep, run_sweep


def test_a_job_that_kills_its_worker_is_retried_then_recorded(
    bench_plugin, bench_pipeline, small_dataset, tmp_path: Path
) -> None:
    dataset = small_dataset(count=3, n_frames=100)
    registry = load_registry()
    plan = plan_sweep(
        registry, [bench_pipeline("crashing", crash_on="v1")], dataset, tmp_path / "out"
    )
    executor = make_executor(registry, "local", ExecutorOptions(jobs=2, retries=1))
    result = run_sweep(plan, executor)
    by_video = {job.video: job for job in result.results}
    assert by_video["v1"].status == "failed"
    assert by_video["v1"].error_type == "WorkerLostError"
    assert "2 tries" in (by_video["v1"].error_message or "")
    assert by_video["v0"].status == "done" and by_video["v2"].status == "done"
