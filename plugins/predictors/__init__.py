"""Built-in motion predictors used by gap matchers."""

from __future__ import annotations

from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry

TRACKFW_PLUGIN_API = 1


@hookimpl
def trackfw_register_stages(registry: Registry) -> None:
    """Register the built-in predictors."""
    from trackfw_plugins.predictors.ar import ArPredictor
    from trackfw_plugins.predictors.camera_aware import CameraAwarePredictor
    from trackfw_plugins.predictors.kalman import KalmanPredictor

    registry.add_predictor(ArPredictor)
    registry.add_predictor(KalmanPredictor)
    registry.add_predictor(CameraAwarePredictor)
