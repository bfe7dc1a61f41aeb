"""Candidate windows of a detection set (docs/algorithms/gap-matchers.md#candidate-windows).

Every 4-subset of V spans an inclusive bounding box whose members form a window W; windows are
deduplicated (bitmasks) and kept when ceil(0.9K) <= |W| <= floor(1.2K). They depend only on V
and |U| = K, so all candidates (AR orders) of one gap share them.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from pydantic import ConfigDict, Field

from trackfw.arrays import BoolArray, FloatArray, IntArray
from trackfw.stages import FiniteModel

_COMBINATION_CHUNK = 200_000


class WindowSettings(FiniteModel):
    """How candidate windows are enumerated and size-filtered."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    subset_points: int = Field(4, ge=1, description="Points of V that span a candidate window.")
    size_lo: float = Field(0.9, gt=0, description="Keep W when |W| >= ceil(size_lo * |U|).")
    size_hi: float = Field(1.2, gt=0, description="Keep W when |W| <= floor(size_hi * |U|).")
    small_U_exhaustive_max: int = Field(  # noqa: N815 - the documented YAML key
        5000, ge=0, description="When |U| or |V| < 4: all |U|-subsets if C(|V|,|U|) <= this."
    )


@dataclass
class WindowSet:
    """Candidate windows of one detection set for one template size.

    Attributes:
        members: (W, N) bool, row w marks the detections inside window w.
        total: number of boxes enumerated (C(N, subset_points), or C(N, K) in the small case).
        after_dedup: distinct membership sets.
        after_size: windows left after the size prescreen (= W).
        rule: "boxes", "small_subsets" or "all_detections" (the small-set rule).
    """

    members: BoolArray
    total: int
    after_dedup: int
    after_size: int
    rule: str


def _combinations(count: int, size: int) -> IntArray:
    total = math.comb(count, size)
    flat = np.fromiter(
        itertools.chain.from_iterable(itertools.combinations(range(count), size)),
        dtype=np.int64,
        count=total * size,
    )
    return flat.reshape(total, size)


def _pack(members: BoolArray) -> NDArray[np.uint8]:
    packed = np.packbits(members, axis=1, bitorder="little")
    width = -(-packed.shape[1] // 8) * 8
    padded = np.zeros((packed.shape[0], width), dtype=np.uint8)
    padded[:, : packed.shape[1]] = packed
    return padded


def _unique_rows(keys: NDArray[np.uint8]) -> IntArray:
    """Indices of the first occurrence of each distinct row, in order of first occurrence."""
    if keys.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    words = np.ascontiguousarray(keys).view(np.uint64)
    if words.shape[1] == 1:
        _, first = np.unique(words[:, 0], return_index=True)
    else:
        _, first = np.unique(words, axis=0, return_index=True)
    return np.sort(first).astype(np.int64)


def build_windows(
    detections: FloatArray, template_size: int, params: WindowSettings | None = None
) -> WindowSet:
    """All candidate windows of V for |U| = template_size, shared by all candidates.

    Args:
        detections: (N, 2) detection points V.
        template_size: |U| (the same for every AR order).
        params: window parameters.

    Returns:
        The deduplicated, size-filtered windows in order of first appearance.

    >>> v = np.array([[0.0, 0], [1, 0], [2, 0], [3, 0], [4, 0]])
    >>> windows = build_windows(v, 4)
    >>> windows.total, windows.after_dedup, windows.members.sum(axis=1).tolist()
    (5, 3, [4, 4])
    """
    params = params if params is not None else WindowSettings()
    detections = np.asarray(detections, dtype=np.float64).reshape(-1, 2)
    count = detections.shape[0]
    subset = params.subset_points
    if template_size < subset or count < subset:
        return _small_windows(count, template_size, params)
    low = math.ceil(params.size_lo * template_size - 1e-9)
    high = math.floor(params.size_hi * template_size + 1e-9)
    x, y = detections[:, 0], detections[:, 1]
    keys: list[NDArray[np.uint8]] = []
    sizes: list[IntArray] = []
    total = math.comb(count, subset)
    combos = _combinations(count, subset)
    for start in range(0, total, _COMBINATION_CHUNK):
        chunk = combos[start : start + _COMBINATION_CHUNK]
        box_x, box_y = x[chunk], y[chunk]
        # Inclusive bounds [OURS]: the four spanning points are always members.
        members = (
            (x[None, :] >= box_x.min(axis=1)[:, None])
            & (x[None, :] <= box_x.max(axis=1)[:, None])
            & (y[None, :] >= box_y.min(axis=1)[:, None])
            & (y[None, :] <= box_y.max(axis=1)[:, None])
        )
        keys.append(_pack(members))
        sizes.append(members.sum(axis=1))
    all_keys = np.concatenate(keys)
    all_sizes = np.concatenate(sizes)
    first = _unique_rows(all_keys)
    sized = first[(all_sizes[first] >= low) & (all_sizes[first] <= high)]
    members = np.unpackbits(all_keys[sized], axis=1, count=count, bitorder="little").astype(bool)
    return WindowSet(members, total, int(first.size), int(sized.size), "boxes")


def _small_windows(count: int, template_size: int, params: WindowSettings) -> WindowSet:
    """[OURS] All |U|-subsets when C(N, K) is small, otherwise the single window W = V."""
    possible = math.comb(count, template_size) if 0 < template_size <= count else 0
    if 0 < possible <= params.small_U_exhaustive_max:
        combos = _combinations(count, template_size)
        members = np.zeros((possible, count), dtype=bool)
        np.put_along_axis(members, combos, True, axis=1)
        return WindowSet(members, possible, possible, possible, "small_subsets")
    members = np.ones((1 if count > 0 else 0, count), dtype=bool)
    return WindowSet(members, 1, 1, members.shape[0], "all_detections")
