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

    registry.add_gap_matcher(AssignmentGapMatcher)
    registry.add_gap_matcher(ReidGapMatcher)
