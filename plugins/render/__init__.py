"""``trackfw render``: a video of a run with tracks, identities and info-less intervals drawn."""

from __future__ import annotations

from typing import Any

from trackfw.hookspecs import hookimpl

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_commands(app: Any) -> None:
    """Add ``trackfw render``."""
    from trackfw_plugins.render.cli import register

    register(app)
