"""The ``local`` executor: jobs in this process, or in a pool of worker processes.

Workers are started with ``spawn`` (no state forked from the parent) and pinned to one thread
per library (:func:`trackfw_plugins.bench.jobs.pin_threads`), so ``--jobs N`` means N busy cores. The
pool lives until :meth:`LocalExecutor.close`, across the waves of a sweep.
"""

from __future__ import annotations

import multiprocessing
from collections import deque
from collections.abc import Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from trackfw_plugins.bench.executor import Executor, ExecutorOptions, ResultCallback
from trackfw_plugins.bench.jobs import Job, JobResult, pin_threads, run_job


class WorkerLostError(RuntimeError):
    """A worker process died (killed, out of memory, a crash in native code) during a job."""


class LocalExecutor(Executor):
    """Runs jobs in this process (``jobs == 1``) or in a process pool of ``jobs`` workers."""

    name = "local"

    def __init__(self, options: ExecutorOptions) -> None:
        super().__init__(options)
        self._pool: ProcessPoolExecutor | None = None

    def _get_pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(
                max_workers=self.options.jobs,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=pin_threads,
            )
        return self._pool

    def run(self, jobs: Sequence[Job], on_result: ResultCallback) -> None:
        """Run every job; a job lost with its worker is retried ``options.retries`` times.

        At most ``jobs`` jobs are handed to the pool at a time, so when a worker dies only the
        jobs in flight are suspects. A suspect is retried alone: a job that kills its worker
        again is reported as failed, the others complete.
        """
        if self.options.jobs <= 1:
            for job in jobs:
                on_result(run_job(job, self.options.registry))
            return
        attempts = {job.label: 0 for job in jobs}
        queue = deque(jobs)
        in_flight: dict[Future[JobResult], Job] = {}
        try:
            while queue or in_flight:
                pool = self._get_pool()
                while queue and len(in_flight) < self.options.jobs:
                    suspect = attempts[queue[0].label] > 0
                    if suspect and in_flight:
                        break
                    job = queue.popleft()
                    in_flight[pool.submit(run_job, job)] = job
                    if suspect:
                        break
                done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                broken = any(isinstance(f.exception(), BrokenProcessPool) for f in done)
                if broken:
                    wait(in_flight)  # every job in flight fails with the pool
                    done = set(in_flight)
                for future in done:
                    job = in_flight.pop(future)
                    error = future.exception()
                    if isinstance(error, BrokenProcessPool):
                        attempts[job.label] += 1
                        if attempts[job.label] <= self.options.retries:
                            queue.appendleft(job)
                            continue
                        lost = WorkerLostError(
                            f"the worker process died during the job ({attempts[job.label]} tries)"
                        )
                        on_result(JobResult.failure(job, lost))
                    elif error is not None:  # the job could not be sent or received
                        on_result(JobResult.failure(job, error))
                    else:
                        on_result(future.result())
                if broken:
                    self.close()  # a broken pool cannot be reused
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Stop the worker processes."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
