"""CEM: continuous energy minimisation for multi-target tracking (Milan, Roth & Schindler 2014).

Written fresh from the equations (the reference code's licence forbids derivative works). The
state is a set of targets, each a contiguous run of frames with one position per frame; the
energy is :mod:`trackfw_plugins.batch_trackers.cem_energy`'s five terms. The tracker:

1. starts from DPNMS's tracks (the reference's default initial solution), one target each;
2. minimises the energy over every position by conjugate gradients, lifespans fixed
   (``cg_iterations`` iterations, scipy's Polak-Ribiere CG with the analytic gradient);
3. for up to ``max_epochs`` rounds runs the jump moves of
   :mod:`trackfw_plugins.batch_trackers.cem_moves` in the reference order (merge, grow, shrink,
   split, add, remove), each accepted only when it lowers the energy, and descends again after a
   move changed the state; it stops after a round in which no move fired.

The tracked point is the head point itself (the reference tracks the foot of a box; with the
paper's fixed boxes the energy is the same up to a shift). A position counts as *observed* when
a detection of its frame lies within ``c / 2`` of it **[OURS]**: CEM has no hard assignment.

See ``docs/algorithms/batch-trackers.md#cem``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from trackfw.arrays import FloatArray
from trackfw_plugins.batch_trackers.cem_energy import Scene, cross_exclusion_energy, total_energy
from trackfw_plugins.batch_trackers.cem_moves import JUMP_MOVES, CemState, pack
from trackfw_plugins.batch_trackers.cem_params import CemParams
from trackfw_plugins.batch_trackers.dpnms import track_dpnms
from trackfw_plugins.batch_trackers.tracks import Tracks, VideoDetections

#: The reference's 2-D target size is the image width over this.
TARGET_SIZE_DIVISOR = 30.0


def video_scene(detections: VideoDetections, width: float, height: float, size: float) -> Scene:
    """Every frame's detections padded to one ``(F, G, 2)`` array (padding has score 0)."""
    bounds = detections.frame_bounds()
    counts = np.diff(bounds)
    padded = max(int(counts.max()) if len(counts) else 0, 1)
    points = np.zeros((detections.n_frames, padded, 2))
    scores = np.zeros((detections.n_frames, padded))
    slot = np.arange(len(detections)) - bounds[detections.frames]
    points[detections.frames, slot] = detections.points
    scores[detections.frames, slot] = detections.scores
    return Scene(points, scores, float(width), float(height), float(size))


def descend(state: CemState, iterations: int, everything: bool = False) -> None:
    """Conjugate gradients on the touched targets' positions (every target's with ``everything``).

    The other targets are held still (they only enter through the exclusion pairs), and every
    lifespan is fixed. The problem is cut to the frames the moving targets live on.
    """
    live = state.live()
    moving = set(live) if everything else state.touched.intersection(live)
    state.touched.clear()
    if not moving:
        return
    spans = [(index, state.target(index)) for index in live]
    window = (
        min(start for index, (start, _) in spans if index in moving),
        max(start + len(points) - 1 for index, (start, points) in spans if index in moving),
    )
    free = pack([item for item in spans if item[0] in moving], window, state.n_frames)
    still = [
        (index, (start, points))
        for index, (start, points) in spans
        if index not in moving and start <= window[1] and start + len(points) > window[0]
    ]
    fixed = pack(still, window, state.n_frames)
    frames = slice(window[0], window[1] + 1)
    scene = replace(
        state.scene, detections=state.scene.detections[frames], scores=state.scene.scores[frames]
    )
    params, alive = state.params, free.alive

    def energy(flat: FloatArray) -> tuple[float, FloatArray]:
        trial = free.positions.copy()
        trial[alive] = flat.reshape(-1, 2)
        value, gradient = total_energy(trial, alive, scene, params, free.spans)
        cross, cross_gradient = cross_exclusion_energy(
            trial, alive, (fixed.positions, fixed.alive), scene.target_size
        )
        gradient = gradient + params.exclusion_weight * cross_gradient
        return value + params.exclusion_weight * cross, gradient[alive].ravel()

    # Imported here: scipy.optimize would otherwise load with every CLI command (about 0.6 s).
    from scipy.optimize import minimize

    start = free.positions[alive].ravel()
    result = minimize(energy, start, jac=True, method="CG", options={"maxiter": iterations})
    if np.all(np.isfinite(result.x)):
        solved = free.positions.copy()
        solved[alive] = result.x.reshape(-1, 2)
        state.set_positions(free, solved)


def initial_state(detections: VideoDetections, scene: Scene, params: CemParams) -> CemState:
    """One target per DPNMS track (a track's missing frames, if any, filled linearly)."""
    state = CemState(scene, params, detections.n_frames)
    tracks = track_dpnms(detections)
    for track_id in tracks.track_ids():
        rows = tracks.ids == track_id
        frames, points = tracks.frames[rows], tracks.points[rows]
        span = np.arange(frames[0], frames[-1] + 1)
        filled = np.column_stack(
            [np.interp(span, frames, points[:, 0]), np.interp(span, frames, points[:, 1])]
        )
        state.add(int(frames[0]), filled)
    return state


def track_cem(
    detections: VideoDetections,
    width: float,
    height: float,
    params: CemParams | None = None,
) -> Tracks:
    """Run CEM on every detection of a video.

    Args:
        detections: all detections (points and scores are used; DPNMS also uses the boxes).
        width, height: the image size in px (the tracking area and the default target size).
        params: settings; the reference's 2-D defaults when None.

    Returns:
        Tracks numbered 1, 2, ... by first frame, one position per frame of each lifespan.
    """
    params = params or CemParams()
    if len(detections) == 0:
        return Tracks.empty()
    size = params.target_size or width / TARGET_SIZE_DIVISOR
    state = initial_state(detections, video_scene(detections, width, height, size), params)
    descend(state, params.cg_iterations, everything=True)
    changed = False
    for _ in range(params.max_epochs):
        fired = False
        for move in JUMP_MOVES:
            if move(state):
                fired = True
                descend(state, params.cg_iterations)
        changed |= fired
        if not fired:
            break
    if changed:
        # The descents after the moves held the untouched targets still; let them all settle.
        descend(state, params.cg_iterations, everything=True)
    return state.as_tracks(detections)
