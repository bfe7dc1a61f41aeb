"""Camera-aware predictor: AR candidates, the same carried through a scene registration, and
the Kalman continuity candidate.

See docs/algorithms/predictors.md#camera-aware-predictor.

The paper's AR candidates keep frame a's image geometry (the camera change is unknown). Two more
kinds of candidate say where the pattern lies on frame b, each with a gate:

* ``reg-ar{k}``: AR order k forecast on frame a, mapped to frame b by the camera motion that the
  static scene of frames a and b shows (:mod:`trackfw_plugins.maths.scene_registration`); absent
  when the registration fails;
* ``reg-walk``: each target's own walk, measured between the segment's look-back frame and
  frame a after registering the one onto the other (so the camera's sway drops out), carried
  on to b at constant velocity and mapped to frame b by the same registration as ``reg-ar``;
* ``continuity``: the Kalman prediction, for a camera that barely moved (short or false
  intervals).

The gap matcher scores every candidate with one cost, so a wrong registration or a moved camera
simply loses; this predictor never chooses.
"""

from __future__ import annotations

from collections.abc import Sequence

from pydantic import Field

from trackfw.arrays import FloatArray
from trackfw.records import GapProblem, Prediction
from trackfw.stages import Predictor, StageParams
from trackfw_plugins.maths.scene_registration import (
    RegistrationSettings,
    SceneFeatures,
    register_features,
    scene_features,
)
from trackfw_plugins.predictors.ar import ArParams, ArPredictor
from trackfw_plugins.predictors.kalman import KalmanPredictor


class CameraAwareParams(StageParams):
    """Parameters of the camera-aware predictor (docs/algorithms/predictors.md#parameters-1)."""

    ar: ArParams = Field(
        default_factory=lambda: ArParams(series="position"),
        description="the AR predictor's parameters (orders, series, ...)",
    )
    free_ar: bool = Field(
        True, description="offer the AR candidates in frame a's geometry (the paper's)"
    )
    registration: bool = Field(
        True, description="offer the AR candidates mapped through the scene registration"
    )
    scene: RegistrationSettings = Field(
        # SIFT + homography: ORB found too few distinctive matches on the weakly textured,
        # tiled ground of the synthetic scenes; a pure camera rotation is a homography.
        default_factory=lambda: RegistrationSettings(
            features="sift", max_features=4000, model="homography"
        ),
        description="scene registration settings",
    )
    registration_gate_at_1080: float = Field(
        100.0, gt=0, description="gate of the registered candidates in pixels at 1080p"
    )
    gate_per_frame_at_1080: float = Field(
        2.0,
        ge=0,
        description="both gates grow by this many pixels (at 1080p) per frame of the interval:"
        " the forecast's common error grows with the horizon",
    )
    walk: bool = Field(
        True,
        description="offer each target's own walk (look-back frame to a, the camera's sway"
        " registered out) carried to b and through the scene registration",
    )
    continuity: bool = Field(
        True, description="offer the Kalman prediction as a positioned candidate"
    )
    continuity_gate_at_1080: float = Field(
        80.0, gt=0, description="gate of the continuity candidate in pixels at 1080p"
    )


def walked_forecast(
    problem: GapProblem, features_a: SceneFeatures, scene: RegistrationSettings
) -> FloatArray | None:
    """``(K, 2)`` where each target would stand on frame a's geometry at b, walking on as it
    walked from the look-back frame to a.

    Image positions mix the walker's motion with the camera's sway; registering the look-back
    frame's scene onto frame a and mapping its positions first leaves the walk alone (on TUD
    virtual-wearer gaps a constant-velocity walk measured this way came within 11 px of the
    head at b, median, against 35 px for the AR forecasts of the raw positions).

    Args:
        problem: the gap problem (its look-back frame and positions at a).
        features_a: frame a's scene features (found once for this and the a -> b registration).
        scene: the registration settings.

    Returns:
        None without a look-back frame with pixels, or when it does not register onto a.
    """
    lookback = problem.lookback
    if lookback is None or lookback.image is None:
        return None
    steps = problem.interval.a - lookback.t
    if steps <= 0:
        return None
    registration = register_features(
        scene_features(lookback.image, lookback.detections.boxes, scene), features_a, scene
    )
    if not registration.ok:
        return None
    at_a = problem.positions_at_a
    velocity = registration.walks(lookback.positions, at_a, steps)
    result: FloatArray = at_a + velocity * problem.horizon
    return result


class CameraAwarePredictor(Predictor[CameraAwareParams]):
    """AR candidates, AR through the scene registration a -> b, and Kalman continuity."""

    name = "camera-aware"
    uses_pixels = True

    def __init__(self, params: CameraAwareParams | None = None) -> None:
        super().__init__(params)
        self._ar = ArPredictor(self.params.ar)
        self._kalman = KalmanPredictor()

    def predict(self, problem: GapProblem) -> Sequence[Prediction]:
        """The candidates, free ones first (ties go to the paper's AR order).

        Returns:
            ``ar{k}`` (gate None) when ``free_ar``; ``reg-ar{k}`` (gated, with the registration
            in ``diagnostics["registration"]``) when the registration succeeds; ``continuity``
            (gated) when ``continuity``. A failed registration is recorded on the first
            candidate.
        """
        params = self.params
        scale = problem.video.height / 1080.0
        growth = params.gate_per_frame_at_1080 * problem.horizon
        forecasts = list(self._ar.predict(problem))
        candidates = list(forecasts) if params.free_ar else []
        registration = None
        if params.registration and problem.frame_a is not None and problem.frame_b is not None:
            boxes_a = problem.detections_a.boxes if problem.detections_a is not None else None
            features_a = scene_features(problem.frame_a, boxes_a, params.scene)
            registration = register_features(
                features_a,
                scene_features(problem.frame_b, problem.detections.boxes, params.scene),
                params.scene,
            )
            if registration.ok:
                summary = registration.summary()
                candidates += [
                    Prediction(
                        label=f"reg-{forecast.label}",
                        positions=registration.apply(forecast.positions),
                        diagnostics={**forecast.diagnostics, "registration": summary},
                        gate=(params.registration_gate_at_1080 + growth) * scale,
                    )
                    for forecast in forecasts
                ]
                walked = walked_forecast(problem, features_a, params.scene) if params.walk else None
                if walked is not None:
                    candidates.append(
                        Prediction(
                            label="reg-walk",
                            positions=registration.apply(walked),
                            diagnostics={"registration": summary},
                            gate=(params.registration_gate_at_1080 + growth) * scale,
                        )
                    )
        if params.continuity:
            (kalman,) = self._kalman.predict(problem)
            candidates.append(
                Prediction(
                    label="continuity",
                    positions=kalman.positions,
                    gate=(params.continuity_gate_at_1080 + growth) * scale,
                )
            )
        if not candidates:
            candidates = forecasts
        if registration is not None and not registration.ok:
            candidates[0].diagnostics["registration"] = registration.summary()
        return candidates
