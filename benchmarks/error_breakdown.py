"""Where a run's MOTA errors come from: each target on each frame, sorted into one kind.

``trackfw eval`` says how many misses and false positives a run has; this says what they were,
so that the next change aims at the largest share. For every target of gt.csv on every frame of
the video (ground-truth point or reported point present), one kind:

- ``right``: reported within ``--dist`` of its head;
- ``missed, detected``: not reported, and a detection of frames.csv lies within ``--near`` of its
  head and nearer to it than to any other head of heads.csv (the detector found it, the
  tracker did not report it);
- ``missed, covered``: not reported, and every detection that near is nearer to another head:
  the target is hidden behind (or merged into the box of) someone else, whose detection it
  is;
- ``missed, not detected``: not reported, no detection that near;
- ``far, on a target`` / ``far, on a bystander`` / ``far, elsewhere``: reported more than
  ``--dist`` from its head, and the reported point lies within ``--dist`` of another target's
  point, on a bystander's head (the rule of the report's "captured by a non-target":
  :mod:`trackfw_plugins.evaluation.capture`), or on neither;
- ``not in view, on a target`` / ``..., on a bystander`` / ``..., elsewhere``: reported on a frame
  where gt.csv has no point for it (it left, or the frame is info-less).

Each kind is split by where the frame lies: ``segment``, ``after b`` (the first ``--after``
frames from each interval's frame b, where MOTA-In judges) or ``interval``. Ground-truth
intervals are read from intervals.csv. The share is of the ground-truth points.

    python benchmarks/error_breakdown.py --dataset wear-Stadtmitte --runs bench/runs/real-<hash>

With ``--against`` a second runs folder of the same videos, it also lists where the two runs
differ: each stretch of frames on which one target falls into another kind in each run, and
how often each change of kind occurs (in ``--phase`` only, when given: ``after b`` is where
two pipelines' MOTA-In differ).

With ``--exits`` it splits the points reported after the target left the view by where the
target's annotation last stood: within ``--edge`` pixels of the image's border, of the edge of
the source frame inside the image (a ``trackfw dataset wear`` video, whose virtual camera shows a
blurred continuation where the real frame does not reach, and whose people vanish at that
edge), or elsewhere (hidden behind someone, or an annotation that stops).

With ``--bench DIR [DIR ...] --pipeline NAME`` in place of ``--dataset`` and ``--runs`` it pools
the runs of one pipeline over several ``trackfw bench`` output folders (each one's manifest.json
names its dataset and that pipeline's runs folder): one table for a family of sets.

    python benchmarks/error_breakdown.py --bench bench/*-Campus --pipeline real --exits

With ``--stretches KIND [KIND ...]`` it lists each stretch of at least ``--min-frames``
consecutive frames on which a target falls into a kind that starts with one of those words
(``far`` lists every ``far, ...`` kind), video by video: where a set's score is lost.
"""

from __future__ import annotations

import argparse
import bisect
import csv
import json
from collections import Counter
from dataclasses import fields
from pathlib import Path

import cv2
import numpy as np

from trackfw.arrays import FloatArray, IntArray
from trackfw.dataset import POSES_FILE, list_videos, load_video
from trackfw.errors import UserError
from trackfw.formats.run import RunRecord, read_run
from trackfw.records import GroundTruth, Interval, VideoContext
from trackfw_plugins.bench.sweep import MANIFEST_FILE
from trackfw_plugins.datasets.wear_camera import CameraPose, pose_homography, transform_points
from trackfw_plugins.datasets.wear_render import GENERATOR as WEAR_GENERATOR
from trackfw_plugins.evaluation.capture import bystander_heads, on_heads
from trackfw_plugins.maths.assignment import distance_matrix

KINDS = (
    "right",
    "missed, detected",
    "missed, covered",
    "missed, not detected",
    "far, on a target",
    "far, on a bystander",
    "far, elsewhere",
    "not in view, on a target",
    "not in view, on a bystander",
    "not in view, elsewhere",
)
PHASES = ("segment", "after b", "interval")

#: Where a target reported after it left the view had last been annotated (``--exits``).
EXITS = ("image edge", "source edge", "elsewhere", "not yet seen")


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


def place_of(point: FloatArray, others: FloatArray, bystanders: FloatArray, dist: float) -> str:
    """What a reported ``(2,)`` point lies on: within ``dist`` of another target's point (``(M,
    2)`` ``others``), on a bystander's head (``(N, 3)`` ``bystanders``), or neither.

    >>> import numpy as np
    >>> bystanders = np.array([[100.0, 0.0, 20.0]])
    >>> place_of(np.array([98.0, 1.0]), np.array([[0.0, 0.0]]), bystanders, 10.0)
    'on a bystander'
    >>> place_of(np.array([2.0, 1.0]), np.array([[0.0, 0.0]]), bystanders, 10.0)
    'on a target'
    """
    if len(others) and np.hypot(*(others - point).T).min() <= dist:
        return "on a target"
    if on_heads(point[None, :], bystanders)[0]:
        return "on a bystander"
    return "elsewhere"


def detected_as(
    own: FloatArray, detections: FloatArray | None, heads: FloatArray, near: float
) -> str:
    """Whether a missed head at ``(2,)`` ``own`` was ``detected`` (a detection within ``near``
    is nearer to it than to every other of the ``(H, 2)`` heads), ``covered`` (every detection
    that near is nearer to someone else's head) or ``not detected``.

    >>> import numpy as np
    >>> heads = np.array([[100.0, 50.0], [112.0, 46.0]])
    >>> detected_as(heads[0], np.array([[101.0, 50.0]]), heads, 22.0)
    'detected'
    >>> detected_as(heads[0], np.array([[110.0, 47.0]]), heads, 22.0)
    'covered'
    >>> detected_as(heads[0], None, heads, 22.0)
    'not detected'
    """
    if detections is None or len(detections) == 0:
        return "not detected"
    distances = np.hypot(*(detections - own).T)
    close = distances <= near
    if not close.any():
        return "not detected"
    mine = distances[close]
    others = heads[np.hypot(*(heads - own).T) > 1e-6]
    if len(others) == 0:
        return "detected"
    theirs = distance_matrix(detections[close], others).min(axis=1)
    return "detected" if (mine <= theirs).any() else "covered"


def video_breakdown(
    video: VideoContext, run_video: Path, dist: float, near: float, after: int
) -> Counter[tuple[str, str]]:
    """Counts of ``(kind, phase)`` over one video's targets and frames."""
    return Counter(video_kinds(video, run_video, dist, near, after).values())


def run_against_truth(
    video: VideoContext, run_video: Path
) -> tuple[GroundTruth, RunRecord, dict[int, FloatArray]]:
    """The video's ground truth (an error without gt.csv targets), its run, and each frame's
    ``(N, 2)`` detections from frames.csv (stable index order)."""
    truth = video.ground_truth
    if truth is None or not truth.targets:
        raise UserError(
            f"{video.path}: no ground truth; expected gt.csv with the people of interest."
        )
    run = read_run(run_video, video.n_frames)
    return truth, run, dict(zip(run.frames.frames.tolist(), run.frames.detections, strict=True))


def video_kinds(
    video: VideoContext, run_video: Path, dist: float, near: float, after: int
) -> dict[tuple[int, int], tuple[str, str]]:
    """``(kind, phase)`` of each ``(frame, target)`` of one video that is in the ground truth or
    reported."""
    truth, run, detections = run_against_truth(video, run_video)
    ids = sorted({target for frame in truth.targets.values() for target in frame})
    kinds: dict[tuple[int, int], tuple[str, str]] = {}
    for frame in sorted(set(truth.targets) | set(run.tracks)):
        points = truth.targets.get(frame, {})
        truth_ids = np.array(list(points), dtype=np.int64)
        truth_points = np.array(list(points.values()), dtype=np.float64).reshape(-1, 2)
        heads = truth.heads.get(frame, np.zeros((0, 3)))
        bystanders = bystander_heads(heads, truth_points)
        phase = phase_of(frame, truth.intervals, after)
        reported = run.tracks.get(frame, {})
        for target in ids:
            point = reported.get(target)
            kind = _kind(
                target,
                truth_ids,
                truth_points,
                None if point is None else np.asarray(point[:2], dtype=np.float64),
                bystanders,
                (detections.get(frame), heads[:, :2]),
                (dist, near),
            )
            if kind is not None:
                kinds[frame, target] = (kind, phase)
    return kinds


#: The kind of a target on a frame where it is neither in the ground truth nor reported.
NEITHER = "not in view, not reported"

#: One stretch where two runs differ: (video, target, first frame, last frame, kind, kind).
Stretch = tuple[str, int, int, int, str, str]


def differences(
    name: str,
    first: dict[tuple[int, int], tuple[str, str]],
    second: dict[tuple[int, int], tuple[str, str]],
    phase: str | None,
) -> list[Stretch]:
    """Stretches of consecutive frames on which one target's kind differs between two runs of
    video ``name`` (``phase`` only, when given): ``(video, target, first frame, last frame,
    kind in the first run, kind in the second)``, frames 0-based.

    >>> first = {(3, 1): ("right", "after b"), (4, 1): ("right", "after b")}
    >>> second = {(3, 1): ("missed, detected", "after b"), (4, 1): ("missed, detected", "after b")}
    >>> differences("v", first, second, None)
    [('v', 1, 3, 4, 'right', 'missed, detected')]
    >>> differences("v", first, {}, "segment")
    []
    """
    stretches: list[Stretch] = []
    for frame, target in sorted(set(first) | set(second), key=lambda key: (key[1], key[0])):
        kind_a, phase_a = first.get((frame, target), (NEITHER, ""))
        kind_b, phase_b = second.get((frame, target), (NEITHER, ""))
        if kind_a == kind_b or (phase is not None and phase not in (phase_a, phase_b)):
            continue
        if stretches and stretches[-1][1] == target and stretches[-1][3] == frame - 1:
            _, _, start, _, last_a, last_b = stretches[-1]
            if (last_a, last_b) == (kind_a, kind_b):
                stretches[-1] = (name, target, start, frame, kind_a, kind_b)
                continue
        stretches.append((name, target, frame, frame, kind_a, kind_b))
    return stretches


def stretches_of(
    name: str,
    kinds: dict[tuple[int, int], tuple[str, str]],
    words: list[str],
    min_frames: int,
) -> list[Stretch]:
    """Stretches of at least ``min_frames`` frames on which one target of video ``name`` falls
    into a kind that starts with one of ``words`` (the second kind of each is
    :data:`NEITHER`), target by target, frames 0-based.

    >>> kinds = {(f, 1): ("far, on a bystander", "segment") for f in range(2, 6)}
    >>> kinds[6, 1] = ("right", "segment")
    >>> stretches_of("v", kinds, ["far"], 3)
    [('v', 1, 2, 5, 'far, on a bystander', 'not in view, not reported')]
    >>> stretches_of("v", kinds, ["missed"], 1)
    []
    """
    return [
        stretch
        for stretch in differences(name, kinds, {}, None)
        if stretch[3] - stretch[2] + 1 >= min_frames
        and any(stretch[4].startswith(word) for word in words)
    ]


def _kind(
    target: int,
    truth_ids: IntArray,
    truth_points: FloatArray,
    point: FloatArray | None,
    bystanders: FloatArray,
    seen: tuple[FloatArray | None, FloatArray],
    limits: tuple[float, float],
) -> str | None:
    """The kind of one target on one frame (None: neither in the ground truth nor reported).

    ``truth_ids`` and ``(N, 2)`` ``truth_points`` are the frame's ground truth, ``point`` the
    target's reported ``(2,)`` point, ``seen`` the frame's ``(D, 2)`` detections (None: no
    frames.csv row) and ``(H, 2)`` heads of heads.csv, ``limits`` the ``(dist, near)``
    distances.
    """
    dist, near = limits
    mine = truth_ids == target
    own = truth_points[mine][0] if mine.any() else None
    if own is None and point is None:
        return None
    if point is None:
        return "missed, " + detected_as(own, *seen, near)
    others = truth_points[~mine]
    if own is None:
        return "not in view, " + place_of(point, others, bystanders, dist)
    if np.hypot(*(point - own)) <= dist:
        return "right"
    return "far, " + place_of(point, others, bystanders, dist)


def where_left(
    point: FloatArray, width: int, height: int, outline: FloatArray | None, edge: float
) -> str:
    """Where a target's last annotated ``(2,)`` point lies, as one of :data:`EXITS`.

    ``outline`` is the ``(4, 2)`` quadrilateral of the image that shows the source frame (a
    virtual-wearer video), or None.

    >>> where_left(np.array([5.0, 200.0]), 640, 480, None, 30.0)
    'image edge'
    >>> shown = np.array([[100.0, 100.0], [500.0, 100.0], [500.0, 400.0], [100.0, 400.0]])
    >>> where_left(np.array([490.0, 200.0]), 640, 480, shown, 30.0)
    'source edge'
    >>> where_left(np.array([300.0, 200.0]), 640, 480, shown, 30.0)
    'elsewhere'
    """
    x, y = float(point[0]), float(point[1])
    if min(x, width - 1 - x, y, height - 1 - y) < edge:
        return "image edge"
    if outline is not None:
        contour = np.asarray(outline, dtype=np.float32).reshape(-1, 1, 2)
        if abs(cv2.pointPolygonTest(contour, (x, y), True)) < edge:
            return "source edge"
    return "elsewhere"


def source_outlines(video: VideoContext) -> dict[int, FloatArray]:
    """0-based frame -> ``(4, 2)`` outline of the source frame in the image, on each frame of a
    ``trackfw dataset wear`` video that shows the real sequence; empty for other videos.

    The source size is meta.json's ``source_size`` (older sets: the video's own size, which is
    the default of ``--size``).
    """
    path = Path(video.path) / POSES_FILE
    if video.meta.get("generator") != WEAR_GENERATOR or not path.is_file():
        return {}
    width, height = video.meta.get("source_size", (video.width, video.height))
    corners = np.array([[0, 0], [width, 0], [width, height], [0, height]], dtype=np.float64)
    names = [field.name for field in fields(CameraPose)]
    outlines: dict[int, FloatArray] = {}
    with path.open(newline="", encoding="utf-8") as stream:
        for row in csv.DictReader(stream):
            if row.get("view", "real") != "real":
                continue
            pose = CameraPose(**{name: float(row[name]) for name in names})
            homography = pose_homography(
                pose,
                (int(width), int(height)),
                (video.width, video.height),
                float(video.meta["horizontal_fov"]),
            )
            outlines[int(row["frame"]) - 1] = transform_points(homography, corners)
    return outlines


def video_exits(
    video: VideoContext, kinds: dict[tuple[int, int], tuple[str, str]], edge: float
) -> Counter[tuple[str, str]]:
    """Counts of ``(kind, exit)``: each point of a target reported after it left the view, by
    where its annotation last stood before that frame (:func:`where_left`)."""
    truth = video.ground_truth
    assert truth is not None  # video_kinds has checked it
    outlines = source_outlines(video)
    annotated: dict[int, list[int]] = {}
    for frame in sorted(truth.targets):
        for target in truth.targets[frame]:
            annotated.setdefault(target, []).append(frame)
    counts: Counter[tuple[str, str]] = Counter()
    for (frame, target), (kind, _) in kinds.items():
        if not kind.startswith("not in view") or kind == NEITHER:
            continue
        frames = annotated.get(target, [])
        before = bisect.bisect_left(frames, frame)
        if before == 0:
            counts[kind, "not yet seen"] += 1
            continue
        last = frames[before - 1]
        point = np.asarray(truth.targets[last][target], dtype=np.float64)
        exit_kind = where_left(point, video.width, video.height, outlines.get(last), edge)
        counts[kind, exit_kind] += 1
    return counts


def print_exits(counts: Counter[tuple[str, str]]) -> None:
    """The ``--exits`` table: reported-after-leaving kinds by where the target left."""
    print(f"\n{'reported after it left':30s}" + "".join(f"{name:>14s}" for name in EXITS))
    for kind in KINDS:
        if kind.startswith("not in view") and kind != NEITHER:
            print(f"{kind:30s}" + "".join(f"{counts[kind, name]:14d}" for name in EXITS))


def bench_runs(bench: Path, pipeline: str) -> tuple[Path, Path]:
    """The dataset folder and pipeline ``pipeline``'s runs folder of one ``trackfw bench``
    output folder, from its manifest.json."""
    path = bench / MANIFEST_FILE
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
        dataset = Path(manifest["dataset"])
        named = {entry["name"]: entry["runs_dir"] for entry in manifest["pipelines"]}
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise UserError(
            f"{path}: not a readable bench manifest ({error}); expected the manifest.json that"
            " trackfw bench writes, with 'dataset' and 'pipelines'."
        ) from error
    if pipeline not in named:
        raise UserError(
            f"{path}: no pipeline named {pipeline!r} in 'pipelines'; expected one of "
            f"{', '.join(sorted(named)) or 'none'}."
        )
    return dataset, Path(named[pipeline])


def run_pairs(args: argparse.Namespace) -> list[tuple[Path, Path]]:
    """``(dataset, runs folder)`` pairs the command line names: one from ``--dataset`` and
    ``--runs``, or one per ``--bench`` folder."""
    if args.bench:
        if args.pipeline is None or args.dataset is not None or args.runs is not None:
            raise UserError("--bench: expected --pipeline NAME and neither --dataset nor --runs.")
        if args.against is not None:
            raise UserError("--against: expected --dataset and --runs, not --bench.")
        return [bench_runs(bench, args.pipeline) for bench in args.bench]
    if args.dataset is None or args.runs is None or args.pipeline is not None:
        raise UserError("expected --dataset and --runs, or --bench with --pipeline.")
    return [(args.dataset, args.runs)]


def parse_arguments() -> argparse.Namespace:
    """The command line's options."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dataset", type=Path, help="dataset folder (gt.csv per video)")
    parser.add_argument("--runs", type=Path, help="runs folder (one per video)")
    parser.add_argument(
        "--bench",
        type=Path,
        nargs="+",
        metavar="DIR",
        help="trackfw bench output folders to pool (with --pipeline), instead of --dataset/--runs",
    )
    parser.add_argument("--pipeline", help="with --bench: the pipeline name whose runs to read")
    parser.add_argument(
        "--dist", type=float, default=40.0, help="match distance in pixels (as eval)"
    )
    parser.add_argument("--near", type=float, default=22.0, help="'detected' distance in pixels")
    parser.add_argument("--after", type=int, default=10, help="frames from b counted as 'after b'")
    parser.add_argument(
        "--against", type=Path, help="a second runs folder: list where its kinds differ"
    )
    parser.add_argument(
        "--phase", choices=PHASES, help="with --against: only the differences in this phase"
    )
    parser.add_argument(
        "--exits", action="store_true", help="split the reports after leaving by where it left"
    )
    parser.add_argument(
        "--edge", type=float, default=30.0, help="with --exits: 'edge' distance in pixels"
    )
    parser.add_argument(
        "--stretches",
        nargs="+",
        metavar="KIND",
        help="list the stretches of the kinds that start with these words",
    )
    parser.add_argument(
        "--min-frames", type=int, default=3, help="with --stretches: the shortest stretch listed"
    )
    return parser.parse_args()


def main() -> None:
    args = parse_arguments()
    counts: Counter[tuple[str, str]] = Counter()
    exits: Counter[tuple[str, str]] = Counter()
    changed: list[Stretch] = []
    listed: list[Stretch] = []
    videos = [
        (load_video(path), runs)
        for dataset, runs in run_pairs(args)
        for path in list_videos(dataset)
    ]
    for video, runs in videos:
        kinds = video_kinds(video, runs / video.name, args.dist, args.near, args.after)
        counts += Counter(kinds.values())
        if args.stretches:
            listed += stretches_of(video.name, kinds, args.stretches, args.min_frames)
        if args.exits:
            exits += video_exits(video, kinds, args.edge)
        if args.against is not None:
            other = video_kinds(video, args.against / video.name, args.dist, args.near, args.after)
            changed += differences(video.name, kinds, other, args.phase)
    truth = sum(
        counts[kind, phase]
        for kind in KINDS
        if not kind.startswith("not in view")
        for phase in PHASES
    )
    source = (
        f"{len(args.bench)} bench folders, pipeline {args.pipeline}"
        if args.bench
        else f"{args.dataset}, runs {args.runs}"
    )
    print(f"{len(videos)} videos of {source}; {truth} ground-truth points")
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
    if args.exits:
        print_exits(exits)
    if args.against is not None:
        print_differences(changed, args.against, args.phase)
    if args.stretches:
        print(f"\nstretches of {', '.join(args.stretches)} (at least {args.min_frames} frames):")
        for name, target, first, last, kind, _ in listed:
            print(
                f"  {name} target {target} frames {first + 1}-{last + 1} ({last - first + 1}): {kind}"
            )


def print_differences(changed: list[Stretch], against: Path, phase: str | None) -> None:
    """Each stretch where the second run's kinds differ, then the frames per change of kind."""
    where = f" ({phase})" if phase else ""
    print(f"\nwhere {against} differs{where}: video, target, frames (1-based), kind -> kind")
    frames: Counter[tuple[str, str]] = Counter()
    for name, target, first, last, kind_a, kind_b in changed:
        print(f"  {name} target {target} frames {first + 1}-{last + 1}: {kind_a} -> {kind_b}")
        frames[kind_a, kind_b] += last - first + 1
    for (kind_a, kind_b), count in frames.most_common():
        print(f"{count:8d} frames  {kind_a} -> {kind_b}")


if __name__ == "__main__":
    try:
        main()
    except UserError as error:
        raise SystemExit(str(error)) from None
