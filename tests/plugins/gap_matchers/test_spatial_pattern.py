"""Gap matchers that use the group's spatial pattern: window-tps-rpm and plain tps-rpm."""

from __future__ import annotations

import numpy as np

from trackfw.records import Detections, GapProblem, Interval, TargetState, VideoContext
from trackfw.registry import load_registry

VIDEO = VideoContext(name="v", path="v", n_frames=300, width=1280, height=720)


def _problem(seed: int, clutter: int) -> tuple[GapProblem, np.ndarray]:
    """8 targets walking right; at b the camera has rotated 12 degrees, zoomed 1.2x and shifted."""
    random = np.random.default_rng(seed)
    pattern = random.uniform([-150, -90], [150, 90], (8, 2))
    velocity = np.array([1.5, 0.2])
    frames = np.arange(-40, 1)[:, None, None]
    histories = (
        pattern[None] + np.array([500.0, 350.0]) + frames * velocity
    )  # (41, 8, 2), ends at a
    horizon = 60
    at_b_world = histories[-1] + horizon * velocity
    angle = np.radians(12)
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    centre = at_b_world.mean(0)
    at_b = (
        (at_b_world - centre) @ rotation.T * 1.2
        + centre
        + [90.0, -40.0]
        + random.normal(0, 2, (8, 2))
    )
    others = random.uniform([0, 0], [1280, 720], (clutter, 2))
    order = random.permutation(8 + clutter)
    points = np.vstack([at_b, others])[order]
    truth = np.array([int(np.flatnonzero(order == k)[0]) for k in range(8)])
    problem = GapProblem(
        interval=Interval(a=100, b=100 + horizon),
        target_ids=np.arange(1, 9),
        histories=[histories[:, k, :] for k in range(8)],
        states=[TargetState(k + 1, histories[-1, k], velocity) for k in range(8)],
        detections=Detections.from_points(points),
        frame_a=None,
        frame_b=None,
        video=VIDEO,
    )
    return problem, truth


def test_window_tps_rpm_relinks_a_transformed_group_among_clutter() -> None:
    matcher = load_registry().build_stage(
        "gap_matcher",
        {"type": "window-tps-rpm", "params": {"lambda2": 0.0, "predictor": {"type": "ar"}}},
    )
    correct = 0
    for seed in range(6):
        problem, truth = _problem(seed, clutter=6)
        solution = matcher.match(problem)
        correct += int((solution.matched_detection == truth).sum())
        assert set(solution.diagnostics["candidates"]) == {"ar1", "ar2", "ar3"}
        # All three AR orders predict the same constant-velocity motion here: ties go to AR(1).
        assert solution.chosen == "ar1"
    # Measured 44 of 48; one seed's pattern has a cheaper wrong window (the method's limit).
    assert correct >= 0.85 * 48


def test_window_tps_rpm_beats_distance_assignment_after_a_pose_change() -> None:
    registry = load_registry()
    window = registry.build_stage(
        "gap_matcher", {"type": "window-tps-rpm", "params": {"lambda2": 0.0}}
    )
    hungarian = registry.build_stage(
        "gap_matcher", {"type": "assignment", "params": {"predictor": {"type": "ar"}}}
    )
    window_correct = hungarian_correct = 0
    for seed in range(4):
        problem, truth = _problem(seed, clutter=4)
        window_correct += int((window.match(problem).matched_detection == truth).sum())
        hungarian_correct += int((hungarian.match(problem).matched_detection == truth).sum())
    assert window_correct > hungarian_correct
    assert window_correct >= 0.85 * 32


def test_window_tps_rpm_needs_pixels_only_for_appearance() -> None:
    registry = load_registry()
    assert registry.build_stage("gap_matcher", {"type": "window-tps-rpm"}).needs_pixels
    assert not registry.build_stage(
        "gap_matcher", {"type": "window-tps-rpm", "params": {"lambda2": 0}}
    ).needs_pixels


def test_plain_tps_rpm_matches_a_slightly_moved_group() -> None:
    problem, truth = _problem(3, clutter=0)
    matcher = load_registry().build_stage(
        "gap_matcher", {"type": "tps-rpm", "params": {"predictor": {"type": "ar"}}}
    )
    solution = matcher.match(problem)
    assert (solution.matched_detection == truth).mean() >= 6 / 8
    assert solution.cost is not None and solution.cost >= 0


def test_no_detection_keeps_predictions() -> None:
    problem, _ = _problem(0, clutter=0)
    problem.detections = Detections.empty()
    for kind in ("window-tps-rpm", "tps-rpm"):
        matcher = load_registry().build_stage(
            "gap_matcher",
            {"type": kind, "params": {"lambda2": 0} if kind == "window-tps-rpm" else {}},
        )
        solution = matcher.match(problem)
        assert (solution.matched_detection == -1).all()
        assert np.isfinite(solution.positions).all()
