"""`trackfw render` on a full disk: the MP4 is checked, and a short one is an error."""

from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path

from trackfw.cli import main
from trackfw_plugins.datasets.points import make_points_video

REPO = Path(__file__).resolve().parents[3]
#: Bytes any file may grow to in the child process, like a disk that fills up (``ulimit -f``).
FILE_SIZE_LIMIT = 20_000


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_SIZE_LIMIT, FILE_SIZE_LIMIT))


def test_render_on_a_full_disk_fails_in_one_line(tmp_path: Path) -> None:
    make_points_video(
        tmp_path / "data" / "clip", n_frames=120, n_targets=3, n_others=1, intervals=[(40, 50)],
        width=320, height=240,
    )  # fmt: skip
    runs = tmp_path / "runs"
    pipeline = REPO / "pipelines" / "kalman1-tr-oracle.yaml"
    assert (
        main(["run", str(pipeline), "--input", str(tmp_path / "data"), "--output", str(runs), "-q"])
        == 0
    )
    out = tmp_path / "render.mp4"
    done = subprocess.run(
        [sys.executable, "-m", "trackfw.cli", "render", str(runs / "clip"), "--out", str(out)],
        capture_output=True, text=True, timeout=300, preexec_fn=_limit_file_size,
    )  # fmt: skip
    assert done.returncode != 0, done.stdout + done.stderr
    assert "wrote" not in done.stdout
    errors = [line for line in done.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and str(out) in errors[0] and "frames" in errors[0], done.stderr[-2000:]
    assert not out.exists()
