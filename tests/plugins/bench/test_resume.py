"""A sweep killed with SIGKILL resumes where it stopped, with the results of an uninterrupted one."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from trackfw.cli import main


def _results(out: Path) -> dict[str, object]:
    """Every run's tracks and gap decisions (timings left out), and the table's metrics."""
    found: dict[str, object] = {}
    for run in sorted((out / "runs").glob("*/*/")):
        if not run.is_dir():
            continue
        gaps = json.loads((run / "gaps.json").read_text())
        for gap in gaps:
            gap.pop("milliseconds")
        key = f"{run.parent.name}/{run.name}"
        found[key] = ((run / "tracks.txt").read_text(), gaps)
    lines = (out / "table.csv").read_text().splitlines()
    header = lines[0].split(",")
    keep = [i for i, name in enumerate(header) if name != "fps" and not name.startswith("ms ")]
    found["table"] = [[line.split(",")[i] for i in keep] for line in lines]
    return found


def test_a_killed_sweep_resumes_to_the_uninterrupted_result(
    bench_plugin, bench_pipeline, small_dataset, tmp_path: Path
) -> None:
    dataset = small_dataset(count=3, n_frames=100)
    pipelines = [
        str(bench_pipeline("slow-a", sleep_ms=2)),
        str(bench_pipeline("slow-b", method="nearest", sleep_ms=2)),
    ]
    killed = tmp_path / "killed"
    command = [sys.executable, "-m", "trackfw.cli", "bench", *pipelines, "--dataset", str(dataset)]
    process = subprocess.Popen(
        [*command, "--out", str(killed), "-q"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "PYTHONPATH": str(bench_plugin)},
    )
    deadline = time.monotonic() + 60
    try:
        while time.monotonic() < deadline and process.poll() is None:
            if list(killed.glob("runs/*/*/summary.json")):
                break
            time.sleep(0.01)
        assert process.poll() is None, "the sweep ended before it could be killed"
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait(timeout=30)
    assert process.returncode == -signal.SIGKILL
    finished = list(killed.glob("runs/*/*/summary.json"))
    assert 1 <= len(finished) < 6, "expected a sweep stopped midway"
    assert not (killed / "table.csv").exists()
    # A run folder left half-written, as a kill inside write_run would leave it.
    half = killed / "runs" / finished[0].parent.parent.name / "v2"
    if not (half / "summary.json").exists():
        half.mkdir(parents=True, exist_ok=True)
        (half / "tracks.txt").write_text("1,1,0,0,80,80,1,-1,-1,-1\n")

    assert main(["bench", *pipelines, "--dataset", str(dataset), "--out", str(killed), "-q"]) == 0
    manifest = json.loads((killed / "manifest.json").read_text())
    assert manifest["counts"]["skipped"] == len(finished)
    assert manifest["counts"]["done"] == 6 - len(finished)

    reference = tmp_path / "reference"
    assert (
        main(["bench", *pipelines, "--dataset", str(dataset), "--out", str(reference), "-q"]) == 0
    )
    assert _results(killed) == _results(reference)
