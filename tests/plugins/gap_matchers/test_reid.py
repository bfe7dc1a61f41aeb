"""The re-ID gap matcher re-links people by appearance when their positions are shuffled."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw.records import (
    Detections,
    GapProblem,
    Interval,
    LookBack,
    Prediction,
    TargetState,
    VideoContext,
)
from trackfw.registry import load_registry
from trackfw.stages import Predictor

COLOURS = [(200, 40, 40), (40, 200, 40), (40, 40, 200), (200, 200, 40)]


def _frame(points: np.ndarray, colours: list[tuple[int, int, int]], seed: int) -> np.ndarray:
    random = np.random.default_rng(seed)
    image = random.integers(90, 110, (360, 640, 3)).astype(np.uint8)
    for (x, y), colour in zip(points.astype(int), colours, strict=True):
        image[y - 8 : y + 8, x - 6 : x + 6] = (30, 30, 30)  # head
        image[y + 8 : y + 100, x - 14 : x + 14] = colour  # body
    return image


AT_A = np.array([[100.0, 80.0], [220.0, 90.0], [340.0, 85.0], [460.0, 95.0]])


def _problem(
    at_b: np.ndarray, colours_b: list[tuple[int, int, int]], detected: int = 4
) -> GapProblem:
    """Four people at ``AT_A`` on frame a, at ``at_b`` on frame b; the first ``detected`` are."""
    return GapProblem(
        interval=Interval(2, 8),
        target_ids=np.arange(1, 5),
        histories=[p[None, :] for p in AT_A],
        states=[TargetState(i + 1, p, np.zeros(2)) for i, p in enumerate(AT_A)],
        detections=Detections.from_points(at_b[:detected]),
        frame_a=_frame(AT_A, COLOURS, 1),
        frame_b=_frame(at_b, colours_b, 2),
        video=VideoContext(name="v", path="v", n_frames=10, width=640, height=360),
    )


@pytest.mark.parametrize("descriptor", ["lomo", "gog", "person-reid"])
def test_reid_relinks_shuffled_people(descriptor: str) -> None:
    order = [2, 0, 3, 1]
    at_b = np.array([[150.0, 120.0], [300.0, 110.0], [420.0, 130.0], [560.0, 100.0]])
    problem = _problem(at_b, [COLOURS[i] for i in order])
    matcher = load_registry().build_stage(
        "gap_matcher", {"type": "reid", "params": {"descriptor": descriptor}}
    )
    solution = matcher.match(problem)
    # Target i wears COLOURS[i]; detection j wears COLOURS[order[j]].
    expected = [order.index(i) for i in range(4)]
    assert solution.matched_detection.tolist() == expected
    assert np.allclose(solution.positions, at_b[expected])
    # Each person stands out from the three others: every match's ratio is below 1.
    assert solution.match_ratios is not None and (solution.match_ratios < 1.0).all()


def test_reid_says_which_match_barely_beat_another_detection() -> None:
    # At b three people are detected: target 1 and two in target 3's colour. Target 1's match
    # stands out; whoever takes a look-alike barely beat (or lost to) the other one; of four
    # targets one is left without a detection, and without a ratio.
    at_b = np.array([[150.0, 120.0], [300.0, 110.0], [420.0, 130.0], [560.0, 100.0]])
    colours = [COLOURS[0], COLOURS[2], COLOURS[2], COLOURS[3]]
    problem = _problem(at_b, colours, detected=3)
    matcher = load_registry().build_stage(
        "gap_matcher", {"type": "reid", "params": {"descriptor": "gog"}}
    )
    ratios = matcher.match(problem).match_ratios
    assert ratios is not None and ratios[0] < 0.9
    assert np.isnan(ratios).sum() == 1  # four targets, three detections
    assert np.nanmax(ratios[1:]) > 0.95


def test_window_tps_rpm_deep_appearance_is_smallest_for_the_same_person() -> None:
    from trackfw_plugins.gap_matchers.window_tps_rpm import appearance_matrix

    order = [2, 0, 3, 1]
    at_b = np.array([[150.0, 120.0], [300.0, 110.0], [420.0, 130.0], [560.0, 100.0]])
    problem = _problem(at_b, [COLOURS[i] for i in order])
    matcher = load_registry().build_stage(
        "gap_matcher", {"type": "window-tps-rpm", "params": {"appearance_region": "person-reid"}}
    )
    distances = appearance_matrix(problem, matcher.params, matcher.embedder)
    assert distances is not None and distances.shape == (4, 4)
    assert distances.argmin(axis=1).tolist() == [order.index(i) for i in range(4)]
    assert matcher.match(problem).diagnostics["appearance_used"] is True


class FixedCandidates(Predictor):
    """Returns the candidates it was given (a stand-in for AR orders)."""

    name = "fixed"

    def __init__(self, candidates: list[Prediction]) -> None:
        super().__init__()
        self.candidates = candidates

    def predict(self, problem: GapProblem) -> list[Prediction]:
        return self.candidates


@pytest.mark.parametrize("descriptor", ["lomo", "gog"])
def test_reid_scores_every_candidate_and_keeps_the_one_that_finds_the_undetected_person(
    descriptor: str,
) -> None:
    from trackfw_plugins.gap_matchers.reid import ReidGapMatcher, ReidParams

    at_b = AT_A + np.array([30.0, 20.0])
    # Target 4 is on frame b but not detected: only the other three are.
    problem = _problem(at_b, COLOURS, detected=3)
    astray = at_b.copy()
    astray[3] = [600.0, 40.0]  # background, nobody there
    candidates = [Prediction("ar1", astray), Prediction("ar2", at_b.copy())]
    matcher = ReidGapMatcher(
        ReidParams(descriptor=descriptor), predictor=FixedCandidates(candidates)
    )
    solution = matcher.match(problem)
    assert solution.matched_detection.tolist() == [0, 1, 2, -1]
    assert solution.chosen == "ar2" and np.allclose(solution.positions[3], at_b[3])
    costs = solution.diagnostics["candidates"]
    assert set(costs) == {"ar1", "ar2"} and costs["ar2"] < costs["ar1"]
    assert solution.cost == pytest.approx(costs["ar2"], abs=1e-6)


REGROUPED_AT_B = np.array([[430.0, 20.0], [560.0, 40.0], [470.0, 130.0], [600.0, 120.0]])


def _regrouped_problem() -> GapProblem:
    """At b, four other people stand exactly in the targets' pattern of frame a (detections 4-7),
    while the targets themselves have regrouped elsewhere (``REGROUPED_AT_B``, detections 0-3)."""
    bystanders = AT_A + np.array([10.0, 150.0])
    others = [(150, 60, 200), (60, 200, 200), (250, 250, 250), (120, 120, 120)]
    points = np.vstack([REGROUPED_AT_B, bystanders])
    problem = _problem(REGROUPED_AT_B, COLOURS)
    problem.detections = Detections.from_points(points)
    problem.frame_b = _frame(points, COLOURS + others, 2)
    return problem


def test_window_tps_rpm_look_check_overrules_a_pattern_found_on_other_people() -> None:
    # The pattern alone picks the wrong people; the look finds the regrouped targets.
    problem = _regrouped_problem()
    registry = load_registry()
    params = {"appearance_region": "person-reid", "predictor": {"type": "ar"}}
    pattern = registry.build_stage("gap_matcher", {"type": "window-tps-rpm", "params": params})
    assert pattern.match(problem).matched_detection.tolist() == [4, 5, 6, 7]
    checked = registry.build_stage(
        "gap_matcher",
        {"type": "window-tps-rpm", "params": {**params, "look_margin": 0.1}},
    )
    solution = checked.match(problem)
    assert solution.matched_detection.tolist() == [0, 1, 2, 3]
    assert np.allclose(solution.positions, REGROUPED_AT_B)
    look = solution.diagnostics["look_check"]
    assert solution.chosen == "look" and look["overruled"] and look["overruled_candidate"] == "ar1"
    assert look["window"] - look["assignment"] > 0.1


def test_window_tps_rpm_look_region_keeps_the_look_near_the_pattern() -> None:
    # The scene of the overrule test: with look_region the assignment by look may only use
    # detections near the chosen window, so the regrouped targets far away are out of its reach.
    problem = _regrouped_problem()
    params = {
        "appearance_region": "person-reid",
        "predictor": {"type": "ar"},
        "look_margin": 0.1,
        "look_region": 0.25,
    }
    matcher = load_registry().build_stage(
        "gap_matcher", {"type": "window-tps-rpm", "params": params}
    )
    solution = matcher.match(problem)
    assert solution.matched_detection.tolist() == [4, 5, 6, 7]
    assert solution.chosen == "ar1"


def test_look_check_assigns_only_allowed_detections() -> None:
    from trackfw_plugins.gap_matchers.window_tps_rpm import look_check

    # Target 0 looks most like detection 3, which lies outside the allowed region; within it the
    # window's pairs (0 -> 0, 1 -> 1) are a swap the look undoes.
    distances = np.array([[0.5, 0.7, 0.9, 0.1], [0.2, 0.9, 0.9, 0.9]])
    allowed = np.array([True, True, True, False])
    rows, record = look_check(np.array([0, 1]), distances, 0.1, allowed)
    assert rows is not None and rows.tolist() == [1, 0]
    assert record["overruled"]
    anywhere, _ = look_check(np.array([0, 1]), distances, 0.1)
    assert anywhere is not None and anywhere.tolist() == [3, 0]


def test_window_tps_rpm_look_check_keeps_a_pattern_the_look_agrees_with() -> None:
    at_b = AT_A + np.array([30.0, 20.0])
    problem = _problem(at_b, COLOURS)
    matcher = load_registry().build_stage(
        "gap_matcher",
        {
            "type": "window-tps-rpm",
            "params": {"appearance_region": "person-reid", "look_margin": 0.1},
        },
    )
    solution = matcher.match(problem)
    assert solution.matched_detection.tolist() == [0, 1, 2, 3]
    assert solution.chosen == "ar1" and not solution.diagnostics["look_check"]["overruled"]


def _with_look_back(problem: GapProblem, colours: list[tuple[int, int, int]]) -> GapProblem:
    """``problem`` with a look-back frame on which the targets at ``AT_A`` wear ``colours``."""
    problem.lookback = LookBack(
        t=0,
        image=_frame(AT_A, colours, 3),
        detections=Detections.from_points(AT_A),
        positions=AT_A.copy(),
    )
    return problem


def test_window_tps_rpm_describes_a_target_unmatched_at_a_on_the_look_back_frame() -> None:
    from trackfw_plugins.gap_matchers.window_tps_rpm import appearance_matrix

    order = [2, 0, 3, 1]
    at_b = np.array([[150.0, 120.0], [300.0, 110.0], [420.0, 130.0], [560.0, 100.0]])
    problem = _with_look_back(_problem(at_b, [COLOURS[i] for i in order]), COLOURS)
    # Frame a is already turned away: nobody is where the targets were predicted.
    problem.frame_a = np.random.default_rng(4).integers(90, 110, (360, 640, 3)).astype(np.uint8)
    matcher = load_registry().build_stage(
        "gap_matcher", {"type": "window-tps-rpm", "params": {"appearance_region": "person-reid"}}
    )
    distances = appearance_matrix(problem, matcher.params, matcher.embedder)
    assert distances is not None
    assert distances.argmin(axis=1).tolist() == [order.index(i) for i in range(4)]


def test_window_tps_rpm_describes_a_target_matched_at_a_on_frame_a() -> None:
    from trackfw_plugins.gap_matchers.window_tps_rpm import appearance_matrix

    order = [2, 0, 3, 1]
    at_b = np.array([[150.0, 120.0], [300.0, 110.0], [420.0, 130.0], [560.0, 100.0]])
    # On the look-back frame the targets wear each other's colours; frame a is what counts.
    problem = _with_look_back(_problem(at_b, [COLOURS[i] for i in order]), COLOURS[::-1])
    problem.detections_a = Detections.from_points(AT_A)
    problem.states = [
        TargetState(i + 1, p, np.zeros(2), matched_detection=i) for i, p in enumerate(AT_A)
    ]
    matcher = load_registry().build_stage(
        "gap_matcher", {"type": "window-tps-rpm", "params": {"appearance_region": "person-reid"}}
    )
    distances = appearance_matrix(problem, matcher.params, matcher.embedder)
    assert distances is not None
    assert distances.argmin(axis=1).tolist() == [order.index(i) for i in range(4)]
