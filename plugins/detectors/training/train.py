"""Training loop, ONNX export and onnxruntime parity check of the head classifier (needs torch).

``train_detector`` collects labelled crops (see :mod:`.sampling`), trains :class:`HeadNet` with
binary cross-entropy and photometric augmentation, exports it to ONNX with a dynamic batch axis,
and checks that onnxruntime (through :class:`HeadScorer`, exactly as the detector runs it) gives
the same probabilities as PyTorch.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from trackfw.errors import UserError
from trackfw_plugins.detectors.edgebox_cnn import SHIPPED_MEAN, SHIPPED_STD
from trackfw_plugins.detectors.head_scorer import (
    CROP_METADATA,
    HeadScorer,
    crops_to_tensor,
    extract_crops,
)
from trackfw_plugins.detectors.proposals import HeadProposer, ProposalSettings
from trackfw_plugins.detectors.training.model import DenseHeadNet, HeadNet
from trackfw_plugins.detectors.training.sampling import (
    AnnotatedFrame,
    SamplingSettings,
    label_boxes,
    sample_crops,
)

#: Largest difference allowed between PyTorch and onnxruntime probabilities.
PARITY_TOLERANCE = 1e-4


@dataclass
class TrainingReport:
    """What training did: crop counts, validation accuracy, parity with onnxruntime."""

    positives: int = 0
    negatives: int = 0
    validation_accuracy: float = math.nan
    validation_recall: float = math.nan
    validation_precision: float = math.nan
    parity_max_difference: float = math.nan
    losses: list[float] = field(default_factory=list)


def collect_crops(
    frames: Iterable[AnnotatedFrame],
    settings: SamplingSettings,
    seed: int,
    proposals: ProposalSettings | None = None,
    use_proposals: bool = True,
) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Labelled crops from all frames: ``(N, s, s, 3)`` uint8 BGR and ``(N,)`` labels.

    ``proposals`` should match the detector's, so that training sees its hard negatives.
    """
    rng = np.random.default_rng(seed)
    proposer = HeadProposer(proposals) if use_proposals else None
    crops: list[NDArray[np.uint8]] = []
    labels: list[NDArray[np.uint8]] = []
    for frame in frames:
        frame_crops, frame_labels = sample_crops(frame, rng, settings, proposer)
        crops.append(frame_crops)
        labels.append(frame_labels)
    if not crops:
        raise UserError("no training frame found; expected datasets with heads.csv or MOT gt.")
    return np.concatenate(crops), np.concatenate(labels)


def augment(images: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """Photometric and mirror augmentation of a ``(N, 3, s, s)`` batch in [0, 1] RGB."""
    count = images.shape[0]

    def uniform(low: float, high: float, *shape: int) -> torch.Tensor:
        return low + (high - low) * torch.rand(*shape, generator=generator)

    flip = torch.rand(count, generator=generator) < 0.5
    images = torch.where(flip[:, None, None, None], images.flip(3), images)
    grey = images.mean(dim=1, keepdim=True)
    to_grey = (torch.rand(count, generator=generator) < 0.1)[:, None, None, None]
    images = torch.where(to_grey, grey.expand_as(images), images)
    mean = images.mean(dim=(1, 2, 3), keepdim=True)
    images = (images - mean) * uniform(0.6, 1.4, count, 1, 1, 1) + mean
    images = images * uniform(0.85, 1.15, count, 3, 1, 1) + uniform(-0.15, 0.15, count, 1, 1, 1)
    noise = torch.randn(images.shape, generator=generator)
    images = images + noise * uniform(0, 0.04, count, 1, 1, 1)
    return images.clamp(0.0, 1.0)


def _normalise(images: torch.Tensor) -> torch.Tensor:
    mean = torch.tensor(SHIPPED_MEAN, dtype=torch.float32).view(1, 3, 1, 1)
    std = torch.tensor(SHIPPED_STD, dtype=torch.float32).view(1, 3, 1, 1)
    return (images - mean) / std


def train_classifier(
    crops: NDArray[np.uint8],
    labels: NDArray[np.uint8],
    epochs: int = 12,
    seed: int = 0,
    batch_size: int = 128,
    log: Callable[[str], None] = print,
) -> tuple[HeadNet, TrainingReport]:
    """Train :class:`HeadNet` on labelled crops; 10 % are held out for validation figures."""
    torch.manual_seed(seed)
    generator = torch.Generator().manual_seed(seed)
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(crops))
    held_out = order[: max(1, len(order) // 10)]
    training = order[len(held_out) :]
    # uint8 NCHW RGB, converted to [0, 1] batch by batch (a float copy of all crops is large).
    images = torch.from_numpy(np.ascontiguousarray(crops[..., ::-1].transpose(0, 3, 1, 2)))
    targets = torch.from_numpy(labels.astype(np.float32))
    report = TrainingReport(positives=int(labels.sum()), negatives=int(len(labels) - labels.sum()))
    model = HeadNet()
    positive_share = float(targets[training].mean())
    # Balanced classes train faster; the weight is taken out of the bias again below.
    positive_weight = (1 - positive_share) / max(positive_share, 1e-6)
    loss_function = nn.BCEWithLogitsLoss(pos_weight=torch.tensor(positive_weight))
    optimiser = torch.optim.AdamW(model.parameters(), lr=2e-3, weight_decay=1e-4)
    steps = max(1, epochs * math.ceil(len(training) / batch_size))
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimiser, max_lr=3e-3, total_steps=steps)
    training_tensor = torch.from_numpy(training)
    for epoch in range(epochs):
        model.train()
        permutation = training_tensor[torch.randperm(len(training), generator=generator)]
        total = 0.0
        for start in range(0, len(permutation), batch_size):
            batch = permutation[start : start + batch_size]
            inputs = _normalise(augment(images[batch].float() / 255.0, generator))
            loss = loss_function(model(inputs).squeeze(1), targets[batch])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            schedule.step()
            total += loss.item() * len(batch)
        report.losses.append(total / len(training))
        log(f"epoch {epoch + 1}/{epochs}: loss {report.losses[-1]:.4f}")
    model.eval()
    with torch.no_grad():
        # Weighting positives by w shifts the optimal logit by log w: undo it, so that a score
        # of 0.5 means even odds at the training prior (far fewer false positives among the
        # hundreds of proposals of a frame than with balanced odds).
        output_layer = model.classifier[-1]
        assert isinstance(output_layer, nn.Linear)
        output_layer.bias.sub_(math.log(max(positive_weight, 1e-6)))
        held_images = images[torch.from_numpy(held_out)].float() / 255.0
        logits = model(_normalise(held_images)).squeeze(1).numpy()
    predicted = logits > 0
    truth = labels[held_out] == 1
    report.validation_accuracy = float(np.mean(predicted == truth))
    report.validation_recall = float(np.sum(predicted & truth) / max(truth.sum(), 1))
    report.validation_precision = float(np.sum(predicted & truth) / max(predicted.sum(), 1))
    return model, report


def export_onnx(
    model: HeadNet, path: Path, input_size: int, crop_settings: SamplingSettings | None = None
) -> None:
    """Write ``model`` as ONNX: input ``crops`` ``(N, 3, s, s)``, output ``logit`` ``(N, 1)``.

    With ``crop_settings``, their context and smallest crop side go into the model's metadata
    (:data:`~trackfw_plugins.detectors.head_scorer.CROP_METADATA`), where the detector reads them.
    """
    model.eval()
    example = torch.zeros(1, 3, input_size, input_size)
    temporary = _export(model, example, path, {"crops": {0: "batch"}}, {"logit": {0: "batch"}})
    if crop_settings is not None:
        import onnx  # in the train extra, beside torch

        exported = onnx.load(str(temporary))
        for name, key in CROP_METADATA.items():
            entry = exported.metadata_props.add()
            entry.key, entry.value = key, repr(float(getattr(crop_settings, name)))
        onnx.save(exported, str(temporary))
    temporary.replace(path)


def _export(
    module: nn.Module,
    example: torch.Tensor,
    path: Path,
    inputs: dict[str, dict[int, str]],
    outputs: dict[str, dict[int, str]],
) -> Path:
    """Export ``module`` (opset 17) to ``path`` + ``.partial``, which it returns; ``inputs`` and
    ``outputs`` name the one input and the one output with their dynamic axes."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(path.name + ".partial")
    with warnings.catch_warnings():
        # The TorchScript exporter is deprecated, but the dynamo one needs onnxscript.
        warnings.simplefilter("ignore", DeprecationWarning)
        torch.onnx.export(
            module,
            (example,),
            str(temporary),
            input_names=list(inputs),
            output_names=list(outputs),
            dynamic_axes={**inputs, **outputs},
            opset_version=17,
            dynamo=False,
        )
    return temporary


def export_dense_onnx(model: HeadNet, path: Path) -> None:
    """Write the fully convolutional twin of a 32-px ``model`` (see :class:`DenseHeadNet`).

    Input ``image`` ``(1, 3, H, W)`` with dynamic H and W, output ``logit_map``.
    """
    dense = DenseHeadNet(model).eval()
    temporary = _export(
        dense,
        torch.zeros(1, 3, 64, 64),
        path,
        {"image": {2: "height", 3: "width"}},
        {"logit_map": {2: "rows", 3: "columns"}},
    )
    temporary.replace(path)


def parity_difference(model: HeadNet, path: Path, crops: NDArray[np.uint8]) -> float:
    """Largest |p_torch - p_onnxruntime| over ``crops`` (scored as the detector scores them)."""
    scorer = HeadScorer(path, mean=SHIPPED_MEAN, std=SHIPPED_STD)
    onnx_scores = scorer.score_crops(crops)
    with torch.no_grad():
        tensor = torch.from_numpy(crops_to_tensor(crops, SHIPPED_MEAN, SHIPPED_STD))
        torch_scores = torch.sigmoid(model(tensor).squeeze(1)).double().numpy()
    return float(np.max(np.abs(onnx_scores - torch_scores))) if len(crops) else 0.0


def mine_hard_negatives(
    model_path: Path,
    frames: Iterable[AnnotatedFrame],
    settings: SamplingSettings,
    proposals: ProposalSettings | None = None,
    threshold: float = 0.3,
    per_frame: int = 100,
    seed: int = 0,
) -> NDArray[np.uint8]:
    """Background proposals that the current model scores at least ``threshold``.

    Returns:
        ``(N, s, s, 3)`` uint8 BGR crops (label 0), the strongest ``per_frame`` of each frame.
    """
    scorer = HeadScorer(model_path, mean=SHIPPED_MEAN, std=SHIPPED_STD)
    proposer = HeadProposer(proposals)
    size = (settings.input_size, settings.input_size)
    mined: list[NDArray[np.uint8]] = []
    for frame in frames:
        boxes = proposer.propose(frame.image)
        boxes = boxes[label_boxes(boxes, frame.heads.reshape(-1, 3)) == 0]
        crops = extract_crops(frame.image, boxes, size, settings.context, settings.min_crop)
        scores = scorer.score_crops(crops)
        strongest = np.argsort(-scores)[:per_frame]
        mined.append(crops[strongest[scores[strongest] >= threshold]])
    return np.concatenate(mined) if mined else np.zeros((0, *size, 3), np.uint8)


def train_detector(
    frames: Iterable[AnnotatedFrame],
    out: Path,
    epochs: int = 12,
    seed: int = 0,
    settings: SamplingSettings | None = None,
    hard_negative_rounds: int = 1,
    dense_out: Path | None = None,
    log: Callable[[str], None] = print,
) -> TrainingReport:
    """Sample crops, train, mine hard negatives and retrain, export to ``out``, check parity.

    The frames are held in memory (they are read once per round).

    Raises:
        UserError: when no frame is given or the exported model disagrees with PyTorch.
    """
    settings = settings or SamplingSettings()
    frame_list = list(frames)
    crops, labels = collect_crops(frame_list, settings, seed)
    log(f"crops: {int(labels.sum())} heads, {int(len(labels) - labels.sum())} background")
    model, report = train_classifier(crops, labels, epochs=epochs, seed=seed, log=log)
    export_onnx(model, out, settings.input_size, settings)
    for round_index in range(hard_negative_rounds):
        mined = mine_hard_negatives(out, frame_list, settings, seed=seed + round_index)
        log(f"hard negatives, round {round_index + 1}: {len(mined)} crops")
        if len(mined) == 0:
            break
        crops = np.concatenate([crops, mined])
        labels = np.concatenate([labels, np.zeros(len(mined), dtype=np.uint8)])
        model, report = train_classifier(crops, labels, epochs=epochs, seed=seed, log=log)
        export_onnx(model, out, settings.input_size, settings)
    report.positives = int(labels.sum())
    report.negatives = int(len(labels) - labels.sum())
    if dense_out is not None:
        export_dense_onnx(model, dense_out)
    report.parity_max_difference = parity_difference(model, out, crops[:512])
    if not report.parity_max_difference <= PARITY_TOLERANCE:
        raise UserError(
            f"{out}: onnxruntime scores differ from PyTorch by {report.parity_max_difference:.2e};"
            f" expected at most {PARITY_TOLERANCE:.0e}."
        )
    log(
        f"validation: accuracy {report.validation_accuracy:.3f}, precision"
        f" {report.validation_precision:.3f}, recall {report.validation_recall:.3f};"
        f" onnx parity {report.parity_max_difference:.1e}"
    )
    return report
