"""``trackfw bench``: the benchmark table across pipelines, as resumable, cached sweeps.

* :mod:`trackfw.bench.jobs`: a job (one pipeline over one video), :func:`run_job`, results;
* :mod:`trackfw.bench.sweep`: planning, scheduling, failures.json and manifest.json;
* :mod:`trackfw.bench.executor`: the executor interface (plugins register executors through the
  ``trackfw_register_executors`` hook);
* :mod:`trackfw.bench.report`: the table (Markdown, CSV, PNG);
* :mod:`trackfw.stage_cache` (core): the detector and classifier outputs the jobs share.
"""

from trackfw.bench.executor import Executor, ExecutorOptions, make_executor
from trackfw.bench.jobs import Job, JobResult, JobTimeoutError, is_done, pin_threads, run_job
from trackfw.bench.sweep import SweepPlan, SweepResult, plan_sweep, run_sweep

__all__ = [
    "Executor",
    "ExecutorOptions",
    "Job",
    "JobResult",
    "JobTimeoutError",
    "SweepPlan",
    "SweepResult",
    "is_done",
    "make_executor",
    "pin_threads",
    "plan_sweep",
    "run_job",
    "run_sweep",
]
