"""Where a run's MOTA errors come from: each target on each frame, sorted into one kind.

``trackfw eval`` says how many misses and false positives a run has; this says what they were,
so that the next change aims at the largest share. For every target of gt.csv on every frame of
the video (ground-truth point or reported point present), one kind:

- ``right``: reported within ``--dist`` of its head;
- ``missed, detected``: not reported, and a detection of frames.csv lies within ``--near`` of its
  head (the detector found it, the tracker did not report it);
- ``missed, not detected``: not reported, no detection that near;
- ``far, on a target`` / ``far, on a bystander`` / ``far, elsewhere``: reported more than
  ``--dist`` from its head, and the reported point lies on another target's head, on a head of
  heads.csv that no target has, or on none;
- ``not in view, on a target`` / ``..., on a bystander`` / ``..., elsewhere``: reported on a frame
  where gt.csv has no point for it (it left, or the frame is info-less).

Each kind is split by where the frame lies: ``segment``, ``after b`` (the first ``--after``
frames from each interval's frame b, where MOTA-In judges) or ``interval``. Ground-truth
intervals are read from intervals.csv. The share is of the ground-truth points.

    python benchmarks/error_breakdown.py --dataset wear-Stadtmitte --runs bench/runs/real-<hash>
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

import numpy as np

from trackfw.arrays import FloatArray
from trackfw.formats.annotations import read_heads, read_intervals, read_targets
from trackfw.formats.run import read_run
from trackfw.records import Interval

KINDS = (
    "right",
    "missed, detected",
    "missed, not detected",
    "far, on a target",
    "far, on a bystander",
    "far, elsewhere",
    "not in view, on a target",
    "not in view, on a bystander",
    "not in view, elsewhere",
)
PHASES = ("segment", "after b", "interval")


def phase_of(frame: int, intervals: list[Interval], after: int) -> str:
    """Where 0-based ``frame`` lies: inside an interval, in the first ``after`` frames from b, or
    in a segment.

    >>> phase_of(5, [Interval(a=3, b=8)], 3), phase_of(9, [Interval(a=3, b=8)], 3)
    ('interval', 'after b')
    >>> phase_of(11, [Interval(a=3, b=8)], 3)
    'segment'
    """
    for interval in intervals:
        if interval.a < frame < interval.b:
            return "interval"
        if interval.b <= frame < interval.b + after:
            return "after b"
    return "segment"


def place_of(point: FloatArray, others: FloatArray, heads: FloatArray, dist: float) -> str:
    """What a reported ``(2,)`` point lies on: another target's head (``(M, 2)`` ``others``), a
    bystander's (a head of ``(N, 2)`` ``heads`` no target has), or neither.

    >>> import numpy as np
    >>> heads = np.array([[0.0, 0.0], [100.0, 0.0]])
    >>> place_of(np.array([98.0, 1.0]), np.array([[0.0, 0.0]]), heads, 10.0)
    'on a bystander'
    >>> place_of(np.array([2.0, 1.0]), np.array([[0.0, 0.0]]), heads, 10.0)
    'on a target'
    """
    if len(others) and np.hypot(*(others - point).T).min() <= dist:
        return "on a target"
    if len(heads) and np.hypot(*(heads - point).T).min() <= dist:
        return "on a bystander"
    return "elsewhere"


def video_breakdown(
    dataset_video: Path, run_video: Path, dist: float, near: float, after: int
) -> Counter[tuple[str, str]]:
    """Counts of ``(kind, phase)`` over one video's targets and frames."""
    targets = read_targets(dataset_video / "gt.csv")
    heads = (
        read_heads(dataset_video / "heads.csv") if (dataset_video / "heads.csv").is_file() else {}
    )
    intervals = read_intervals(dataset_video / "intervals.csv")
    run = read_run(run_video)
    detections = dict(zip(run.frames.frames.tolist(), run.frames.detections, strict=True))
    ids = sorted({target for frame in targets.values() for target in frame})
    counts: Counter[tuple[str, str]] = Counter()
    for frame in sorted(set(targets) | set(run.tracks)):
        truth, reported = targets.get(frame, {}), run.tracks.get(frame, {})
        phase = phase_of(frame, intervals, after)
        all_heads = heads.get(frame, np.zeros((0, 3)))[:, :2]
        for target in ids:
            kind = _kind(target, truth, reported, all_heads, detections.get(frame), dist, near)
            if kind is not None:
                counts[kind, phase] += 1
    return counts


def _kind(
    target: int,
    truth: dict[int, tuple[float, float]],
    reported: dict[int, tuple[float, ...]],
    heads: FloatArray,
    detections: FloatArray | None,
    dist: float,
    near: float,
) -> str | None:
    """The kind of one target on one frame (None: neither in the ground truth nor reported)."""
    own = truth.get(target)
    point = reported.get(target)
    if own is None and point is None:
        return None
    others = np.array([p for t, p in truth.items() if t != target], dtype=np.float64).reshape(-1, 2)
    if point is None:
        found = detections is not None and len(detections) > 0
        if found and np.hypot(*(np.asarray(detections) - own).T).min() <= near:
            return "missed, detected"
        return "missed, not detected"
    where = np.asarray(point[:2], dtype=np.float64)
    if own is None:
        return "not in view, " + place_of(where, others, heads, dist)
    if np.hypot(*(where - own)) <= dist:
        return "right"
    return "far, " + place_of(where, others, heads, dist)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--dataset", type=Path, required=True, help="dataset folder (gt.csv per video)"
    )
    parser.add_argument("--runs", type=Path, required=True, help="runs folder (one per video)")
    parser.add_argument(
        "--dist", type=float, default=40.0, help="match distance in pixels (as eval)"
    )
    parser.add_argument("--near", type=float, default=22.0, help="'detected' distance in pixels")
    parser.add_argument("--after", type=int, default=10, help="frames from b counted as 'after b'")
    args = parser.parse_args()
    counts: Counter[tuple[str, str]] = Counter()
    videos = sorted(path for path in args.runs.iterdir() if (path / "tracks.txt").is_file())
    for run_video in videos:
        counts += video_breakdown(
            args.dataset / run_video.name, run_video, args.dist, args.near, args.after
        )
    truth = sum(
        counts[kind, phase]
        for kind in KINDS
        if not kind.startswith("not in view")
        for phase in PHASES
    )
    print(f"{len(videos)} videos of {args.dataset}, runs {args.runs}; {truth} ground-truth points")
    print(
        f"{'kind':30s}"
        + "".join(f"{phase:>12s}" for phase in PHASES)
        + f"{'all':>10s}{'% of gt':>10s}"
    )
    for kind in KINDS:
        row = [counts[kind, phase] for phase in PHASES]
        share = 100.0 * sum(row) / max(truth, 1)
        print(
            f"{kind:30s}"
            + "".join(f"{value:12d}" for value in row)
            + f"{sum(row):10d}{share:10.1f}"
        )


if __name__ == "__main__":
    main()
