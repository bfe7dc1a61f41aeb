"""Built-in motion predictors used by gap matchers."""

from __future__ import annotations

from trackfw.registry import stage_modules

TRACKFW_PLUGIN_API = 1

trackfw_register_stages = stage_modules(__name__, "ar", "kalman", "camera_aware")
