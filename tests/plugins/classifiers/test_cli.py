"""End-to-end test of ``trackfw train classifier`` on a tiny dataset written on the fly."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from trackfw.dataset import write_meta
from trackfw.errors import UserError
from trackfw.formats.annotations import write_heads, write_intervals
from trackfw.records import Interval
from trackfw_plugins.classifiers.cli import CACHE_FOLDER, register
from trackfw_plugins.classifiers.svm_model import load_model

FRAMES = 30


def write_video(
    folder: Path, seed: int, interval: tuple[int, int], make_frames: Callable[..., list[np.ndarray]]
) -> None:
    """Frames that pan fast during the interval; heads are a group outside it, one head inside."""
    a, b = interval
    rng = np.random.default_rng(seed)
    shifts, x = [], 0
    for t in range(FRAMES):
        x += 40 if a < t < b else int(rng.integers(0, 2))
        shifts.append(x)
    (folder / "img1").mkdir(parents=True)
    heads = []
    for t, image in enumerate(make_frames(shifts, seed=seed)):
        small = cv2.resize(image, (320, 180), interpolation=cv2.INTER_AREA)
        cv2.imwrite(str(folder / "img1" / f"{t + 1:06d}.jpg"), small)
        if a < t < b:
            heads.append((t, 1, 160.0, 20.0, 10.0))
        else:
            for head in range(6):
                heads.append((t, head + 1, 60.0 + 40 * head, 90.0 + 5 * (head % 2), 12.0))
    write_heads(folder / "heads.csv", heads)
    write_intervals(folder / "intervals.csv", [Interval(a, b, "sky")])
    write_meta(folder / "meta.json", {"width": 320, "height": 180, "fps": 30, "n_frames": FRAMES})


@pytest.fixture(scope="module")
def dataset(
    tmp_path_factory: pytest.TempPathFactory, make_frames: Callable[..., list[np.ndarray]]
) -> Path:
    root = tmp_path_factory.mktemp("dataset")
    for index, interval in enumerate([(8, 16), (12, 22), (5, 12)]):
        write_video(root / f"video{index}", index, interval, make_frames)
    (root / "train.txt").write_text("video0\nvideo1\n")
    (root / "test.txt").write_text("video2\n")
    return root


def test_train_evaluate_and_cache(dataset: Path, tmp_path: Path) -> None:
    app = typer.Typer()
    register(app)
    runner = CliRunner()
    out = tmp_path / "model.json"
    arguments = [
        "--dataset", str(dataset), "--out", str(out), "--videos-from", str(dataset / "train.txt"),
        "--evaluate-on", str(dataset / "test.txt"), "--report", str(tmp_path / "report.json"),
        "--detector-param", "source=heads",
    ]  # fmt: skip
    result = runner.invoke(app, arguments)
    assert result.exit_code == 0, result.output
    assert "cross-validated (2 folds" in result.output
    model = load_model(out)
    assert model.training["videos"] == ["video0", "video1"]
    assert model.training["detector"] == {"type": "oracle", "params": {"source": "heads"}}
    assert model.features["flow"] == "dis"
    report = json.loads((tmp_path / "report.json").read_text())
    test = report["test"]
    assert [row["video"] for row in test["videos"]] == ["video2"]
    # 6 info-less frames in the test video: the panning is obvious, most must be found.
    assert test["svm"]["tp"] + test["svm"]["fn"] == 6
    assert test["svm"]["recall"] >= 0.5
    cached = sorted(path.name.split(".")[0] for path in (tmp_path / CACHE_FOLDER).iterdir())
    assert cached == ["video0", "video1", "video2"]
    again = runner.invoke(app, arguments)
    assert again.exit_code == 0 and again.output.count("(cached)") == 3
    assert np.array_equal(load_model(out).dual_coef, model.dual_coef)


def test_unknown_video_and_detector_are_user_errors(dataset: Path, tmp_path: Path) -> None:
    from trackfw_plugins.classifiers.cli import train_classifier

    missing = tmp_path / "split.txt"
    missing.write_text("nope\n")
    with pytest.raises(UserError, match="no video named 'nope'"):
        train_classifier(dataset, tmp_path / "m.json", videos_from=missing, echo=lambda _: None)
    with pytest.raises(UserError, match="unknown detector"):
        train_classifier(dataset, tmp_path / "m.json", detector="orcale", echo=lambda _: None)
    with pytest.raises(UserError, match="--flow"):
        train_classifier(dataset, tmp_path / "m.json", flow="lucas", echo=lambda _: None)


def test_rule_options_are_recorded_and_checked(dataset: Path, tmp_path: Path) -> None:
    app = typer.Typer()
    register(app)
    out = tmp_path / "rules.json"
    arguments = [
        "--dataset", str(dataset), "--out", str(out), "--detector-param", "source=heads",
        "--reference", "replay", "--turn-motion", "8", "--reanchor-after", "20",
        "--enter-probability", "0.6", "--leave-probability", "0.4",
    ]  # fmt: skip
    result = CliRunner().invoke(app, arguments)
    assert result.exit_code == 0, result.output
    recorded = load_model(out).features["online_rules"]
    assert recorded["turn_motion"] == 8.0 and recorded["reanchor_after"] == 20
    assert (recorded["enter_probability"], recorded["leave_probability"]) == (0.6, 0.4)
    assert load_model(out).training["online_rules"] == recorded
    from trackfw_plugins.classifiers.cli import train_classifier

    with pytest.raises(UserError, match="online rule"):
        train_classifier(dataset, tmp_path / "m.json", leave_probability=0.9, echo=lambda _: None)


def test_any_detector_trains_and_one_video_is_in_sample(dataset: Path, tmp_path: Path) -> None:
    """A pixel detector (yolox) measures N_t and S_t; one video gives no held-out fold."""
    app = typer.Typer()
    register(app)
    (tmp_path / "one.txt").write_text("video0\n")
    out = tmp_path / "model.json"
    arguments = [
        "--dataset", str(dataset), "--out", str(out), "--detector", "yolox",
        "--detector-param", "model=light-person-192", "--videos-from", str(tmp_path / "one.txt"),
    ]  # fmt: skip
    result = CliRunner().invoke(app, arguments)
    assert result.exit_code == 0, result.output
    assert "in-sample (one video: no held-out fold" in result.output
    assert "cross-validated" not in result.output
    model = load_model(out)
    assert model.training["detector"] == {"type": "yolox", "params": {"model": "light-person-192"}}
    assert model.training["videos"] == ["video0"]
