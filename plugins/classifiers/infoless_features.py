"""The 11-d info-less feature, computed online, frame by frame.

See docs/algorithms/infoless-classifier.md#per-frame-measurements and
docs/algorithms/infoless-classifier.md#feature-vector.

Per frame ``t`` three measurements are taken [PAPER §3.2]:

* ``M_t``: mean optical-flow magnitude from frame ``t-1`` to ``t``, in pixels of the working
  resolution (the frame resized to ``flow_width`` pixels wide); ``M_0 = 0``.
* ``N_t``: the number of head detections.
* ``S_t``: the mean distance of the detections from their centroid (0 when ``N_t <= 1``).

From them, ``C_t = |S_t - S_a| / S_a`` (Eq. 1) against the most recent frame ``a < t`` recognised
as informative, and the feature ``x_t = [M_{t-4}..M_t, N_{t-4}..N_t, C_t]``.

The work is split in three parts so that training can cache the measurements and replay the
recursion with any decision policy (ground-truth labels for training, the classifier's own
decisions for evaluation) without recomputing optical flow:

* :class:`OpticalFlowMeter` turns images into ``M_t``;
* :class:`FeatureAssembler` turns ``(M_t, N_t, S_t)`` plus the decisions into ``x_t``;
* :class:`InfolessFeatureExtractor` chains the two for the online classifiers.
"""

from __future__ import annotations

from collections import deque
from typing import Any, Literal, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from trackfw.arrays import FloatArray

FlowMethod = Literal["dis", "farneback"]
DisPreset = Literal["ultrafast", "fast", "medium"]

#: History length of M and N in the feature [PAPER: x_t has 11 dimensions = 5 + 5 + 1].
HISTORY = 5
#: Default clip of C_t [OURS].
DEFAULT_C_MAX = 10.0
#: Names of the 11 feature dimensions, in order.
FEATURE_LAYOUT: tuple[str, ...] = (
    *(f"M_t-{lag}" if lag else "M_t" for lag in range(HISTORY - 1, -1, -1)),
    *(f"N_t-{lag}" if lag else "N_t" for lag in range(HISTORY - 1, -1, -1)),
    "C_t",
)
FEATURE_SIZE = len(FEATURE_LAYOUT)


def latest_motion(features: FloatArray) -> float:
    """``M_t``, the current frame's motion, from an ``(11,)`` feature ``x_t``.

    >>> latest_motion(np.arange(11.0)), latest_count(np.arange(11.0))
    (4.0, 9.0)
    """
    return float(features[HISTORY - 1])


def latest_count(features: FloatArray) -> float:
    """``N_t``, the current frame's number of detections, from an ``(11,)`` feature ``x_t``."""
    return float(features[2 * HISTORY - 1])


_DIS_PRESETS: dict[str, int] = {
    "ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST,
    "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
    "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM,
}

#: Farnebäck settings [OURS; ORIG: Farnebäck 2003]:
#: pyr_scale, levels, winsize, iterations, poly_n, poly_sigma, flags.
FARNEBACK_SETTINGS = (0.5, 3, 15, 3, 5, 1.2, 0)


def spread(points: FloatArray) -> float:
    """``S_t``: mean Euclidean distance of ``(N, 2)`` points from their centroid; 0 if N <= 1.

    >>> spread(np.array([[0.0, 0.0], [2.0, 0.0]]))
    1.0
    >>> spread(np.zeros((1, 2)))
    0.0
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(points) <= 1:
        return 0.0
    offsets = points - points.mean(axis=0)
    return float(np.mean(np.hypot(offsets[:, 0], offsets[:, 1])))


def relative_change(spread_t: float, spread_a: float, c_max: float = DEFAULT_C_MAX) -> float:
    """``C_t = |S_t - S_a| / S_a`` (Eq. 1), clipped to ``c_max``; the S_a = 0 rules are ours.

    >>> relative_change(3.0, 2.0)
    0.5
    >>> relative_change(0.0, 0.0), relative_change(1.0, 0.0), relative_change(500.0, 1.0)
    (0.0, 10.0, 10.0)
    """
    if spread_a == 0.0:
        return 0.0 if spread_t == 0.0 else float(c_max)
    return float(min(abs(spread_t - spread_a) / spread_a, c_max))


def to_working_grey(image: NDArray[np.uint8], width: int) -> NDArray[np.uint8]:
    """Greyscale ``(h, width)`` copy of a ``(H, W)`` grey or ``(H, W, 3)`` BGR image.

    The aspect ratio is kept. Smaller frames are enlarged too, so that ``M_t`` is always in
    pixels of a ``width``-wide frame, whatever the video's resolution.
    """
    if image.ndim == 3:
        # Convert first: resizing one channel is three times cheaper than resizing three.
        image = np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
    elif image.ndim != 2:
        raise ValueError(f"expected a (H, W) or (H, W, 3) image, got shape {image.shape}")
    height = max(1, round(image.shape[0] * width / image.shape[1]))
    if image.shape[1] == width and image.shape[0] == height:
        return np.ascontiguousarray(image)
    interpolation = cv2.INTER_AREA if image.shape[1] > width else cv2.INTER_LINEAR
    return np.asarray(
        cv2.resize(image, (width, height), interpolation=interpolation), dtype=np.uint8
    )


class OpticalFlowMeter:
    """Mean optical-flow magnitude between consecutive frames (``M_t``).

    The previous frame is kept already converted and resized, so each frame is converted once.

    Args:
        method: ``"dis"`` (OpenCV DIS flow, fast) or ``"farneback"`` (``FARNEBACK_SETTINGS``).
        width: working width in pixels.
        dis_preset: DIS preset (ignored by Farnebäck).
    """

    def __init__(
        self, method: FlowMethod = "dis", width: int = 320, dis_preset: DisPreset = "ultrafast"
    ) -> None:
        if method not in ("dis", "farneback"):
            raise ValueError(f"flow method must be 'dis' or 'farneback', got {method!r}")
        if width < 16:
            raise ValueError(f"flow width must be at least 16 pixels, got {width}")
        if dis_preset not in _DIS_PRESETS:
            raise ValueError(
                f"DIS preset must be one of {sorted(_DIS_PRESETS)}, got {dis_preset!r}"
            )
        self.method = method
        self.width = width
        self.dis_preset = dis_preset
        self._dis = cv2.DISOpticalFlow.create(_DIS_PRESETS[dis_preset]) if method == "dis" else None
        self._previous: NDArray[np.uint8] | None = None

    def reset(self) -> None:
        """Forget the previous frame (a new video starts)."""
        self._previous = None

    def measure(self, image: NDArray[np.uint8]) -> float:
        """``M_t`` for ``image`` (frame t) against the previous call's image; 0 on the first."""
        current = to_working_grey(np.asarray(image), self.width)
        previous, self._previous = self._previous, current
        if previous is None or previous.shape != current.shape:
            return 0.0
        if self._dis is not None:
            flow = self._dis.calc(previous, current, cast(Any, None))
        else:
            pyr_scale, levels, window, iterations, poly_n, poly_sigma, flags = FARNEBACK_SETTINGS
            flow = cv2.calcOpticalFlowFarneback(
                previous,
                current,
                cast(Any, None),
                pyr_scale,
                levels,
                window,
                iterations,
                poly_n,
                poly_sigma,
                flags,
            )
        magnitude = cv2.magnitude(flow[..., 0], flow[..., 1])
        # float64 accumulation: the sum of ~10^5 float32 values must not depend on rounding.
        return float(np.mean(magnitude, dtype=np.float64))


class FeatureAssembler:
    """The recursion from measurements to the 11-d feature.

    Call :meth:`push` for frames in order, and :meth:`mark_informative` with the decision of the
    latest pushed frame before pushing the next. The first frame after :meth:`reset` is the
    initial reference (frame 0 carries the annotation and is always informative); a frame that
    is never marked does not become the reference.

    Args:
        c_max: clip of ``C_t``.
    """

    def __init__(self, c_max: float = DEFAULT_C_MAX) -> None:
        if not c_max > 0:
            raise ValueError(f"c_max must be positive, got {c_max}")
        self.c_max = float(c_max)
        self.reset()

    def reset(self) -> None:
        """Start a new video."""
        self._motion: deque[float] = deque(maxlen=HISTORY)
        self._counts: deque[float] = deque(maxlen=HISTORY)
        self._reference_spread: float | None = None
        self._latest_t: int | None = None
        self._latest_spread = 0.0
        self._latest_informative = False
        self._latest_anchor = False

    def push(self, t: int, motion: float, count: float, spread_t: float) -> FloatArray:
        """Add frame ``t``'s ``M_t``, ``N_t``, ``S_t``; return ``x_t`` as an ``(11,)`` array."""
        if self._latest_t is not None and t <= self._latest_t:
            raise ValueError(
                f"frames must come in increasing order: got {t} after {self._latest_t}"
            )
        if self._latest_t is None:
            # Warm-up [OURS]: the missing history repeats the earliest value.
            self._motion.extend([float(motion)] * HISTORY)
            self._counts.extend([float(count)] * HISTORY)
            change = 0.0
            self._latest_informative = True
        else:
            if self._latest_informative or self._latest_anchor:
                self._reference_spread = self._latest_spread
            self._motion.append(float(motion))
            self._counts.append(float(count))
            reference = self._reference_spread
            change = 0.0 if reference is None else relative_change(spread_t, reference, self.c_max)
            self._latest_informative = False
        self._latest_anchor = False
        self._latest_t = t
        self._latest_spread = float(spread_t)
        return np.array([*self._motion, *self._counts, change], dtype=np.float64)

    def mark_informative(self, t: int, informative: bool) -> None:
        """Record whether frame ``t`` (the latest pushed) was recognised as informative.

        May be called again for the same frame to replace a provisional decision.
        """
        if t != self._latest_t:
            raise ValueError(
                f"mark_informative({t}) must follow push({t}); the latest frame is {self._latest_t}"
            )
        self._latest_informative = bool(informative)

    def reanchor(self, t: int) -> None:
        """Make frame ``t`` (the latest pushed) the reference ``a`` of ``C_t`` whatever its label.

        An [OURS] re-anchoring rule (:mod:`online_rules`) calls this while a long run of info-less
        decisions keeps the reference frozen, so that ``C_t`` stops comparing with a scene that
        may have changed since.
        """
        if t != self._latest_t:
            raise ValueError(
                f"reanchor({t}) must follow push({t}); the latest frame is {self._latest_t}"
            )
        self._latest_anchor = True


def assemble_features(
    motion: FloatArray,
    counts: FloatArray,
    spreads: FloatArray,
    informative: NDArray[np.bool_],
    c_max: float = DEFAULT_C_MAX,
) -> FloatArray:
    """Features of a whole video with known decisions (training uses the ground truth).

    Args:
        motion: ``(T,)`` ``M_t``.
        counts: ``(T,)`` ``N_t``.
        spreads: ``(T,)`` ``S_t``.
        informative: ``(T,)`` whether each frame may serve as the reference ``a``.
        c_max: clip of ``C_t``.

    Returns:
        ``(T, 11)`` features.

    >>> assemble_features(np.array([0.0, 1.0]), np.array([2.0, 3.0]), np.array([4.0, 6.0]),
    ...                   np.array([True, True]))[1].tolist()
    [0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 2.0, 2.0, 2.0, 3.0, 0.5]
    """
    assembler = FeatureAssembler(c_max)
    features = np.zeros((len(motion), FEATURE_SIZE), dtype=np.float64)
    for t in range(len(motion)):
        features[t] = assembler.push(t, motion[t], counts[t], spreads[t])
        assembler.mark_informative(t, bool(informative[t]))
    return features


class InfolessFeatureExtractor:
    """Online 11-d features from frames and detections.

    Args:
        flow: optical-flow method.
        flow_width: working width of the flow in pixels.
        dis_preset: DIS preset.
        c_max: clip of ``C_t``.
    """

    def __init__(
        self,
        flow: FlowMethod = "dis",
        flow_width: int = 320,
        dis_preset: DisPreset = "ultrafast",
        c_max: float = DEFAULT_C_MAX,
    ) -> None:
        self.meter = OpticalFlowMeter(flow, flow_width, dis_preset)
        self.assembler = FeatureAssembler(c_max)
        #: ``(M_t, N_t, S_t)`` of the latest frame, for logging and caching.
        self.last_measurements: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def reset(self) -> None:
        """Start a new video."""
        self.meter.reset()
        self.assembler.reset()

    def update(self, t: int, image: NDArray[np.uint8], detection_points: FloatArray) -> FloatArray:
        """Feature ``x_t`` of frame ``t``.

        Args:
            t: frame index (increasing).
            image: ``(H, W, 3)`` BGR or ``(H, W)`` grey uint8 pixels of frame t.
            detection_points: ``(N, 2)`` head points on frame t.

        Returns:
            ``(11,)`` feature ``[M_{t-4}..M_t, N_{t-4}..N_t, C_t]``.
        """
        points = np.asarray(detection_points, dtype=np.float64).reshape(-1, 2)
        motion = self.meter.measure(image)
        spread_t = spread(points)
        self.last_measurements = (motion, float(len(points)), spread_t)
        return self.assembler.push(t, motion, float(len(points)), spread_t)

    def mark_informative(self, t: int, informative: bool) -> None:
        """Frame ``t``'s decision: an informative frame becomes the reference ``a`` of C_t."""
        self.assembler.mark_informative(t, informative)
