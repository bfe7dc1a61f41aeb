"""Built-in gap matchers."""

from __future__ import annotations

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Register the built-in gap matchers."""
    from trackfw_plugins.gap_matchers.assignment import AssignmentGapMatcher
    from trackfw_plugins.gap_matchers.reid import ReidGapMatcher
    from trackfw_plugins.gap_matchers.tps_rpm import TpsRpmGapMatcher
    from trackfw_plugins.gap_matchers.window_tps_rpm import WindowTpsRpmGapMatcher

    registry.add_gap_matcher(AssignmentGapMatcher)
    registry.add_gap_matcher(ReidGapMatcher)
    registry.add_gap_matcher(TpsRpmGapMatcher)
    registry.add_gap_matcher(WindowTpsRpmGapMatcher)
