"""DPNMS: greedy dynamic-programming min-cost flow with NMS in the loop.

Pirsiavash, Ramanan & Fowlkes, "Globally-optimal greedy algorithms for tracking a variable number
of objects", CVPR 2011, in the behaviour of the authors' released DP code (the "DP_NMS" row of
MOTChallenge and of Table 1 of Yu et al. 2018). Written fresh from the description in
``docs/algorithms/batch-trackers.md#dpnms``:

* every detection is a node with cost ``c_i = betta - score_i``; a track costs
  ``c_en + sum(c_i) + (len - 1) * c_ij + c_ex``;
* a detection in frame ``f`` may follow a detection in frame ``f - 1`` when their boxes overlap with
  IoU > ``link_iou`` and heights within ``height_ratio`` (consecutive frames only, so any missed
  frame splits a track: no skip links);
* tracks are taken one at a time, cheapest first, by one DP pass over the frame-ordered graph;
  after each, the detections overlapping the track in its frames are suppressed (IoU >
  ``nms_iou``, or covering more than ``nms_cover`` of the track box) and only the nodes whose best
  path started at a suppressed node's origin are recomputed;
* it stops when the cheapest remaining track costs ``stop_cost`` or more. The released code
  appends that last over-threshold track before testing; ``legacy_last_track`` keeps the quirk.

Output tracks hold observed detections only (``observed`` is always True).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from trackfw.arrays import FloatArray, IntArray
from trackfw.stages import StageParams
from trackfw_plugins.batch_trackers.tracks import Tracks, VideoDetections
from trackfw_plugins.maths.box_overlap import box_iou


class DpnmsParams(StageParams):
    """DPNMS settings; defaults are those of the authors' released code (``main.m``)."""

    birth_cost: float = Field(10.0, ge=0.0, description="c_en: cost of starting a track")
    death_cost: float = Field(10.0, ge=0.0, description="c_ex: cost of ending a track")
    link_cost: float = Field(0.0, ge=0.0, description="c_ij: cost of each frame-to-frame link")
    betta: float = Field(0.2, ge=0.0, description="detection cost c_i = betta - score_i")
    stop_cost: float = Field(
        18.0, description="thr_cost: stop when the cheapest remaining track costs this or more"
    )
    max_tracks: int | None = Field(
        None, ge=1, description="at most this many tracks; null = no cap"
    )
    nms: bool = Field(True, description="suppress overlapping detections after each track (DP_NMS)")
    nms_iou: float = Field(0.5, gt=0.0, lt=1.0, description="in-loop NMS: IoU above this")
    nms_cover: float = Field(
        0.9, gt=0.0, le=1.0, description="in-loop NMS: intersection / track-box area above this"
    )
    link_iou: float = Field(
        0.5, ge=0.0, lt=1.0, description="two detections in consecutive frames link above this IoU"
    )
    height_ratio: float = Field(
        0.8, ge=0.0, le=1.0, description="and when min(h_i/h_j, h_j/h_i) is above this"
    )
    legacy_last_track: bool = Field(
        True,
        description="keep the released code's quirk: the first track over stop_cost is returned too",
    )


def link_graph(detections: VideoDetections, params: DpnmsParams) -> list[list[int]]:
    """Predecessors of every detection: the overlapping detections of the previous frame.

    Returns:
        One list per detection (``N`` lists) of detection rows in frame ``f - 1``, ascending.
    """
    boxes = detections.boxes()
    heights = detections.sizes[:, 1]
    bounds = detections.frame_bounds()
    predecessors: list[list[int]] = [[] for _ in range(len(detections))]
    for frame in range(1, detections.n_frames):
        previous = np.arange(bounds[frame - 1], bounds[frame])
        current = np.arange(bounds[frame], bounds[frame + 1])
        if len(previous) == 0 or len(current) == 0:
            continue
        overlap = box_iou(boxes[current], boxes[previous])
        ratio = np.minimum(
            heights[current, None] / heights[None, previous],
            heights[None, previous] / heights[current, None],
        )
        rows, columns = np.nonzero((overlap > params.link_iou) & (ratio > params.height_ratio))
        for row, column in zip(rows.tolist(), columns.tolist(), strict=True):
            predecessors[int(current[row])].append(int(previous[column]))
    return predecessors


def suppressed_by(detections: VideoDetections, track: IntArray, params: DpnmsParams) -> IntArray:
    """Rows suppressed by ``track``: itself and, with NMS, what overlaps it in its frames."""
    if not params.nms:
        return track
    bounds = detections.frame_bounds()
    frames = detections.frames[track]
    starts = bounds[frames]
    counts = bounds[frames + 1] - starts
    owner = np.repeat(np.arange(len(track)), counts)
    # Row of every candidate in the track's frames, built without a Python loop.
    candidates = np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())
    boxes = detections.boxes()
    track_boxes = boxes[track][owner]
    other = boxes[candidates]
    left = np.maximum(track_boxes[:, 0], other[:, 0])
    top = np.maximum(track_boxes[:, 1], other[:, 1])
    right = np.minimum(track_boxes[:, 0] + track_boxes[:, 2], other[:, 0] + other[:, 2])
    bottom = np.minimum(track_boxes[:, 1] + track_boxes[:, 3], other[:, 1] + other[:, 3])
    intersection = np.clip(right - left, 0.0, None) * np.clip(bottom - top, 0.0, None)
    track_area = track_boxes[:, 2] * track_boxes[:, 3]
    union = track_area + other[:, 2] * other[:, 3] - intersection
    hit = (intersection > params.nms_iou * union) | (intersection > params.nms_cover * track_area)
    return np.union1d(track, candidates[hit]).astype(np.int64)


def track_dpnms(detections: VideoDetections, params: DpnmsParams | None = None) -> Tracks:
    """Run DPNMS on every detection of a video.

    Args:
        detections: all detections (boxes and scores are used).
        params: settings; the released code's defaults when None.

    Returns:
        Tracks numbered 1, 2, ... in the order they were found; every point is observed.
    """
    params = params or DpnmsParams()
    count = len(detections)
    if count == 0:
        return Tracks.empty()
    predecessors = link_graph(detections, params)
    node_cost = (params.betta - detections.scores).tolist()
    best = [0.0] * count
    link = [-1] * count
    origin = list(range(count))
    best_array = np.zeros(count)
    redo: list[int] = list(range(count))
    found: list[IntArray] = []
    while params.max_tracks is None or len(found) < params.max_tracks:
        for node in redo:
            best[node] = node_cost[node] + params.birth_cost
            link[node] = -1
            origin[node] = node
        # Nodes are in frame order, so every predecessor is final before its successor is seen.
        for node in redo:
            before = predecessors[node]
            if not before:
                continue
            parent = min(before, key=best.__getitem__)
            extended = params.link_cost + node_cost[node] + best[parent]
            if extended < best[node]:
                best[node] = extended
                link[node] = parent
                origin[node] = origin[parent]
        if redo:
            best_array[redo] = [best[node] for node in redo]
        end = int(np.argmin(best_array))
        track_cost = float(best_array[end]) + params.death_cost
        # Every node used up: nothing left to take (the released code would add a bogus track).
        if not math.isfinite(track_cost):
            break
        if track_cost >= params.stop_cost and not params.legacy_last_track:
            break
        path = [end]
        while link[path[-1]] >= 0:
            path.append(link[path[-1]])
        track = np.array(path[::-1], dtype=np.int64)
        found.append(track)
        if track_cost >= params.stop_cost:
            break
        suppressed = suppressed_by(detections, track, params)
        origins = np.asarray(origin, dtype=np.int64)
        affected = np.isin(origins, origins[suppressed])
        affected[suppressed] = False
        redo = np.flatnonzero(affected).tolist()
        for node in suppressed.tolist():
            node_cost[node] = math.inf
            best[node] = math.inf
        best_array[suppressed] = math.inf
    return _as_tracks(detections, found)


def _as_tracks(detections: VideoDetections, found: list[IntArray]) -> Tracks:
    if not found:
        return Tracks.empty()
    rows = np.concatenate(found)
    ids = np.repeat(np.arange(1, len(found) + 1), [len(track) for track in found])
    points: FloatArray = detections.points[rows]
    return Tracks(ids, detections.frames[rows], points, np.ones(len(rows), dtype=bool))
