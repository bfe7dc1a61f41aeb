"""``trackfw dataset synth``: rendered wearable-camera videos with ground truth.

The paper's 30 GoPro videos are not public, so this generator makes benchmark data of the same
shape: people walking on a square seen from a head-worn camera on a 2nd to 4th floor, with
info-less intervals of the paper's three kinds (sky or building, another group, the walking path)
after which the camera pose differs. See :mod:`.presets` for the ``paper`` preset and
:func:`generate_demo` for the small built-in demo clip.
"""

from __future__ import annotations

from .generate import generate_dataset, generate_demo, generate_video
from .presets import VideoPlan, custom_plan, demo_plan, paper_plan
from .simulate import Simulation, simulate

__all__ = [
    "Simulation",
    "VideoPlan",
    "custom_plan",
    "demo_plan",
    "generate_dataset",
    "generate_demo",
    "generate_video",
    "paper_plan",
    "simulate",
]
