"""``trackfw bench``: the benchmark table across pipelines, as resumable, cached sweeps.

A plugin package (entry point ``bench``) that depends on the evaluation plugin for the metrics:

* :mod:`trackfw_plugins.bench.jobs`: a job (one pipeline over one video), :func:`run_job`, results;
* :mod:`trackfw_plugins.bench.sweep`: planning, scheduling, failures.json and manifest.json;
* :mod:`trackfw_plugins.bench.executor`: the executor interface (plugins register executors through
  the ``trackfw_register_executors`` hook; ``local`` and ``dask`` come with the executors plugin);
* :mod:`trackfw_plugins.bench.report`: the table (Markdown, CSV, PNG), from
  :mod:`trackfw_plugins.evaluation`;
* :mod:`trackfw.stage_cache` (core): the detector and classifier outputs the jobs share.

Only the hook is defined here, so that loading the plugin (every ``trackfw`` command) stays cheap.
"""

from __future__ import annotations

from typing import Any

from trackfw.hookspecs import hookimpl

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_commands(app: Any) -> None:
    """Add ``trackfw bench``."""
    from trackfw_plugins.bench.cli import register

    register(app)
