"""What the matches at b were worth: the gap matcher's proposals and the tracker's check, judged.

gaps.json records, per interval, the gap matcher's match of each target on frame b and (``at_b``,
from trackers that check them, as the built-in ``kalman`` does) what the tracker made of it: kept,
refused and why, re-matched or found by look. This judges both against the ground truth of
frame b, so that a change to the gap matcher or to the check can be aimed at what goes wrong
there. For each target recorded in ``at_b``, a detection (the proposed one, then the one it holds
after the check) is:

- ``right``: within ``--near`` pixels of the target's own ground-truth point, and no other head
  of heads.csv is nearer to it;
- ``wrong``: someone else's (or no one's) while the target is in view;
- ``absent``: any detection, while the target is not in view on frame b (it left, or is hidden);
- ``none, in view`` / ``none, out of view``: no detection.

    python benchmarks/checks_at_b.py --dataset wear-Stadtmitte --runs bench/runs/real-<hash>

It prints, per reason the check gave (``kept`` when it gave none), the proposals' verdicts, then
the verdicts after the check, counted over every gap of every video; then the verdicts after the
check by who gave the detection (``by``: the gap matcher, continuity or the look).
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from error_breakdown import run_against_truth

from trackfw.arrays import FloatArray
from trackfw.dataset import list_videos, load_video
from trackfw.errors import UserError
from trackfw.records import VideoContext

VERDICTS = ("right", "wrong", "absent", "none, in view", "none, out of view")


def judge(
    target: int,
    detection: int | None,
    points: FloatArray,
    targets: dict[int, tuple[float, float]],
    heads: FloatArray,
    near: float,
) -> str:
    """The verdict on ``target`` holding ``detection`` (a row of ``(N, 2)`` ``points``) on frame b.

    ``targets`` are the ground-truth points of that frame by id, ``heads`` its ``(M, 3)`` heads.

    >>> import numpy as np
    >>> points = np.array([[100.0, 50.0], [300.0, 50.0]])
    >>> heads = np.array([[100.0, 50.0, 20.0], [296.0, 50.0, 20.0]])
    >>> truth = {1: (100.0, 50.0), 2: (310.0, 50.0)}
    >>> [judge(1, 0, points, truth, heads, 22.0), judge(2, 1, points, truth, heads, 22.0)]
    ['right', 'wrong']
    >>> [judge(3, 0, points, truth, heads, 22.0), judge(3, None, points, truth, heads, 22.0)]
    ['absent', 'none, out of view']
    """
    present = target in targets
    if detection is None:
        return "none, in view" if present else "none, out of view"
    if not present:
        return "absent"
    point = points[detection]
    own = float(np.hypot(*(point - np.asarray(targets[target]))))
    others = np.hypot(heads[:, 0] - point[0], heads[:, 1] - point[1]) if len(heads) else []
    nearest = min(others, default=np.inf)
    return "right" if own <= near and own <= nearest + 1e-6 else "wrong"


def video_checks(video: VideoContext, run_video: Path, near: float) -> Counter[tuple[str, ...]]:
    """Counts of ``(reason, proposal verdict, final verdict, by)`` over one video's checks at b
    (``by``: who gave the held detection, ``none`` when it holds none)."""
    truth, run, detections = run_against_truth(video, run_video)
    counts: Counter[tuple[str, ...]] = Counter()
    for gap in run.gaps or []:
        if not gap.get("at_b") or gap.get("b") is None:
            continue
        b = int(gap["b"]) - 1  # gaps.json counts frames from 1
        points = np.asarray(detections.get(b, np.zeros((0, 2))), dtype=np.float64).reshape(-1, 2)
        targets = truth.targets.get(b, {})
        heads = truth.heads.get(b, np.zeros((0, 3)))
        for target_id, outcome in gap["at_b"].items():
            target = int(target_id)
            verdicts = [
                judge(
                    target, _row(outcome.get(key), points, run_video), points, targets, heads, near
                )
                for key in ("proposed", "detection")
            ]
            by = outcome.get("by") or ("none" if outcome.get("detection") is None else "?")
            counts[(outcome.get("refused") or "kept", *verdicts, by)] += 1
    return counts


def _row(index: Any, points: FloatArray, run_video: Path) -> int | None:
    """The row of a stable detection index among frame b's detections (frames.csv order)."""
    if index is None:
        return None
    if not 0 <= int(index) < len(points):
        raise UserError(
            f"{run_video}: gaps.json names detection {index} on frame b, which frames.csv does"
            f" not list; expected an index below {len(points)}."
        )
    return int(index)


def print_table(counts: Counter[tuple[str, ...]]) -> None:
    """Per reason, the proposals' verdicts and, after the check, the targets' verdicts; then the
    verdicts after the check per giver of the held detection."""
    reasons = sorted({key[0] for key in counts}, key=lambda reason: (reason != "kept", reason))
    givers = sorted({key[3] for key in counts})
    width = max(len(verdict) for verdict in VERDICTS) + 2
    for title, column, group, rows in (
        ("proposed by the gap matcher", 1, 0, reasons),
        ("held after the check", 2, 0, reasons),
        ("held after the check, by who gave it", 2, 3, givers),
    ):
        print(f"\n{title}:")
        print(
            f"{'check at b' if group == 0 else 'by':<22}"
            + "".join(f"{v:>{width}}" for v in VERDICTS)
        )
        for row in [*rows, "all"]:
            verdicts: Counter[str] = Counter()
            for key, count in counts.items():
                if row in ("all", key[group]):
                    verdicts[key[column]] += count
            print(f"{row:<22}" + "".join(f"{verdicts[v]:>{width}}" for v in VERDICTS))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--dataset", type=Path, required=True, help="dataset folder (gt.csv per video)"
    )
    parser.add_argument("--runs", type=Path, required=True, help="runs folder (one per video)")
    parser.add_argument(
        "--near", type=float, default=22.0, help="how near its own head a right detection lies, px"
    )
    args = parser.parse_args()
    counts: Counter[tuple[str, ...]] = Counter()
    videos = list_videos(args.dataset)
    for path in videos:
        video = load_video(path)
        counts += video_checks(video, args.runs / video.name, args.near)
    print(
        f"{len(videos)} videos of {args.dataset}, runs {args.runs}; {sum(counts.values())} checks at b"
    )
    print_table(counts)


if __name__ == "__main__":
    try:
        main()
    except UserError as error:
        raise SystemExit(str(error)) from None
