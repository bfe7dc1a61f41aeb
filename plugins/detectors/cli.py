"""``trackfw train detector``: train the edgebox-cnn head classifier and export it to ONNX."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Annotated, Any

import typer

# The options of ``train_detector_command``, one alias each (typer reads them from the signature).
OutOption = Annotated[Path, typer.Option("--out", help="Where to write the ONNX model.")]
DatasetOption = Annotated[
    list[Path] | None,
    typer.Option("--dataset", help="trackfw dataset with heads.csv (repeatable)."),
]
MotOption = Annotated[
    list[Path] | None,
    typer.Option("--mot", help="MOTChallenge sequence with gt/gt.txt (repeatable)."),
]
EpochsOption = Annotated[int, typer.Option("--epochs", min=1, help="Training epochs.")]
SeedOption = Annotated[int, typer.Option("--seed", help="Seed of sampling and training.")]
DatasetFrameStepOption = Annotated[
    int,
    typer.Option("--dataset-frame-step", min=1, help="Use every n-th dataset frame."),
]
MotFrameStepOption = Annotated[
    int, typer.Option("--mot-frame-step", min=1, help="Use every n-th MOT frame.")
]
HardNegativeRoundsOption = Annotated[
    int,
    typer.Option(
        "--hard-negative-rounds", min=0, help="Rounds of hard-negative mining + retraining."
    ),
]
DenseOutOption = Annotated[
    Path | None,
    typer.Option("--dense-out", help="Also write the fully convolutional model here."),
]
InputSizeOption = Annotated[int, typer.Option("--input-size", min=16, help="CNN input side (px).")]
MinCropOption = Annotated[
    float,
    typer.Option(
        "--min-crop",
        min=0.0,
        help="Smallest crop side, px at 1080p (recorded in the model; the detector reads it).",
    ),
]


def register(train_app: typer.Typer) -> None:
    """Add the ``detector`` command to the ``train`` group."""

    @train_app.command("detector")
    def train_detector_command(
        out: OutOption,
        dataset: DatasetOption = None,
        mot: MotOption = None,
        epochs: EpochsOption = 12,
        seed: SeedOption = 0,
        dataset_frame_step: DatasetFrameStepOption = 5,
        mot_frame_step: MotFrameStepOption = 2,
        hard_negative_rounds: HardNegativeRoundsOption = 1,
        dense_out: DenseOutOption = None,
        input_size: InputSizeOption = 32,
        min_crop: MinCropOption = 0.0,
    ) -> None:
        """Train the head classifier of the edgebox-cnn detector (needs PyTorch: trackfw\\[train])."""
        datasets, sequences = dataset or [], mot or []
        train_detector = _check_and_import(datasets, sequences, out, dense_out)
        from trackfw_plugins.detectors.training.sampling import (
            SamplingSettings,
            iter_dataset_frames,
            iter_mot_frames,
        )

        frames = itertools.chain(
            *(iter_dataset_frames(path, dataset_frame_step) for path in datasets),
            *(iter_mot_frames(path, mot_frame_step) for path in sequences),
        )
        report = train_detector(
            frames,
            out,
            epochs=epochs,
            seed=seed,
            settings=SamplingSettings(input_size=input_size, min_crop=min_crop),
            hard_negative_rounds=hard_negative_rounds,
            dense_out=dense_out,
            log=typer.echo,
        )
        typer.echo(
            f"wrote {out}: {report.positives} head / {report.negatives} background crops,"
            f" validation accuracy {report.validation_accuracy:.3f}"
        )


def _check_and_import(
    datasets: list[Path], sequences: list[Path], out: Path, dense_out: Path | None
) -> Any:
    """Refuse missing data or unwritable outputs before training; the trainer (needs PyTorch)."""
    from trackfw.atomic import check_output_file
    from trackfw.errors import UserError

    if not datasets and not sequences:
        raise UserError("trackfw train detector: give at least one --dataset or --mot.")
    check_output_file(out, "--out")
    if dense_out is not None:
        check_output_file(dense_out, "--dense-out")
    try:
        from trackfw_plugins.detectors.training.train import train_detector
    except ImportError as error:
        raise UserError(
            f"trackfw train detector needs PyTorch ({error}); install the extra: pip install"
            " 'trackfw[train]'."
        ) from error
    return train_detector
