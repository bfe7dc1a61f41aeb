"""Shared fixtures: the real data in ../shared/data is optional and skipped when absent."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO_ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path of ../shared/data; the test is skipped when a fresh checkout does not have it."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data not found at {SHARED_DATA} (only present in the dev workspace)")
    return SHARED_DATA


@pytest.fixture
def bad_input(capfd: pytest.CaptureFixture[str]) -> Callable[..., str]:
    """Run ``trackfw ARGUMENTS`` in this process and check it failed as bad input should.

    One ``error:`` line on stderr (FFmpeg's and OpenCV's own lines included: capfd sees file
    descriptor 2), the fragments in it, exit code 2 (or ``code``), no traceback. Returns the line.
    """
    from trackfw.cli import main

    def check(arguments: Sequence[object], *fragments: str, code: int = 2) -> str:
        exit_code = main([str(argument) for argument in arguments])
        stderr = capfd.readouterr().err
        lines = [line for line in stderr.splitlines() if line.strip()]
        assert exit_code == code, stderr
        assert "Traceback" not in stderr
        assert len(lines) == 1, stderr
        assert lines[0].startswith("error: "), lines[0]
        for fragment in fragments:
            assert fragment in lines[0], (fragment, lines[0])
        return lines[0]

    return check


@pytest.fixture(scope="session")
def bad_input_workspace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder to run bad commands in: a two-video point dataset, a pipeline, a finished run of
    it, and things that are not what a command expects (a text file, an empty folder, a text
    file named .mp4, a JSON file that is no model).

    The commands under test must write nothing; each test starts from this same folder.
    """
    from trackfw.cli import main
    from trackfw_plugins.datasets.points import make_points_video

    root = tmp_path_factory.mktemp("bad-inputs")
    for name in ("v1", "v2"):
        make_points_video(root / "data" / name, n_frames=60, intervals=((20, 30),))
    (root / "pipeline.yaml").write_text(
        "name: sweep\n"
        "stages:\n"
        "  detector:    {type: oracle}\n"
        "  classifier:  {type: oracle}\n"
        "  tracker:     {type: kalman, params: {association: hungarian}}\n"
        "  gap_matcher: {type: assignment, params: {method: hungarian, predictor: {type: kalman}}}\n",
        encoding="utf-8",
    )
    arguments = ["run", str(root / "pipeline.yaml"), "-i", str(root / "data"), "-q"]
    assert main([*arguments, "-o", str(root / "runs")]) == 0
    (root / "file.txt").write_text("not what any command expects\n", encoding="utf-8")
    (root / "fake.mp4").write_text("this is text, not a video\n", encoding="utf-8")
    (root / "notmodel.json").write_text('{"not": "a model"}\n', encoding="utf-8")
    (root / "bad.onnx").write_text("not protobuf\n", encoding="utf-8")
    (root / "emptydir").mkdir()
    return root


@pytest.fixture
def in_bad_input_workspace(
    bad_input_workspace: Path, monkeypatch: pytest.MonkeyPatch
) -> Iterator[Path]:
    """Work in :func:`bad_input_workspace`; fails the test when the command wrote anything."""
    before = sorted(path for path in bad_input_workspace.rglob("*"))
    monkeypatch.chdir(bad_input_workspace)
    yield bad_input_workspace
    after = sorted(path for path in bad_input_workspace.rglob("*"))
    assert after == before, "a failed command wrote files"
