"""`trackfw dataset synth` killed midway: its hidden staging folder must not break the dataset."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from trackfw.cli import main

from ....conftest import ORACLE_PIPELINE

SYNTH = ["dataset", "synth", "--size", "160x90", "--videos", "1", "--jobs", "1", "--seed", "3"]


def _staging(out: Path) -> list[Path]:
    return sorted(child for child in out.iterdir() if child.name.startswith("."))


def _kill_midway(out: Path) -> None:
    """Start a synth that rewrites the dataset's video and SIGKILL it while it writes frames."""
    process = subprocess.Popen(
        [sys.executable, "-m", "trackfw.cli", *SYNTH, "--frames", "3000", "--out", str(out),
         "--force"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            partial = [folder / "video.mp4" for folder in _staging(out)]
            if any(path.is_file() and path.stat().st_size > 0 for path in partial):
                break
            assert process.poll() is None, "synth ended before it could be killed"
            time.sleep(0.05)
        else:
            pytest.fail("synth never started writing its video")
    finally:
        os.kill(process.pid, signal.SIGKILL)
        process.wait()


def test_killed_synth_leaves_a_dataset_that_check_and_run_accept_and_force_cleans(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "data"
    assert main([*SYNTH, "--frames", "60", "--out", str(out), "--format", "jpg"]) == 0
    _kill_midway(out)
    assert _staging(out), "the kill left no staging folder: nothing was reproduced"
    capsys.readouterr()
    assert main(["dataset", "check", str(out)]) == 0, capsys.readouterr().err
    pipeline = tmp_path / "oracle.yaml"
    pipeline.write_text(ORACLE_PIPELINE)
    runs = tmp_path / "runs"
    assert main(["run", str(pipeline), "--input", str(out), "--output", str(runs), "-q"]) == 0
    assert [child.name for child in runs.iterdir()] == ["synth001-plaza"]
    assert main([*SYNTH, "--frames", "60", "--out", str(out), "--format", "jpg", "--force"]) == 0
    assert _staging(out) == []
