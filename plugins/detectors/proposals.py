"""Head-sized box proposals of a frame: EdgeBoxes (the paper's) plus optional DoG blobs [OURS].

Used both by the ``edgebox-cnn`` detector and by the training sampler, so that the classifier is
trained on the very kind of boxes it scores at run time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from trackfw.arrays import FloatArray
from trackfw_plugins.detectors.blob_proposals import blob_boxes, blob_sigmas
from trackfw_plugins.detectors.edge_proposals import EdgeBoxesSettings, EdgeBoxProposer


@dataclass(frozen=True)
class ProposalSettings:
    """Where proposals come from and which sizes are kept.

    Attributes:
        edge_boxes: the EdgeBoxes arguments; ``edge_boxes_width`` 0 turns EdgeBoxes off.
        edge_boxes_width: frames are reduced to this width for EdgeBoxes (px).
        blob_width: frames are reduced to this width for DoG blobs (px); 0 turns blobs off.
        blob_threshold: minimum scale-normalised DoG response (grey levels / 255).
        blob_max_per_scale: strongest blobs kept per scale.
        blob_scales_per_octave: blob scales per doubling of the head size.
        blob_max_head_size: largest blob proposed, px at 1080p (scaled by height / 1080):
            larger heads close the contours EdgeBoxes looks for.
        min_head_size: smallest box side kept, px at 1080p (scaled by height / 1080).
        max_head_size: largest box side kept, px at 1080p (scaled by height / 1080).
        sed_model: optional structured-edge model for EdgeBoxes.
    """

    edge_boxes: EdgeBoxesSettings = field(default_factory=EdgeBoxesSettings)
    edge_boxes_width: int = 640
    blob_width: int = 640
    blob_threshold: float = 0.05
    blob_max_per_scale: int = 150
    blob_scales_per_octave: int = 3
    blob_max_head_size: float = 48.0
    min_head_size: float = 8.0
    max_head_size: float = 120.0
    sed_model: str | Path | None = None


def _reduce(image: NDArray[np.uint8], width: int) -> tuple[NDArray[np.uint8], float]:
    """The frame reduced to ``width`` (never enlarged) and the scale applied."""
    scale = min(1.0, width / image.shape[1])
    if scale == 1.0:
        return image, 1.0
    size = (round(image.shape[1] * scale), round(image.shape[0] * scale))
    return np.asarray(cv2.resize(image, size, interpolation=cv2.INTER_AREA)), scale


class HeadProposer:
    """Head-sized proposals of a full frame, in frame pixels.

    Raises:
        UserError: when the optional SED model cannot be loaded.
    """

    def __init__(self, settings: ProposalSettings | None = None) -> None:
        self.settings = settings or ProposalSettings()
        self.edge_boxes = (
            EdgeBoxProposer(self.settings.edge_boxes, self.settings.sed_model)
            if self.settings.edge_boxes_width > 0
            else None
        )

    def _head_sized(self, boxes: FloatArray, frame_height: int) -> FloatArray:
        """The boxes whose sides lie within the head-size range of a frame this tall."""
        size_scale = frame_height / 1080.0
        smallest = self.settings.min_head_size * size_scale
        largest = self.settings.max_head_size * size_scale
        short_side = np.minimum(boxes[:, 2], boxes[:, 3])
        long_side = np.maximum(boxes[:, 2], boxes[:, 3])
        # The tolerance keeps blobs made at exactly the smallest size despite rounding.
        return boxes[(short_side >= 0.999 * smallest) & (long_side <= 1.001 * largest)]

    def edge_box_proposals(self, image: NDArray[np.uint8]) -> FloatArray:
        """Head-sized EdgeBoxes proposals ``(N, 4)`` of a ``(H, W, 3)`` frame (none when off)."""
        if self.edge_boxes is None:
            return np.zeros((0, 4))
        reduced, scale = _reduce(image, self.settings.edge_boxes_width)
        boxes, _objectness = self.edge_boxes.propose(reduced)
        return self._head_sized(boxes / scale, image.shape[0])

    def blob_proposals(self, image: NDArray[np.uint8]) -> FloatArray:
        """Head-sized DoG blob proposals ``(N, 4)`` of a ``(H, W, 3)`` frame (none when off)."""
        settings = self.settings
        if settings.blob_width <= 0:
            return np.zeros((0, 4))
        size_scale = image.shape[0] / 1080.0
        reduced, scale = _reduce(image, settings.blob_width)
        sigmas = blob_sigmas(
            settings.min_head_size * size_scale * scale,
            min(settings.blob_max_head_size, settings.max_head_size) * size_scale * scale,
            settings.blob_scales_per_octave,
        )
        boxes, _response = blob_boxes(
            reduced, sigmas, settings.blob_threshold, settings.blob_max_per_scale
        )
        return self._head_sized(boxes / scale, image.shape[0])

    def propose(self, image: NDArray[np.uint8]) -> FloatArray:
        """``(N, 4)`` boxes ``(left, top, width, height)`` of head size on a ``(H, W, 3)`` frame.

        EdgeBoxes proposals come first, then blobs.
        """
        return np.concatenate([self.edge_box_proposals(image), self.blob_proposals(image)])
