"""Built-in trackers: the segment tracker, and the batch trackers of ``trackfw_plugins.batch_trackers``.

The batch trackers register here, through the existing ``trackers`` entry point, so that an
installation made before they existed finds them without reinstalling.
"""

from __future__ import annotations

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Register the built-in segment and batch trackers."""
    from trackfw_plugins.batch_trackers.stages import BATCH_TRACKERS
    from trackfw_plugins.trackers.kalman import KalmanTracker

    registry.add_tracker(KalmanTracker)
    for tracker in BATCH_TRACKERS:
        registry.add_batch_tracker(tracker)
