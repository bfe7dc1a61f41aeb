"""The pieces of the online loop: the frame front and the segment."""

from __future__ import annotations

import numpy as np

from trackfw.dataset import load_video
from trackfw.front import FrameFront, FrameRecord, Observation
from trackfw.records import ClassifierDecision, Detections, FrameData, TargetState, VideoContext
from trackfw.segment import Segment
from trackfw.stages import Classifier, Detector


class EveryFrameInfoless(Classifier):
    """Says every frame is info-less, and remembers which frames it was told were first."""

    name = "always-infoless"

    def __init__(self) -> None:
        super().__init__()
        self.first_frames: list[int] = []

    def classify(self, frame: FrameData, detections: Detections) -> ClassifierDecision:
        if frame.first:
            self.first_frames.append(frame.t)
        return ClassifierDecision(probability=0.9, infoless=True)


class TwoPoints(Detector):
    """Two detections whose index the detector scrambled."""

    name = "two-points"

    def detect(self, frame: FrameData) -> Detections:
        return Detections(np.array([[1.0, 2.0], [3.0, 4.0]]), np.ones(2), index=np.array([7, 9]))


def test_front_keeps_the_first_frame_informative_and_reindexes_detections(points_video) -> None:
    video = load_video(points_video("v", n_frames=5, intervals=[]))
    classifier = EveryFrameInfoless()
    seen: list[int] = []
    observations = list(FrameFront(video, TwoPoints(), classifier, None, False, seen.append))
    assert seen == [0, 1, 2, 3, 4]
    assert [o.infoless for o in observations] == [False, True, True, True, True]
    assert [o.first for o in observations] == [True, False, False, False, False]
    assert classifier.first_frames == [0]
    assert observations[0].record.probability == 0.9
    assert observations[2].detections.index.tolist() == [0, 1]
    assert {"detector", "classifier"} <= set(observations[0].record.milliseconds)


def _observation(t: int, points: list[list[float]]) -> Observation:
    image = np.full((4, 4, 3), t, dtype=np.uint8)
    return Observation(FrameRecord(t, "ok", detections=Detections.from_points(points)), image)


def test_segment_histories_and_gap_problem_come_from_its_frames() -> None:
    segment = Segment(np.array([4, 8], dtype=np.int64))
    assert [h.shape for h in segment.histories()] == [(0, 2), (0, 2)]
    segment.add(_observation(0, [[0.0, 0.0]]), np.array([[0.0, 0.0], [10.0, 0.0]]))
    segment.add(_observation(1, [[1.0, 0.0]]), np.array([[1.0, 0.0], [11.0, 1.0]]))
    histories = segment.histories()
    assert histories[1].tolist() == [[10.0, 0.0], [11.0, 1.0]]
    b = _observation(9, [[5.0, 5.0], [6.0, 6.0]])
    states = [TargetState(4, np.array([1.0, 0.0])), TargetState(8, np.array([11.0, 1.0]))]
    problem = segment.gap_problem(b, states, VideoContext("v", "v", 10, 4, 4))
    assert (problem.interval.a, problem.interval.b, problem.horizon) == (1, 9, 8)
    assert problem.frame_a is not None and int(problem.frame_a[0, 0, 0]) == 1
    assert problem.frame_b is not None and int(problem.frame_b[0, 0, 0]) == 9
    assert problem.detections_a is not None and problem.detections_a.points.tolist() == [[1.0, 0.0]]
    assert len(problem.detections) == 2 and problem.target_ids.tolist() == [4, 8]
    after = segment.next()
    assert after.target_ids is segment.target_ids and after.positions == [] and after.last is None


def test_the_gap_problem_carries_the_frame_lookback_frames_before_a() -> None:
    # Frames 0..9 of a segment with a look-back of 4 frames: the problem carries frame 5 (a is
    # 9), its detections and the positions of the targets taking part, and only frames 5..9
    # are held.
    segment = Segment(np.array([4, 8], dtype=np.int64), lookback_frames=4)
    for t in range(10):
        segment.add(_observation(t, [[float(t), 0.0]]), np.array([[t, 0.0], [10.0 + t, 1.0]]))
    assert [observation.t for observation in segment.recent] == [5, 6, 7, 8, 9]
    states = [TargetState(4, np.array([9.0, 0.0])), TargetState(8, np.array([19.0, 1.0]))]
    b = _observation(20, [[5.0, 5.0]])
    problem = segment.gap_problem(b, states, VideoContext("v", "v", 30, 4, 4), np.array([1]))
    lookback = problem.lookback
    assert lookback is not None and lookback.t == 5
    assert lookback.image is not None and int(lookback.image[0, 0, 0]) == 5
    assert lookback.detections.points.tolist() == [[5.0, 0.0]]
    assert lookback.positions.tolist() == [[15.0, 1.0]]
    assert segment.next().lookback_frames == 4


def test_a_segment_of_one_frame_has_no_lookback() -> None:
    segment = Segment(np.array([4], dtype=np.int64), lookback_frames=4)
    segment.add(_observation(3, [[1.0, 0.0]]), np.array([[1.0, 0.0]]))
    states = [TargetState(4, np.array([1.0, 0.0]))]
    problem = segment.gap_problem(_observation(9, []), states, VideoContext("v", "v", 10, 4, 4))
    assert problem.lookback is None


class Scripted(Classifier):
    """Decides each frame from a script of ``(info-less, revises)``; logs when it is called."""

    name = "scripted"

    def __init__(
        self, script: list[tuple[bool, int]], hindsight: int, onset: dict[int, int] | None = None
    ) -> None:
        super().__init__()
        self.script = script
        self.hindsight = hindsight
        self.onset = onset or {}
        self.classified: list[int] = []

    @property
    def hindsight_frames(self) -> int:
        return self.hindsight

    @property
    def onset_frames(self) -> int:
        return max(self.onset.values(), default=0)

    def classify(self, frame: FrameData, detections: Detections) -> ClassifierDecision:
        self.classified.append(frame.t)
        infoless, revises = self.script[frame.t]
        return ClassifierDecision(
            probability=0.5, infoless=infoless, revises=revises, onset=self.onset.get(frame.t, 0)
        )


def _front(
    points_video,
    script: list[tuple[bool, int]],
    hindsight: int,
    onset: dict[int, int] | None = None,
):
    video = load_video(points_video("v", n_frames=len(script), intervals=[]))
    classifier = Scripted(script, hindsight, onset)
    front = FrameFront(video, TwoPoints(), classifier, None, False)
    return front, classifier


def test_hindsight_revises_the_end_of_an_interval_before_tracking_sees_it(points_video) -> None:
    # Frames 2..6 decided info-less; frame 7 leaves the interval and revises 6 and 5.
    script = [(False, 0)] * 2 + [(True, 0)] * 5 + [(False, 2)] + [(False, 0)] * 2
    front, classifier = _front(points_video, script, hindsight=3)
    seen: list[tuple[int, bool, int]] = []
    for observation in front:
        # When a frame reaches the tracking, the classifier has gone at most 3 frames further.
        seen.append((observation.t, observation.infoless, classifier.classified[-1]))
        assert classifier.classified[-1] - observation.t <= 3
    assert [t for t, _, _ in seen] == list(range(10))
    assert [t for t, infoless, _ in seen if infoless] == [2, 3, 4]
    # Frames 5 and 6 waited for frame 7's decision; frames 2..4 left the queue as it filled.
    assert [(t, last) for t, _, last in seen if 2 <= t <= 7] == [
        (2, 5),
        (3, 6),
        (4, 7),
        (5, 7),
        (6, 7),
        (7, 7),
    ]


def test_hindsight_may_undo_a_short_interval_whole_and_never_reaches_further(points_video) -> None:
    script = [(False, 0), (True, 0), (True, 0), (False, 5), (True, 0), (False, 0)]
    front, _ = _front(points_video, script, hindsight=4)
    assert [o.infoless for o in front] == [False, False, False, False, True, False]
    # Without hindsight the front ignores what a decision says about earlier frames.
    front, _ = _front(points_video, script, hindsight=0)
    assert [o.infoless for o in front] == [False, True, True, False, True, False]


def test_the_start_of_an_interval_revises_the_frames_before_it_before_tracking_sees_them(
    points_video,
) -> None:
    # Frames 4..6 decided info-less; frame 4 enters the interval and turns 3 and 2 info-less.
    script = [(False, 0)] * 4 + [(True, 0)] * 3 + [(False, 0)] * 3
    front, classifier = _front(points_video, script, hindsight=0, onset={4: 2})
    seen = []
    for observation in front:
        seen.append((observation.t, observation.infoless, classifier.classified[-1]))
        # An informative frame waits for at most 2 later decisions.
        assert classifier.classified[-1] - observation.t <= 2
    assert [t for t, _, _ in seen] == list(range(10))
    assert [t for t, infoless, _ in seen if infoless] == [2, 3, 4, 5, 6]
    assert [(t, last) for t, _, last in seen if t in (2, 3)] == [(2, 4), (3, 4)]


def test_the_start_of_an_interval_never_turns_the_first_frame_info_less(points_video) -> None:
    script = [(False, 0), (True, 0), (False, 0)]
    front, _ = _front(points_video, script, hindsight=0, onset={1: 1})
    assert [o.infoless for o in front] == [False, True, False]


def test_both_revisions_together_keep_frame_order(points_video) -> None:
    # 2..4 info-less, 5 leaves it revising 4; 7 enters another, revising 6.
    script = [(False, 0)] * 2 + [(True, 0)] * 3 + [(False, 1), (False, 0), (True, 0), (False, 0)]
    front, _ = _front(points_video, script, hindsight=3, onset={7: 1})
    observations = list(front)
    assert [o.t for o in observations] == list(range(9))
    assert [o.t for o in observations if o.infoless] == [2, 3, 6, 7]
