"""Executors for ``trackfw bench``: ``local`` (a process pool) and ``dask`` (Dask distributed).

The ``trackfw bench`` command itself comes with the bench plugin (:mod:`trackfw_plugins.bench`).
The executor classes are imported only when one is built, so loading the plugin stays cheap (and
``dask`` is needed only when it is used).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from trackfw.hookspecs import hookimpl

if TYPE_CHECKING:
    from trackfw.registry import Registry
    from trackfw_plugins.bench.executor import ExecutorOptions

TRACKFW_PLUGIN_API = 1


def local_executor(options: ExecutorOptions) -> Any:
    """The ``local`` executor: in this process for one job at a time, else a process pool."""
    from trackfw_plugins.executors.local import LocalExecutor

    return LocalExecutor(options)


def dask_executor(options: ExecutorOptions) -> Any:
    """The ``dask`` executor: a LocalCluster, or the scheduler at ``--address``."""
    from trackfw_plugins.executors.dask import DaskExecutor

    return DaskExecutor(options)


@hookimpl
def trackfw_register_executors(registry: Registry) -> None:
    """Register ``local`` and ``dask``."""
    registry.add_executor("local", local_executor)
    registry.add_executor("dask", dask_executor)
