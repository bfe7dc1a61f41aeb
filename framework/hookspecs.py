"""The hooks a trackfw plugin may implement.

A plugin is a module exposed through the ``trackfw`` entry-point group. It implements any of the
hooks below with the :data:`hookimpl` marker::

    from trackfw.hookspecs import hookimpl

    @hookimpl
    def trackfw_register_stages(registry):
        registry.add_detector(MyDetector)

Every hook is documented in ``docs/plugins.md``; a test fails when one is missing there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    from trackfw.registry import Registry

PROJECT_NAME = "trackfw"

hookspec = pluggy.HookspecMarker(PROJECT_NAME)
hookimpl = pluggy.HookimplMarker(PROJECT_NAME)


@hookspec
def trackfw_register_stages(registry: Registry) -> None:
    """Register stage classes.

    Call ``registry.add_detector``, ``add_classifier``, ``add_tracker``, ``add_gap_matcher``,
    ``add_predictor`` or ``add_batch_tracker`` with each class. A class must subclass the matching
    base in :mod:`trackfw.stages`, set a unique ``name`` and a ``Params`` model.

    A batch tracker (:class:`trackfw.stages.BatchTracker`) replaces the segment tracker, the
    classifier and the gap matcher of a pipeline: its ``track(detections, video)`` gets every
    frame's detections of a video at once and returns :class:`trackfw.records.Tracks` with
    identities of its own.
    """


@hookspec
def trackfw_register_inputs(registry: Registry) -> None:
    """Register named inputs that pipelines may use as ``input: builtin:NAME``.

    Call ``registry.add_input(name, factory, description)``; ``factory()`` returns the path of a
    video or dataset folder, creating it on first use if needed (deterministically, no download).
    """


@hookspec
def trackfw_register_commands(app: Any) -> None:
    """Add sub-commands to the ``trackfw`` command line.

    ``app`` is the root :class:`typer.Typer`; add commands or groups to it
    (``app.add_typer(group, name="dataset")``). Keep imports inside the command functions so that
    ``trackfw --help`` stays fast.
    """


@hookspec
def trackfw_register_executors(registry: Registry) -> None:
    """Register executors that run the jobs of ``trackfw bench`` (``--executor NAME``).

    Call ``registry.add_executor(name, cls_or_factory)``. ``cls_or_factory(options)`` receives a
    :class:`trackfw_plugins.bench.executor.ExecutorOptions` and returns an object with a
    ``run(jobs, on_result)`` method (:class:`trackfw_plugins.bench.executor.Executor`): it runs every
    :class:`trackfw_plugins.bench.jobs.Job` through :func:`trackfw_plugins.bench.jobs.run_job`, wherever it likes,
    and calls ``on_result`` with each :class:`trackfw_plugins.bench.jobs.JobResult` as it arrives.
    """
