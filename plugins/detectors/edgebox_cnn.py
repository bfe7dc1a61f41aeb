"""The reference head detector: EdgeBoxes proposals scored by a small CNN.

See docs/algorithms/detectors.md#edgeboxes-cnn.

Pipeline per frame: EdgeBoxes on the frame reduced to ``work_width`` (plus, [OURS], DoG blob
proposals, see :mod:`.blob_proposals`) → keep head-sized boxes → grow by R-CNN context, warp to
the CNN input and score in batches (onnxruntime) → threshold 0.7 → ``cv2.dnn.NMSBoxes(boxes,
scores, 0.7, 0.3)`` → drop boxes centred on a better box ([OURS]) → detection point = box
centre. ``blob_width: 0`` gives the paper's EdgeBoxes-only proposals. By default EdgeBoxes runs
in a second thread while the blob proposals are scored, so that a frame uses two cores; the
result is the same as in sequence.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack
from importlib import resources
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from trackfw.records import Detections, FrameData
from trackfw.stages import Detector, StageParams
from trackfw_plugins.detectors.boxes import (
    detections_from_boxes,
    frame_pixels,
    non_maximum_suppression,
    suppress_nested_centres,
)
from trackfw_plugins.detectors.edge_proposals import EdgeBoxesSettings
from trackfw_plugins.detectors.head_scorer import HeadScorer
from trackfw_plugins.detectors.proposals import HeadProposer, ProposalSettings

SHIPPED_MODEL = "head_cnn.onnx"
"""File name of the head classifier shipped in ``trackfw_plugins/detectors/models``."""

#: Normalisation of the shipped model (pixels in [0, 1], RGB).
SHIPPED_MEAN = (0.5, 0.5, 0.5)
SHIPPED_STD = (0.25, 0.25, 0.25)


def shipped_model_path() -> Path:
    """Path of the shipped head classifier (a real file in both wheel and editable installs)."""
    resource = resources.files("trackfw_plugins.detectors") / "models" / SHIPPED_MODEL
    with ExitStack() as stack:
        # Package data installed from a wheel or an editable checkout is already a file, so
        # the path stays valid after the context closes.
        return Path(stack.enter_context(resources.as_file(resource)))


class EdgeBoxCnnParams(StageParams):
    """Parameters of the ``edgebox-cnn`` detector."""

    model: str = Field(
        "", description="ONNX head classifier; empty = the model shipped with trackfw."
    )
    sed_model: str = Field(
        "",
        description="Optional OpenCV structured-edge model (model.yml.gz); empty = Sobel edges.",
    )
    work_width: int = Field(
        640, ge=0, description="Frames are reduced to this width for EdgeBoxes (px); 0 = off."
    )
    alpha: float = Field(0.65, gt=0, lt=1, description="EdgeBoxes sliding-window step size.")
    beta: float = Field(0.75, gt=0, le=1, description="EdgeBoxes NMS threshold on proposals.")
    kappa: float = Field(2.0, gt=0, description="EdgeBoxes scale sensitivity (>1: small boxes).")
    max_aspect_ratio: float = Field(1.5, ge=1, description="EdgeBoxes max box aspect ratio.")
    min_box_area: float = Field(
        64.0, ge=1, description="EdgeBoxes min box area, in working-resolution px²."
    )
    max_boxes: int = Field(500, ge=1, le=100_000, description="EdgeBoxes max number of proposals.")
    edge_min_mag: float = Field(0.4, ge=0, description="EdgeBoxes edge min magnitude.")
    edge_merge_threshold: float = Field(1.0, ge=0, description="EdgeBoxes edge merge threshold.")
    cluster_min_mag: float = Field(1.0, ge=0, description="EdgeBoxes cluster min magnitude.")
    blob_width: int = Field(
        640,
        ge=0,
        description="Frames are reduced to this width for DoG blob proposals (px); 0 = off.",
    )
    blob_threshold: float = Field(
        0.05, ge=0, description="Min scale-normalised DoG response of a blob (grey/255)."
    )
    blob_max_per_scale: int = Field(150, ge=1, description="Strongest blobs kept per scale.")
    blob_scales_per_octave: int = Field(
        3, ge=1, le=8, description="Blob scales per doubling of the head size."
    )
    blob_max_head_size: float = Field(
        48.0,
        gt=0,
        description="Largest blob proposed, in px at 1080p (scaled by height/1080); larger heads"
        " are left to EdgeBoxes.",
    )
    min_head_size: float = Field(
        8.0, gt=0, description="Smallest box side kept, in px at 1080p (scaled by height/1080)."
    )
    max_head_size: float = Field(
        120.0, gt=0, description="Largest box side kept, in px at 1080p (scaled by height/1080)."
    )
    context: float | None = Field(
        None,
        ge=0,
        lt=112,
        description="R-CNN context: px of a 224-px warped frame added around each box; None = the"
        " value the model records (16 when it records none).",
    )
    min_crop: float | None = Field(
        None,
        ge=0,
        description="Smallest crop side, px at 1080p (scaled by height/1080); None = the value the"
        " model records (0 when it records none). It must match the model's training.",
    )
    input_size: int = Field(0, ge=0, description="CNN input side (px); 0 = read it from the model.")
    mean: tuple[float, float, float] = Field(
        SHIPPED_MEAN, description="Per-channel mean of [0,1] RGB pixels for the CNN."
    )
    std: tuple[float, float, float] = Field(
        SHIPPED_STD, description="Per-channel std of [0,1] RGB pixels for the CNN."
    )
    output_form: Literal["auto", "logit", "logits2", "probability"] = Field(
        "auto",
        description="CNN output: logit (sigmoid), logits2 (softmax, 1=head), probability, auto.",
    )
    score_threshold: float = Field(0.7, ge=0, le=1, description="Head score threshold.")
    nms_iou: float = Field(0.3, gt=0, le=1, description="IoU threshold of cv2.dnn.NMSBoxes.")
    nms_centre_ratio: float = Field(
        0.7,
        ge=0,
        description="After NMS, drop a box whose centre is within this share of the larger"
        " side of the two boxes from a better box's centre; 0 = IoU NMS only.",
    )
    batch_size: int = Field(64, ge=1, description="Crops per onnxruntime call.")
    intra_op_threads: int = Field(
        0,
        ge=0,
        description="onnxruntime intra-op threads; 0 = OMP_NUM_THREADS if set (1 in bench"
        " workers), else the CPU count (at most 4).",
    )
    overlap_proposals: bool = Field(
        True,
        description="Run EdgeBoxes in a second thread while the blob proposals are scored.",
    )

    def proposal_settings(self) -> ProposalSettings:
        """The proposal part of these parameters."""
        return ProposalSettings(
            edge_boxes=EdgeBoxesSettings(
                alpha=self.alpha,
                beta=self.beta,
                kappa=self.kappa,
                max_aspect_ratio=self.max_aspect_ratio,
                min_box_area=self.min_box_area,
                max_boxes=self.max_boxes,
                edge_min_mag=self.edge_min_mag,
                edge_merge_threshold=self.edge_merge_threshold,
                cluster_min_mag=self.cluster_min_mag,
            ),
            edge_boxes_width=self.work_width,
            blob_width=self.blob_width,
            blob_threshold=self.blob_threshold,
            blob_max_per_scale=self.blob_max_per_scale,
            blob_scales_per_octave=self.blob_scales_per_octave,
            blob_max_head_size=self.blob_max_head_size,
            min_head_size=self.min_head_size,
            max_head_size=self.max_head_size,
            sed_model=self.sed_model or None,
        )


class EdgeBoxCnnDetector(Detector[EdgeBoxCnnParams]):
    """EdgeBoxes (+ blob) proposals scored by a small CNN head classifier (the paper's detector)."""

    name = "edgebox-cnn"
    uses_pixels = True

    @classmethod
    def resource_files(cls, params: EdgeBoxCnnParams) -> list[Path]:
        """The shipped head classifier when no ``model`` is given."""
        return [] if params.model else [shipped_model_path()]

    def __init__(self, params: EdgeBoxCnnParams | None = None) -> None:
        super().__init__(params)
        settings = self.params
        model_path = Path(settings.model) if settings.model else shipped_model_path()
        input_size = (settings.input_size, settings.input_size) if settings.input_size else None
        self.scorer = HeadScorer(
            model_path,
            input_size=input_size,
            mean=settings.mean,
            std=settings.std,
            output_form=settings.output_form,
            intra_op_threads=settings.intra_op_threads,
            batch_size=settings.batch_size,
            context=settings.context,
            min_crop=settings.min_crop,
        )
        self.proposer = HeadProposer(settings.proposal_settings())
        self._edge_boxes_thread: ThreadPoolExecutor | None = None
        #: Seconds of the last frame's steps (for benchmarks): EdgeBoxes, blobs, scoring, and
        #: the whole proposal step as the caller waited for it (less than the sum of the first
        #: two when EdgeBoxes runs in its own thread).
        self.last_timing: dict[str, float] = {
            "edge_boxes": 0.0,
            "blobs": 0.0,
            "proposals": 0.0,
            "scoring": 0.0,
            "proposed": 0,
        }

    @property
    def context(self) -> float:
        """The R-CNN context crops are cut with (the model's, unless configured)."""
        return self.scorer.context

    @property
    def min_crop(self) -> float:
        """The smallest crop side, px at 1080p (the model's, unless configured)."""
        return self.scorer.min_crop

    def proposals(self, image: NDArray[np.uint8]) -> NDArray[np.float64]:
        """Head-sized proposals of a full frame, ``(N, 4)`` in frame pixels."""
        return self.proposer.propose(image)

    def _timed_edge_boxes(self, image: NDArray[np.uint8]) -> tuple[NDArray[np.float64], float]:
        started = time.perf_counter()
        return self.proposer.edge_box_proposals(image), time.perf_counter() - started

    def detect_image(self, image: NDArray[np.uint8]) -> Detections:
        """Detect heads on a ``(H, W, 3)`` uint8 BGR image."""
        started = time.perf_counter()
        pending = None
        if self.params.overlap_proposals:
            # OpenCV and onnxruntime release the GIL, so EdgeBoxes runs on a second core while
            # this thread finds and scores the blobs.
            if self._edge_boxes_thread is None:
                self._edge_boxes_thread = ThreadPoolExecutor(
                    max_workers=1, thread_name_prefix="edge-boxes"
                )
            pending = self._edge_boxes_thread.submit(self._timed_edge_boxes, image)
        blobs = self.proposer.blob_proposals(image)
        blobs_time = time.perf_counter() - started
        scoring_started = time.perf_counter()
        blob_scores = self.scorer.score_boxes(image, blobs)
        scoring_time = time.perf_counter() - scoring_started
        waiting_started = time.perf_counter()
        edge_boxes, edge_boxes_time = (
            pending.result() if pending is not None else self._timed_edge_boxes(image)
        )
        proposal_time = blobs_time + time.perf_counter() - waiting_started
        scoring_started = time.perf_counter()
        edge_box_scores = self.scorer.score_boxes(image, edge_boxes)
        scoring_time += time.perf_counter() - scoring_started
        boxes = np.concatenate([edge_boxes, blobs])
        scores = np.concatenate([edge_box_scores, blob_scores])
        self.last_timing = {
            "edge_boxes": edge_boxes_time,
            "blobs": blobs_time,
            "proposals": proposal_time,
            "scoring": scoring_time,
            "proposed": len(boxes),
        }
        kept = non_maximum_suppression(
            boxes, scores, self.params.score_threshold, self.params.nms_iou
        )
        kept = suppress_nested_centres(boxes, kept, self.params.nms_centre_ratio)
        return detections_from_boxes(boxes[kept], scores[kept], "centre")

    def detect(self, frame: FrameData) -> Detections:
        """Detect heads on ``frame`` (its image must be decoded)."""
        return self.detect_image(frame_pixels(frame, self.name))
