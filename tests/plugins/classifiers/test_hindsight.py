"""The end of an interval decided in hindsight (docs/algorithms/infoless-classifier.md#hindsight)."""

from __future__ import annotations

import pytest

from trackfw_plugins.classifiers.hindsight import EndHindsight, OnsetHindsight
from trackfw_plugins.classifiers.scene_check import SceneCheckClassifier, SceneCheckParams
from trackfw_plugins.classifiers.svm import SvmClassifier, SvmParams

# (info-less, M_t, N_t): steady on the group, the turn away, the view away (no people), the
# turn back arriving on frame 5 with people in view, then steady frames the SVM still calls
# info-less because its feature remembers the turn.
AWAY_AND_BACK = [
    (False, 1.0, 4),
    (True, 30.0, 1),
    (True, 2.0, 0),
    (True, 2.0, 0),
    (True, 35.0, 0),
    (True, 20.0, 4),
    (True, 1.5, 4),
    (True, 1.2, 4),
]


def _push_all(hindsight: EndHindsight, frames: list[tuple[bool, float, int]]) -> list[int]:
    return [hindsight.push(*frame) for frame in frames]


def test_leaving_revises_back_to_the_frame_the_turn_arrived_on() -> None:
    hindsight = EndHindsight(frames=8, max_motion=4.0, min_detections=1)
    assert _push_all(hindsight, AWAY_AND_BACK) == [0] * len(AWAY_AND_BACK)
    # Frames 7, 6 and 5 are informative: the camera stood still from each to the next. Frame 4
    # is not: M_5 = 20, the turn's last step, moved from it to frame 5.
    assert hindsight.push(False, 1.0, 4) == 3


def test_the_walk_stops_at_a_frame_without_people_and_at_the_window() -> None:
    # The view away is steady but shows nobody: never revised, so the interval keeps its start.
    steady_sky = [(False, 1.0, 4), (True, 30.0, 0), (True, 1.0, 0), (True, 1.0, 3)]
    hindsight = EndHindsight(frames=8, max_motion=4.0, min_detections=1)
    _push_all(hindsight, steady_sky)
    assert hindsight.push(False, 1.0, 4) == 1
    hindsight = EndHindsight(frames=2, max_motion=4.0, min_detections=1)
    _push_all(hindsight, AWAY_AND_BACK)
    assert hindsight.push(False, 1.0, 4) == 2


def test_a_false_interval_on_a_steady_view_is_undone_whole_and_zero_frames_never_revise() -> None:
    jolt = [(False, 1.0, 5), (True, 2.0, 5), (True, 1.0, 4)]
    hindsight = EndHindsight(frames=8, max_motion=4.0, min_detections=1)
    _push_all(hindsight, jolt)
    assert hindsight.push(False, 1.0, 5) == 2
    # Revised frames are informative now: the next informative frame revises nothing.
    assert hindsight.push(False, 1.0, 5) == 0
    off = EndHindsight(frames=0, max_motion=4.0, min_detections=1)
    assert _push_all(off, [*jolt, (False, 1.0, 5)]) == [0, 0, 0, 0]


def test_an_informative_frame_after_a_turn_revises_nothing() -> None:
    # The classifier leaves on the very frame the turn moves into: the camera was not still.
    hindsight = EndHindsight(frames=8, max_motion=4.0, min_detections=1)
    _push_all(hindsight, AWAY_AND_BACK[:5])
    assert hindsight.push(False, 20.0, 4) == 0
    with pytest.raises(ValueError, match="at least 0"):
        EndHindsight(frames=-1, max_motion=4.0, min_detections=1)


def test_the_svm_classifiers_declare_their_hindsight() -> None:
    assert SvmClassifier().hindsight_frames == 0  # the paper's: every decision final at once
    assert SvmClassifier(SvmParams(hindsight_frames=6)).hindsight_frames == 6
    params = SceneCheckParams(svm=SvmParams(hindsight_frames=4))
    assert SceneCheckClassifier(params).hindsight_frames == 4


def test_entering_revises_the_frames_the_turn_had_begun_on() -> None:
    onset = OnsetHindsight(frames=3, min_probability=0.3)
    # (info-less, probability, fixed): steady, then two frames of a beginning turn.
    assert [onset.push(*f) for f in [(False, 0.1, True), (False, 0.2, False)]] == [0, 0]
    assert [onset.push(*f) for f in [(False, 0.35, False), (False, 0.45, False)]] == [0, 0]
    assert onset.push(True, 0.9, False) == 2
    # Inside the interval nothing more is revised.
    assert onset.push(True, 0.95, False) == 0


def test_the_onset_walk_stops_at_a_fixed_frame_and_at_the_window() -> None:
    onset = OnsetHindsight(frames=1, min_probability=0.3)
    for frame in [(False, 0.4, False), (False, 0.4, False)]:
        onset.push(*frame)
    assert onset.push(True, 0.8, False) == 1  # the window: one frame
    fixed = OnsetHindsight(frames=4, min_probability=0.3)
    fixed.push(False, 0.4, False)
    fixed.push(False, 0.45, True)  # ended an interval in hindsight: never revised
    assert fixed.push(True, 0.8, False) == 0
    never = OnsetHindsight(frames=0, min_probability=0.3)
    never.push(False, 0.45, False)
    assert never.push(True, 0.8, False) == 0
    with pytest.raises(ValueError, match="at least 0"):
        OnsetHindsight(frames=-1, min_probability=0.3)


def test_the_svm_classifiers_declare_their_onset() -> None:
    assert SvmClassifier(SvmParams()).onset_frames == 0
    assert SvmClassifier(SvmParams(onset_frames=2)).onset_frames == 2
    assert SceneCheckClassifier(SceneCheckParams(svm=SvmParams(onset_frames=1))).onset_frames == 1
