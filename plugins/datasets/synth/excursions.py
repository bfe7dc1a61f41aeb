"""Targets that walk out of view and come back (``--leave``): the case of the target lifecycle.

A leaving target steps out of its group, walks in a straight line (along the wearer's building,
either way, or away from it into the square) until its head has left the image, stays out of
view for a while, and walks back to its place in the group. The shortest such walk is chosen:
sideways when the group is near a side of the image, away from the building when the camera
looks steeply down and the top edge is near. The wearer keeps watching the group: the
excursions are added after the camera poses are planned, so the camera does not follow the
leaver. The ground truth needs no special case: gt.csv and heads.csv have no row for a head
outside the image, so the target is absent from them while it is away.

The excursions draw from their own random stream (the video seed and a fixed tag), so a video
without ``--leave`` is drawn exactly as before the option existed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trackfw.arrays import FloatArray, IntArray

from .people import Crowd
from .presets import IntervalPlan
from .render import HEAD_DIAMETER_M
from .scene import CameraModel, Pose
from .wearer import HEAD_CENTRE_BELOW_TOP

#: Tag of the excursions' random stream (independent of the rest of the video's draws).
EXCURSION_STREAM = 17
#: Frames of normal video kept before an excursion starts and after it ends, at least.
EXCURSION_MARGIN_FRAMES = 10
#: Walking distances tried, in metres: the shortest walk that takes the head out of view wins.
DISTANCES_M = np.arange(1.0, 30.01, 0.5)
#: Walking directions on the ground (world X along the building, Y into the square); never
#: towards the building, where the square ends.
DIRECTIONS: tuple[tuple[float, float], ...] = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0))


@dataclass(frozen=True)
class Excursion:
    """One target's walk out of view and back (0-based frames).

    Attributes:
        target: the target's id (1-based, as in gt.csv).
        start: first frame of the walk out.
        out_frames: frames walking out (eased in and out).
        away_frames: frames standing off at ``distance`` metres, head outside the image.
        back_frames: frames walking back to the group.
        distance: how far the target walks, in metres.
        direction: ``(2,)`` unit direction of the walk out on the ground.
    """

    target: int
    start: int
    out_frames: int
    away_frames: int
    back_frames: int
    distance: float
    direction: tuple[float, float]

    @property
    def away(self) -> range:
        """The frames on which the target stands off, out of view."""
        first = self.start + self.out_frames
        return range(first, first + self.away_frames)

    @property
    def end(self) -> int:
        """The first frame after the walk back (the target is in its group again)."""
        return self.start + self.out_frames + self.away_frames + self.back_frames

    def offsets(self, n_frames: int) -> FloatArray:
        """``(n_frames, 2)`` the target's displacement from its group place (metres)."""
        frames = np.arange(n_frames, dtype=np.float64)
        going = np.clip((frames - self.start + 1) / (self.out_frames + 1), 0.0, 1.0)
        back_start = self.start + self.out_frames + self.away_frames
        coming = np.clip((frames - back_start + 1) / (self.back_frames + 1), 0.0, 1.0)
        # Smoothstep both ways: the walk starts and stops without a jump in speed.
        share = _smoothstep(going) - _smoothstep(coming)
        return self.distance * share[:, None] * np.asarray(self.direction)[None, :]

    def as_notes(self) -> dict[str, object]:
        """The excursion for meta.json, 1-based frames."""
        return {
            "id": self.target,
            "leaves": self.start + 1,
            "away": [self.away.start + 1, self.away.stop],
            "back": self.end,
            "distance_m": round(self.distance, 2),
            "direction": list(self.direction),
        }


def _smoothstep(u: FloatArray) -> FloatArray:
    return u * u * (3.0 - 2.0 * u)


def add_excursions(
    seed: int,
    crowd: Crowd,
    poses: FloatArray,
    camera: CameraModel,
    intervals: tuple[IntervalPlan, ...],
    count: int,
    fps: float,
) -> tuple[Crowd, list[Excursion]]:
    """Send ``count`` targets (different ones) out of view and back once each.

    Args:
        seed: the video's seed (the excursions use their own stream of it).
        crowd: everyone; targets are ``crowd.is_target``. Not modified.
        poses: ``(T, 7)`` camera poses (``scene.POSE_COLUMNS``).
        camera: intrinsics.
        intervals: the planned info-less intervals (the away frames avoid them, so the target
            is seen missing on informative frames).
        count: how many targets leave.
        fps: frame rate (walking speeds are in metres per second).

    Returns:
        The crowd with the leavers' paths changed, and the excursions that fitted (when no walk
        fits in the video the target stays with its group, and fewer excursions result).
    """
    rng = np.random.default_rng(np.random.SeedSequence([seed, EXCURSION_STREAM]))
    positions = crowd.positions.copy()
    infoless = np.zeros(positions.shape[1], dtype=bool)
    for interval in intervals:
        infoless[interval.start : interval.start + interval.length] = True
    views = _Views(poses, camera, fps)
    candidates = [int(i) for i in np.flatnonzero(crowd.is_target)]
    excursions: list[Excursion] = []
    for _ in range(count):
        # The same draws whatever the geometry, so one excursion's failure moves no other.
        peak_speed = rng.uniform(1.6, 2.2)  # m/s at the middle of the eased walk: a brisk walk
        away_frames = round(rng.uniform(1.0, 2.5) * fps)
        where, who = rng.uniform(size=2)
        moved = Crowd(positions, crowd.heights, crowd.is_target, crowd.group)
        excursion = _fit(moved, views, infoless, candidates, peak_speed, away_frames, where, who)
        if excursion is None:
            continue
        positions[excursion.target - 1] += excursion.offsets(positions.shape[1])
        candidates.remove(excursion.target - 1)
        excursions.append(excursion)
    changed = Crowd(positions, crowd.heights, crowd.is_target, crowd.group, dict(crowd.notes))
    return changed, excursions


def _fit(
    crowd: Crowd,
    views: _Views,
    infoless: np.ndarray,
    candidates: list[int],
    peak_speed: float,
    away_frames: int,
    where: float,
    who: float,
) -> Excursion | None:
    """The shortest excursion that takes a candidate's head out of view, or None.

    For each distance (shortest first): the walk's length follows from the distance and the
    speed; its start is the ``where`` share of the starts whose away frames are all informative;
    every candidate and direction whose head is then outside the image (by a head's size) on
    every away frame qualifies, and ``who`` picks one of them.
    """
    n_frames = len(infoless)
    for distance in DISTANCES_M:
        walk = max(round(1.5 * float(distance) / peak_speed * views.fps), 1)  # smoothstep peak 1.5x
        last = n_frames - EXCURSION_MARGIN_FRAMES - 2 * walk - away_frames
        starts = [
            start
            for start in range(EXCURSION_MARGIN_FRAMES, last + 1)
            if not infoless[start + walk : start + walk + away_frames].any()
        ]
        if not starts:
            return None  # longer walks fit even less
        start = starts[min(int(where * len(starts)), len(starts) - 1)]
        away = np.arange(start + walk, start + walk + away_frames)
        fitting = [
            (person, direction)
            for person in candidates
            for direction in DIRECTIONS
            if views.outside(crowd, person, away, float(distance) * np.asarray(direction))
        ]
        if fitting:
            person, direction = fitting[min(int(who * len(fitting)), len(fitting) - 1)]
            return Excursion(person + 1, start, walk, away_frames, walk, float(distance), direction)
    return None


class _Views:
    """Every frame's camera at once, to test many heads on many frames quickly."""

    def __init__(self, poses: FloatArray, camera: CameraModel, fps: float) -> None:
        self.camera = camera
        self.fps = fps
        self.rotations = np.stack([Pose.from_row(row).rotation_matrix for row in poses])
        self.centres = poses[:, 4:7]
        self.focals = camera.focal * poses[:, 3]

    def outside(self, crowd: Crowd, person: int, frames: IntArray, shift: FloatArray) -> bool:
        """True when ``person``'s head moved by ``shift`` (metres, ground) is outside the image
        by a head's size (or behind the camera) on every one of ``frames``."""
        heads = np.column_stack(
            [crowd.positions[person, frames] + shift, np.full(len(frames), crowd.heights[person])]
        )
        heads[:, 2] -= HEAD_CENTRE_BELOW_TOP
        local = np.einsum("fij,fj->fi", self.rotations[frames], heads - self.centres[frames])
        depth = local[:, 2]
        ahead = depth > 0.3
        if not ahead.any():
            return True
        focal = self.focals[frames][ahead]
        x = focal * local[ahead, 0] / depth[ahead] + self.camera.width / 2.0
        y = focal * local[ahead, 1] / depth[ahead] + self.camera.height / 2.0
        margin = focal * HEAD_DIAMETER_M / depth[ahead]
        inside = (
            (x >= -margin)
            & (x <= self.camera.width + margin)
            & (y >= -margin)
            & (y <= self.camera.height + margin)
        )
        return not bool(inside.any())
