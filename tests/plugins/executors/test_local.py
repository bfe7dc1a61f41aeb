"""The local executor and the executor hook."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry, load_registry
from trackfw_plugins.bench.executor import ExecutorOptions
from trackfw_plugins.bench.jobs import Job, run_job


def test_builtin_executors_register_through_the_hook() -> None:
    registry = load_registry()
    assert not registry.failures, registry.failures
    assert {"local", "dask"} <= set(registry.executors)
    assert registry.executors["local"].source.package == "trackfw"


def test_a_process_pool_gives_the_in_process_results(sweep, tmp_path: Path) -> None:
    serial, serial_rows = sweep(tmp_path / "serial", jobs=1)
    pooled, pooled_rows = sweep(tmp_path / "pooled", jobs=2)
    assert pooled.count("done") == 4 and not pooled.failures
    assert pooled_rows == serial_rows
    workers = {result.worker for result in pooled.results}
    assert all(int(worker.rsplit(":", 1)[1]) != os.getpid() for worker in workers)
    assert {result.worker for result in serial.results} == {f"{os.uname().nodename}:{os.getpid()}"}


class ReverseExecutor:
    """A third-party executor: runs the jobs in reverse order, in this process."""

    def __init__(self, options: ExecutorOptions) -> None:
        self.options = options
        self.seen: list[str] = []

    def run(self, jobs: Sequence[Job], on_result) -> None:
        for job in reversed(jobs):
            self.seen.append(job.label)
            on_result(run_job(job, self.options.registry))


def _plugin(broken: bool = False) -> ModuleType:
    module = ModuleType("reverse_plugin")

    @hookimpl
    def trackfw_register_executors(registry: Registry) -> None:
        registry.add_executor("reverse", ReverseExecutor)
        if broken:
            raise RuntimeError("broken after registering")

    module.trackfw_register_executors = trackfw_register_executors  # type: ignore[attr-defined]
    return module


def test_a_third_party_executor_runs_the_sweep(sweep, tmp_path: Path) -> None:
    registry = load_registry(extra_modules=[("reverse", _plugin())])
    assert registry.executors["reverse"].factory is ReverseExecutor
    result, rows = sweep(tmp_path / "reverse", executor="reverse", registry=registry)
    assert result.count("done") == 4
    _, local_rows = sweep(tmp_path / "local")
    assert rows == local_rows


def test_an_executor_hook_that_raises_is_recorded_and_rolled_back() -> None:
    registry = load_registry(extra_modules=[("reverse", _plugin(broken=True))])
    assert "reverse" not in registry.executors
    assert any("trackfw_register_executors failed" in f.error for f in registry.failures)
    assert "local" in registry.executors
