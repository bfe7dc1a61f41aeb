"""Tests of the AR predictor stage."""

from __future__ import annotations

import json

import numpy as np
import pydantic
import pytest

from trackfw.records import Detections, GapProblem, Interval, TargetState, VideoContext
from trackfw_plugins.predictors.ar import ArPredictor


def _problem(histories: list[np.ndarray], a: int = 50, b: int = 80) -> GapProblem:
    return GapProblem(
        interval=Interval(a=a, b=b),
        target_ids=np.array([7, 3, 11][: len(histories)], dtype=np.int64),
        histories=histories,
        states=[TargetState(target_id=0, position=history[-1]) for history in histories],
        detections=Detections.empty(),
        frame_a=None,
        frame_b=None,
        video=VideoContext(name="v", path="v", n_frames=200, width=1920, height=1080),
    )


def test_one_prediction_per_order_with_fallbacks() -> None:
    moving = np.cumsum(np.tile([2.0, 1.0], (30, 1)), axis=0)
    short = np.array([[10.0, 10.0], [12.0, 11.0]])
    single = np.array([[5.0, 5.0]])
    predictions = ArPredictor().predict(_problem([moving, short, single]))
    assert [prediction.label for prediction in predictions] == ["ar1", "ar2", "ar3"]
    for prediction in predictions:
        assert prediction.positions.shape == (3, 2)
        np.testing.assert_allclose(prediction.positions[0], moving[-1] + 30 * np.array([2.0, 1.0]))
        np.testing.assert_allclose(prediction.positions[1], [72.0, 41.0])
        np.testing.assert_allclose(prediction.positions[2], [5.0, 5.0])
        fallbacks = prediction.diagnostics["fallbacks"]
        assert fallbacks[3] == "constant_velocity"
        assert fallbacks[11] == "constant_position"
        json.dumps(prediction.diagnostics)
    assert [prediction.diagnostics["fallbacks"][7] for prediction in predictions] == [1, 2, 3]


def test_params_are_validated() -> None:
    assert ArPredictor.Params().orders == [1, 2, 3]
    with pytest.raises(pydantic.ValidationError):
        ArPredictor.Params(orders=[0])
    with pytest.raises(pydantic.ValidationError):
        ArPredictor.Params(orders=[11])
    with pytest.raises(pydantic.ValidationError):
        ArPredictor.Params(series="velocity")
    with pytest.raises(pydantic.ValidationError, match="shrink_to"):
        ArPredictor.Params(shrink_to=0.995)
    for name, field in ArPredictor.Params.model_fields.items():
        assert field.description, name


def test_max_history_parameter_reaches_the_forecast() -> None:
    rng = np.random.default_rng(8)
    history = np.cumsum(rng.normal(size=(100, 2)) + np.array([1.0, 0.5]), axis=0)
    capped = ArPredictor(ArPredictor.Params(orders=[2], max_history=20))
    full = ArPredictor(ArPredictor.Params(orders=[2], max_history=100))
    (on_capped,) = capped.predict(_problem([history], a=100, b=110))
    (on_truncated,) = full.predict(_problem([history[-20:]], a=100, b=110))
    (on_full,) = full.predict(_problem([history], a=100, b=110))
    np.testing.assert_array_equal(on_capped.positions, on_truncated.positions)
    assert np.abs(on_full.positions - on_capped.positions).max() > 1e-3


def test_relative_motion_zero_moves_the_group_rigidly() -> None:
    from trackfw.records import Detections, GapProblem, Interval, TargetState, VideoContext
    from trackfw_plugins.predictors.ar import ArPredictor

    steps = np.arange(30)[:, None]
    histories = [
        np.hstack([10 + 2.0 * steps, 50 + 0 * steps]),
        np.hstack([100 + 0.5 * steps, 80 + 1.0 * steps]),
    ]
    problem = GapProblem(
        interval=Interval(29, 59),
        target_ids=np.array([1, 2]),
        histories=histories,
        states=[TargetState(i + 1, h[-1]) for i, h in enumerate(histories)],
        detections=Detections.empty(),
        frame_a=None,
        frame_b=None,
        video=VideoContext("v", "v", 100, 640, 480),
    )
    independent = ArPredictor(ArPredictor.Params(orders=[1])).predict(problem)[0].positions
    rigid = (
        ArPredictor(ArPredictor.Params(orders=[1], relative_motion=0.0))
        .predict(problem)[0]
        .positions
    )
    at_a = np.array([h[-1] for h in histories])
    assert np.allclose(independent, at_a + 30 * np.array([[2.0, 0.0], [0.5, 1.0]]), atol=1e-3)
    assert np.allclose(rigid - at_a, (independent - at_a).mean(axis=0), atol=1e-9)
    assert np.allclose(rigid[1] - rigid[0], at_a[1] - at_a[0])
