"""Frames per second of a whole pipeline run in one process, with the milliseconds of each stage.

Usage::

    python benchmarks/pipeline_speed.py [--pipeline pipelines/proposed.yaml] --input DIR [--videos 3]
        [--set PATH=VALUE ...]

Runs ``trackfw run PIPELINE --input VIDEO`` (the user's command, one process, no stage cache) on
the first ``--videos`` videos of a dataset folder (or on one video folder) and reads each run's
summary.json. Prints, per video and over all of them, frames per second (decoding, every stage
and writing the outputs included) and the mean milliseconds per call of each stage; the gap
matcher runs only on the frames that end an interval.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from trackfw.formats.run import SUMMARY_FILE
from trackfw.stages import STAGE_KINDS


def video_folders(source: Path, count: int) -> list[Path]:
    """The video folders of a dataset (or the folder itself when it is one video)."""
    from trackfw.dataset import list_videos

    videos = list_videos(source)
    return videos[:count] if videos else [source]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pipeline", type=Path, default=Path("pipelines/proposed.yaml"))
    parser.add_argument("--input", type=Path, required=True, help="dataset or video folder")
    parser.add_argument("--videos", type=int, default=3, help="videos of the dataset to run")
    parser.add_argument("--set", action="append", default=[], help="override, PATH=VALUE")
    arguments = parser.parse_args()
    frames = 0
    seconds = 0.0
    stage_ms: dict[str, list[tuple[float, int]]] = {stage: [] for stage in STAGE_KINDS}
    # The console script installed beside this interpreter: exactly the user's command.
    trackfw = str(Path(sys.executable).with_name("trackfw"))
    with tempfile.TemporaryDirectory() as scratch:
        for video in video_folders(arguments.input, arguments.videos):
            out = Path(scratch) / video.name
            command = [
                trackfw,
                "run",
                str(arguments.pipeline),
                "--input",
                str(video),
                "--output",
                str(out),
                "--quiet",
            ]
            for override in arguments.set:
                command += ["--set", override]
            subprocess.run(command, check=True)
            summaries = list(out.rglob(SUMMARY_FILE))
            if len(summaries) != 1:
                raise SystemExit(f"{out}: expected one summary.json, found {len(summaries)}")
            summary = json.loads(summaries[0].read_text())
            frames += summary["n_frames"]
            seconds += summary["seconds"]
            print(
                f"{video.name}: {summary['n_frames']} frames, {summary['frames_per_second']:.2f} fps,"
                + "".join(
                    f" {stage} {value:.1f} ms" if value is not None else f" {stage} -"
                    for stage, value in summary["ms_per_frame"].items()
                )
            )
            for stage in STAGE_KINDS:
                value = summary["ms_per_frame"].get(stage)
                if value is not None:
                    calls = summary["intervals"] if stage == "gap_matcher" else summary["n_frames"]
                    stage_ms[stage].append((value, max(calls, 1)))
    print(
        f"{arguments.pipeline} on {arguments.input}: {frames} frames in {seconds:.1f} s"
        f" = {frames / seconds:.2f} fps (one process, load average {os.getloadavg()[0]:.2f})"
    )
    for stage, values in stage_ms.items():
        if values:
            weighted = sum(value * calls for value, calls in values) / sum(c for _, c in values)
            print(f"  {stage:12s} {weighted:8.1f} ms per call")


if __name__ == "__main__":
    main()
