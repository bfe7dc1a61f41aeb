"""Render simulated videos and write them in the trackfw dataset layout.

See docs/algorithms/datasets.md#dataset-layout.

Each video is written into a hidden temporary folder next to its final place and renamed when
complete, so an interrupted run never leaves a video that looks finished. Videos are rendered in
a process pool (one video per task; OpenCV pinned to one thread per worker).
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from trackfw.arrays import ImageArray
from trackfw.atomic import atomic_open, replacing_folder, write_text
from trackfw.dataset import IMAGE_FOLDER, META_FILE, POSES_FILE, VIDEO_FILE, write_meta
from trackfw.errors import UserError
from trackfw.formats.annotations import write_annotations
from trackfw.video_io import check_written_video

from .presets import VideoPlan, demo_plan
from .render import (
    BODY_WIDTH_M,
    HEAD_DIAMETER_M,
    PersonSprites,
    SensorNoise,
    motion_blur,
    paste,
    random_look,
    shadow_sprite,
)
from .scene import (
    POSE_COLUMNS,
    CameraModel,
    Pose,
    TexturedPlane,
    corner_elevations,
    draw_plane,
    project,
    sky_image,
)
from .simulate import PARAPET_HEIGHT, Simulation, simulate
from .textures import facade_texture, ground_texture, load_background, plain_texture

GENERATOR_VERSION = 1
FORMATS = ("mp4", "jpg")
GROUND_PPM = 20.0
#: Direction the shadows fall on the ground (unit vector, world x/y).
SUN = np.array([0.6, 0.8])


@dataclass(frozen=True)
class VideoResult:
    """What one generated video holds."""

    name: str
    path: Path
    n_frames: int
    n_intervals: int
    seconds: float


class FrameRenderer:
    """Draws the frames of one simulated video."""

    def __init__(self, simulation: Simulation) -> None:
        self.simulation = simulation
        plan = simulation.plan
        site = plan.site
        rng = np.random.default_rng(np.random.SeedSequence([plan.seed, 99]))
        self.camera = simulation.camera
        self.half_camera = CameraModel(plan.width // 2, plan.height // 2, plan.hfov_deg)
        far = site.facade_distance
        # Texture detail follows the frame size (a small video needs no fine texture).
        detail = float(np.clip(plan.width / 1280.0, 0.35, 1.5))
        ground_ppm = GROUND_PPM * detail
        ground_size = (int(120 * ground_ppm), int((far + 3) * ground_ppm))
        if plan.background:
            ground = load_background(Path(plan.background), ground_size, ground_ppm)
        else:
            ground = ground_texture(rng, site.ground_style, site.ground_colour, ground_size, ground_ppm)
        # A slight blur of the texture is a cheap mip-map: far, minified ground does not shimmer.
        ground = cv2.GaussianBlur(ground, (0, 0), 0.8)
        floor = site.walkway_height
        facade_height = rng.uniform(16.0, 26.0)
        x_axis, y_axis, down = np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, -1.0])
        self.far_planes = [
            # The square's texture covers x in [-60, 60] m; mirrored copies extend it to
            # +-180 m so no view sideways runs off its edge.
            TexturedPlane("ground", np.array([-60.0, -3.0, 0.0]), x_axis, y_axis, ground, ground_ppm,
                          extent=(-ground_size[0], 0.0, 2.0 * ground_size[0], ground_size[1])),
            TexturedPlane("facade", np.array([-70.0, far, facade_height]), x_axis, down,
                          facade_texture(rng, site.facade_colour, (1400, int(facade_height * 10)), 10.0),
                          10.0),
        ]
        near_ppm = 40.0 * detail
        walkway = plain_texture(rng, site.walkway_colour, (int(120 * near_ppm), int(2.5 * near_ppm)),
                                near_ppm, stripe_metres=0.5)
        red, green, blue = site.walkway_colour
        parapet = plain_texture(rng, (int(red * 0.85), int(green * 0.85), int(blue * 0.85)),
                                (int(120 * near_ppm), int(PARAPET_HEIGHT * near_ppm)), near_ppm)
        red, green, blue = site.facade_colour
        wall_colour = (int(red * 0.8), int(green * 0.8), int(blue * 0.8))
        wall_ppm = 24.0 * detail
        wall = facade_texture(rng, wall_colour, (int(120 * wall_ppm), int(3.4 * wall_ppm)), wall_ppm,
                              storey_metres=3.4)
        self.near_planes = [
            TexturedPlane("walkway", np.array([-60.0, -2.5, floor]), x_axis, y_axis, walkway, near_ppm),
            TexturedPlane("parapet", np.array([-60.0, 0.0, floor + PARAPET_HEIGHT]), x_axis, down,
                          parapet, near_ppm),
            TexturedPlane("wall", np.array([-60.0, -2.5, floor + 3.4]), x_axis, down, wall, wall_ppm),
        ]
        crowd = simulation.crowd
        self.sprites = [PersonSprites.build(random_look(rng), rng) for _ in range(crowd.count)]
        self.shadow = [shadow_sprite()]
        self.walked = crowd.walked()
        self.noise = SensorNoise(rng, (plan.height, plan.width), sigma=rng.uniform(2.5, 5.0))
        self.sky = ((235, 200, 150), (245, 235, 225)) if rng.random() < 0.7 else ((190, 185, 180),
                                                                                 (225, 225, 225))
        self.defocus = rng.uniform(0.5, 0.9)

    def render(self, frame: int) -> ImageArray:
        """The BGR image ``(H, W, 3)`` of a 0-based frame."""
        simulation = self.simulation
        pose = simulation.pose(frame)
        camera = self.camera
        # The sky, the square and the far facade are smooth: draw them at half resolution and
        # upsample (a quarter of the warping cost); people and near planes at full resolution.
        half = self.half_camera
        if float(corner_elevations(pose, half).max()) > -0.03:
            image = sky_image(pose, half, self.sky[0], self.sky[1])
        else:  # looking down: the square and the facade cover the whole picture
            image = np.empty((half.height, half.width, 3), dtype=np.uint8)
            image[:] = self.sky[1]
        for plane in self.far_planes:
            draw_plane(image, plane, pose, half)
        image = cv2.resize(image, (camera.width, camera.height), interpolation=cv2.INTER_LINEAR)
        self._draw_people(image, frame, pose)
        for plane in self.near_planes:
            draw_plane(image, plane, pose, camera)
        image = motion_blur(image, simulation.blur[frame])
        image = cv2.GaussianBlur(image, (3, 3), self.defocus)
        image = cv2.convertScaleAbs(image, alpha=float(simulation.gain[frame]), beta=0.0)
        return self.noise.apply(image, frame)

    def _draw_people(self, image: ImageArray, frame: int, pose: Pose) -> None:
        crowd, camera = self.simulation.crowd, self.camera
        count = crowd.count
        ground = crowd.positions[:, frame]
        right = pose.rotation_matrix[0].copy()
        right[2] = 0.0
        right /= max(float(np.linalg.norm(right)), 1e-9)
        heights = crowd.heights[:, None]
        sun_side = np.array([-SUN[1], SUN[0]])
        shadow_centre = ground + 0.3 * SUN
        neck_height = heights - HEAD_DIAMETER_M - 0.03
        # All the points of every person in one projection: feet, neck, neck side, head centre,
        # and three shadow points on the ground.
        points = np.concatenate([
            np.column_stack([ground, np.zeros(count)]),
            np.column_stack([ground, neck_height]),
            np.column_stack([ground, neck_height]) - right * BODY_WIDTH_M / 2.0,
            np.column_stack([ground, heights - 0.11]),
            np.column_stack([shadow_centre - 0.45 * SUN, np.zeros(count)]),
            np.column_stack([shadow_centre + 0.45 * SUN, np.zeros(count)]),
            np.column_stack([shadow_centre - 0.45 * SUN - 0.3 * sun_side, np.zeros(count)]),
        ])
        pixels_all, depth_all = project(points, pose, camera)
        pixels = pixels_all.reshape(7, count, 2)
        depths = depth_all.reshape(7, count)
        feet, neck, neck_side, heads = pixels[0], pixels[1], pixels[2], pixels[3]
        # A person is drawn when the box around feet and head (grown by the body width and the
        # shadow) meets the image.
        margin = 2.0 * np.linalg.norm(neck_side - neck, axis=1) + 0.5 * np.linalg.norm(
            heads - feet, axis=1) + 4.0
        onscreen = (ground[:, 1] > 0.3) & (depths[0] > 0.5) & (depths[3] > 0.5) & (
            np.minimum(feet[:, 0], heads[:, 0]) < camera.width + margin) & (
            np.maximum(feet[:, 0], heads[:, 0]) > -margin) & (
            np.minimum(feet[:, 1], heads[:, 1]) < camera.height + margin) & (
            np.maximum(feet[:, 1], heads[:, 1]) > -margin)
        order = [int(p) for p in np.argsort(-depths[0]) if onscreen[p]]
        shadow_ok = np.all(depths[4:] > 0.3, axis=0)
        for person in order:
            if shadow_ok[person]:
                paste(image, self.shadow, pixels[4:, person])
        diameters = 1.15 * camera.focal * pose.scale * HEAD_DIAMETER_M / np.maximum(depths[3], 1e-3)
        for person in order:
            sprites = self.sprites[person]
            phase = int(self.walked[person, frame] / 0.35) % len(sprites.bodies)
            paste(image, sprites.bodies[phase], np.stack([neck[person], feet[person], neck_side[person]]))
            upward = heads[person] - feet[person]
            length = float(np.hypot(upward[0], upward[1]))
            unit = upward / length if length > 1e-6 else np.array([0.0, -1.0])
            across = np.array([-unit[1], unit[0]])
            radius = diameters[person] / 2.0
            top = heads[person] + unit * radius
            paste(image, sprites.head, np.stack([top, heads[person] - unit * radius, top + across * radius]))


# ---------------------------------------------------------------------------------------- writing


def _meta(simulation: Simulation, output_format: str) -> dict[str, Any]:
    plan = simulation.plan
    camera = simulation.camera
    crowd = simulation.crowd
    return {
        "fps": plan.fps,
        "width": plan.width,
        "height": plan.height,
        "n_frames": plan.n_frames,
        "source": "synth",
        "generator_version": GENERATOR_VERSION,
        "seed": plan.seed,
        "preset": plan.preset,
        "site": plan.site.name,
        "format": output_format,
        "camera": {
            "model": "pinhole, no distortion",
            "hfov_deg": camera.hfov_deg,
            "focal_px": round(camera.focal, 3),
            "eye_height_m": round(plan.site.eye_height, 3),
            "storey": plan.site.storey,
        },
        "pose_columns": {
            "pan": "heading in degrees, 0 looks along +Y (away from the wearer's building)",
            "tilt": "elevation in degrees, negative looks down",
            "roll": "rotation about the optical axis in degrees",
            "scale": "focal-length factor (1 = hfov_deg)",
            "tx,ty,tz": "camera centre in metres (X along the building, Y into the square, Z up)",
        },
        "wearer": dataclasses.asdict(plan.wearer),
        "n_targets": int(crowd.is_target.sum()),
        "target_ids": [int(i) + 1 for i in np.flatnonzero(crowd.is_target)],
        "n_people": crowd.count,
        "motion": crowd.notes,
        "trajectories": plan.trajectories,
        "background": plan.background,
        "intervals": [
            {"start": interval.start + 1, "end": interval.end + 1, "kind": interval.kind,
             "shows": variant, "offsets_after": list(np.round(offsets, 3))}
            for interval, variant, offsets in zip(plan.intervals, simulation.motion.variants,
                                                   simulation.motion.segment_offsets[1:], strict=False)
        ],
        "head_size": "head diameter in pixels",
    }


def _poses_text(simulation: Simulation) -> str:
    lines = ["frame," + ",".join(POSE_COLUMNS)]
    for frame, row in enumerate(simulation.motion.poses):
        lines.append(f"{frame + 1}," + ",".join(f"{value:.4f}" for value in row))
    return "\n".join(lines) + "\n"


def _write_png(path: Path, image: ImageArray) -> None:
    ok, buffer = cv2.imencode(".png", image)
    if not ok:
        raise UserError(f"{path}: could not encode the preview image.")
    with atomic_open(path, "wb") as stream:
        stream.write(buffer.tobytes())


def _annotate(image: ImageArray, simulation: Simulation, frame: int, label: str) -> ImageArray:
    canvas = image.copy()
    for target_id, (x, y) in simulation.targets.get(frame, {}).items():
        cv2.circle(canvas, (round(x), round(y)), 14, (0, 255, 255), 2, cv2.LINE_AA)
        cv2.putText(canvas, str(target_id), (int(x) + 12, int(y) - 12), cv2.FONT_HERSHEY_SIMPLEX,
                    0.8, (0, 255, 255), 2, cv2.LINE_AA)
    cv2.putText(canvas, label, (12, 36), cv2.FONT_HERSHEY_SIMPLEX, 1.0, (0, 0, 255), 2, cv2.LINE_AA)
    return canvas


def _preview_frames(simulation: Simulation) -> dict[int, str]:
    """Frames to keep for the preview: a and b of the first interval and its middle."""
    plan = simulation.plan
    if not plan.intervals:
        return {0: "frame 1"}
    interval = plan.intervals[0]
    variant = simulation.motion.variants[0]
    a, b = interval.start - 1, interval.start + interval.length
    middle = interval.start + interval.length // 2
    return {a: f"a = {a + 1}", middle: f"{interval.kind} ({variant}) {middle + 1}",
            b: f"b = {b + 1}"}


def _iterate_frames(simulation: Simulation) -> Iterator[tuple[int, ImageArray]]:
    renderer = FrameRenderer(simulation)
    for frame in range(simulation.plan.n_frames):
        yield frame, renderer.render(frame)


def generate_video(plan: VideoPlan, out_dir: Path, output_format: str = "mp4",
                   preview_dir: Path | None = None, force: bool = False) -> VideoResult:
    """Simulate, render and write one video to ``out_dir / plan.name``.

    Args:
        plan: the video plan.
        out_dir: the dataset folder.
        output_format: ``mp4`` (video.mp4, codec mp4v) or ``jpg`` (img1/000001.jpg ...).
        preview_dir: when given, a PNG strip (frames a, middle, b) is saved there.
        force: replace an existing video folder of the same name.

    Returns:
        a summary of the written video.
    """
    if output_format not in FORMATS:
        raise UserError(f"--format {output_format!r}: expected one of {', '.join(FORMATS)}.")
    started = time.perf_counter()
    cv2.setNumThreads(1)
    final = out_dir / plan.name
    if final.exists() and not force:
        raise UserError(f"{final}: already exists; use --force to replace it.")
    out_dir.mkdir(parents=True, exist_ok=True)
    temporary = Path(tempfile.mkdtemp(prefix=f".{plan.name}.", suffix=".tmp", dir=out_dir))
    with replacing_folder(temporary, final):
        simulation = simulate(plan)
        wanted = _preview_frames(simulation) if preview_dir is not None else {}
        kept: dict[int, ImageArray] = {}
        writer = None
        if output_format == "mp4":
            writer = cv2.VideoWriter(str(temporary / VIDEO_FILE), cv2.VideoWriter.fourcc(*"mp4v"),
                                     plan.fps, (plan.width, plan.height))
            if not writer.isOpened():
                raise UserError(f"{temporary / VIDEO_FILE}: OpenCV cannot write mp4v video here;"
                                " expected a writable folder (or use --format jpg).")
        else:
            (temporary / IMAGE_FOLDER).mkdir()
        try:
            for frame, image in _iterate_frames(simulation):
                if frame in wanted:
                    kept[frame] = image
                if writer is not None:
                    writer.write(image)
                else:
                    path = temporary / IMAGE_FOLDER / f"{frame + 1:06d}.jpg"
                    if not cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, 92]):
                        raise UserError(f"{path}: could not write the frame.")
        finally:
            if writer is not None:
                writer.release()
        if writer is not None:
            check_written_video(temporary / VIDEO_FILE, plan.n_frames, shown=final / VIDEO_FILE)
        write_annotations(temporary, simulation.targets, simulation.heads, simulation.intervals)
        write_text(temporary / POSES_FILE, _poses_text(simulation))
        write_meta(temporary / META_FILE, _meta(simulation, output_format))
        if preview_dir is not None and kept:
            panels = [cv2.resize(_annotate(kept[frame], simulation, frame, label), (640, int(
                640 * plan.height / plan.width)), interpolation=cv2.INTER_AREA)
                for frame, label in sorted(wanted.items())]
            kind = plan.intervals[0].kind if plan.intervals else "none"
            _write_png(preview_dir / f"{plan.name}_{kind}.png", np.concatenate(panels, axis=1))
        temporary.chmod(0o755)  # mkdtemp makes it private; a dataset folder is not
    return VideoResult(plan.name, final, plan.n_frames, len(plan.intervals),
                       time.perf_counter() - started)


def staging_folders(out_dir: Path) -> list[Path]:
    """The hidden staging folders (``.NAME.XXXX.tmp``) that :func:`generate_video` writes into.

    A generator killed midway (SIGKILL, power loss) cannot remove its own; readers skip hidden
    folders, and ``--force`` removes them.
    """
    if not out_dir.is_dir():
        return []
    return sorted(
        child
        for child in out_dir.iterdir()
        if child.is_dir() and child.name.startswith(".") and child.name.endswith(".tmp")
    )


def remove_staging_folders(out_dir: Path) -> list[Path]:
    """Remove the staging folders a killed run left in ``out_dir``; returns them."""
    stale = staging_folders(out_dir)
    for folder in stale:
        shutil.rmtree(folder, ignore_errors=True)
    return stale


def _worker_init() -> None:
    cv2.setNumThreads(1)
    os.environ.setdefault("OMP_NUM_THREADS", "1")


def _run_one(arguments: tuple[VideoPlan, Path, str, Path | None, bool]) -> VideoResult:
    plan, out_dir, output_format, preview_dir, force = arguments
    return generate_video(plan, out_dir, output_format, preview_dir, force)


def generate_dataset(
    plans: list[VideoPlan],
    out_dir: Path,
    output_format: str = "mp4",
    jobs: int = 2,
    preview: bool = False,
    force: bool = False,
    progress: Callable[[VideoResult, int, int], None] | None = None,
) -> list[VideoResult]:
    """Generate every planned video into ``out_dir`` (a process pool when ``jobs > 1``).

    Videos are submitted longest first so the pool stays busy to the end.
    """
    if jobs < 1:
        raise UserError(f"--jobs {jobs}: expected a positive number of processes.")
    out_dir.mkdir(parents=True, exist_ok=True)
    if force:
        remove_staging_folders(out_dir)
    preview_dir = out_dir / "preview" if preview else None
    if preview_dir is not None:
        preview_dir.mkdir(exist_ok=True)
    ordered = sorted(plans, key=lambda plan: -plan.n_frames * plan.width * plan.height)
    tasks = [(plan, out_dir, output_format, preview_dir, force) for plan in ordered]
    results: list[VideoResult] = []
    if jobs == 1 or len(tasks) == 1:
        for task in tasks:
            results.append(_run_one(task))
            if progress is not None:
                progress(results[-1], len(results), len(tasks))
    else:
        import multiprocessing

        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), mp_context=context,
                                 initializer=_worker_init) as pool:
            futures = [pool.submit(_run_one, task) for task in tasks]
            try:
                for future in as_completed(futures):
                    results.append(future.result())
                    if progress is not None:
                        progress(results[-1], len(results), len(tasks))
            except BaseException:
                # One failed video stops the run: do not render the rest first.
                pool.shutdown(wait=True, cancel_futures=True)
                raise
    order = {plan.name: index for index, plan in enumerate(plans)}
    return sorted(results, key=lambda result: order[result.name])


def generate_demo(out_dir: Path) -> Path:
    """Write the small deterministic demo video (640x360, 150 frames, 6 targets, one 30-frame
    'sky' interval at 1-based frames 61-90) into ``out_dir`` and return its folder."""
    return generate_video(demo_plan(), Path(out_dir), "mp4", preview_dir=None, force=True).path


__all__ = ["FORMATS", "FrameRenderer", "VideoResult", "generate_dataset", "generate_demo",
           "generate_video"]
