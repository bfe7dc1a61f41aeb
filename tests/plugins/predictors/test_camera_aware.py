"""Tests of the camera-aware predictor and of its candidates in the window gap matcher."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from trackfw.records import (
    Detections,
    GapProblem,
    Interval,
    LookBack,
    Prediction,
    TargetState,
    VideoContext,
)
from trackfw_plugins.datasets.points import gap_scene
from trackfw_plugins.gap_matchers.window_tps_rpm import (
    WindowTpsRpmGapMatcher,
    WindowTpsRpmParams,
    score_candidates,
)
from trackfw_plugins.maths.window_association import WindowAssociationParams, select_candidate
from trackfw_plugins.predictors.camera_aware import CameraAwareParams, CameraAwarePredictor


def _problem(
    frame: Callable[..., np.ndarray], shift: tuple[float, float], scene_moves: bool
) -> tuple[GapProblem, np.ndarray]:
    """Five still targets; the camera pans by ``shift`` (the scene too when ``scene_moves``)."""
    targets = np.array(
        [[200.0, 200.0], [260.0, 215.0], [320.0, 190.0], [230.0, 280.0], [300.0, 290.0]]
    )
    clutter = np.array([[520.0, 100.0], [560.0, 130.0], [80.0, 400.0], [500.0, 400.0]])
    moved = targets + shift
    image_a = frame(5)
    matrix = (
        np.float64([[1, 0, shift[0]], [0, 1, shift[1]]])
        if scene_moves
        else np.float64([[1, 0, 0], [0, 1, 0]])
    )
    image_b = cv2.warpAffine(image_a, matrix, (640, 480), borderMode=cv2.BORDER_REFLECT)
    detections = Detections(points=np.vstack([clutter, moved]), scores=np.ones(9))
    states = [
        TargetState(target_id=i + 1, position=p, velocity=np.zeros(2))
        for i, p in enumerate(targets)
    ]
    problem = GapProblem(
        interval=Interval(a=40, b=60),
        target_ids=np.arange(1, 6, dtype=np.int64),
        histories=[np.repeat(p[None], 40, axis=0) for p in targets],
        states=states,
        detections=detections,
        frame_a=image_a,
        frame_b=image_b,
        video=VideoContext(name="v", path="v", n_frames=100, width=640, height=480),
    )
    return problem, np.arange(4, 9)


def test_registered_candidates_follow_the_camera(textured_frame: Callable[..., np.ndarray]) -> None:
    problem, _ = _problem(textured_frame, (60.0, -25.0), scene_moves=True)
    candidates = CameraAwarePredictor().predict(problem)
    labels = [candidate.label for candidate in candidates]
    # No look-back frame in this problem: no reg-walk.
    assert labels == ["ar1", "ar2", "ar3", "reg-ar1", "reg-ar2", "reg-ar3", "continuity"]
    registered = candidates[3]
    assert registered.gate is not None and candidates[0].gate is None
    assert registered.diagnostics["registration"]["ok"]
    np.testing.assert_allclose(
        registered.positions, problem.positions_at_a + np.array([60.0, -25.0]), atol=3.0
    )


def test_failed_registration_offers_no_registered_candidate(
    textured_frame: Callable[..., np.ndarray],
) -> None:
    problem, _ = _problem(textured_frame, (0.0, 0.0), scene_moves=False)
    problem.frame_b = textured_frame(9)  # another scene: nothing registers
    candidates = CameraAwarePredictor().predict(problem)
    assert not any(candidate.label.startswith("reg-") for candidate in candidates)
    assert candidates[0].diagnostics["registration"]["ok"] is False


def test_gap_matcher_picks_the_registered_candidate_and_records_it(
    textured_frame: Callable[..., np.ndarray],
) -> None:
    problem, truth = _problem(textured_frame, (60.0, -25.0), scene_moves=True)
    predictor = CameraAwarePredictor(CameraAwareParams(continuity=False))
    matcher = WindowTpsRpmGapMatcher(
        WindowTpsRpmParams(lambda2=0.0, lambda3=1.0), predictor=predictor
    )
    solution = matcher.match(problem)
    assert solution.chosen is not None and solution.chosen.startswith("reg-")
    assert solution.matched_detection.tolist() == truth.tolist()
    record = solution.diagnostics["candidates"][solution.chosen]
    assert record["predictor"]["registration"]["inliers"] >= 15
    assert record["gate_px"] > 0


def test_window_search_is_skipped_only_when_it_cannot_win() -> None:
    candidates, detections, truth = gap_scene(30, seed=4, candidates=3)
    params = WindowAssociationParams()
    free = [Prediction(f"ar{k + 1}", u) for k, u in enumerate(candidates)]
    placed = Prediction("reg-ar1", detections[truth] + 4.0, gate=60.0)
    results, evidence = score_candidates([*free, placed], detections, None, params, None, 1.0)
    assert [r.diagnostics.fallback for r in results[:3]] == ["bound"] * 3
    assert select_candidate(results) == 3
    assert results[3].matched_detection.tolist() == truth.tolist()
    assert 0.0 < evidence[3] < 0.2
    # Far from the group the positioned candidate finds nothing: every window is searched.
    astray = Prediction("reg-ar1", detections[truth] + 400.0, gate=60.0)
    results, _ = score_candidates([*free, astray], detections, None, params, None, 1.0)
    assert all(r.diagnostics.fallback != "bound" for r in results[:3])
    assert select_candidate(results) < 3


def test_the_walk_is_measured_with_the_cameras_sway_registered_out(
    textured_frame: Callable[..., np.ndarray],
) -> None:
    # The targets walk 2 px per frame to the right. Between the look-back frame (a - 10) and a
    # the camera swayed, so the scene (and every head) stood 30 px further right on the
    # look-back frame: the image positions say the targets walked left. After the interval
    # (20 frames) the camera has panned by (60, -25).
    problem, _ = _problem(textured_frame, (60.0, -25.0), scene_moves=True)
    at_a = problem.positions_at_a
    problem.lookback = LookBack(
        t=30,
        image=textured_frame(5, 30.0),
        detections=Detections.from_points(np.zeros((0, 2))),
        positions=at_a - np.array([20.0, 0.0]) + np.array([30.0, 0.0]),
    )
    candidates = {c.label: c for c in CameraAwarePredictor().predict(problem)}
    walked = candidates["reg-walk"]
    assert walked.gate == candidates["reg-ar1"].gate
    expected = at_a + np.array([2.0 * 20, 0.0]) + np.array([60.0, -25.0])
    np.testing.assert_allclose(walked.positions, expected, atol=3.0)
    off = CameraAwarePredictor(CameraAwareParams(walk=False)).predict(problem)
    assert "reg-walk" not in [candidate.label for candidate in off]
