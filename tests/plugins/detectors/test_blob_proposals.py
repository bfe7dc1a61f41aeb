"""Tests of the DoG blob proposals and of the combined head proposer."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw_plugins.detectors.blob_proposals import blob_boxes, blob_sigmas
from trackfw_plugins.detectors.edge_proposals import EdgeBoxesSettings
from trackfw_plugins.detectors.proposals import HeadProposer, ProposalSettings


@pytest.mark.parametrize("radius", [4, 9, 20])
def test_strongest_blob_sits_on_the_disc_at_its_size(make_disc_image, radius: int) -> None:
    image = make_disc_image([(150.0, 90.0)], radius=radius, size=(180, 300))
    boxes, responses = blob_boxes(image, blob_sigmas(4.0, 80.0))
    assert len(boxes) == len(responses) > 0
    best = boxes[np.argmax(responses)]
    centre = best[:2] + best[2:] / 2
    assert np.hypot(centre[0] - 150.0, centre[1] - 90.0) <= max(1.5, 0.15 * radius)
    assert best[2] == pytest.approx(2 * radius, rel=0.3)


def test_flat_frame_has_no_blob() -> None:
    boxes, _ = blob_boxes(np.full((60, 80, 3), 100, np.uint8), blob_sigmas(4.0, 30.0))
    assert boxes.shape == (0, 4)


def test_proposer_keeps_only_head_sizes_and_can_switch_sources_off(make_disc_image) -> None:
    image = make_disc_image([(100.0, 100.0), (300.0, 200.0)], radius=10)  # 360 px high
    both = HeadProposer().propose(image)
    sides = np.maximum(both[:, 2], both[:, 3])
    assert len(both) > 0
    assert sides.min() >= 8 * 360 / 1080 * 0.999 and sides.max() <= 120 * 360 / 1080 * 1.001
    blobs_only = HeadProposer(ProposalSettings(edge_boxes_width=0)).propose(image)
    edges_only = HeadProposer(ProposalSettings(blob_width=0)).propose(image)
    assert len(blobs_only) + len(edges_only) == len(both)
    assert len(HeadProposer(ProposalSettings(EdgeBoxesSettings(), 0, 0)).propose(image)) == 0


def test_blobs_stop_at_their_largest_head_size(make_disc_image) -> None:
    image = make_disc_image([(150.0, 180.0)], radius=10)  # 360 px high: 60 px at 1080p

    def largest_blob_on_disc(largest: float) -> float:
        settings = ProposalSettings(edge_boxes_width=0, blob_max_head_size=largest)
        boxes = HeadProposer(settings).propose(image)
        centres = boxes[:, :2] + boxes[:, 2:] / 2
        on_disc = np.hypot(centres[:, 0] - 150.0, centres[:, 1] - 180.0) < 3.0
        assert boxes[:, 2].max() <= largest * 360 / 1080 * 1.001
        return float(boxes[on_disc, 2].max(initial=0.0))

    assert largest_blob_on_disc(120.0) == pytest.approx(20.0, rel=0.3)
    assert largest_blob_on_disc(30.0) <= 10.0 * 1.001
