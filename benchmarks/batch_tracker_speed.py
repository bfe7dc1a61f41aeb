"""Speed of the batch trackers on oracle detections (every visible head, 80x80 px boxes at 1080p).

Targets (issue 21), one core: dpnms >= 2000 frames/s, gtcsa >= 200 frames/s, smot and cem under
30 s per 1000-frame video. Every video of the dataset is tracked by each tracker; the figures are
total frames / total seconds, and seconds per 1000 frames.

    trackfw dataset synth --preset paper --seed 5 --out /tmp/synth
    python benchmarks/batch_tracker_speed.py /tmp/synth [--trackers dpnms gtcsa smot cem] [--videos N]
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from trackfw.dataset import list_videos, load_video
from trackfw.records import VideoContext
from trackfw_plugins.batch_trackers.bytetrack import track_bytetrack
from trackfw_plugins.batch_trackers.cem import track_cem
from trackfw_plugins.batch_trackers.dpnms import track_dpnms
from trackfw_plugins.batch_trackers.gtcsa import track_gtcsa
from trackfw_plugins.batch_trackers.smot import track_smot
from trackfw_plugins.batch_trackers.tracks import PAPER_BOX_SIZE, Tracks, VideoDetections
from trackfw_plugins.maths.gog import single_threaded_blas

TRACKERS: dict[str, Callable[[VideoDetections, VideoContext], Tracks]] = {
    "dpnms": lambda detections, video: track_dpnms(detections),
    "bytetrack": lambda detections, video: track_bytetrack(detections, video.fps),
    "gtcsa": lambda detections, video: track_gtcsa(detections, video.height),
    "smot": lambda detections, video: track_smot(detections),
    "cem": lambda detections, video: track_cem(detections, video.width, video.height),
}


def oracle_detections(video: VideoContext) -> VideoDetections:
    """Every annotated head of the video as a detection with score 1 and the paper's box."""
    heads = video.ground_truth.heads if video.ground_truth is not None else {}
    frames = [np.full(len(rows), frame) for frame, rows in heads.items()]
    points = [rows[:, :2] for rows in heads.values()]
    box = PAPER_BOX_SIZE * video.height / 1080.0
    return VideoDetections.from_points(
        np.concatenate(frames) if frames else np.zeros(0),
        np.concatenate(points) if points else np.zeros((0, 2)),
        video.n_frames,
        box_size=box,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--trackers", nargs="+", default=list(TRACKERS), choices=list(TRACKERS))
    parser.add_argument("--videos", type=int, default=None, help="only the first N videos")
    args = parser.parse_args()
    videos = [load_video(path) for path in list_videos(args.dataset)][: args.videos]
    inputs = [(video, oracle_detections(video)) for video in videos]
    total_frames = sum(video.n_frames for video in videos)
    total_detections = sum(len(detections) for _, detections in inputs)
    print(f"{len(videos)} videos, {total_frames} frames, {total_detections} detections")
    print(f"load: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    for name in args.trackers:
        run = TRACKERS[name]
        started = time.process_time()
        tracks = 0
        # One core, as the stages run them (BLAS held to one thread).
        with single_threaded_blas():
            for video, detections in inputs:
                tracks += len(run(detections, video).track_ids())
        seconds = time.process_time() - started
        print(
            f"{name:10s} {total_frames / seconds:10.1f} frames/s  "
            f"{1000.0 * seconds / total_frames:8.2f} s per 1000 frames  ({tracks} tracks, "
            f"{seconds:.2f} s CPU)"
        )


if __name__ == "__main__":
    main()
