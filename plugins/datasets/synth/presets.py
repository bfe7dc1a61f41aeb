"""Sites and video plans: what each video will contain, decided before any pixel is drawn.

The ``paper`` preset mirrors the statistics of Yu et al. 2018, section 4.1: 30 videos from 10
sites, 26 with one info-less interval (11 sky or building, 10 another group, 5 the walking path)
and 4 without, lengths 90-351 frames, intervals 18-249 frames with a mean of about 83.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from trackfw.errors import UserError

INTERVAL_KINDS = ("sky", "group", "path")
#: Frames before the first interval, between intervals and after the last one, at least.
MIN_LEAD_FRAMES = 20
MIN_GAP_FRAMES = 20
MIN_TAIL_FRAMES = 15
MIN_INTERVAL_FRAMES = 18
MAX_INTERVAL_FRAMES = 249
PAPER_MEAN_INTERVAL = 83.0
PAPER_LENGTH_RANGE = (90, 351)


@dataclass(frozen=True)
class Site:
    """One filming place: the square, the wearer's floor and the look of the surroundings.

    Attributes:
        name: short identifier, used in video names.
        ground_style: one of ``textures.GROUND_STYLES``.
        ground_colour: BGR base colour of the ground.
        facade_colour: BGR colour of the building across the square.
        walkway_colour: BGR colour of the wearer's walkway and parapet.
        storey: the wearer's floor (2 to 4).
        facade_distance: distance of the opposite building (metres).
        group_distance: horizontal distance range of the people of interest at frame 1 (metres).
        background_people: number of other pedestrians.
    """

    name: str
    ground_style: str
    ground_colour: tuple[int, int, int]
    facade_colour: tuple[int, int, int]
    walkway_colour: tuple[int, int, int]
    storey: int
    facade_distance: float
    group_distance: tuple[float, float]
    background_people: int

    @property
    def eye_height(self) -> float:
        """Camera height above the square in metres: the floor (3.6 m per storey above a ground
        floor raised 0.4 m) plus 1.6 m eye height, so 5.6, 9.2 and 12.8 m for storeys 2, 3, 4."""
        return self.walkway_height + 1.6

    @property
    def walkway_height(self) -> float:
        """Height of the wearer's walkway floor above the square (metres)."""
        return (self.storey - 1) * 3.6 + 0.4


SITES: tuple[Site, ...] = (
    Site("plaza", "paving", (150, 160, 170), (170, 185, 200), (120, 125, 130), 3, 60, (7, 11), 22),
    Site("campus", "tiles", (170, 170, 165), (140, 150, 165), (140, 140, 140), 2, 55, (6, 10), 18),
    Site("street", "asphalt", (95, 95, 100), (120, 140, 170), (150, 150, 150), 4, 58, (8, 12), 26),
    Site("station", "checker", (190, 190, 185), (110, 110, 120), (100, 110, 120), 3, 62, (7, 11), 30),
    Site("market", "brick", (80, 100, 150), (150, 175, 190), (130, 130, 125), 2, 55, (6, 10), 24),
    Site("park", "gravel", (120, 170, 180), (160, 170, 160), (110, 120, 115), 3, 65, (7, 11), 14),
    Site("mall", "tiles", (200, 195, 190), (175, 170, 160), (160, 160, 160), 4, 56, (8, 12), 28),
    Site("harbour", "paving", (140, 140, 125), (120, 160, 190), (115, 115, 110), 2, 64, (6, 10), 16),
    Site("courtyard", "brick", (90, 110, 140), (165, 180, 195), (125, 130, 135), 3, 55, (7, 11), 20),
    Site("terminal", "asphalt", (110, 110, 115), (150, 150, 145), (145, 145, 150), 4, 60, (8, 12), 22),
)

DEMO_SITE = Site("demo", "paving", (150, 160, 170), (170, 185, 200), (120, 125, 130), 2, 50,
                 (5.5, 6.5), 10)


@dataclass(frozen=True)
class WearerConfig:
    """Limits of the wearer's head motion.

    Attributes:
        max_pan_change: largest pan change across an interval (degrees).
        min_pan_change: smallest pan change across an interval (degrees).
        max_roll_change: largest roll change across an interval (degrees).
        scale_range: range of the scale factor after / before an interval.
        max_tilt_change: largest tilt change across an interval (degrees).
        path_move: range of the viewpoint move during a 'path' interval (metres).
        drift_deg: standard deviation of the slow drift of pan, tilt, roll (degrees).
        jitter_deg: amplitude of the walking jitter of pan, tilt, roll (degrees).
        min_in_view: fraction of target-frames that must stay in the image after a pose change
            (changes are shrunk until it holds).
    """

    max_pan_change: float = 30.0
    min_pan_change: float = 6.0
    max_roll_change: float = 10.0
    scale_range: tuple[float, float] = (0.7, 1.4)
    max_tilt_change: float = 6.0
    path_move: tuple[float, float] = (1.5, 8.0)
    drift_deg: tuple[float, float, float] = (1.5, 1.0, 1.0)
    jitter_deg: tuple[float, float, float] = (0.25, 0.35, 0.2)
    min_in_view: float = 0.85


@dataclass(frozen=True)
class IntervalPlan:
    """One planned info-less interval: ``length`` frames from the 0-based frame ``start``."""

    start: int
    length: int
    kind: str

    @property
    def end(self) -> int:
        """0-based last info-less frame."""
        return self.start + self.length - 1


@dataclass(frozen=True)
class VideoPlan:
    """Everything that decides one video (its seed fixes the rest).

    ``leave`` targets walk out of view and back once each (:mod:`.excursions`); 0 keeps the
    group in view as in the paper.
    """

    name: str
    seed: int
    site: Site
    n_frames: int
    intervals: tuple[IntervalPlan, ...]
    n_targets: int
    fps: float = 30.0
    width: int = 1280
    height: int = 720
    preset: str = "custom"
    trajectories: str | None = None
    background: str | None = None
    hfov_deg: float = 75.0
    wearer: WearerConfig = WearerConfig()
    leave: int = 0


def _video_seed(seed: int, index: int) -> int:
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def paper_interval_lengths(rng: np.random.Generator, count: int) -> list[int]:
    """``count`` interval lengths spanning 18..249 frames with a mean of about 83.

    Skewed like the paper's (most intervals short, a few long): log-normal draws, the smallest
    and largest pinned to the paper's extremes, the rest scaled (by bisection) to the mean.
    """
    if count <= 0:
        return []
    draws = np.sort(rng.lognormal(mean=np.log(65.0), sigma=0.55, size=count))
    if count == 1:
        return [round(PAPER_MEAN_INTERVAL)]
    middle = draws[1:-1]
    low, high = 0.05, 20.0
    target_total = PAPER_MEAN_INTERVAL * count - MIN_INTERVAL_FRAMES - MAX_INTERVAL_FRAMES
    for _step in range(60):
        factor = (low + high) / 2.0
        total = np.clip(middle * factor, MIN_INTERVAL_FRAMES, MAX_INTERVAL_FRAMES).sum()
        low, high = (factor, high) if total < target_total else (low, factor)
    scaled = np.clip(np.round(middle * (low + high) / 2.0), MIN_INTERVAL_FRAMES, MAX_INTERVAL_FRAMES)
    lengths = [MIN_INTERVAL_FRAMES, *(int(value) for value in scaled), MAX_INTERVAL_FRAMES]
    order = rng.permutation(count)
    return [lengths[index] for index in order]


def layout_intervals(
    rng: np.random.Generator, n_frames: int, lengths: list[int], kinds: list[str]
) -> tuple[IntervalPlan, ...]:
    """Place intervals of the given lengths in a video, keeping segments of normal frames
    between them (at least MIN_LEAD, MIN_GAP and MIN_TAIL frames); spare frames are shared out
    at random."""
    needed = sum(lengths) + MIN_LEAD_FRAMES + MIN_TAIL_FRAMES + MIN_GAP_FRAMES * max(len(lengths) - 1, 0)
    if needed > n_frames:
        raise UserError(
            f"--frames {n_frames}: too short for {len(lengths)} interval(s) of {sum(lengths)} frames;"
            f" expected at least {needed} frames."
        )
    spare = n_frames - needed
    shares = rng.dirichlet(np.ones(len(lengths) + 1)) * spare
    extra = np.floor(shares).astype(int)
    extra[0] += spare - int(extra.sum())
    intervals = []
    cursor = MIN_LEAD_FRAMES + int(extra[0])
    for index, (length, kind) in enumerate(zip(lengths, kinds, strict=True)):
        intervals.append(IntervalPlan(start=cursor, length=int(length), kind=kind))
        cursor += int(length) + MIN_GAP_FRAMES + int(extra[index + 1])
    return tuple(intervals)


def paper_plan(
    seed: int,
    videos: int | None = None,
    frames: int | None = None,
    intervals: int | None = None,
    width: int = 1280,
    height: int = 720,
    fps: float = 30.0,
) -> list[VideoPlan]:
    """The 30-video plan of the paper's dataset (or ``videos`` of them, repeating the recipe).

    Args:
        seed: dataset seed.
        videos: number of videos (30 by default; more repeat the recipe with new draws).
        frames: force every video to this length.
        intervals: force every video that has an interval to have this many.
        width, height, fps: frame geometry.
    """
    count = 30 if videos is None else videos
    plans: list[VideoPlan] = []
    block = 0
    while len(plans) < count:
        plans.extend(_paper_block(seed, block, frames, intervals, width, height, fps))
        block += 1
    return plans[:count]


def _paper_block(seed: int, block: int, frames: int | None, interval_count: int | None,
                 width: int, height: int, fps: float) -> list[VideoPlan]:
    rng = np.random.default_rng(np.random.SeedSequence([seed, 1_000_003, block]))
    kinds = ["sky"] * 11 + ["group"] * 10 + ["path"] * 5
    kinds = [kinds[index] for index in rng.permutation(len(kinds))]
    lengths = paper_interval_lengths(rng, 26)
    site_order = [SITES[index // 3] for index in rng.permutation(30)]
    with_interval = set(rng.permutation(30)[:26].tolist())
    # Video lengths: interval plus lead and tail; the 4 videos without an interval take the
    # paper's extremes (90 and 351 frames) so the range is exactly the paper's.
    plain_lengths = [PAPER_LENGTH_RANGE[0], PAPER_LENGTH_RANGE[1],
                     int(rng.integers(120, 300)), int(rng.integers(120, 300))]
    plans = []
    interval_index = 0
    plain_index = 0
    for index in range(30):
        video_rng = np.random.default_rng(np.random.SeedSequence([seed, block, index, 7]))
        number = block * 30 + index + 1
        site = site_order[index]
        if index in with_interval:
            count = 1 if interval_count is None else interval_count
            first_kind = kinds[interval_index]
            own_kinds = [first_kind] + [str(video_rng.choice(INTERVAL_KINDS)) for _ in range(count - 1)]
            own_lengths = [lengths[interval_index]] + [
                int(np.clip(video_rng.lognormal(np.log(70.0), 0.5), MIN_INTERVAL_FRAMES, 200))
                for _ in range(count - 1)]
            own_lengths = own_lengths[:count]
            own_kinds = own_kinds[:count]
            interval_index += 1
            if frames is None:
                lead = int(video_rng.integers(MIN_LEAD_FRAMES + 5, 90))
                tail = int(video_rng.integers(MIN_TAIL_FRAMES + 10, 80))
                gaps = sum(int(video_rng.integers(MIN_GAP_FRAMES, 80)) for _ in range(count - 1))
                n_frames = lead + tail + gaps + sum(own_lengths)
                if count <= 1:
                    n_frames = int(np.clip(n_frames, *PAPER_LENGTH_RANGE))
                    n_frames = max(n_frames, sum(own_lengths) + MIN_LEAD_FRAMES + MIN_TAIL_FRAMES)
            else:
                n_frames = frames
                budget = frames - MIN_LEAD_FRAMES - MIN_TAIL_FRAMES - MIN_GAP_FRAMES * max(count - 1, 0)
                if sum(own_lengths) > budget and count:
                    shrink = budget / sum(own_lengths)
                    own_lengths = [max(MIN_INTERVAL_FRAMES, int(length * shrink)) for length in own_lengths]
            planned = layout_intervals(video_rng, n_frames, own_lengths, own_kinds)
        else:
            n_frames = plain_lengths[plain_index] if frames is None else frames
            plain_index += 1
            planned = ()
        plans.append(VideoPlan(
            name=f"synth{number:03d}-{site.name}",
            seed=_video_seed(seed, number),
            site=site,
            n_frames=n_frames,
            intervals=planned,
            n_targets=int(video_rng.integers(5, 11)),
            fps=fps,
            width=width,
            height=height,
            preset="paper",
        ))
    return plans


#: Shortest video of the ``paper-leave`` preset: a walk out of view and back takes 5-12 s.
LEAVE_MIN_FRAMES = 450


def with_leavers(plans: list[VideoPlan], leave: int, preset: str | None = None,
                 min_frames: int | None = None) -> list[VideoPlan]:
    """The same plans with ``leave`` targets per video walking out of view and back.

    Args:
        plans: the plans.
        leave: targets per video that leave once (:mod:`.excursions`).
        preset: a new preset name for the plans (None keeps theirs).
        min_frames: lengthen shorter videos to this many frames (only their tail grows: the
            intervals stay where they were).
    """
    return [replace(plan, leave=leave, preset=plan.preset if preset is None else preset,
                    n_frames=plan.n_frames if min_frames is None else max(plan.n_frames, min_frames))
            for plan in plans]


def custom_plan(
    seed: int,
    videos: int = 1,
    frames: int = 300,
    intervals: int = 1,
    width: int = 1280,
    height: int = 720,
    fps: float = 30.0,
) -> list[VideoPlan]:
    """``videos`` videos of ``frames`` frames with ``intervals`` intervals each; kinds cycle
    sky, group, path; sites cycle through :data:`SITES`."""
    plans = []
    for index in range(videos):
        rng = np.random.default_rng(np.random.SeedSequence([seed, index, 11]))
        kinds = [INTERVAL_KINDS[(index + k) % 3] for k in range(intervals)]
        budget = frames - MIN_LEAD_FRAMES - MIN_TAIL_FRAMES - MIN_GAP_FRAMES * max(intervals - 1, 0)
        cap = max(MIN_INTERVAL_FRAMES, budget // max(intervals, 1)) if intervals else 0
        lengths = [int(np.clip(rng.lognormal(np.log(70.0), 0.5), MIN_INTERVAL_FRAMES,
                               min(MAX_INTERVAL_FRAMES, cap))) for _ in range(intervals)]
        site = SITES[index % len(SITES)]
        plans.append(VideoPlan(
            name=f"synth{index + 1:03d}-{site.name}",
            seed=_video_seed(seed, index + 1),
            site=site,
            n_frames=frames,
            intervals=layout_intervals(rng, frames, lengths, kinds),
            n_targets=int(rng.integers(5, 11)),
            fps=fps,
            width=width,
            height=height,
        ))
    return plans


def demo_plan() -> VideoPlan:
    """The small built-in demo: 640x360, 150 frames, 6 targets, one 30-frame 'sky' interval
    from frame 60 (0-based; 1-based 61..90)."""
    return VideoPlan(
        name="demo",
        seed=20180601,
        site=DEMO_SITE,
        n_frames=150,
        intervals=(IntervalPlan(start=60, length=30, kind="sky"),),
        n_targets=6,
        width=640,
        height=360,
        preset="demo",
    )


def with_options(plans: list[VideoPlan], trajectories: str | None, background: str | None,
                 hfov_deg: float | None = None, wearer: WearerConfig | None = None
                 ) -> list[VideoPlan]:
    """The same plans with a trajectory source, a background image, a field of view or head
    motion limits set."""
    return [replace(plan, trajectories=trajectories, background=background,
                    hfov_deg=plan.hfov_deg if hfov_deg is None else hfov_deg,
                    wearer=plan.wearer if wearer is None else wearer) for plan in plans]
