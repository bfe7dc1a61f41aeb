"""Bad input to every core command: one ``error:`` line, exit code 2, no traceback, nothing written.

Signals: Ctrl-C (SIGINT) exits 130 and SIGTERM 143, leaving only complete files.
Plugin commands have their own sweeps under tests/plugins/<package>/test_cli_bad_inputs.py.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from trackfw.cli import main

from ..conftest import assert_one_error_line
from .conftest import PIPELINE


def run_cli(capsys: pytest.CaptureFixture[str], *arguments: object) -> tuple[int, str]:
    """Exit code and stderr of ``trackfw ARGUMENTS`` run in this process."""
    code = main([str(argument) for argument in arguments])
    return code, capsys.readouterr().err


def assert_run_refused(
    capture: pytest.CaptureFixture[str], pipeline: Path, source: Path, output: Path, *fragments: str
) -> None:
    """``trackfw run`` of ``source`` into ``output`` fails in one error line holding
    ``fragments`` and writes nothing."""
    code, stderr = run_cli(capture, "run", pipeline, "-i", source, "-o", output, "-q")
    assert_one_error_line(code, stderr, *fragments)
    assert not output.exists()


def files_under(folder: Path) -> list[Path]:
    return sorted(path for path in folder.rglob("*") if path.is_file()) if folder.exists() else []


# ----------------------------------------------------------------------------------- usage errors

USAGE_ERRORS = [
    (["frobnicate"], ["No such command 'frobnicate'", "Usage: trackfw", "trackfw --help"]),
    (["run"], ["Missing argument", "Usage: trackfw run", "trackfw run --help"]),
    (["run", "p.yaml", "--frobnicate"], ["No such option: --frobnicate", "trackfw run --help"]),
    (["run", "p.yaml", "--output"], ["--output", "requires an argument"]),
    (["validate"], ["Missing argument", "Usage: trackfw validate"]),
    (["plugins", "extra"], ["unexpected extra argument", "Usage: trackfw plugins"]),
    (["bench", "p.yaml", "--dataset", "d", "--jobs", "many"], ["--jobs", "integer"]),
    (
        ["bench", "p.yaml", "--dataset", "d", "--jobs", "0"],
        ["--jobs", "greater than or equal to 1"],
    ),
    (["eval", "--runs", "r"], ["Missing option '--dataset'"]),
    (["render", "r", "--trail", "-3"], ["--trail", "greater than or equal to 0"]),
    (["dataset", "frobnicate"], ["No such command 'frobnicate'", "trackfw dataset --help"]),
    (["train", "classifier", "--frobnicate"], ["No such option", "trackfw train classifier"]),
]


@pytest.mark.parametrize(("arguments", "fragments"), USAGE_ERRORS, ids=lambda v: "-".join(v))
def test_usage_errors_are_one_line_with_the_usage(
    arguments: list[str],
    fragments: list[str],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # typer >= 0.26 vendors click: the error path must not need the click package.
    monkeypatch.setitem(sys.modules, "click", None)
    code, stderr = run_cli(capsys, *arguments)
    assert_one_error_line(code, stderr, *fragments)


@pytest.mark.parametrize("group", [[], ["dataset"], ["train"]], ids=["root", "dataset", "train"])
def test_a_group_without_command_shows_its_help(
    group: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(group)
    captured = capsys.readouterr()
    assert code == 2
    assert "Usage: trackfw" in captured.out + captured.err
    assert "Traceback" not in captured.err and "error:" not in captured.err


def test_an_unexpected_exception_is_one_line_with_exit_1(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # A bug, not bad input: one line, exit 1, and --debug for the traceback.
    def broken(*_arguments: object, **_options: object) -> None:
        raise ZeroDivisionError("a bug")

    monkeypatch.setitem(sys.modules, "click", None)
    monkeypatch.setattr("trackfw.pipeline.load_pipeline", broken)
    code, stderr = run_cli(capsys, "validate", "p.yaml")
    assert_one_error_line(code, stderr, "ZeroDivisionError: a bug", "--debug", expected_code=1)
    with pytest.raises(ZeroDivisionError):
        main(["--debug", "validate", "p.yaml"])


# ---------------------------------------------------------------------------------- run --output


def test_output_that_is_an_existing_file_fails_before_any_work(
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    existing = tmp_path / "results.txt"
    existing.write_text("keep me\n", encoding="utf-8")
    video = points_video()

    def no_work(*_arguments: object) -> None:
        raise AssertionError("videos were read before the output was checked")

    monkeypatch.setattr("trackfw.runner.load_video", no_work)
    code, stderr = run_cli(capsys, "run", pipeline_file(), "-i", video, "-o", existing, "-q")
    assert_one_error_line(code, stderr, "--output", str(existing), "existing file", "folder")
    assert existing.read_text(encoding="utf-8") == "keep me\n"


def test_output_inside_a_file_fails_before_any_work(
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    existing = tmp_path / "results.txt"
    existing.write_text("", encoding="utf-8")
    code, stderr = run_cli(
        capsys, "run", pipeline_file(), "-i", points_video(), "-o", existing / "sub", "-q"
    )
    assert_one_error_line(code, stderr, "--output", str(existing), "not a folder")


def test_output_in_an_unwritable_folder_fails_before_any_work(
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    if os.access(locked, os.W_OK):
        # root writes anywhere: make the permission check see what a normal user would.
        real_access = os.access
        monkeypatch.setattr(
            os,
            "access",
            lambda path, mode, **kw: False if Path(path) == locked else real_access(path, mode),
        )
    try:
        code, stderr = run_cli(
            capsys, "run", pipeline_file(), "-i", points_video(), "-o", locked / "out", "-q"
        )
    finally:
        locked.chmod(0o755)
    assert_one_error_line(code, stderr, "--output", str(locked), "not writable")
    assert files_under(locked) == []


def test_default_output_is_checked_too(
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "runs").write_text("", encoding="utf-8")  # a file where runs/ should go
    code, stderr = run_cli(capsys, "run", pipeline_file(), "-i", points_video(), "-q")
    assert_one_error_line(code, stderr, "output", "runs", "not a folder")


# ---------------------------------------------------------------------------------------- signals


@contextmanager
def _signal_not_ignored(signum: int) -> Iterator[None]:
    """Python's default handler for ``signum`` while inside, when the process ignores it.

    A background job (``cmd &``, ``nohup``) inherits SIGINT ignored, and the CLI rightly leaves
    an ignored signal ignored; the test stands in for a terminal where Ctrl-C reaches the run.
    """
    if signal.getsignal(signum) is not signal.SIG_IGN:
        yield
        return
    default = signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL
    signal.signal(signum, default)
    try:
        yield
    finally:
        signal.signal(signum, signal.SIG_IGN)


@pytest.mark.parametrize(
    ("signum", "expected_code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["int", "term"]
)
def test_a_signal_mid_run_exits_128_plus_signal_and_leaves_only_complete_videos(
    signum: int,
    expected_code: int,
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from trackfw.engine import Engine

    points_video("a")
    points_video("b")
    output = tmp_path / "out"
    real_run_video = Engine.run_video
    calls: list[str] = []

    def run_video(self: Engine, video: object, *arguments: object, **options: object) -> object:
        calls.append(str(getattr(video, "name", "")))
        if len(calls) == 2:  # the user presses Ctrl-C (or kill runs) during the second video
            os.kill(os.getpid(), signum)
        return real_run_video(self, video, *arguments, **options)  # type: ignore[arg-type]

    monkeypatch.setattr(Engine, "run_video", run_video)
    with _signal_not_ignored(signum):
        previous = signal.getsignal(signum)
        code, stderr = run_cli(
            capsys, "run", pipeline_file(PIPELINE), "-i", tmp_path / "data", "-o", output, "-q"
        )
        assert signal.getsignal(signum) == previous  # the CLI put the handler back
    assert_one_error_line(
        code, stderr, f"interrupted by {signal.Signals(signum).name}", expected_code=expected_code
    )
    assert calls == ["a", "b"]
    assert {path.name for path in files_under(output / "a")} >= {"summary.json", "tracks.txt"}
    assert not (output / "b").exists()
    assert not [path for path in files_under(output) if path.suffix == ".tmp"]


# ------------------------------------------------------------------------------------ run --input


@pytest.mark.parametrize(
    ("content", "fragments"),
    [
        (b"", ["empty file (0 bytes)", "expected a video file"]),
        (b"this is a text file, not a video\n" * 20, ["not a video FFmpeg can open"]),
        (b"\x00\x00\x00\x18ftypmp42" + bytes(200), ["not a video FFmpeg can open"]),
    ],
    ids=["empty", "text", "mp4-header-only"],
)
def test_a_file_that_is_no_video_is_reported_once_in_trackfw_words(
    content: bytes,
    fragments: list[str],
    pipeline_file: Callable[..., Path],
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
) -> None:
    fake = tmp_path / "clip.mp4"
    fake.write_bytes(content)
    # capfd sees file descriptor 2, where FFmpeg writes its own "moov atom not found".
    assert_run_refused(capfd, pipeline_file(), fake, tmp_path / "out", str(fake), *fragments)


def test_a_fake_video_inside_a_video_folder_with_meta_is_reported_too(
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
) -> None:
    # meta.json gives the size and the frame count, so nothing used to open the file before the
    # decoder silently reported every frame as unread.
    video = points_video()
    (video / "video.mp4").write_text("not a video\n", encoding="utf-8")
    fake = video / "video.mp4"
    assert_run_refused(capfd, pipeline_file(), video, tmp_path / "out", str(fake), "not a video")


def _write_frames(folder: Path, sizes: list[tuple[int, int]], suffix: str = ".jpg") -> list[Path]:
    import cv2
    import numpy as np

    folder.mkdir(parents=True)
    paths = []
    for index, (width, height) in enumerate(sizes, start=1):
        path = folder / f"{index:06d}{suffix}"
        assert cv2.imwrite(str(path), np.full((height, width, 3), 40 * index % 256, np.uint8))
        paths.append(path)
    return paths


@pytest.mark.parametrize("suffix", [".jpg", ".png", ".bmp"])
def test_frames_of_mixed_sizes_name_the_first_odd_one_and_the_expected_size(
    suffix: str,
    pipeline_file: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    paths = _write_frames(
        tmp_path / "clip" / "img1", [(64, 48), (64, 48), (32, 24), (48, 64)], suffix
    )
    fragments = (str(paths[2]), "32x24", "expected 64x48", paths[0].name)
    assert_run_refused(capsys, pipeline_file(), tmp_path / "clip", tmp_path / "out", *fragments)


def test_frames_of_mixed_sizes_are_refused_when_meta_gives_the_size_too(
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    video = points_video()  # meta.json with width, height and n_frames
    paths = _write_frames(video / "img1", [(64, 48), (64, 40)], ".png")
    fragments = (str(paths[1]), "64x40", "expected 64x48")
    assert_run_refused(capsys, pipeline_file(), video, tmp_path / "out", *fragments)


# ------------------------------------------------------------ run, validate, bench: the sweep

RUN = ["run", "pipeline.yaml", "-q", "-o", "out"]
BENCH = ["bench", "pipeline.yaml", "--dataset", "data", "-q"]

BAD_INPUT_CASES = [
    (["validate", "missing.yaml"], ["missing.yaml: pipeline file not found"]),
    (["validate", "emptydir"], ["emptydir", "pipeline file"]),
    (["validate", "fake.mp4"], ["fake.mp4"]),
    ([*RUN, "-i", "emptydir"], ["emptydir: no video found"]),
    ([*RUN, "-i", "missing"], ["--input: 'missing' does not exist"]),
    ([*RUN, "-i", "builtin:nope"], ["unknown input 'nope'"]),
    ([*RUN, "-i", "data", "--set", "noequals"], ["--set 'noequals'", "PATH=VALUE"]),
    ([*RUN, "-i", "data", "--set", "stages.tracker.params.zzz=1"], ["zzz: unknown parameter"]),
    ([*RUN, "-i", "fake.mp4"], ["fake.mp4: not a video FFmpeg can open"]),
    (["run", "pipeline.yaml", "-q", "-i", "data", "-o", "file.txt"], ["--output", "file.txt"]),
    ([*BENCH, "-o", "file.txt"], ["--out", "file.txt is an existing file"]),
    ([*BENCH, "-o", "b", "--cache-dir", "file.txt"], ["--cache-dir", "file.txt"]),
    ([*BENCH, "-o", "b", "--dist", "nan"], ["--dist is nan"]),
    ([*BENCH, "-o", "b", "--timeout", "-1"], ["--timeout is -1.0"]),
    ([*BENCH, "-o", "b", "--executor", "nope"], ["unknown executor 'nope'"]),
    (["bench", "missing.yaml", "--dataset", "data", "-o", "b"], ["missing.yaml"]),
    (["bench", "pipeline.yaml", "--dataset", "missing", "-o", "b"], ["missing: no such file"]),
]


def test_core_commands_refuse_bad_input_in_one_line(bad_input_case: Callable[[], str]) -> None:
    bad_input_case()


@pytest.mark.parametrize(
    ("meta", "fragments"),
    [
        ('{"n_frames": "abc", "width": 640, "height": 480}', ['n_frames is "abc"', "whole number"]),
        ('{"n_frames": 40, "width": -5, "height": 480}', ["width is -5", ">= 1"]),
        ('{"n_frames": 40.5, "width": 640, "height": 480}', ["n_frames is 40.5"]),
        ('{"n_frames": 40, "width": 640, "height": 480, "fps": "fast"}', ['fps is "fast"']),
        ('{"n_frames": 40, "width": 640, "height": true}', ["height is true"]),
    ],
    ids=["n_frames-text", "width-negative", "n_frames-fraction", "fps-text", "height-bool"],
)
def test_meta_json_numbers_are_checked(
    meta: str,
    fragments: list[str],
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    bad_input: Callable[..., str],
) -> None:
    video = points_video(n_frames=40, intervals=((10, 15),))
    (video / "meta.json").write_text(meta, encoding="utf-8")
    output = tmp_path / "out"
    bad_input(["run", pipeline_file(), "-i", video, "-o", output, "-q"], "meta.json", *fragments)
    assert not output.exists()


def test_an_ignored_sigint_stays_ignored(
    pipeline_file: Callable[..., Path],
    points_video: Callable[..., Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Background jobs of a shell script inherit SIGINT ignored; Ctrl-C is not meant for them.
    from trackfw.engine import Engine

    real_run_video = Engine.run_video

    def run_video(self: Engine, *arguments: object, **options: object) -> object:
        os.kill(os.getpid(), signal.SIGINT)
        return real_run_video(self, *arguments, **options)  # type: ignore[arg-type]

    monkeypatch.setattr(Engine, "run_video", run_video)
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        code, stderr = run_cli(
            capsys, "run", pipeline_file(), "-i", points_video(), "-o", tmp_path / "out", "-q"
        )
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, previous)
    assert code == 0, stderr
    assert (tmp_path / "out" / "video" / "summary.json").is_file()
