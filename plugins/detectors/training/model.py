"""The small CNN head classifier (PyTorch; only imported for training and export)."""

from __future__ import annotations

import torch
from torch import nn


def _block(in_channels: int, out_channels: int) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(in_channels, out_channels, kernel_size=3, padding=1, bias=False),
        nn.BatchNorm2d(out_channels),
        nn.ReLU(inplace=True),
        nn.MaxPool2d(2),
    )


class HeadNet(nn.Module):
    """Three conv blocks and a small fully connected head: ``(N, 3, s, s)`` -> ``(N, 1)`` logit.

    The input is a normalised RGB crop (see ``head_scorer.crops_to_tensor``), ``s`` 32 or 48.
    The feature map is pooled to 4×4 and flattened, so the classifier keeps the spatial layout
    and learns that the head must sit in the middle of the crop.
    """

    def __init__(self, width: int = 16) -> None:
        super().__init__()
        self.features = nn.Sequential(
            _block(3, width),
            _block(width, 2 * width),
            _block(2 * width, 4 * width),
            nn.AdaptiveAvgPool2d(4),
        )
        self.classifier = nn.Sequential(
            nn.Flatten(),
            nn.Dropout(0.3),
            nn.Linear(4 * width * 16, 64),
            nn.ReLU(inplace=True),
            nn.Linear(64, 1),
        )

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        """``(N, 3, s, s)`` float32 -> ``(N, 1)`` head logit."""
        return self.classifier(self.features(images))


class DenseHeadNet(nn.Module):
    """:class:`HeadNet` made fully convolutional, for dense scoring of whole frames.

    The fully connected layers become a 4×4 and a 1×1 convolution with the same weights, so an
    ``(1, 3, H, W)`` frame gives a ``(1, 1, H/8 - 3, W/8 - 3)`` map of logits: cell ``(i, j)``
    scores the 32×32 window whose top-left corner is ``(8 j, 8 i)`` (the ``onnx`` detector's
    ``score_map`` decoding with stride 8 and window 32). Only valid for 32-px models.
    """

    def __init__(self, model: HeadNet) -> None:
        super().__init__()
        self.features = nn.Sequential(*list(model.features.children())[:-1])
        first: nn.Linear = model.classifier[2]  # type: ignore[assignment]
        last: nn.Linear = model.classifier[4]  # type: ignore[assignment]
        channels = first.in_features // 16
        self.hidden = nn.Conv2d(channels, first.out_features, kernel_size=4)
        self.output = nn.Conv2d(first.out_features, 1, kernel_size=1)
        self.hidden.weight = nn.Parameter(
            first.weight.detach().view(first.out_features, channels, 4, 4).clone()
        )
        self.hidden.bias = nn.Parameter(first.bias.detach().clone())
        self.output.weight = nn.Parameter(
            last.weight.detach().view(1, first.out_features, 1, 1).clone()
        )
        self.output.bias = nn.Parameter(last.bias.detach().clone())

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        """``(1, 3, H, W)`` float32 -> ``(1, 1, H', W')`` logits."""
        return self.output(torch.relu(self.hidden(self.features(images))))
