"""Every file trackfw reads or writes, each kind in one place with one reader and one writer.

* :mod:`trackfw.formats.run`: a run's files (tracks.txt, frames.csv, gaps.json, summary.json),
  their names and the frames.csv columns;
* :mod:`trackfw.formats.annotations`: a video's annotations (gt.csv, heads.csv, intervals.csv);
* :mod:`trackfw.formats.mot`: MOTChallenge text (gt.txt, det.txt, tracks.txt; MOT15 10-column
  and MOT16/17 9-column layouts);
* :mod:`trackfw.formats.head_point`: the head point (and size) of a body box, one rule;
* :mod:`trackfw.formats.text`: what the readers share (UTF-8 text, numbers, JSON, headed CSV).

Readers raise :class:`trackfw.errors.UserError` with one sentence naming the file, the line and
the field; writers write atomically (:mod:`trackfw.atomic`).
"""

from trackfw.formats.head_point import (
    HEAD_FRACTION,
    HEAD_SIZE_FRACTION,
    MEASURED_HEAD_FRACTION,
    BoxAnchor,
    body_head_points,
    body_heads,
    box_points,
)
from trackfw.formats.mot import (
    MotRows,
    boxes_by_frame,
    detections_by_frame,
    mot_track_text,
    read_mot_detections,
    read_mot_ground_truth,
    read_mot_text,
    rows_by_frame,
)

__all__ = [
    "HEAD_FRACTION",
    "HEAD_SIZE_FRACTION",
    "MEASURED_HEAD_FRACTION",
    "BoxAnchor",
    "MotRows",
    "body_head_points",
    "body_heads",
    "box_points",
    "boxes_by_frame",
    "detections_by_frame",
    "mot_track_text",
    "read_mot_detections",
    "read_mot_ground_truth",
    "read_mot_text",
    "rows_by_frame",
]
