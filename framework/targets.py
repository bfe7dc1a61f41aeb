"""The people of interest: which targets a run follows, and from which frame (``engine.init``).

Modes (docs/algorithms/index.md#targets):

* ``gt``: the rows of the video's gt.csv on the start frame (the paper's protocol);
* ``detections``: every detection of the start frame (bystanders become targets too);
* ``region``: the detections whose head point lies inside the box ``engine.region`` (x, y, w, h);
* ``targets``: a file of points, ``frame,id,x,y`` under that header (the gt.csv layout), or
  MOTChallenge text whose boxes become head points by the one rule of
  :mod:`trackfw.formats.head_point`; the run starts on the file's first frame;
* ``auto``: ``gt`` when the video has targets on the start frame, else ``detections``.

The start frame is ``engine.start_frame`` (1-based) when set, else the first readable frame (or
the targets file's first frame). Nothing is reported before it; the targets are created on the
first readable frame at or after it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw.errors import UserError
from trackfw.formats.annotations import GT_COLUMNS, read_targets
from trackfw.formats.head_point import body_head_points
from trackfw.formats.mot import read_mot_ground_truth
from trackfw.formats.text import read_text
from trackfw.pipeline import EngineOptions
from trackfw.records import Detections, VideoContext

#: ``{0-based frame: {id: (x, y)}}``, the shape of gt.csv and of a targets file once read.
FramePoints = dict[int, dict[int, tuple[float, float]]]
_EXPECTED = (
    f"target points under the header {','.join(GT_COLUMNS)} (the gt.csv layout) or MOTChallenge"
    " text (frame,id,left,top,width,height,...)"
)


@dataclass(frozen=True)
class ChosenTargets:
    """The targets a run starts with.

    Attributes:
        ids: ``(K,)`` target ids (the track ids of tracks.txt).
        positions: ``(K, 2)`` their points ``(x, y)`` on the start frame.
        source: the mode that chose them (``gt``, ``detections``, ``region``, ``targets``).
    """

    ids: IntArray
    positions: FloatArray
    source: str


def read_target_file(path: Path, n_frames: int | None = None) -> FramePoints:
    """A targets file (``--targets``) as ``{0-based frame: {id: (x, y)}}``.

    A first line of numbers is MOTChallenge text (read by :func:`read_mot_ground_truth`, boxes
    turned into head points by :func:`body_head_points`); anything else must be the gt.csv
    layout (read by :func:`read_targets`).

    Raises:
        UserError: one line naming the file, the line and the field: a bad value, a frame outside
            the video, an id that is not a positive integer or appears twice in a frame, or no
            row at all.
    """
    path = Path(path)
    first = next((line for line in read_text(path, _EXPECTED).splitlines() if line.strip()), "")
    if not first:
        raise UserError(f"{path}: empty file; expected {_EXPECTED}.")
    if _is_numeric(first) and len(first.split(",")) == len(GT_COLUMNS):
        # Points without their header: say what is missing rather than "expected 6 values".
        raise UserError(
            f"{path}: line 1: {len(GT_COLUMNS)} values and no header; expected the header"
            f" {','.join(GT_COLUMNS)} on line 1 above the points (the gt.csv layout)."
        )
    points = _mot_points(path, n_frames) if _is_numeric(first) else read_targets(path, n_frames)
    if not points:
        raise UserError(f"{path}: no target rows; expected {_EXPECTED}.")
    return points


def _is_numeric(line: str) -> bool:
    try:
        [float(value) for value in line.split(",")]
    except ValueError:
        return False
    return True


def _mot_points(path: Path, n_frames: int | None) -> FramePoints:
    rows = read_mot_ground_truth(path, n_frames)
    bad = np.flatnonzero(rows.ids < 1)
    if len(bad):
        index = int(bad[0])
        raise UserError(
            f"{path}: line {rows.lines[index]}: id {rows.ids[index]} is not a positive integer;"
            " expected ids 1, 2, ... (they become the track ids of tracks.txt)."
        )
    points: FramePoints = {}
    heads = body_head_points(rows.boxes)
    for frame, target_id, (x, y) in zip(
        rows.frames.tolist(), rows.ids.tolist(), heads.tolist(), strict=True
    ):
        points.setdefault(frame - 1, {})[target_id] = (x, y)
    return points


def parse_region(text: str, option: str = "--region") -> tuple[float, float, float, float]:
    """``"x,y,w,h"`` as four finite numbers with a positive width and height.

    >>> parse_region("100,50,300,200")
    (100.0, 50.0, 300.0, 200.0)
    """
    parts = text.split(",")
    expected = "expected x,y,w,h: four finite numbers (pixels), w and h > 0"
    try:
        values = [float(part) for part in parts]
    except ValueError:
        values = []
    if len(values) != 4 or not all(np.isfinite(values)):
        raise UserError(f"{option} {text!r}: {expected}.")
    if values[2] <= 0 or values[3] <= 0:
        raise UserError(f"{option} {text!r}: width and height must be > 0; {expected}.")
    return values[0], values[1], values[2], values[3]


class TargetChooser:
    """Chooses the targets of each video as the engine options say (one per engine)."""

    def __init__(self, options: EngineOptions) -> None:
        self.options = options
        self._points: FramePoints | None = None

    def check(self, videos: Sequence[VideoContext]) -> None:
        """Raise the UserError a run would meet on its start frame, before anything is written:
        a bad targets file, a start frame beyond a video, a region outside the image."""
        options = self.options
        if options.init == "targets" and len(videos) > 1:
            raise UserError(
                f"{options.targets}: a targets file names the people of one video; the input has"
                f" {len(videos)} videos (give one video with --input)."
            )
        for video in videos:
            start = self.start_frame(video)
            if start >= video.n_frames:
                raise UserError(
                    f"{video.path}: start frame {start + 1} is beyond the video's"
                    f" {video.n_frames} frames."
                )
            if options.region is not None:
                _check_region(options.region, video)

    def start_frame(self, video: VideoContext) -> int:
        """0-based frame before which nothing is tracked or reported."""
        if self.options.start_frame is not None:
            start = self.options.start_frame - 1
            if self.options.init == "targets" and start not in self._file(video):
                raise UserError(
                    f"{self.options.targets}: no target on frame {start + 1}"
                    " (engine.start_frame); expected rows for the start frame."
                )
            return start
        if self.options.init == "targets":
            return min(self._file(video))
        return 0

    def choose(self, video: VideoContext, t: int, detections: Detections) -> ChosenTargets:
        """The targets on frame ``t``, the first readable frame at or after the start frame."""
        mode = self.options.init
        if mode == "targets":
            # The file's frame, even when that frame could not be read and t is a later one.
            return _from_points(self._file(video)[self.start_frame(video)], "targets")
        truth = video.ground_truth
        annotated = truth.targets.get(t, {}) if truth is not None else {}
        if mode == "gt" or (mode == "auto" and annotated):
            if not annotated:
                raise UserError(
                    f"{video.path}: gt.csv has no target on frame {t + 1}; expected the people of"
                    " interest annotated on the start frame (or engine.init: detections, region"
                    " or targets)."
                )
            return _from_points(annotated, "gt")
        if mode == "region":
            assert self.options.region is not None  # EngineOptions requires it with init: region
            return _in_region(video, t, detections, self.options.region)
        return ChosenTargets(
            np.arange(1, len(detections) + 1, dtype=np.int64),
            detections.points.copy(),
            "detections",
        )

    def _file(self, video: VideoContext) -> FramePoints:
        if self._points is None:
            assert self.options.targets is not None  # EngineOptions requires it with init: targets
            self._points = read_target_file(Path(self.options.targets), video.n_frames)
        return self._points


def _from_points(points: dict[int, tuple[float, float]], source: str) -> ChosenTargets:
    ids = np.array(sorted(points), dtype=np.int64)
    positions = np.array([points[int(i)] for i in ids], dtype=np.float64).reshape(-1, 2)
    return ChosenTargets(ids, positions, source)


def _in_region(
    video: VideoContext, t: int, detections: Detections, region: tuple[float, float, float, float]
) -> ChosenTargets:
    x, y, width, height = region
    points = detections.points
    inside = (
        (points[:, 0] >= x)
        & (points[:, 0] < x + width)
        & (points[:, 1] >= y)
        & (points[:, 1] < y + height)
    )
    if not inside.any():
        raise UserError(
            f"{video.path}: no detection inside engine.region {_box_text(region)} on frame"
            f" {t + 1} ({len(points)} detections on that frame); expected the people of interest"
            " inside the box."
        )
    chosen = points[inside].copy()
    return ChosenTargets(np.arange(1, len(chosen) + 1, dtype=np.int64), chosen, "region")


def _check_region(region: tuple[float, float, float, float], video: VideoContext) -> None:
    x, y, width, height = region
    if x >= video.width or y >= video.height or x + width <= 0 or y + height <= 0:
        raise UserError(
            f"{video.path}: engine.region {_box_text(region)} lies outside the"
            f" {video.width}x{video.height} image; expected a box x,y,w,h that overlaps it."
        )


def _box_text(region: tuple[float, float, float, float]) -> str:
    return ",".join(f"{value:g}" for value in region)
