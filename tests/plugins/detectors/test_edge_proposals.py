"""Tests of the Sobel/Canny edge map, the SED-style orientation and the EdgeBoxes proposer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from trackfw.errors import UserError
from trackfw_plugins.detectors.edge_proposals import (
    EdgeBoxesSettings,
    EdgeBoxProposer,
    edge_orientation,
    gradient_edges,
    thin_edges,
)


def test_gradient_edges_are_normalised_and_thinned(make_disc_image) -> None:
    image = make_disc_image([(100.0, 100.0)], radius=20, size=(200, 200))
    edges = gradient_edges(image)
    assert edges.dtype == np.float32 and edges.shape == (200, 200)
    assert edges.min() >= 0.0 and edges.max() == pytest.approx(1.0)
    thinned = thin_edges(edges, image)
    assert np.count_nonzero(thinned) < np.count_nonzero(edges > 0.05)
    # The edge lies on the disc's rim, not at its centre nor in the flat background.
    assert thinned[100, 100] == 0.0 and thinned[10, 10] == 0.0
    rim = thinned[100, 75:85].max()
    assert rim > 0.5


def test_flat_image_has_no_edges() -> None:
    assert gradient_edges(np.full((50, 60, 3), 90, dtype=np.uint8)).max() < 1e-3


def test_orientation_is_in_range_and_separates_crossing_edges() -> None:
    rng = np.random.default_rng(3)
    # Two straight edges at 30° and 120° (perpendicular), drawn as thin ridges plus noise.
    rows, columns = np.mgrid[0:96, 0:96].astype(np.float32)
    angles = []
    for degrees in (30.0, 120.0):
        theta = np.radians(degrees)
        distance = (columns - 48) * np.sin(theta) - (rows - 48) * np.cos(theta)
        ridge = np.exp(-(distance**2) / 2.0) + 0.01 * rng.random((96, 96))
        orientation = edge_orientation(ridge.astype(np.float32))
        assert orientation.min() >= 0.0 and orientation.max() < np.pi
        on_edge = (np.abs(distance) < 1.0) & (np.abs(rows - 48) < 20)
        angles.append(float(np.median(orientation[on_edge])))
    # Orientation is an angle modulo π: perpendicular edges differ by about π/2.
    difference = abs(angles[0] - angles[1])
    assert min(difference, np.pi - difference) == pytest.approx(np.pi / 2, abs=0.2)


def test_proposer_finds_a_box_around_each_disc(make_disc_image) -> None:
    centres = [(100.0, 100.0), (300.0, 200.0), (500.0, 120.0)]
    image = make_disc_image(centres, radius=12)
    boxes, scores = EdgeBoxProposer(EdgeBoxesSettings()).propose(image)
    assert boxes.shape[1] == 4 and len(boxes) == len(scores) > 0
    box_centres = boxes[:, :2] + boxes[:, 2:] / 2
    sides = np.sqrt(boxes[:, 2] * boxes[:, 3])
    for x, y in centres:
        near = np.hypot(box_centres[:, 0] - x, box_centres[:, 1] - y) < 6
        assert (near & (sides > 16) & (sides < 40)).any()


def test_missing_sed_model_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserError, match="sed_model"):
        EdgeBoxProposer(EdgeBoxesSettings(), sed_model_path=tmp_path / "model.yml.gz")


def test_damaged_sed_model_is_a_user_error(tmp_path: Path) -> None:
    damaged = tmp_path / "model.yml.gz"
    damaged.write_bytes(b"not a model")
    with pytest.raises(UserError, match="sed_model"):
        EdgeBoxProposer(EdgeBoxesSettings(), sed_model_path=damaged)


def test_proposals_do_not_depend_on_earlier_frames() -> None:
    rng = np.random.default_rng(3)
    frame = (rng.random((180, 320, 3)) * 255).astype(np.uint8)
    other = (rng.random((180, 320, 3)) * 255).astype(np.uint8)
    proposer = EdgeBoxProposer(EdgeBoxesSettings())
    first, _ = proposer.propose(frame)
    for _ in range(3):
        proposer.propose(other)
    again, _ = proposer.propose(frame)
    np.testing.assert_array_equal(first, again)
