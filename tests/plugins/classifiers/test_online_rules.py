"""Tests of the online decision rules (hysteresis and re-anchoring of C_t's reference)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw.records import Detections, FrameData, VideoContext
from trackfw_plugins.classifiers.infoless_features import FeatureAssembler
from trackfw_plugins.classifiers.measurements import FeatureSettings, VideoMeasurements
from trackfw_plugins.classifiers.online_rules import OnlineDecider, OnlineRules, model_rules
from trackfw_plugins.classifiers.svm import SvmClassifier, SvmParams
from trackfw_plugins.classifiers.svm_model import load_model
from trackfw_plugins.classifiers.training import classify_online, fit_model, select_rules


def stuck_sequence() -> tuple[list[float], list[float], list[float]]:
    """Steady frames (spread 100), a 5-frame turn, then a steady but changed scene (spread 200).

    A classifier that calls a frame info-less when it moves fast or when C_t > 0.3 stays stuck
    after the turn under the paper's rule: the reference keeps the old spread, C_t stays 1.
    """
    motion = [0.5] * 10 + [12.0] * 5 + [0.5] * 30
    counts = [6.0] * len(motion)
    spreads = [100.0] * 10 + [150.0] * 5 + [200.0] * 30
    return motion, counts, spreads


def run_rules(rules: OnlineRules) -> list[bool]:
    """Decisions of the toy classifier of :func:`stuck_sequence` under ``rules``."""
    motion, counts, spreads = stuck_sequence()
    assembler = FeatureAssembler()
    decider = OnlineDecider(rules, assembler)
    decisions = []
    for t, (m, n, s) in enumerate(zip(motion, counts, spreads, strict=True)):
        features = assembler.push(t, m, n, s)
        probability = 1.0 if features[4] > 5.0 or features[-1] > 0.3 else 0.0
        infoless = t > 0 and decider.decide(probability)
        decider.settle(t, infoless, features)
        decisions.append(infoless)
    return decisions


def test_paper_rule_stays_stuck_and_reanchoring_unsticks() -> None:
    stuck = run_rules(OnlineRules())
    assert all(stuck[10:])  # never leaves after the turn
    freed = run_rules(OnlineRules(reanchor_after=8, reanchor_max_motion=2.0))
    assert all(freed[10:15]) and not any(freed[10 + 8 + 5 :])
    # The motion condition: the turn is still in the 5-frame history, so no early re-anchor.
    assert freed[15] and freed[16]
    first_informative = freed.index(False, 10)
    history_clear = 15 + 4  # the first frame whose 5 motion values are all steady
    assert first_informative > history_clear


def test_no_reanchoring_on_a_frame_without_people() -> None:
    assembler = FeatureAssembler()
    decider = OnlineDecider(OnlineRules(reanchor_after=2), assembler)
    assembler.push(0, 0.0, 4.0, 100.0)
    assembler.mark_informative(0, True)
    anchored = []
    for t, count in enumerate([0.0, 0.0, 0.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0], start=1):
        features = assembler.push(t, 0.0, count, 0.0 if count == 0 else 50.0)
        anchored.append(decider.settle(t, True, features))
    # Only once the whole 5-frame history shows at least 2 people (frame 8 onwards).
    assert anchored.index(True) == 7
    assert decider.rules.reanchor_min_detections == 2


def test_hysteresis_keeps_an_interval_open() -> None:
    probabilities = [0.1, 0.6, 0.4, 0.25, 0.1, 0.45]
    for rules, expected in (
        (OnlineRules(), [False, True, False, False, False, False]),
        (OnlineRules(0.5, 0.3), [False, True, True, False, False, False]),
    ):
        assembler = FeatureAssembler()
        decider = OnlineDecider(rules, assembler)
        decisions = []
        for t, probability in enumerate(probabilities):
            features = assembler.push(t, 0.0, 3.0, 10.0)
            decisions.append(decider.decide(probability))
            decider.settle(t, decisions[-1], features)
        assert decisions == expected


def test_settling_twice_replaces_the_first_decision() -> None:
    assembler = FeatureAssembler()
    decider = OnlineDecider(OnlineRules(reanchor_after=3), assembler)
    for t in range(3):
        features = assembler.push(t, 0.0, 3.0, 10.0)
        decider.settle(t, True, features)
        decider.settle(t, True, features)
    assert decider.run == 0  # re-anchored once at the third frame, not earlier
    features = assembler.push(3, 0.0, 3.0, 10.0)
    decider.settle(3, True, features)
    decider.settle(3, False, features)
    assert decider.run == 0 and not decider.inside


def test_reanchor_moves_the_reference_without_marking_informative() -> None:
    assembler = FeatureAssembler()
    assembler.push(0, 0.0, 2.0, 100.0)
    assembler.push(1, 0.0, 2.0, 200.0)
    assembler.mark_informative(1, False)
    assembler.reanchor(1)
    assert assembler.push(2, 0.0, 2.0, 300.0)[-1] == pytest.approx(0.5)
    assembler.mark_informative(2, False)
    assert assembler.push(3, 0.0, 2.0, 300.0)[-1] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="reanchor"):
        assembler.reanchor(2)


def test_rules_validate_and_round_trip() -> None:
    rules = OnlineRules(0.6, 0.2, 30)
    assert OnlineRules.from_dict(rules.as_dict()) == rules
    assert rules.as_dict()["reanchor_max_motion"] is None
    assert OnlineRules.from_dict(None) == OnlineRules()
    with pytest.raises(ValueError):
        OnlineRules(0.3, 0.5)
    with pytest.raises(ValueError):
        OnlineRules(reanchor_after=-1)
    with pytest.raises(UserError, match="online_rules"):
        OnlineRules.from_dict({"enter": 0.5}, "m.json")
    with pytest.raises(UserError, match="online_rules"):
        OnlineRules.from_dict({"enter_probability": 0.2, "leave_probability": 0.4}, "m.json")


@pytest.fixture(scope="module")
def rules_model_path(
    tmp_path_factory: pytest.TempPathFactory, make_measurements: Callable[..., VideoMeasurements]
) -> Path:
    videos = [make_measurements(f"video{i}", i) for i in range(4)]
    rules = OnlineRules(0.5, 0.3, 20, 4.0, turn_motion=5.0)
    model, _ = fit_model(videos, FeatureSettings(), reference="replay", rules=rules)
    path = tmp_path_factory.mktemp("rules") / "rules.json"
    model.save(path)
    return path


def test_model_records_rules_and_stage_uses_them(rules_model_path: Path) -> None:
    model = load_model(rules_model_path)
    recorded = OnlineRules(0.5, 0.3, 20, 4.0, turn_motion=5.0)
    assert model_rules(model) == recorded
    stage = SvmClassifier(SvmParams(model=str(rules_model_path)))
    assert stage.rules == recorded
    plain = SvmClassifier(SvmParams(model=str(rules_model_path), threshold=0.7))
    assert plain.rules == OnlineRules(0.7, 0.7, 20, 4.0, turn_motion=5.0)
    custom = SvmClassifier(
        SvmParams(model=str(rules_model_path), leave_threshold=0.1, reanchor_after=0, max_hold=7)
    )
    assert custom.rules == OnlineRules(0.5, 0.1, 0, 4.0, turn_motion=5.0, max_hold=7)
    with pytest.raises(UserError, match="leave_probability"):
        SvmClassifier(SvmParams(model=str(rules_model_path), threshold=0.2, leave_threshold=0.4))


def test_replay_uses_the_model_rules_by_default(
    rules_model_path: Path, make_measurements: Callable[..., VideoMeasurements]
) -> None:
    model = load_model(rules_model_path)
    video = make_measurements("held-out", 11)
    _, default = classify_online(model, video)
    _, explicit = classify_online(model, video, rules=model_rules(model))
    assert np.array_equal(default, explicit)
    _, plain = classify_online(model, video, threshold=0.5)
    _, paper = classify_online(model, video, rules=OnlineRules())
    assert np.array_equal(plain, paper)


def test_select_rules_returns_the_best_candidate(
    make_measurements: Callable[..., VideoMeasurements],
) -> None:
    videos = [make_measurements(f"video{i}", i) for i in range(4)]
    candidates = (OnlineRules(), OnlineRules(0.5, 0.3, 20), OnlineRules(1.0, 1.0))
    chosen, rows = select_rules(videos, FeatureSettings(), candidates, folds=2)
    assert len(rows) == 3 and chosen in candidates
    scores = [0.0 if row["f1"] is None or math.isnan(row["f1"]) else row["f1"] for row in rows]
    assert scores[candidates.index(chosen)] == max(scores)
    assert chosen != OnlineRules(1.0, 1.0)  # never firing cannot win


def group_glance(return_spread: float) -> tuple[list[float], list[float], list[bool]]:
    """Motion, spreads and true labels of a look at another group between two camera turns."""
    motion = [0.5] * 10 + [20.0] * 5 + [0.5] * 30 + [20.0] * 5 + [0.5] * 20
    spreads = [100.0] * 10 + [80.0] * 5 + [60.0] * 30 + [80.0] * 5 + [return_spread] * 20
    labels = [False] * 10 + [True] * 40 + [False] * 20
    return motion, spreads, labels


def run_glance(rules: OnlineRules, return_spread: float, use_change: bool) -> list[bool]:
    """Decisions of a toy classifier that fires on fast motion (and on C_t > 0.3 if asked)."""
    motion, spreads, _ = group_glance(return_spread)
    assembler = FeatureAssembler()
    decider = OnlineDecider(rules, assembler)
    decisions = []
    for t, (m, s) in enumerate(zip(motion, spreads, strict=True)):
        features = assembler.push(t, m, 6.0, s)
        fires = features[4] > 5.0 or (use_change and features[-1] > 0.3)
        infoless = t > 0 and decider.decide(1.0 if fires else 0.0, features)
        decider.settle(t, infoless, features)
        decisions.append(infoless)
    return decisions


def test_turn_latch_holds_an_interval_between_two_turns() -> None:
    _, _, labels = group_glance(100.0)
    plain = run_glance(OnlineRules(), 100.0, use_change=False)
    assert plain[10:15] == [True] * 5 and not any(plain[15:45])  # the look itself is missed
    latched = run_glance(OnlineRules(turn_motion=10.0), 100.0, use_change=False)
    assert latched == labels
    bounded = run_glance(OnlineRules(turn_motion=10.0, max_hold=10), 100.0, use_change=False)
    assert bounded[10:20] == [True] * 10 and not any(bounded[21:45])


def test_release_reanchors_on_the_scene_the_camera_came_back_to() -> None:
    # Back from the glance, the people of interest have spread out: C_t = 0.5 against the old
    # reference, so without re-anchoring the classifier stays stuck.
    stuck = run_glance(OnlineRules(turn_motion=10.0, reanchor_on_release=False), 150.0, True)
    assert all(stuck[50:])
    freed = run_glance(OnlineRules(turn_motion=10.0), 150.0, True)
    assert freed[49] and freed[50] and not any(freed[51:])


def test_an_early_interval_latches_on_its_first_turn() -> None:
    motion, spreads, labels = group_glance(100.0)
    # The toy classifier also fires on the two frames before the turn (it was early).
    results = {}
    for late in (False, True):
        assembler = FeatureAssembler()
        decider = OnlineDecider(OnlineRules(turn_motion=10.0, latch_late_turns=late), assembler)
        decisions = []
        for t, (m, s) in enumerate(zip(motion, spreads, strict=True)):
            features = assembler.push(t, m, 6.0, s)
            fires = features[4] > 5.0 or t in (8, 9)
            infoless = t > 0 and decider.decide(1.0 if fires else 0.0, features)
            decider.settle(t, infoless, features)
            decisions.append(infoless)
        results[late] = decisions
    assert not any(results[False][16:45])
    assert results[True][8:50] == [True] * 42 and results[True][10:] == labels[10:]


def sky_look(rules: OnlineRules) -> list[bool]:
    """Six people; a turn to the sky (frames 10-39: no one in view, the camera wandering a little)
    and the turn back to the six (frames 37-39). The toy SVM fires on motion alone, as the shipped
    one does in the sky once the reference of C_t has no people either."""
    motion = [0.5] * 10 + [20.0] * 3 + [0.5, 9.0, 0.5, 9.0] + [0.5] * 20 + [20.0] * 3 + [0.5] * 20
    counts = [6.0] * 10 + [0.0] * 30 + [6.0] * 20
    assembler = FeatureAssembler()
    decider = OnlineDecider(rules, assembler)
    decisions = []
    for t, (m, n) in enumerate(zip(motion, counts, strict=True)):
        features = assembler.push(t, m, n, 100.0 if n else 0.0)
        infoless = t > 0 and decider.decide(1.0 if features[4] > 10.0 else 0.0, features)
        decider.settle(t, infoless, features)
        decisions.append(infoless)
    return decisions


def test_an_interval_is_not_left_where_no_one_is_in_view() -> None:
    latch = {"turn_motion": 8.0, "reanchor_after": 30}
    # The wandering ends the latch's second turn, and the calm sky frames come out informative.
    left = sky_look(OnlineRules(**latch))
    assert all(left[10:15]) and not any(left[15:37])
    kept = sky_look(OnlineRules(**latch, leave_min_detections=1))
    assert all(kept[10:40]) and not any(kept[40:])
    assert OnlineRules.from_dict({"leave_min_detections": 2}).leave_min_detections == 2
    with pytest.raises(ValueError, match="leave_min_detections"):
        OnlineRules(leave_min_detections=-1)


def test_stage_and_replay_agree_under_the_rules(
    rules_model_path: Path, make_frames: Callable[..., list[np.ndarray]]
) -> None:
    video = VideoContext(name="toy", path="toy", n_frames=60, width=640, height=360)
    shifts, x = [], 0
    for t in range(60):
        x += 24 if 10 <= t < 15 or 35 <= t < 40 else 1
        shifts.append(x)
    stage = SvmClassifier(SvmParams(model=str(rules_model_path)))
    stage.start(video)
    rows, decisions = [], []
    points = np.array([[200.0 + 40 * i, 150.0 + 7 * (i % 2)] for i in range(6)])
    for t, image in enumerate(make_frames(shifts)):
        frame = FrameData(t, image, video, first=t == 0)
        decision = stage.classify(frame, Detections.from_points(points))
        infoless = decision.infoless
        decisions.append(infoless)
        rows.append(stage.extractor.last_measurements)
    table = np.asarray(rows)
    replayed = VideoMeasurements(
        "toy", np.arange(60), table[:, 0], table[:, 1], table[:, 2], np.zeros(60, bool)
    )
    _, expected = classify_online(load_model(rules_model_path), replayed)
    assert decisions == expected.tolist()
    assert any(decisions)  # the turns are seen


def test_the_shipped_model_brings_its_rules() -> None:
    stage = SvmClassifier(SvmParams())
    assert stage.rules == model_rules(stage.model) != OnlineRules()
    # Read back, so that a rule added after the model was trained compares at its default.
    assert OnlineRules.from_dict(stage.model.training["online_rules"]) == stage.rules
    assert stage.model.training["rule_selection"]  # chosen by cross-validation, recorded
