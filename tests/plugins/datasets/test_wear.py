"""``trackfw dataset wear``: a virtual wearer over a (tiny fake or real) MOT sequence."""

from __future__ import annotations

import csv
import itertools
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from trackfw.dataset import load_video
from trackfw.errors import UserError
from trackfw.formats import HEAD_FRACTION, body_head_points
from trackfw_plugins.datasets import check as check_module
from trackfw_plugins.datasets import wear_cli
from trackfw_plugins.datasets.check import check_dataset
from trackfw_plugins.datasets.mot import load_mot_sequence
from trackfw_plugins.datasets.wear import (
    SWAY_AMPLITUDE,
    CameraPose,
    FrameFormat,
    WearSettings,
    generate_dataset,
    local_scale,
    pose_homography,
    transform_points,
)

WIDTH, HEIGHT, FRAMES, PEOPLE = 64, 48, 44, 6
BOX_WIDTH, BOX_HEIGHT = 8.0, 20.0
TINY = WearSettings(
    n_intervals=3, min_interval=5, max_interval=8, min_segment=6, frame_format=FrameFormat.jpg
)


def make_fake_sequence(folder: Path) -> Path:
    """A 64x48 MOT15 sequence: dark texture, each person's head proxy is a bright 5x5 square."""
    rng = np.random.default_rng(7)
    background = rng.integers(20, 70, size=(HEIGHT, WIDTH, 3)).astype(np.uint8)
    (folder / "img1").mkdir(parents=True)
    (folder / "gt").mkdir()
    lines = []
    for frame in range(FRAMES):
        image = background.copy()
        for person in range(PEOPLE):
            x = 6 + 10 * person + 0.1 * frame * (-1) ** person
            y = 16.0 + 2 * (person % 2)
            column, row = round(x), round(y)
            image[row - 2 : row + 3, column - 2 : column + 3] = 255
            left, top = x - BOX_WIDTH / 2, y - HEAD_FRACTION * BOX_HEIGHT
            lines.append(
                f"{frame + 1},{person + 1},{left:.3f},{top:.3f},{BOX_WIDTH},{BOX_HEIGHT},1,-1,-1,-1"
            )
        cv2.imwrite(
            str(folder / "img1" / f"{frame + 1:06d}.jpg"), image, [cv2.IMWRITE_JPEG_QUALITY, 98]
        )
    (folder / "gt" / "gt.txt").write_text("\n".join(lines) + "\n")
    (folder / "seqinfo.ini").write_text(
        f"[Sequence]\nname=Fake\nimDir=img1\nframeRate=25\nseqLength={FRAMES}\n"
        f"imWidth={WIDTH}\nimHeight={HEIGHT}\nimExt=.jpg\n"
    )
    return folder


@pytest.fixture(scope="module")
def fake_sequence(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_fake_sequence(tmp_path_factory.mktemp("mot") / "Fake")


@pytest.fixture(scope="module")
def fake_dataset(fake_sequence: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wear") / "dataset"
    generate_dataset(fake_sequence, out, seed=3, n_videos=2, settings=TINY)
    return out


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as stream:
        return list(csv.DictReader(stream))


# ------------------------------------------------------------------------------------ geometry


def test_identity_pose_is_the_identity_and_pan_shifts_by_focal_tangent() -> None:
    assert np.allclose(pose_homography(CameraPose(), (640, 480), (640, 480), 80.0), np.eye(3))
    homography = pose_homography(CameraPose(pan=20.0), (640, 480), (640, 480), 80.0)
    focal = 320 / math.tan(math.radians(40))
    centre = transform_points(homography, np.array([[320.0, 240.0]]))[0]
    assert centre[0] == pytest.approx(320 + focal * math.tan(math.radians(20)))
    assert centre[1] == pytest.approx(240)
    zoomed = pose_homography(CameraPose(scale=1.3), (640, 480), (320, 240), 80.0)
    corner = transform_points(zoomed, np.array([[640.0, 480.0]]))[0]
    assert corner == pytest.approx([160 + 0.5 * 1.3 * 320, 120 + 0.5 * 1.3 * 240])


def test_transform_and_local_scale_agree_with_opencv_and_finite_differences() -> None:
    pose = CameraPose(pan=-25.0, tilt=6.0, roll=9.0, scale=0.8, tx=3.0, ty=-2.0)
    homography = pose_homography(pose, (640, 480), (640, 480), 80.0)
    points = np.array([[10.0, 20.0], [320.0, 240.0], [600.0, 400.0]])
    expected = cv2.perspectiveTransform(points[None], homography)[0]
    assert np.allclose(transform_points(homography, points), expected)
    step = 1e-3
    for point, scale in zip(points, local_scale(homography, points), strict=True):
        dx = transform_points(homography, point + np.array([step, 0.0])) - transform_points(
            homography, point
        )
        dy = transform_points(homography, point + np.array([0.0, step])) - transform_points(
            homography, point
        )
        jacobian = np.column_stack([dx[0], dy[0]]) / step
        assert scale == pytest.approx(math.sqrt(abs(np.linalg.det(jacobian))), rel=1e-4)


# ------------------------------------------------------------------------------------ datasets


def test_wear_writes_a_dataset_that_check_accepts(fake_dataset: Path) -> None:
    report = check_dataset(fake_dataset)
    assert report.problems == []
    assert report.stats["videos"] == 2
    assert report.stats["frames"]["total"] == 2 * FRAMES
    assert report.stats["intervals"]["count"] == 6
    assert set(report.stats["intervals"]["by_kind"]) == {"sky", "group", "path"}
    assert (
        5
        <= report.stats["intervals"]["length"]["min"]
        <= report.stats["intervals"]["length"]["max"]
        <= 8
    )
    for video in sorted(p for p in fake_dataset.iterdir() if p.name != "preview"):
        context = load_video(video)
        assert context.n_frames == FRAMES and (context.width, context.height) == (WIDTH, HEIGHT)
        ground_truth = context.ground_truth
        assert ground_truth is not None
        targets = set(ground_truth.targets[0])
        assert 5 <= len(targets) <= PEOPLE
        assert targets == set(json.loads((video / "meta.json").read_text())["targets"])
        infoless = {t for i in ground_truth.intervals for t in range(i.a + 1, i.b)}
        assert not infoless & set(ground_truth.targets)
        assert len(list((video / "img1").glob("*.jpg"))) == FRAMES
    previews = sorted(path.name for path in (fake_dataset / "preview").glob("*.png"))
    for kind in ("sky", "group", "path", "a", "b", "swing"):
        assert any(name.endswith(f"_{kind}.png") for name in previews)


def test_ground_truth_points_land_on_the_bright_head_squares(fake_dataset: Path) -> None:
    checked = 0
    for video in sorted(p for p in fake_dataset.iterdir() if p.name != "preview"):
        labels = {int(row["frame"]): row["view"] for row in _rows(video / "poses.csv")}
        heads = _rows(video / "heads.csv")
        assert {labels[int(row["frame"])] for row in heads} <= {"real", "group"}
        for row in heads + _rows(video / "gt.csv"):
            x, y = float(row["x"]), float(row["y"])
            if not (3 <= x <= WIDTH - 4 and 3 <= y <= HEIGHT - 10):
                continue
            image = cv2.imread(str(video / "img1" / f"{int(row['frame']):06d}.jpg"))
            assert image is not None
            on_head = int(image[round(y), round(x)].max())
            below = int(image[round(y) + 7, round(x)].max())
            assert on_head >= 170, (video.name, row)
            assert below < 130, (video.name, row)
            checked += 1
    assert checked > 200


def test_gt_equals_mot_heads_moved_by_the_recorded_poses(
    fake_dataset: Path, fake_sequence: Path
) -> None:
    sequence = load_mot_sequence(fake_sequence)
    video = sorted(p for p in fake_dataset.iterdir() if p.name != "preview")[0]
    poses = {int(row["frame"]): row for row in _rows(video / "poses.csv")}
    for row in _rows(video / "gt.csv"):
        frame = int(row["frame"])
        pose = CameraPose(
            *(float(poses[frame][key]) for key in ("pan", "tilt", "roll", "scale", "tx", "ty"))
        )
        homography = pose_homography(pose, (WIDTH, HEIGHT), (WIDTH, HEIGHT), 80.0)
        boxes = sequence.boxes_at(frame - 1)
        proxy = body_head_points(boxes[boxes[:, 0] == int(row["id"])][:, 1:])
        # poses.csv keeps 4 decimals, so allow for that rounding.
        assert transform_points(homography, proxy)[0] == pytest.approx(
            [float(row["x"]), float(row["y"])], abs=0.05
        )


def test_same_seed_same_bytes_other_seed_other_video(fake_sequence: Path, tmp_path: Path) -> None:
    settings = WearSettings(
        n_intervals=1, min_interval=5, max_interval=8, min_segment=6, frame_format=FrameFormat.jpg
    )
    first = generate_dataset(fake_sequence, tmp_path / "a", seed=11, settings=settings)[0]
    second = generate_dataset(fake_sequence, tmp_path / "b", seed=11, settings=settings)[0]
    other = generate_dataset(fake_sequence, tmp_path / "c", seed=12, settings=settings)[0]
    files = sorted(p.relative_to(first) for p in first.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(second) for p in second.rglob("*") if p.is_file())
    for name in files:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name
    assert (first / "poses.csv").read_bytes() != (other / "poses.csv").read_bytes()


def test_poses_jump_after_each_interval_and_stay_in_range(fake_dataset: Path) -> None:
    for video in sorted(p for p in fake_dataset.iterdir() if p.name != "preview"):
        meta = json.loads((video / "meta.json").read_text())
        poses = meta["segment_poses"]
        assert len(poses) == len(meta["intervals"]) + 1
        assert meta["source_size"] == [WIDTH, HEIGHT]
        for pose in poses:
            assert (
                abs(pose["pan"]) <= 30 and abs(pose["roll"]) <= 10 and 0.7 <= pose["scale"] <= 1.4
            )
        for before, after in itertools.pairwise(poses):
            assert (
                abs(after["pan"] - before["pan"]) >= 10
                or abs(after["roll"] - before["roll"]) >= 5
                or abs(math.log(after["scale"] / before["scale"])) >= math.log(1.2)
            )
        # The frames really use them: frames a and b differ by the jump, less the sway.
        rows = {int(row["frame"]): row for row in _rows(video / "poses.csv")}
        pan_sway, _, roll_sway, scale_sway = SWAY_AMPLITUDE
        for number, interval in enumerate(meta["intervals"]):
            frame_a, frame_b = rows[interval["start"] - 1], rows[interval["end"] + 1]
            assert frame_a["view"] == frame_b["view"] == "real"
            for row, pose in ((frame_a, poses[number]), (frame_b, poses[number + 1])):
                assert abs(float(row["pan"]) - pose["pan"]) <= pan_sway + 1e-3
                assert abs(float(row["roll"]) - pose["roll"]) <= roll_sway + 1e-3
                assert abs(math.log(float(row["scale"]) / pose["scale"])) <= scale_sway + 1e-3


def test_mp4_and_output_size(fake_sequence: Path, tmp_path: Path) -> None:
    settings = WearSettings(
        n_intervals=1, min_interval=5, max_interval=8, min_segment=6, output_size=(96, 64)
    )
    video = generate_dataset(fake_sequence, tmp_path / "mp4", seed=0, settings=settings)[0]
    assert (video / "video.mp4").is_file() and not (video / "img1").exists()
    report = check_dataset(tmp_path / "mp4")
    assert report.problems == []
    capture = cv2.VideoCapture(str(video / "video.mp4"))
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == FRAMES
    assert (capture.get(cv2.CAP_PROP_FRAME_WIDTH), capture.get(cv2.CAP_PROP_FRAME_HEIGHT)) == (
        96,
        64,
    )
    capture.release()


def test_refuses_non_empty_out_and_force_replaces_same_names(
    fake_sequence: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    settings = WearSettings(
        n_intervals=1, min_interval=5, max_interval=8, min_segment=6, frame_format=FrameFormat.jpg
    )
    with pytest.raises(UserError, match="not empty"):
        generate_dataset(fake_sequence, out, seed=0, settings=settings)
    video = generate_dataset(fake_sequence, out, seed=0, settings=settings, force=True)[0]
    (video / "stale.txt").write_text("old")
    generate_dataset(fake_sequence, out, seed=0, settings=settings, force=True)
    assert not (video / "stale.txt").exists()
    assert (out / "notes.txt").read_text() == "mine"
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_sequence_too_short_for_the_intervals_is_a_user_error(
    fake_sequence: Path, tmp_path: Path
) -> None:
    settings = WearSettings(n_intervals=4, min_segment=12, frame_format=FrameFormat.jpg)
    with pytest.raises(UserError, match="fewer --intervals"):
        generate_dataset(fake_sequence, tmp_path / "x", settings=settings)
    assert not [p for p in (tmp_path / "x").rglob("*") if p.is_dir() and p.name != "preview"]


def test_cli_wear_then_check(fake_sequence: Path, tmp_path: Path) -> None:
    app = typer.Typer()

    @app.callback()
    def main() -> None:
        """Test group."""

    wear_cli.register(app)
    check_module.register(app)
    runner = CliRunner()
    out = tmp_path / "cli"
    arguments = [
        "wear",
        "--mot",
        str(fake_sequence),
        "--out",
        str(out),
        "--intervals",
        "1",
        "--format",
        "jpg",
        "--min-length",
        "5",
        "--max-length",
        "8",
        "--seed",
        "4",
    ]
    result = runner.invoke(app, arguments)
    assert result.exit_code == 0, result.output
    assert len([p for p in out.iterdir() if p.name != "preview"]) == 1
    result = runner.invoke(app, ["check", str(out)])
    assert result.exit_code == 0, result.output
    assert "no problem found" in result.output
    again = runner.invoke(app, arguments)
    assert isinstance(again.exception, UserError)
    bad_size = runner.invoke(app, [*arguments, "--force", "--size", "12by9"])
    assert isinstance(bad_size.exception, UserError) and "--size" in str(bad_size.exception)


# ------------------------------------------------------------------------------------ real data


def test_real_tud_stadtmitte(shared_data: Path, tmp_path: Path) -> None:
    source = shared_data / "TUD-Stadtmitte"
    settings = WearSettings(frame_format=FrameFormat.jpg, output_size=(320, 240))
    video = generate_dataset(source, tmp_path / "tud", seed=0, settings=settings)[0]
    report = check_dataset(tmp_path / "tud")
    assert report.problems == []
    meta = json.loads((video / "meta.json").read_text())
    assert meta["n_frames"] == 179 and (meta["width"], meta["height"]) == (320, 240)
    assert meta["source_size"] == [640, 480]
    assert 5 <= len(meta["targets"]) <= 7  # 7 people on frame 1
    assert len(meta["intervals"]) == 2  # one per 80 frames
    for interval in meta["intervals"]:
        assert 15 <= interval["end"] - interval["start"] + 1 <= 60
    sequence = load_mot_sequence(source)
    poses = {int(row["frame"]): row for row in _rows(video / "poses.csv")}
    gt = _rows(video / "gt.csv")
    assert len({row["frame"] for row in gt}) > 60
    for row in gt[::25]:
        frame = int(row["frame"])
        pose = CameraPose(
            *(float(poses[frame][key]) for key in ("pan", "tilt", "roll", "scale", "tx", "ty"))
        )
        homography = pose_homography(pose, (640, 480), (320, 240), 80.0)
        boxes = sequence.boxes_at(frame - 1)
        proxy = body_head_points(boxes[boxes[:, 0] == int(row["id"])][:, 1:])
        assert transform_points(homography, proxy)[0] == pytest.approx(
            [float(row["x"]), float(row["y"])], abs=0.05
        )


def test_targets_k_chooses_k_people_of_interest_among_bystanders(
    fake_sequence: Path, tmp_path: Path
) -> None:
    """``--targets 2``: gt.csv holds two people; the others stay in heads.csv as bystanders."""
    from dataclasses import replace

    out = tmp_path / "two"
    generate_dataset(fake_sequence, out, seed=3, n_videos=2, settings=replace(TINY, n_targets=2))
    for video in sorted(p for p in out.iterdir() if (p / "gt.csv").is_file()):
        gt_ids = {int(row["id"]) for row in _rows(video / "gt.csv")}
        head_ids = {int(row["id"]) for row in _rows(video / "heads.csv")}
        meta = json.loads((video / "meta.json").read_text())
        assert len(meta["targets"]) == 2 and gt_ids == set(meta["targets"])
        assert gt_ids < head_ids and len(head_ids - gt_ids) >= 2
        # The two are neighbours on frame 1, both in view there.
        first = [row for row in _rows(video / "gt.csv") if row["frame"] == "1"]
        assert len(first) == 2


def test_targets_k_must_be_positive(fake_sequence: Path, tmp_path: Path) -> None:
    app = typer.Typer()

    @app.callback()
    def main() -> None:
        """Test group."""

    wear_cli.register(app)
    out = tmp_path / "bad"
    result = CliRunner().invoke(
        app, ["wear", "--mot", str(fake_sequence), "--out", str(out), "--targets", "0"]
    )
    assert isinstance(result.exception, UserError) and "--targets is 0" in str(result.exception)
    assert not out.exists()
