"""Shared fixtures: the real data in ../shared/data is optional and skipped when absent."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO_ROOT.parent / "shared" / "data"

#: The smallest segment pipeline: oracle detections and decisions, Kalman tracking, assignment.
ORACLE_PIPELINE = """\
name: oracle
stages:
  detector:    {type: oracle}
  classifier:  {type: oracle}
  tracker:     {type: kalman}
  gap_matcher: {type: assignment}
"""


def decode_video(path: Path) -> list[Any]:
    """Every frame of the video file at ``path``, decoded with OpenCV (``(H, W, 3)`` BGR)."""
    import cv2

    capture = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        frames.append(frame)
    capture.release()
    return frames


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path of ../shared/data; the test is skipped when a fresh checkout does not have it."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data not found at {SHARED_DATA} (only present in the dev workspace)")
    return SHARED_DATA


def assert_one_error_line(code: int, stderr: str, *fragments: str, expected_code: int = 2) -> str:
    """The command exited with ``expected_code`` and said why in one ``error:`` line holding
    ``fragments``, without a traceback. Returns the line."""
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert code == expected_code, stderr
    assert "Traceback" not in stderr
    assert len(lines) == 1, stderr
    assert lines[0].startswith("error: "), lines[0]
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    return lines[0]


@pytest.fixture
def bad_input(capfd: pytest.CaptureFixture[str]) -> Callable[..., str]:
    """Run ``trackfw ARGUMENTS`` in this process and check it failed as bad input should.

    One ``error:`` line on stderr (FFmpeg's and OpenCV's own lines included: capfd sees file
    descriptor 2), the fragments in it, exit code 2 (or ``code``), no traceback. Returns the line.
    """
    from trackfw.cli import main

    def check(arguments: Sequence[object], *fragments: str, code: int = 2) -> str:
        exit_code = main([str(argument) for argument in arguments])
        return assert_one_error_line(
            exit_code, capfd.readouterr().err, *fragments, expected_code=code
        )

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


BadInputCase = tuple[Sequence[str], Sequence[str]]
"""One row of a sweep: the ``trackfw`` arguments and the fragments its error line must hold."""


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """A test taking ``bad_input_case`` runs once per row of its module's ``BAD_INPUT_CASES``.

    Each command package's sweep (tests/**/test_cli_bad_inputs.py) is then a table and one line.
    """
    if "bad_input_case" in metafunc.fixturenames:
        cases: list[BadInputCase] = metafunc.module.BAD_INPUT_CASES
        ids = [
            "-".join(arguments)[:60] + "-" + "-".join(fragments)[:60]
            for arguments, fragments in cases
        ]
        metafunc.parametrize("bad_input_case", cases, ids=ids, indirect=True)


@pytest.fixture
def bad_input_case(
    request: pytest.FixtureRequest, in_bad_input_workspace: Path, bad_input: Callable[..., str]
) -> Callable[[], str]:
    """Check one row of ``BAD_INPUT_CASES`` in :func:`in_bad_input_workspace`: call it to run the
    command and assert it failed in one line (see :func:`bad_input`)."""
    arguments, fragments = request.param
    return lambda: bad_input(arguments, *fragments)


def _textured_frame(seed: int, shift: float = 0.0) -> Any:
    """A 640x480 BGR frame rich in corners (blurred noise and rectangles), moved ``shift`` px."""
    import cv2
    import numpy as np

    rng = np.random.default_rng(seed)
    image = cv2.GaussianBlur(rng.integers(0, 255, (480, 640, 3), dtype=np.uint8), (5, 5), 0)
    for _ in range(80):
        x, y = (int(v) for v in rng.integers(0, 600, 2))
        colour = tuple(int(c) for c in rng.integers(0, 255, 3))
        cv2.rectangle(image, (x, y % 440), (x + 30, y % 440 + 25), colour, -1)
    matrix = np.float64([[1, 0, shift], [0, 1, 0]])
    return cv2.warpAffine(image, matrix, (640, 480), borderMode=cv2.BORDER_REFLECT)


@pytest.fixture
def textured_frame() -> Callable[..., Any]:
    """``textured_frame(seed, shift=0.0)``: a synthetic scene for registration tests."""
    return _textured_frame
