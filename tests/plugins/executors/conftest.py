"""A small point-only dataset and a helper that runs a sweep with a given executor."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from trackfw.registry import Registry, load_registry
from trackfw_plugins.bench.executor import ExecutorOptions, make_executor
from trackfw_plugins.bench.report import build_table
from trackfw_plugins.bench.sweep import SweepResult, plan_sweep, run_sweep
from trackfw_plugins.datasets.points import make_points_video

REPO = Path(__file__).resolve().parents[3]
PIPELINES = [
    REPO / "pipelines" / "kalman1-tr-oracle.yaml",
    REPO / "pipelines" / "kalman2-ar-oracle.yaml",
]


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("executors") / "dataset"
    for index in range(2):
        make_points_video(
            root / f"v{index}",
            n_frames=100,
            n_targets=5,
            n_others=2,
            intervals=[(30, 45)],
            seed=index,
        )
    return root


@pytest.fixture
def sweep(dataset: Path) -> Callable[..., tuple[SweepResult, list[list[str]]]]:
    """Run the two oracle pipelines with an executor; returns the sweep and its quality rows."""

    def run(
        out: Path, executor: str = "local", jobs: int = 1, registry: Registry | None = None
    ) -> tuple[SweepResult, list[list[str]]]:
        registry = registry or load_registry()
        plan = plan_sweep(registry, PIPELINES, dataset, out)
        runner = make_executor(registry, executor, ExecutorOptions(jobs=jobs, registry=registry))
        result = run_sweep(plan, runner, executor_name=executor)
        rows = [
            [
                row.pipeline,
                *(f"{row.value(m):.6f}" for m in ("MOTA", "MOTP", "MOTA-In", "IDF1", "HOTA")),
            ]
            for row in build_table(plan)
        ]
        return result, rows

    return run
