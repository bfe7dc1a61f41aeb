"""A virtual wearer over a real MOTChallenge sequence (the command is in :mod:`.wear_cli`).

Every frame of the sequence is seen through a head-worn camera whose pose changes smoothly
(head sway, walking bob) within a segment and jumps to a clearly different pose after each
info-less interval. The pose is a rotation homography ``H = K_out R K_src^-1`` of the real frame:

* ``pan`` (degrees, rotation about the vertical axis; positive moves the content right),
* ``tilt`` (degrees, about the horizontal axis; positive moves the content up),
* ``roll`` (degrees, about the optical axis),
* ``scale`` (zoom of the output focal length), ``tx``/``ty`` (output pixels, the walking bob).

``K_src`` has the focal length of a ``horizontal_fov`` camera (80 degrees [OURS]); ``K_out`` is
the same camera zoomed by ``scale`` and by the factor that makes the source cover ``--size``. The
parts of the output the real frame does not cover are filled with a strongly blurred, mirrored
continuation of it (no black border, no recognisable head).

Ground truth: every MOT body box gives a head proxy ``(left + width/2, top + 0.08 height)`` with
size ``0.13 height`` (:func:`trackfw.formats.body_heads`, the head-point rule), moved by the frame's
homography (the size by the homography's local scale). The people of interest are a spatial group
of 5-10 people visible on frame 1 (a random person and its nearest neighbours); gt.csv holds them on
every informative frame where they are inside the image, heads.csv every visible person (and the
other group's heads during ``group`` intervals, with ids offset by ``group_id_offset``).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from pathlib import Path

from trackfw.atomic import replacing_folder
from trackfw.errors import UserError
from trackfw_plugins.datasets.mot import load_mot_sequence
from trackfw_plugins.datasets.wear_camera import (
    CameraPose,
    local_scale,
    pose_homography,
    transform_points,
)
from trackfw_plugins.datasets.wear_plan import (
    SWAY_AMPLITUDE,
    FrameFormat,
    VideoPlan,
    WearSettings,
    plan_video,
)
from trackfw_plugins.datasets.wear_render import RenderedFrame, render_frame, render_video

#: The plan, the renderer and the camera are in their own modules; these names stay importable
#: from here, where the generator's conventions are written.
__all__ = [
    "PREVIEW_FOLDER",
    "SWAY_AMPLITUDE",
    "CameraPose",
    "FrameFormat",
    "RenderedFrame",
    "VideoPlan",
    "WearSettings",
    "generate_dataset",
    "local_scale",
    "plan_video",
    "pose_homography",
    "render_frame",
    "render_video",
    "transform_points",
]

PREVIEW_FOLDER = "preview"


def generate_dataset(
    mot_folder: Path,
    out_folder: Path,
    seed: int = 0,
    n_videos: int = 1,
    settings: WearSettings | None = None,
    force: bool = False,
    progress: Callable[[str, int, int], None] | None = None,
) -> list[Path]:
    """Write ``n_videos`` virtual-wearer videos of one MOT sequence into ``out_folder``.

    Each video is rendered into a hidden temporary folder and renamed when complete, so an
    interrupted run never leaves a video that looks finished. With ``force``, video folders of
    the same names are replaced and anything else in ``out_folder`` is left alone (so that
    several sequences can share one dataset folder).

    Args:
        mot_folder: the MOTChallenge sequence folder.
        out_folder: the dataset folder to write.
        seed: random seed; the same seed gives the same videos.
        n_videos: how many videos (different intervals and poses) to make.
        settings: wearer settings (defaults when omitted).
        force: allow a non-empty ``out_folder``.
        progress: called with (video name, frames done, frames in the video).

    Returns:
        The video folders written.
    """
    settings = settings or WearSettings()
    if seed < 0:
        raise UserError(f"--seed is {seed}; expected a non-negative integer.")
    if n_videos < 1:
        raise UserError(f"--videos is {n_videos}; expected at least 1.")
    if out_folder.exists() and not out_folder.is_dir():
        raise UserError(f"{out_folder}: exists and is not a folder; expected a dataset folder.")
    if out_folder.is_dir() and any(out_folder.iterdir()) and not force:
        raise UserError(
            f"{out_folder}: folder is not empty; expected a new or empty folder, or --force to"
            " replace its videos of the same names."
        )
    sequence = load_mot_sequence(mot_folder)
    preview_folder = out_folder / PREVIEW_FOLDER
    preview_folder.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for index in range(n_videos):
        plan = plan_video(sequence, settings, seed, index)
        final = out_folder / plan.name
        partial = out_folder / f".{plan.name}.partial-{os.getpid()}"
        if partial.exists():
            shutil.rmtree(partial)

        def report(done: int, name: str = plan.name) -> None:
            if progress is not None:
                progress(name, done, sequence.n_frames)

        with replacing_folder(partial, final):
            render_video(sequence, plan, settings, partial, preview_folder, report)
        written.append(final)
    return written
