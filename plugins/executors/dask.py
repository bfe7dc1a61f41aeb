"""The ``dask`` executor (optional extra ``trackfw[dask]``): Dask distributed.

Without ``--address`` a :class:`distributed.LocalCluster` of ``--jobs`` worker processes (one
thread each) is started for the sweep and stopped after it; with ``--address`` the jobs go to an
existing scheduler, whose workers must have trackfw and the same plugins installed and see the
dataset and output folders at the same paths. A job whose worker is lost is rescheduled by Dask
(``retries``: the scheduler's allowed failures for a LocalCluster, task retries always); one
lost too often is reported as failed.
"""

from __future__ import annotations

import logging
import uuid
from collections.abc import Sequence
from typing import Any

from trackfw.errors import UserError
from trackfw_plugins.bench.executor import Executor, ExecutorOptions, ResultCallback
from trackfw_plugins.bench.jobs import Job, JobResult, pin_threads, run_job


class DaskExecutor(Executor):
    """Runs jobs on a Dask cluster."""

    name = "dask"

    def __init__(self, options: ExecutorOptions) -> None:
        super().__init__(options)
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise UserError(
                "--executor dask needs Dask distributed, the optional extra: pip install 'trackfw[dask]'."
            ) from None
        self._client: Any = None
        self._cluster: Any = None

    def _connect(self) -> Any:
        if self._client is not None:
            return self._client
        import dask
        from distributed import Client, LocalCluster

        if self.options.address:
            try:
                self._client = Client(self.options.address, timeout="20s")
            except (OSError, TimeoutError) as error:
                raise UserError(
                    f"--address {self.options.address}: cannot reach the Dask scheduler ({error})."
                ) from None
        else:
            config = {"distributed.scheduler.allowed-failures": max(0, self.options.retries)}
            with dask.config.set(config):
                self._cluster = LocalCluster(
                    n_workers=max(1, self.options.jobs),
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                )
            self._client = Client(self._cluster)
        self._client.run(pin_threads)
        return self._client

    def run(self, jobs: Sequence[Job], on_result: ResultCallback) -> None:
        """Submit every job and report each result as it completes."""
        from distributed import as_completed

        if not jobs:
            return
        client = self._connect()
        batch = uuid.uuid4().hex[:8]
        futures: list[Any] = []
        by_key: dict[str, Job] = {}
        for job in jobs:
            key = f"trackfw-bench-{batch}-{len(futures)}"
            futures.append(
                client.submit(run_job, job, key=key, pure=False, retries=self.options.retries)
            )
            by_key[key] = job
        for future in as_completed(futures):
            job = by_key[future.key]
            try:
                result = future.result()
            except Exception as error:  # KilledWorker, a lost connection, a cancelled task
                result = JobResult.failure(job, error)
            if not isinstance(result, JobResult):
                result = JobResult.failure(job, TypeError(f"a worker returned {result!r}"))
            on_result(result)

    def close(self) -> None:
        """Disconnect; stop the LocalCluster if this executor started it."""
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None
