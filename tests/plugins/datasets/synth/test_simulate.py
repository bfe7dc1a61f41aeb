"""Motion, camera and ground truth without pixels."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from trackfw_plugins.datasets.synth.people import read_trajectory_file, trajectory_crowd
from trackfw_plugins.datasets.synth.presets import (
    IntervalPlan,
    WearerConfig,
    custom_plan,
    paper_plan,
)
from trackfw_plugins.datasets.synth.scene import CameraModel, Pose, look_at, project, rotation
from trackfw_plugins.datasets.synth.simulate import simulate


def _small_plan(kind: str, seed: int = 3):
    plan = custom_plan(seed, videos=1, frames=120, intervals=1, width=320, height=180)[0]
    return replace(plan, intervals=(IntervalPlan(start=40, length=30, kind=kind),))


def test_rotation_is_orthonormal_and_look_at_centres_the_target() -> None:
    matrix = rotation(23.0, -37.0, 8.0)
    assert np.allclose(matrix @ matrix.T, np.eye(3))
    camera = CameraModel(640, 360, 75.0)
    centre = np.array([1.0, -0.2, 9.0])
    target = np.array([4.0, 11.0, 1.2])
    pan, tilt = look_at(centre, target)
    pixels, depth = project(target[None], Pose(pan, tilt, 5.0, 1.3, *centre), camera)
    assert depth[0] > 0
    assert np.allclose(pixels[0], [320.0, 180.0], atol=1e-6)


@pytest.mark.parametrize("kind", ["sky", "group", "path"])
def test_ground_truth_is_inside_the_image_and_outside_intervals(kind: str) -> None:
    simulation = simulate(_small_plan(kind))
    plan = simulation.plan
    infoless = simulation.infoless()
    n_targets = plan.n_targets
    assert simulation.targets, "no ground truth at all"
    for frame, targets in simulation.targets.items():
        assert not infoless[frame]
        assert set(targets) <= set(range(1, n_targets + 1))
        for x, y in targets.values():
            assert 0 <= x <= plan.width - 1 and 0 <= y <= plan.height - 1
    # The people of interest are a group visible on frame 1.
    assert len(simulation.targets[0]) == n_targets
    for frame, person, x, y, size in simulation.heads:
        assert 0 <= frame < plan.n_frames and person >= 1 and size > 0
        assert 0 <= x <= plan.width - 1 and 0 <= y <= plan.height - 1
    # Most targets are back in view on the first frame after the interval.
    b = simulation.intervals[0].b
    assert len(simulation.targets.get(b, {})) >= 0.8 * n_targets


@pytest.mark.parametrize("kind", ["sky", "group", "path"])
def test_pose_differs_after_the_interval(kind: str) -> None:
    simulation = simulate(_small_plan(kind, seed=11))
    before, after = simulation.motion.segment_offsets
    pan_change = abs(after[0] - before[0])
    assert (
        pan_change > 1.0 or abs(after[3] / before[3] - 1) > 0.05 or abs(after[2] - before[2]) > 1.0
    )
    assert abs(after[2] - before[2]) <= 10.0 + 1e-9
    assert 0.7 - 1e-9 <= after[3] / before[3] <= 1.4 + 1e-9
    interval = simulation.intervals[0]
    poses = simulation.motion.poses
    if kind == "path":  # the wearer walked: the viewpoint moved along the walkway
        assert abs(poses[interval.b, 4] - poses[interval.a, 4]) >= 1.5
    else:
        assert np.allclose(poses[interval.b, 4:7], poses[interval.a, 4:7])
    # The swing is fast: the camera turns further inside the interval than across it.
    inside = poses[interval.a + 1 : interval.b]
    assert (
        np.max(np.abs(inside[:, 1] - poses[interval.a, 1])) > 10
        or np.max(np.abs((inside[:, 0] - poses[interval.a, 0] + 180) % 360 - 180)) > 30
    )


def test_group_interval_looks_at_another_group() -> None:
    simulation = simulate(_small_plan("group"))
    interval = simulation.intervals[0]
    middle = (interval.a + interval.b) // 2
    visible = {person for frame, person, *_ in simulation.heads if frame == middle}
    assert any(person > simulation.plan.n_targets for person in visible)
    assert not any(person <= simulation.plan.n_targets for person in visible)


def test_simulation_is_deterministic_for_a_seed() -> None:
    first, second = simulate(_small_plan("sky", 5)), simulate(_small_plan("sky", 5))
    assert first.targets == second.targets and first.heads == second.heads
    assert np.array_equal(first.motion.poses, second.motion.poses)
    plan = _small_plan("sky", 5)
    other = simulate(replace(plan, seed=plan.seed + 1))
    assert not np.array_equal(other.motion.poses, first.motion.poses)


def test_paper_videos_keep_their_targets_in_view() -> None:
    plans = [plan for plan in paper_plan(0) if plan.intervals][:3]
    for plan in plans:
        simulation = simulate(replace(plan, width=640, height=360))
        normal = (~simulation.infoless()).sum()
        shown = sum(len(targets) for targets in simulation.targets.values())
        assert shown >= 0.8 * normal * plan.n_targets


def test_trajectory_file_is_resampled_to_the_frame_rate(tmp_path: Path) -> None:
    rows = []
    for step in range(30):  # 2.5 Hz: frame numbers step by 10
        for person in range(6):
            rows.append(
                f"{step * 10}\t{person + 1}.0\t{person * 0.8 + 0.5 * step:.2f}\t{person % 2:.2f}"
            )
    path = tmp_path / "walk.txt"
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    assert len(read_trajectory_file(path)) == 6
    crowd = trajectory_crowd(np.random.default_rng(0), path, 90, 30.0, 5, np.array([0.0, 9.0]))
    assert crowd.positions.shape[1:] == (90, 2)
    assert crowd.is_target.sum() == 5
    steps = np.linalg.norm(np.diff(crowd.positions, axis=1), axis=2)
    # 0.5 m per 0.4 s is 1.25 m/s, i.e. about 0.042 m per frame at 30 fps.
    assert np.allclose(steps, 1.25 / 30.0, atol=0.01)
    assert crowd.positions[crowd.is_target][:, :, 1].min() >= 3.0


def test_eth_hotel_trajectories_drive_a_video(shared_data: Path) -> None:
    source = shared_data / "eth_ucy" / "sgan_format" / "biwi_hotel.txt"
    plan = replace(_small_plan("sky"), trajectories=str(source))
    simulation = simulate(plan)
    assert simulation.crowd.notes["motion"] == "trajectories"
    assert len(simulation.targets[0]) == plan.n_targets
    speeds = np.linalg.norm(np.diff(simulation.crowd.positions, axis=1), axis=2) * plan.fps
    assert np.percentile(speeds, 95) < 3.0  # walking, not teleporting


def test_pose_change_limits_are_configurable() -> None:
    limits = WearerConfig(
        max_pan_change=8.0, min_pan_change=4.0, max_roll_change=2.0, scale_range=(0.95, 1.05)
    )
    for kind in ("sky", "group", "path"):
        simulation = simulate(replace(_small_plan(kind, seed=21), wearer=limits))
        before, after = simulation.motion.segment_offsets
        assert abs(after[0] - before[0]) <= 8.0 + 1e-9
        assert abs(after[2] - before[2]) <= 2.0 + 1e-9
        assert 0.95 - 1e-9 <= after[3] / before[3] <= 1.05 + 1e-9
