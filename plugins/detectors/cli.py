"""``trackfw train detector``: train the edgebox-cnn head classifier and export it to ONNX."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Annotated

import typer


def register(train_app: typer.Typer) -> None:
    """Add the ``detector`` command to the ``train`` group."""

    @train_app.command("detector")
    def train_detector_command(
        out: Annotated[Path, typer.Option("--out", help="Where to write the ONNX model.")],
        dataset: Annotated[
            list[Path] | None,
            typer.Option("--dataset", help="trackfw dataset with heads.csv (repeatable)."),
        ] = None,
        mot: Annotated[
            list[Path] | None,
            typer.Option("--mot", help="MOTChallenge sequence with gt/gt.txt (repeatable)."),
        ] = None,
        epochs: Annotated[int, typer.Option("--epochs", min=1, help="Training epochs.")] = 12,
        seed: Annotated[int, typer.Option("--seed", help="Seed of sampling and training.")] = 0,
        dataset_frame_step: Annotated[
            int,
            typer.Option("--dataset-frame-step", min=1, help="Use every n-th dataset frame."),
        ] = 5,
        mot_frame_step: Annotated[
            int, typer.Option("--mot-frame-step", min=1, help="Use every n-th MOT frame.")
        ] = 2,
        hard_negative_rounds: Annotated[
            int,
            typer.Option(
                "--hard-negative-rounds", min=0, help="Rounds of hard-negative mining + retraining."
            ),
        ] = 1,
        dense_out: Annotated[
            Path | None,
            typer.Option("--dense-out", help="Also write the fully convolutional model here."),
        ] = None,
        input_size: Annotated[
            int, typer.Option("--input-size", min=16, help="CNN input side (px).")
        ] = 32,
        min_crop: Annotated[
            float,
            typer.Option(
                "--min-crop",
                min=0.0,
                help="Smallest crop side, px at 1080p (recorded in the model; the detector reads it).",
            ),
        ] = 0.0,
    ) -> None:
        """Train the head classifier of the edgebox-cnn detector (needs PyTorch: trackfw\\[train])."""
        from trackfw.atomic import check_output_file
        from trackfw.errors import UserError

        datasets, sequences = dataset or [], mot or []
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
