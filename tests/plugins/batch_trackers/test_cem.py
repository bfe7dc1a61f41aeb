"""CEM: the brief's sanity tests and one test per jump move."""

from __future__ import annotations

import numpy as np
import pytest

from trackfw_plugins.batch_trackers.cem import CemParams, descend, track_cem, video_scene
from trackfw_plugins.batch_trackers.cem_energy import total_energy
from trackfw_plugins.batch_trackers.cem_moves import (
    JUMP_MOVES,
    CemState,
    add_move,
    grow_move,
    remove_move,
    shrink_move,
    split_move,
)
from trackfw_plugins.batch_trackers.tracks import VideoDetections

from .conftest import line_path, path_detections

WIDTH, HEIGHT = 640.0, 480.0  # c = 640 / 30 = 21.3 px


def _state(detections: VideoDetections, targets: list[tuple[int, np.ndarray]]) -> CemState:
    scene = video_scene(detections, WIDTH, HEIGHT, WIDTH / 30.0)
    state = CemState(scene, CemParams(), detections.n_frames)
    for start, points in targets:
        state.add(start, points)
    return state


def _energy(state: CemState) -> float:
    positions, alive = state.dense()
    return total_energy(positions, alive, state.scene, state.params)[0]


def test_a_targets_share_is_what_the_total_changes_by() -> None:
    random = np.random.default_rng(3)
    paths = [line_path((100, 100), (3, 1), 20), line_path((300, 200), (-2, 2), 20)]
    detections = path_detections(paths, 20)
    targets = [
        (0, paths[0] + random.normal(0, 5, (20, 2))),
        (4, paths[1][4:15] + random.normal(0, 5, (11, 2))),
        (2, line_path((120, 110), (1, 1), 9)),
    ]
    state = _state(detections, targets)
    for index in range(3):
        others = _state(detections, [target for k, target in enumerate(targets) if k != index])
        start, points = targets[index]
        share = state.share(start, points, [index])
        assert share == pytest.approx(_energy(state) - _energy(others), rel=1e-9, abs=1e-9)


def test_two_straight_targets_are_followed_within_a_pixel_and_no_move_fires() -> None:
    paths = [line_path((100, 100), (3, 1), 40), line_path((400, 300), (-2, 0.5), 40)]
    detections = path_detections(paths, 40)
    state = _state(detections, [(0, path.copy()) for path in paths])
    descend(state, 30)
    for index, path in enumerate(paths):
        assert np.abs(state.target(index)[1] - path).max() < 1.0
    assert [move(state) for move in JUMP_MOVES] == [False] * 6
    tracks = track_cem(detections, WIDTH, HEIGHT)
    assert tracks.track_ids().tolist() == [1, 2]
    for track_id, path in zip((1, 2), paths, strict=True):
        frames, points, observed = tracks.track(track_id)
        assert frames.tolist() == list(range(40)) and observed.all()
        assert np.abs(points - path).max() < 1.0


def test_a_short_gap_is_merged_and_filled_in() -> None:
    path = line_path((100, 100), (3, 1), 40)
    missed = path.copy()
    missed[20:25] = np.nan  # DPNMS gives two tracks here: no skip links
    tracks = track_cem(path_detections([missed], 40), WIDTH, HEIGHT)
    assert tracks.track_ids().tolist() == [1]
    frames, points, observed = tracks.track(1)
    assert frames.tolist() == list(range(40))
    assert not observed[20:25].any() and observed[:20].all() and observed[25:].all()
    assert np.abs(points - path).max() < 2.0


def test_remove_deletes_a_target_far_from_every_detection() -> None:
    path = line_path((100, 100), (3, 1), 20)
    stray = line_path((500, 400), (0, 0), 20)
    state = _state(path_detections([path], 20), [(0, path), (0, stray)])
    assert remove_move(state)
    assert len(state.targets) == 1 and np.array_equal(state.target(0)[1], path)
    assert not remove_move(state)


def test_add_seeds_a_moving_target_on_freepath_detections() -> None:
    path = line_path((100, 100), (4, -2), 20)
    state = _state(path_detections([path], 20), [])
    assert add_move(state)
    # One seed: the others lie within 2 c of it, or make a worse start.
    start, points = state.target(0)
    assert len(points) == 3
    assert np.allclose(points, path[start : start + 3])


def test_grow_extends_a_target_onto_its_detections_and_shrink_cuts_frames_without() -> None:
    path = line_path((100, 100), (3, 1), 40)
    state = _state(path_detections([path], 40), [(10, path[10:30].copy())])
    assert grow_move(state)
    start, points = state.target(0)
    assert (start, len(points)) == (0, 40)
    assert np.allclose(points, path)
    short = path.copy()
    short[30:] = np.nan
    state = _state(path_detections([short], 40), [(0, path.copy())])
    assert shrink_move(state)
    start, points = state.target(0)
    assert (start, len(points)) == (0, 30)


def test_split_cuts_a_target_where_it_jumps() -> None:
    first = line_path((100, 100), (3, 1), 15)
    second = line_path((450, 350), (3, 1), 15) + np.array([45.0, 15.0])
    joined = np.vstack([first, second])
    paths = [np.vstack([first, np.full((15, 2), np.nan)]), np.vstack([first * np.nan, second])]
    state = _state(path_detections(paths, 30), [(0, joined)])
    assert split_move(state)
    assert [(start, len(points)) for start, points in map(state.target, state.live())] == [
        (0, 15),
        (15, 15),
    ]


def test_bad_parameters_are_refused() -> None:
    for bad in ({"existence": -0.1}, {"target_size": 0.0}, {"cg_iterations": 0}):
        with pytest.raises(ValueError):
            CemParams(**bad)


def test_the_packed_layout_has_the_energy_of_one_column_per_target() -> None:
    paths = [line_path((100, 100), (3, 1), 30), line_path((300, 200), (-2, 2), 30)]
    targets = [(0, paths[0][:10]), (12, paths[0][12:]), (3, paths[1][3:20]), (22, paths[1][22:])]
    state = _state(path_detections(paths, 30), targets)
    packed = state.packed()
    assert packed.positions.shape[1] == 2  # four targets, two at a time
    one_each = np.zeros((30, 4, 2))
    alive = np.zeros((30, 4), dtype=bool)
    for column, (start, points) in enumerate(targets):
        one_each[start : start + len(points), column] = points
        alive[start : start + len(points), column] = True
    expected = total_energy(one_each, alive, state.scene, state.params)[0]
    got = total_energy(packed.positions, packed.alive, state.scene, state.params, packed.spans)[0]
    assert got == pytest.approx(expected, rel=1e-12)


def test_a_local_descent_moves_only_the_touched_target_and_lowers_the_energy() -> None:
    paths = [line_path((100, 100), (3, 1), 30), line_path((130, 110), (3, 1), 30)]
    noisy = paths[1] + np.random.default_rng(1).normal(0, 4, (30, 2))
    state = _state(path_detections(paths, 30), [(0, paths[0].copy())])
    descend(state, 30)
    kept = state.target(0)[1].copy()
    state.add(0, noisy)
    before = _energy(state)
    descend(state, 30)
    assert np.array_equal(state.target(0)[1], kept) and not state.touched
    assert _energy(state) < before
