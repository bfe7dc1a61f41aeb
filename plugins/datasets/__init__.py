"""Datasets: the bundled demo input and the ``trackfw dataset`` commands."""

from __future__ import annotations

from typing import Any

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_inputs(registry: Registry) -> None:
    """Register ``builtin:demo``."""
    from trackfw_plugins.datasets.demo import demo_path

    registry.add_input(
        "demo",
        demo_path,
        "a short synthetic wearable-camera clip with ground truth (generated on first use)",
    )


@hookimpl
def trackfw_register_commands(app: Any) -> None:
    """Add the ``dataset`` command group."""
    from trackfw.cli import command_group
    from trackfw_plugins.datasets import check, wear_cli
    from trackfw_plugins.datasets.synth import cli as synth_cli

    dataset_app = command_group(app, "dataset", "Make or check a wearable-camera dataset.")
    synth_cli.register(dataset_app)
    wear_cli.register(dataset_app)
    check.register(dataset_app)
