"""Executors run the jobs of a sweep: in this process, in a process pool, on a Dask cluster.

An executor is registered by a plugin through the ``trackfw_register_executors`` hook
(``registry.add_executor(name, cls_or_factory)``); ``trackfw bench --executor NAME`` picks it.
The built-in ``local`` and ``dask`` executors live in ``trackfw_plugins.executors``.

The contract: :meth:`Executor.run` calls ``on_result`` exactly once per job, in this process,
with the :class:`~trackfw_plugins.bench.jobs.JobResult` of :func:`~trackfw_plugins.bench.jobs.run_job` (which
never raises for a job's own failure). When the infrastructure loses a job (a worker process
dies, a cluster drops it after its retries), the executor reports a failed result for it
(:meth:`JobResult.failure`) rather than raising, so the sweep goes on. A sweep may call ``run``
more than once (in waves); an optional ``close()`` is called once at its end.
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from trackfw.errors import UserError
from trackfw_plugins.bench.jobs import Job, JobResult

if TYPE_CHECKING:
    from trackfw.registry import Registry

ResultCallback = Callable[[JobResult], None]


@dataclass(frozen=True)
class ExecutorOptions:
    """Options every executor receives.

    Attributes:
        jobs: how many jobs may run at once (worker processes of the local pool, workers of a
            Dask LocalCluster); 1 runs jobs one after the other.
        address: address of an existing scheduler (``tcp://host:8786``), or None.
        retries: how many times a job whose worker was lost is tried again.
        registry: the caller's plugin registry, for executors that run jobs in this process.
    """

    jobs: int = 1
    address: str | None = None
    retries: int = 1
    registry: Registry | None = None


class Executor(abc.ABC):
    """Base class of executors (subclassing it is optional: ``run`` is all that is called)."""

    name: ClassVar[str] = ""

    def __init__(self, options: ExecutorOptions) -> None:
        self.options = options

    @abc.abstractmethod
    def run(self, jobs: Sequence[Job], on_result: ResultCallback) -> None:
        """Run every job; call ``on_result`` once per job as its result arrives."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """Release workers; called once after the sweep's last ``run`` (optional)."""


def make_executor(registry: Registry, name: str, options: ExecutorOptions) -> Any:
    """Build the executor registered as ``name``.

    Raises:
        UserError: no such executor, or it cannot start (a missing optional dependency, an
            unreachable scheduler).
    """
    try:
        entry = registry.get_executor(name)
    except KeyError as error:
        raise UserError(f"--executor: {error.args[0]}.") from None
    executor = entry.factory(options)
    if not callable(getattr(executor, "run", None)):
        raise UserError(
            f"--executor {name}: the plugin {entry.source.package} returned {executor!r},"
            " expected an object with a run(jobs, on_result) method."
        )
    return executor


__all__ = ["Executor", "ExecutorOptions", "ResultCallback", "make_executor"]
