"""`trackfw dataset synth` on a full disk: a short video is an error, never "Done"."""

from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path

#: Bytes any file may grow to in the child process, like a disk that fills up (``ulimit -f``).
FILE_SIZE_LIMIT = 40_000


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_SIZE_LIMIT, FILE_SIZE_LIMIT))


def test_synth_on_a_full_disk_fails_in_one_line_without_done(tmp_path: Path) -> None:
    out = tmp_path / "data"
    done = subprocess.run(
        [sys.executable, "-m", "trackfw.cli", "dataset", "synth", "--out", str(out), "--videos",
         "1", "--frames", "60", "--size", "320x180", "--jobs", "1", "--seed", "1"],
        capture_output=True, text=True, timeout=300, preexec_fn=_limit_file_size,
    )  # fmt: skip
    assert done.returncode != 0, done.stdout + done.stderr
    assert "Done" not in done.stdout
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "video.mp4" in errors[0] and "of 60 frames" in errors[0], (
        done.stderr[-2000:]
    )
    assert [child.name for child in out.iterdir() if child.is_dir()] == []  # no half video
