"""trackfw render: an MP4 with identities, trails, info-less frames and interval panels."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from trackfw.cli import main
from trackfw_plugins.datasets.points import make_points_video
from trackfw_plugins.render.draw import (
    RunData,
    blank_frame,
    draw_frame,
    identity_colour,
    load_run_data,
)

from ...conftest import decode_video

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    make_points_video(
        tmp_path / "data" / "clip",
        n_frames=60,
        n_targets=3,
        n_others=1,
        intervals=[(20, 29)],
        width=320,
        height=240,
    )
    out = tmp_path / "runs"
    pipeline = REPO / "pipelines" / "kalman1-tr-oracle.yaml"
    assert (
        main(["run", str(pipeline), "--input", str(tmp_path / "data"), "--output", str(out), "-q"])
        == 0
    )
    return out


def test_render_writes_frames_panels_and_pngs(run_dir: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "render" / "clip.mp4"
    code = main(
        [
            "render",
            str(run_dir),
            "--out",
            str(out),
            "--panel-frames",
            "5",
            "--png-frames",
            "10,25",
            "--png-panels",
        ]
    )
    assert code == 0, capsys.readouterr().err
    data = load_run_data(run_dir / "clip")
    assert len(data.gaps) == 1
    frames = decode_video(out)
    assert len(frames) == 60 + 5  # every video frame plus the held panel
    assert frames[0].shape == (240, 320, 3)
    pngs = sorted(path.name for path in out.parent.glob("*.png"))
    gap = data.gaps[0]
    panel_name = f"clip-gap{gap.a + 1:06d}-{gap.b + 1:06d}.png"
    assert pngs == ["clip-frame000010.png", "clip-frame000025.png", panel_name]

    still = cv2.imread(str(out.parent / "clip-frame000010.png"))
    assert still is not None
    # Each target's point is drawn in its identity colour.
    for target, (x, y) in data.tracks[9].items():
        colour = np.array(identity_colour(target), dtype=int)
        assert np.abs(still[round(y), round(x)].astype(int) - colour).max() <= 2, target
    # An info-less frame is marked with a red border; a normal one is not.
    infoless = cv2.imread(str(out.parent / "clip-frame000025.png"))
    assert infoless is not None
    assert 24 in data.infoless
    assert tuple(infoless[1, 160]) == (40, 40, 220)
    assert tuple(still[1, 160]) != (40, 40, 220)
    panel = cv2.imread(str(out.parent / panel_name))
    assert panel is not None
    # A line per identity crosses the divider between frame a and frame b.
    crossing = panel[:, 160 + 6]
    for target in data.tracks[data.gaps[0].a]:
        colour = np.array(identity_colour(target), dtype=int)
        assert (np.abs(crossing.astype(int) - colour).max(axis=1) <= 40).any(), target


def test_render_names_the_videos_when_several_runs_are_present(
    run_dir: Path, tmp_path: Path, capsys
) -> None:
    make_points_video(tmp_path / "data" / "other", n_frames=20, intervals=[], width=320, height=240)
    pipeline = REPO / "pipelines" / "kalman1-tr-oracle.yaml"
    assert (
        main(
            [
                "run",
                str(pipeline),
                "--input",
                str(tmp_path / "data"),
                "--output",
                str(run_dir),
                "-q",
            ]
        )
        == 0
    )
    assert main(["render", str(run_dir)]) == 2
    assert "choose one with --video" in capsys.readouterr().err
    assert main(["render", str(run_dir), "--video", "other", "--panel-frames", "0"]) == 0
    assert len(decode_video(run_dir / "other" / "render.mp4")) == 20


def test_png_frame_out_of_range_is_an_error_naming_the_valid_range(
    run_dir: Path, tmp_path: Path, capsys
) -> None:
    out = tmp_path / "render" / "clip.mp4"
    code = main(["render", str(run_dir), "--out", str(out), "--png-frames", "10,9999"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "9999" in err and "1 to 60" in err, err
    assert len(err.strip().splitlines()) == 1, err
    # Nothing is half done: no video and no still from the valid frame number.
    assert not out.parent.exists() or not any(out.parent.iterdir())


def test_render_refuses_a_cut_short_frames_csv_like_eval(
    run_dir: Path, tmp_path: Path, capsys
) -> None:
    frames = run_dir / "clip" / "frames.csv"
    frames.write_text("\n".join(frames.read_text().splitlines()[:31]) + "\n")  # 30 of 60 rows
    out = tmp_path / "render" / "clip.mp4"
    assert main(["render", str(run_dir / "clip"), "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "30 of 60" in error and "'clip'" in error, error
    assert not out.exists()


@pytest.mark.parametrize(("width", "height"), [(640, 360), (1920, 1080)])
def test_labels_outline_surrounds_the_text(tmp_path: Path, width: int, height: int) -> None:
    """The dark outline and the white text come from the same glyphs (OpenCV 5 garbled them).

    OpenCV 5 draws glyphs whose width depends on the stroke thickness, so an outline drawn with a
    thick stroke under text drawn with a thin one ran ahead of it, letter by letter.
    """
    data = RunData(tmp_path, "clip", None, "kalman1-tr-oracle", 60, 80.0)
    drawn = draw_frame(blank_frame(width, height), 9, data)
    grey = drawn.max(axis=2)
    fill = (grey >= 200).astype(np.uint8)
    outline = (grey <= 20).astype(np.uint8)
    assert fill.sum() > 50 and outline.sum() > fill.sum(), "no label drawn"
    fill_rows, fill_cols = np.nonzero(fill)
    out_rows, out_cols = np.nonzero(outline)
    # The outline's box holds the text's box with a thin margin on every side.
    margins = (
        fill_cols.min() - out_cols.min(),
        out_cols.max() - fill_cols.max(),
        fill_rows.min() - out_rows.min(),
        out_rows.max() - fill_rows.max(),
    )
    assert all(1 <= margin <= 6 for margin in margins), margins
    # No outline pixel strays from the text: each lies within a few pixels of a white one.
    distance = cv2.distanceTransform(1 - fill, cv2.DIST_L2, 3)
    assert distance[outline.astype(bool)].max() <= 8.0


def _colour_box(image: np.ndarray, colour: tuple[int, int, int]) -> tuple[int, int]:
    """Width and height of the pixels drawn in ``colour``."""
    rows, cols = np.nonzero(np.abs(image.astype(int) - np.array(colour)).max(axis=2) <= 40)
    return int(cols.max() - cols.min() + 1), int(rows.max() - rows.min() + 1)


def test_boxes_take_the_detection_size_or_a_head_size_scaled_to_the_frame(
    tmp_path: Path,
) -> None:
    """Not the fixed 80x80 of tracks.txt: at 640x360 that covered a whole group."""
    data = RunData(tmp_path, "clip", None, "p", 60, 80.0)
    # Target 1 sits on a detection of 20x30 px; target 2 on no detection with a size.
    data.tracks = {0: {1: (200.0, 150.0), 2: (420.0, 200.0)}}
    data.detections = {0: (np.array([[201.0, 149.0]]), np.array([[20.0, 30.0]]))}
    drawn = draw_frame(blank_frame(640, 360), 0, data, trail=0)
    width, height = _colour_box(drawn, identity_colour(1))
    assert abs(width - 20) <= 3 and abs(height - 30) <= 3, (width, height)
    # No size known: the 80 px head of 1080p scaled to 360 rows is 27 px.
    width, height = _colour_box(drawn, identity_colour(2))
    assert abs(width - 27) <= 3 and abs(height - 27) <= 3, (width, height)


def test_a_run_records_detection_sizes_for_render(run_dir: Path) -> None:
    """frames.csv carries each detection's box size; render reads it back per detection."""
    data = load_run_data(run_dir / "clip")
    points, sizes = data.detections[9]
    assert len(points) and sizes.shape == (len(points), 2)
    assert np.isfinite(sizes).all() and (sizes > 0).all()
    # The MOT-text output keeps its 80x80 convention.
    first = (run_dir / "clip" / "tracks.txt").read_text().splitlines()[0].split(",")
    assert first[4:6] == ["80", "80"]
