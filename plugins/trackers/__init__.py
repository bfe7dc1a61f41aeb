"""Built-in segment trackers."""

from __future__ import annotations

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Register the built-in trackers."""
    from trackfw_plugins.trackers.kalman import KalmanTracker

    registry.add_tracker(KalmanTracker)
