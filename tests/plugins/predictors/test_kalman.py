"""Tests of the Kalman "TR" predictor."""

from __future__ import annotations

import numpy as np

from trackfw.records import Detections, GapProblem, Interval, TargetState, VideoContext
from trackfw_plugins.predictors.kalman import KalmanPredictor


def test_constant_velocity_extrapolation_and_missing_velocity() -> None:
    states = [
        TargetState(target_id=1, position=np.array([10.0, 20.0]), velocity=np.array([1.5, -2.0])),
        TargetState(target_id=2, position=np.array([300.0, 40.0]), velocity=None),
    ]
    problem = GapProblem(
        interval=Interval(a=10, b=35),
        target_ids=np.array([1, 2], dtype=np.int64),
        histories=[np.array([[10.0, 20.0]]), np.array([[300.0, 40.0]])],
        states=states,
        detections=Detections.empty(),
        frame_a=None,
        frame_b=None,
        video=VideoContext(name="v", path="v", n_frames=100, width=640, height=480),
    )
    predictions = KalmanPredictor().predict(problem)
    assert len(predictions) == 1
    assert predictions[0].label == "kalman"
    np.testing.assert_allclose(
        predictions[0].positions, [[10.0 + 25 * 1.5, 20.0 - 25 * 2.0], [300.0, 40.0]]
    )
