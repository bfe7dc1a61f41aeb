"""The appearance veto of re-acquisition: looks decide, except on patches cut by the border."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw.records import Detections
from trackfw_plugins.trackers.appearance_memory import (
    AppearanceMemory,
    AppearanceSettings,
    covered_fractions,
)


def _image() -> np.ndarray:
    # Left half red, right half noisy green: a red-patch target and green-patch bystanders.
    rng = np.random.default_rng(0)
    image = np.zeros((360, 640, 3), dtype=np.uint8)
    image[:, :320, 2] = 200
    image[:, 320:, 1] = rng.integers(100, 255, size=(360, 320))
    return image


def test_patch_veto_refuses_a_different_look_inside_but_not_at_the_border() -> None:
    image = _image()
    memory = AppearanceMemory(AppearanceSettings(descriptor="patch"), 1, 360, 25.0)
    seen = Detections.from_points(np.array([[150.0, 180.0]]))
    memory.remember(0, image, np.array([0]), seen, np.array([0]))
    # A bystander in the green half well inside the image, and one at the right edge whose
    # patch is half replicated border.
    candidates = Detections.from_points(np.array([[480.0, 180.0], [635.0, 180.0], [160.0, 170.0]]))
    veto = memory.veto(image, np.array([0]), candidates, np.arange(3), np.ones((1, 3), dtype=bool))
    assert veto.tolist() == [[True, False, False]]


def test_entering_pairs_need_a_descriptor_and_the_stricter_distance() -> None:
    image = _image()
    settings = AppearanceSettings(descriptor="patch", max_distance=1.2, reentry_max_distance=0.05)
    memory = AppearanceMemory(settings, 2, 360, 25.0)
    seen = Detections.from_points(np.array([[150.0, 180.0]]))
    memory.remember(0, image, np.array([0]), seen, np.array([0]))  # target 1 never described
    candidates = Detections.from_points(np.array([[480.0, 180.0], [635.0, 180.0]]))
    entering = np.array([[True, True], [True, False]])
    veto = memory.veto(
        image, np.array([0, 1]), candidates, np.arange(2), np.ones((2, 2), dtype=bool), entering
    )
    # Inside: farther than 0.05 though within 1.2; at the border the patch says nothing, so an
    # entering pair there is refused; target 1 has no descriptor: its entering pair is refused.
    assert veto.tolist() == [[True, True], [True, False]]


def _heads(points: list[list[float]], sides: list[float]) -> Detections:
    xy = np.array(points, dtype=np.float64)
    side = np.array(sides, dtype=np.float64)
    boxes = np.column_stack([xy - side[:, None] / 2, side, side])
    return Detections(points=xy, scores=np.ones(len(xy)), boxes=boxes)


def test_a_refresh_waits_while_someone_nearer_covers_the_target() -> None:
    image = _image()
    settings = AppearanceSettings(descriptor="patch", refresh_s=0.04, refresh_cover_max=0.3)
    memory = AppearanceMemory(settings, 1, 360, 25.0)
    alone = _heads([[150.0, 180.0]], [12.0])
    memory.remember(0, image, np.array([0]), alone, np.array([0]))
    first = memory.descriptors[0]
    assert first is not None
    # Then a nearer person (larger head) stands right over it, in the green half: no refresh.
    crowded = _heads([[330.0, 180.0], [335.0, 175.0]], [12.0, 20.0])
    memory.remember(1, image, np.array([0]), crowded, np.array([0]))
    assert memory.descriptors[0] is first
    # Seen as the nearer of the two, it is not covered by the farther one.
    memory.remember(2, image, np.array([0]), crowded, np.array([1]))
    assert memory.descriptors[0] is not first


def test_the_first_descriptor_is_taken_even_when_covered() -> None:
    memory = AppearanceMemory(
        AppearanceSettings(descriptor="patch", refresh_cover_max=0.3), 1, 360, 25.0
    )
    crowded = _heads([[150.0, 180.0], [155.0, 175.0]], [12.0, 20.0])
    memory.remember(0, _image(), np.array([0]), crowded, np.array([0]))
    assert memory.descriptors[0] is not None


def test_covered_fractions_of_no_boxes_is_empty() -> None:
    assert covered_fractions(np.zeros((0, 4))).shape == (0,)


def test_a_crop_unlike_the_target_twice_in_a_row_is_a_swap() -> None:
    image = _image()
    settings = AppearanceSettings(
        descriptor="patch", refresh_s=0.04, swap_max_distance=0.3, swap_recheck_s=0.2
    )
    memory = AppearanceMemory(settings, 1, 360, 25.0)
    red, green = _heads([[150.0, 180.0]], [12.0]), _heads([[480.0, 180.0]], [12.0])
    target, row = np.array([0]), np.array([0])
    assert memory.remember(0, image, target, red, row).tolist() == []
    first = memory.descriptors[0]
    # Unlike once: not yet a swap, and the look is not taken; the second check waits 0.2 s.
    assert memory.remember(1, image, target, green, row).tolist() == []
    assert memory.remember(3, image, target, green, row).tolist() == []
    assert memory.remember(6, image, target, green, row).tolist() == [0]
    assert memory.descriptors[0] is first
    # One unlike crop followed by a like one is no swap.
    assert memory.remember(7, image, target, green, row).tolist() == []
    assert memory.remember(12, image, target, red, row).tolist() == []
    assert memory.remember(13, image, target, green, row).tolist() == []


def test_a_detection_is_described_once_per_frame() -> None:
    image = _image()
    memory = AppearanceMemory(AppearanceSettings(descriptor="patch"), 1, 360, 25.0)
    described: list[list[int]] = []
    describe_now = memory._describe

    def counted(image: np.ndarray, detections: Detections, rows: np.ndarray) -> np.ndarray:
        described.append(rows.tolist())
        return describe_now(image, detections, rows)

    memory._describe = counted  # type: ignore[method-assign]
    frame = Detections.from_points(np.array([[150.0, 180.0], [480.0, 180.0], [160.0, 170.0]]))
    first = memory.describe(image, frame, np.array([2, 0]))
    again = memory.describe(image, frame, np.array([0, 1, 2]))
    assert described == [[0, 2], [1]]
    assert np.array_equal(again[[2, 0]], first)
    assert np.array_equal(again, describe_now(image, frame, np.arange(3)))
    # The next frame's detections (a new object) are described afresh.
    memory.describe(image, Detections.from_points(frame.points.copy()), np.array([0]))
    assert described[-1] == [0]


class _RecordingEmbedder:
    """Stands in for the person-reid embedder: records the angle each call cuts its crops at."""

    def __init__(self) -> None:
        self.angles: list[float] = []

    def describe(self, image: np.ndarray, boxes: np.ndarray, angle: float = 0.0) -> np.ndarray:
        self.angles.append(angle)
        return np.ones((len(boxes), 4)) / 2.0


def test_upright_crops_read_the_roll_once_per_frame_and_keep_the_last_one_found(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from trackfw_plugins.trackers import appearance_memory

    readings = iter([7.5, None])
    read: list[int] = []

    def upright_angle(image: np.ndarray) -> float | None:
        read.append(id(image))
        return next(readings)

    monkeypatch.setattr(appearance_memory, "upright_angle", upright_angle)
    settings = AppearanceSettings(descriptor="person-reid", upright_crops=True)
    memory = AppearanceMemory(settings, 1, 360, 25.0)
    embedder = _RecordingEmbedder()
    memory.embedder = embedder  # type: ignore[assignment]
    first, second = _image(), _image()
    heads = Detections.from_points(np.array([[150.0, 180.0], [480.0, 180.0]]))
    memory.describe(first, heads, np.array([0]))
    memory.describe(first, Detections.from_points(heads.points.copy()), np.array([1]))
    # The second frame shows no vertical lines: its crops keep the first frame's roll.
    memory.describe(second, heads, np.array([0]))
    assert embedder.angles == [7.5, 7.5, 7.5]
    assert read == [id(first), id(second)]


def test_crops_stand_as_they_are_without_upright_crops(monkeypatch: pytest.MonkeyPatch) -> None:
    from trackfw_plugins.trackers import appearance_memory

    def never(image: np.ndarray) -> float | None:
        raise AssertionError("the roll is read only with upright_crops")

    monkeypatch.setattr(appearance_memory, "upright_angle", never)
    memory = AppearanceMemory(AppearanceSettings(descriptor="person-reid"), 1, 360, 25.0)
    embedder = _RecordingEmbedder()
    memory.embedder = embedder  # type: ignore[assignment]
    memory.describe(_image(), Detections.from_points(np.array([[150.0, 180.0]])), np.array([0]))
    assert embedder.angles == [0.0]


def test_upright_crops_without_person_reid_is_refused() -> None:
    with pytest.raises(ValueError, match="upright_crops cuts person-reid crops"):
        AppearanceSettings(descriptor="patch", upright_crops=True)
