"""Info-less intervals of the virtual wearer: where they fall and what the camera sees in them.

The three kinds of the paper are made from the real sequence itself:

* ``sky``: the wearer looks up. A heavily zoomed, blurred and brightened crop of the band above
  every head (the facade in TUD), drifting slowly.
* ``group``: the wearer looks at another group. A horizontally flipped, zoomed crop of the same
  sequence at another time, centred on someone, so that other people appear (their heads are
  recorded in heads.csv, never in gt.csv).
* ``path``: the wearer looks down while walking. The blurred ground band below every foot,
  strongly zoomed, flowing downwards and slowly expanding (forward motion).

Each interval starts with a fast swing away from the real view and ends with a swing back: the
two views slide past each other with an eased progress and a box motion blur along the swing
proportional to the per-frame displacement. The swings are info-less frames too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from trackfw.arrays import FloatArray
from trackfw.errors import UserError
from trackfw.formats import body_heads
from trackfw_plugins.datasets.mot import MotSequence, read_frame

#: The paper's three kinds of info-less interval.
WEAR_KINDS = ("sky", "group", "path")
#: Shortest possible interval: a swing away, one frame of the other view, a swing back.
SHORTEST_INTERVAL = 3
#: Fraction of an interval spent on each swing, and the longest swing (frames) [OURS].
SWING_FRACTION = 0.2
LONGEST_SWING = 6
#: Motion-blur length as a fraction of the per-frame swing displacement [OURS].
SWING_BLUR = 0.8


def place_intervals(
    n_frames: int,
    n_intervals: int,
    min_length: int,
    max_length: int,
    min_segment: int,
    rng: np.random.Generator,
    max_infoless_fraction: float = 0.5,
) -> list[tuple[int, int]]:
    """Random, non-overlapping info-less intervals with informative frames around each.

    Args:
        n_frames: frames of the video.
        n_intervals: how many intervals.
        min_length: shortest interval (frames), lowered when the video is too short for it.
        max_length: longest interval (frames), lowered likewise.
        min_segment: fewest informative frames before, between and after the intervals.
        rng: random generator.
        max_infoless_fraction: most of the video the intervals may take together [OURS], so
            that a short sequence keeps enough informative frames.

    Returns:
        ``(first, last)`` 0-based inclusive info-less frames per interval, in time order.

    Raises:
        UserError: the video is too short for that many intervals.

    >>> place_intervals(100, 2, 10, 20, 12, np.random.default_rng(0))[0][0] >= 12
    True
    """
    count = max(n_intervals, 1)
    longest = min(
        max_length,
        (n_frames - (n_intervals + 1) * min_segment) // count,
        math.floor(max_infoless_fraction * n_frames / count),
    )
    if n_intervals < 1 or longest < SHORTEST_INTERVAL:
        raise UserError(
            f"a video of {n_frames} frames cannot hold {n_intervals} info-less interval(s) of at"
            f" least {SHORTEST_INTERVAL} frames with {min_segment} informative frames around"
            " each; expected fewer --intervals."
        )
    shortest = max(SHORTEST_INTERVAL, min(min_length, longest))
    lengths = rng.integers(shortest, longest + 1, size=n_intervals)
    free = n_frames - int(lengths.sum()) - (n_intervals + 1) * min_segment
    segments = min_segment + rng.multinomial(
        free, np.full(n_intervals + 1, 1.0 / (n_intervals + 1))
    )
    intervals: list[tuple[int, int]] = []
    cursor = 0
    for index in range(n_intervals):
        first = cursor + int(segments[index])
        last = first + int(lengths[index]) - 1
        intervals.append((first, last))
        cursor = last + 1
    return intervals


@dataclass
class InfolessView:
    """What the camera sees during one interval, and how it swings there and back.

    Geometry maps source pixels to output pixels: ``output = output_centre + zoom * (source -
    centre)`` (``x`` negated for ``group``, which is flipped), with ``centre`` moving by
    ``drift`` source pixels per frame of the interval.

    Attributes:
        kind: ``sky``, ``group`` or ``path``.
        first: 0-based first info-less frame.
        last: 0-based last info-less frame (inclusive).
        swing_in: frames of the swing away from the real view.
        swing_out: frames of the swing back.
        enter_from: side the other view enters from: ``top``, ``bottom``, ``left`` or ``right``.
        zoom: source-to-output scale of the other view.
        centre: ``(x, y)`` source point at the output centre on the first frame.
        drift: ``(dx, dy)`` source pixels per frame.
        growth: relative zoom increase per frame (forward motion on the path).
        blur_sigma: Gaussian blur of the other view, output pixels.
        brightness: gain applied to the other view.
        time_offset: ``group``: the other group's frame is ``t + time_offset``.
        band: ``(top, bottom)`` source rows the texture of ``sky`` / ``path`` is cut from.
    """

    kind: str
    first: int
    last: int
    swing_in: int
    swing_out: int
    enter_from: str
    zoom: float
    centre: tuple[float, float]
    drift: tuple[float, float]
    growth: float = 0.0
    blur_sigma: float = 0.0
    brightness: float = 1.0
    time_offset: int = 0
    band: tuple[int, int] = (0, 0)
    _texture: np.ndarray | None = field(default=None, repr=False)

    @property
    def length(self) -> int:
        """Number of info-less frames."""
        return self.last - self.first + 1


def _swing_lengths(length: int) -> tuple[int, int]:
    swing = max(1, min(LONGEST_SWING, round(SWING_FRACTION * length), (length - 1) // 2))
    return swing, swing


def make_view(
    kind: str,
    first: int,
    last: int,
    sequence: MotSequence,
    output_size: tuple[int, int],
    rng: np.random.Generator,
) -> InfolessView:
    """Draw the random parameters of one interval's view.

    Args:
        kind: ``sky``, ``group`` or ``path``.
        first: 0-based first info-less frame.
        last: 0-based last info-less frame.
        sequence: the real sequence.
        output_size: ``(width, height)`` of the output video.
        rng: random generator.
    """
    all_boxes = [boxes for boxes in sequence.boxes.values() if len(boxes)]
    stacked = np.concatenate(all_boxes) if all_boxes else np.zeros((0, 5))
    makers = {"sky": _sky_view, "path": _path_view, "group": _group_view}
    if kind not in makers:
        raise ValueError(f"unknown interval kind {kind!r}")
    return makers[kind](_ViewPlace(first, last, sequence, output_size, stacked), rng)


@dataclass(frozen=True)
class _ViewPlace:
    """Where a view is drawn: the interval (0-based frames), the sequence, the output size
    ``(width, height)`` and every box of the sequence stacked (n, 5)."""

    first: int
    last: int
    sequence: MotSequence
    output_size: tuple[int, int]
    stacked: FloatArray

    @property
    def frame_size(self) -> tuple[int, int]:
        """``(width, height)`` of the sequence's frames."""
        return self.sequence.width, self.sequence.height

    @property
    def cover(self) -> float:
        """The zoom at which the output is covered by the source frame."""
        width, height = self.frame_size
        return max(self.output_size[0] / width, self.output_size[1] / height)

    @property
    def swing(self) -> tuple[int, int]:
        """Frames of the swing into and out of the view."""
        return _swing_lengths(self.last - self.first + 1)


def _sky_view(place: _ViewPlace, rng: np.random.Generator) -> InfolessView:
    """The sky band above the people (``sky``), drifting sideways."""
    width, height, (out_width, out_height) = *place.frame_size, place.output_size
    stacked, cover = place.stacked, place.cover
    # The band above (nearly) every head, so no face survives the zoom.
    top_of_people = float(np.percentile(stacked[:, 2], 5)) if len(stacked) else 0.2 * height
    band_bottom = int(np.clip(top_of_people, 0.1 * height, 0.3 * height))
    zoom = max(out_height / band_bottom, 2.5 * cover)
    half_width = out_width / (2 * zoom)
    centre = (float(rng.uniform(half_width, width - half_width)), out_height / (2 * zoom))
    drift = (float(rng.choice([-1, 1]) * rng.uniform(0.2, 0.6)), 0.0)
    return InfolessView(
        "sky",
        place.first,
        place.last,
        *place.swing,
        "top",
        zoom,
        centre,
        drift,
        blur_sigma=0.012 * out_width,
        brightness=1.0,
        band=(0, band_bottom),
    )


def _path_view(place: _ViewPlace, rng: np.random.Generator) -> InfolessView:
    """The ground band below the people (``path``), flowing down as when walking forwards."""
    width, height = place.frame_size
    out_width, out_height = place.output_size
    bottom_of_people = (
        float(np.percentile(place.stacked[:, 2] + place.stacked[:, 4], 95))
        if len(place.stacked)
        else 0.75 * height
    )
    band_top = int(np.clip(bottom_of_people, 0.7 * height, 0.88 * height))
    band_height = height - band_top
    zoom = max(out_height / band_height, 2.5 * place.cover)
    half_width = out_width / (2 * zoom)
    centre = (float(rng.uniform(half_width, width - half_width)), band_height / 2)
    # Forward walking: the ground flows down by 1-2.5 % of the frame height per frame.
    flow = float(rng.uniform(0.01, 0.025)) * out_height / zoom
    return InfolessView(
        "path",
        place.first,
        place.last,
        *place.swing,
        "bottom",
        zoom,
        centre,
        (0.0, -flow),
        growth=0.003,
        blur_sigma=0.008 * out_width,
        brightness=float(rng.uniform(0.85, 1.0)),
        band=(band_top, height),
    )


def _group_view(place: _ViewPlace, rng: np.random.Generator) -> InfolessView:
    """A close-up of another moment of the sequence (``group``), at least the interval's length
    away in time so its people are elsewhere."""
    first, last, sequence = place.first, place.last, place.sequence
    width, height = place.frame_size
    length = last - first + 1
    lowest, highest = -first, sequence.n_frames - 1 - last
    separation = min(length, max(-lowest, highest))
    offsets = [o for o in range(lowest, highest + 1) if abs(o) >= separation]
    time_offset = int(rng.choice(offsets)) if offsets else 0
    zoom = place.cover * float(rng.uniform(1.15, 1.5))
    heads = body_heads(sequence.boxes_at(first + time_offset)[:, 1:])
    if len(heads):
        person = heads[int(rng.integers(len(heads)))]
        centre = (float(person[0]), float(person[1] + 0.25 * height))
    else:
        centre = (width / 2, height / 2)
    view = InfolessView(
        "group",
        place.first,
        place.last,
        *place.swing,
        str(rng.choice(["left", "right"])),
        zoom,
        centre,
        (float(rng.uniform(-0.4, 0.4)), 0.0),
        blur_sigma=0.0,
        brightness=float(rng.uniform(0.85, 1.1)),
        time_offset=time_offset,
    )
    view.centre = _clamped_centre(view, 0, sequence, place.output_size)
    return view


def _clamped_centre(
    view: InfolessView, step: int, sequence: MotSequence, output_size: tuple[int, int]
) -> tuple[float, float]:
    """Group views stay inside the source frame: a mirrored border would duplicate people."""
    half_width = output_size[0] / (2 * view.zoom)
    half_height = output_size[1] / (2 * view.zoom)
    x = view.centre[0] + view.drift[0] * step
    y = view.centre[1] + view.drift[1] * step
    x = min(max(x, half_width), sequence.width - half_width)
    y = min(max(y, half_height), sequence.height - half_height)
    return x, y


def render_view(
    view: InfolessView, frame: int, sequence: MotSequence, output_size: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """The other view on 0-based ``frame`` of the interval.

    Returns:
        ``(image, heads)``: the ``(height, width, 3)`` uint8 image and an ``(M, 4)`` array of
        ``source id, x, y, head_size`` of the heads visible in it (only ``group`` has any).
    """
    out_width, out_height = output_size
    step = frame - view.first
    zoom = view.zoom * (1.0 + view.growth * step)
    no_heads = np.zeros((0, 4), dtype=np.float64)
    if view.kind == "group":
        source_frame = frame + view.time_offset
        image = read_frame(sequence, source_frame)
        centre_x, centre_y = _clamped_centre(view, step, sequence, output_size)
        # Flipped horizontally: x_out = W/2 - zoom (x - cx).
        matrix = np.array(
            [
                [-zoom, 0.0, out_width / 2 + zoom * centre_x],
                [0.0, zoom, out_height / 2 - zoom * centre_y],
            ]
        )
        warped = cv2.warpAffine(
            image, matrix, output_size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101
        )
        boxes = sequence.boxes_at(source_frame)
        proxies = body_heads(boxes[:, 1:])
        x = out_width / 2 - zoom * (proxies[:, 0] - centre_x)
        y = out_height / 2 + zoom * (proxies[:, 1] - centre_y)
        inside = (x >= 0) & (x < out_width) & (y >= 0) & (y < out_height)
        heads = np.stack([boxes[:, 0], x, y, proxies[:, 2] * zoom], axis=1)[inside]
        return _gain(warped, view.brightness), heads
    if view._texture is None:
        band_top, band_bottom = view.band
        view._texture = read_frame(sequence, view.first)[band_top:band_bottom].copy()
    centre_x = view.centre[0] + view.drift[0] * step
    centre_y = view.centre[1] + view.drift[1] * step
    matrix = np.array(
        [
            [zoom, 0.0, out_width / 2 - zoom * centre_x],
            [0.0, zoom, out_height / 2 - zoom * centre_y],
        ]
    )
    warped = cv2.warpAffine(
        view._texture,
        matrix,
        output_size,
        flags=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REFLECT_101,
    )
    warped = cv2.GaussianBlur(warped, (0, 0), view.blur_sigma)
    if view.kind == "path":
        flow = max(1, round(abs(view.drift[1]) * zoom))
        warped = cv2.blur(warped, (1, flow))
        return _gain(warped, view.brightness), no_heads
    # Looking up: the auto-exposure meets a bright sky; wash the facade out towards it.
    ramp = np.linspace(250.0, 205.0, out_height)[:, None, None]
    sky = np.concatenate([ramp + 5.0, ramp, ramp - 10.0], axis=2)
    washed = 0.7 * warped.astype(np.float64) + 0.3 * sky
    return np.clip(washed, 0, 255).astype(np.uint8), no_heads


def _gain(image: np.ndarray, gain: float) -> np.ndarray:
    return cv2.convertScaleAbs(image, alpha=gain, beta=0.0)


def swing_progress(view: InfolessView, frame: int) -> tuple[float, float] | None:
    """How far the other view has slid in on a swing frame.

    Returns:
        ``(progress, step)``: the fraction of the frame the other view covers (0 = only the
        real view, 1 = only the other view) and its change since the previous frame; ``None``
        on a frame that shows the other view alone.
    """

    def eased(index: int, count: int) -> float:
        return 0.5 - 0.5 * math.cos(math.pi * index / (count + 1))

    step = frame - view.first
    if step < view.swing_in:
        return eased(step + 1, view.swing_in), eased(step + 1, view.swing_in) - eased(
            step, view.swing_in
        )
    back = step - (view.length - view.swing_out)
    if back >= 0:
        progress = 1.0 - eased(back + 1, view.swing_out)
        return progress, progress - (1.0 - eased(back, view.swing_out))
    return None


def compose_swing(
    real: np.ndarray, other: np.ndarray, progress: float, step: float, enter_from: str
) -> np.ndarray:
    """Slide ``other`` in over ``real`` from ``enter_from`` with a motion blur along the swing.

    Args:
        real: ``(H, W, 3)`` the warped real frame.
        other: ``(H, W, 3)`` the other view.
        progress: fraction of the frame covered by ``other``, in [0, 1].
        step: change of ``progress`` since the previous frame (its size sets the blur).
        enter_from: ``top``, ``bottom``, ``left`` or ``right``.

    Returns:
        ``(H, W, 3)`` uint8 image.
    """
    height, width = real.shape[:2]
    vertical = enter_from in ("top", "bottom")
    extent = height if vertical else width
    first_is_other = enter_from in ("top", "left")
    parts = [other, real] if first_is_other else [real, other]
    canvas = np.concatenate(parts, axis=0 if vertical else 1)
    offset = round((1.0 - progress) * extent) if first_is_other else round(progress * extent)
    offset = min(max(offset, 0), extent)
    image = canvas[offset : offset + height] if vertical else canvas[:, offset : offset + width]
    blur = int(min(max(round(SWING_BLUR * abs(step) * extent), 1), 0.3 * extent))
    if blur > 1:
        image = cv2.blur(image, (1, blur) if vertical else (blur, 1))
    return np.ascontiguousarray(image)
