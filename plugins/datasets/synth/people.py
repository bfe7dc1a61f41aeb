"""Where the people walk: a built-in group motion model and the ETH/UCY trajectory loader.

Positions are ground-plane metres in the world frame of :mod:`.scene` (the square is ``Y > 0``).
Everything is sampled at the video frame rate: ``positions`` has shape ``(P, T, 2)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from trackfw.arrays import FloatArray
from trackfw.errors import UserError

#: Where pedestrians may roam (metres): x_min, x_max, y_min, y_max.
SQUARE_BOUNDS = (-40.0, 40.0, 3.0, 50.0)


@dataclass
class Crowd:
    """Every person of one video.

    Attributes:
        positions: ``(P, T, 2)`` ground positions in metres.
        heights: ``(P,)`` body heights in metres.
        is_target: ``(P,)`` True for the people of interest.
        group: ``(P,)`` group number (people walking together share it).
    """

    positions: FloatArray
    heights: FloatArray
    is_target: np.ndarray
    group: np.ndarray
    notes: dict[str, object] = field(default_factory=dict)

    @property
    def count(self) -> int:
        """Number of people ``P``."""
        return int(self.positions.shape[0])

    def walked(self) -> FloatArray:
        """``(P, T)`` cumulative walked distance in metres (drives the gait animation)."""
        steps = np.linalg.norm(np.diff(self.positions, axis=1), axis=2)
        return np.concatenate([np.zeros((self.count, 1)), np.cumsum(steps, axis=1)], axis=1)

    def append(self, other: Crowd) -> Crowd:
        """A crowd with ``other``'s people added after this one's (group numbers kept apart)."""
        offset = int(self.group.max()) + 1 if self.count else 0
        return Crowd(
            positions=np.concatenate([self.positions, other.positions]),
            heights=np.concatenate([self.heights, other.heights]),
            is_target=np.concatenate([self.is_target, other.is_target]),
            group=np.concatenate([self.group, other.group + offset]),
            notes={**self.notes, **other.notes},
        )


def _heights(rng: np.random.Generator, count: int) -> FloatArray:
    return np.clip(rng.normal(1.72, 0.08, size=count), 1.50, 1.95)


def formation(rng: np.random.Generator, count: int) -> FloatArray:
    """``(count, 2)`` member offsets of a walking group: rows of 2-4 side by side, in metres
    (x across the walking direction, y along it), centred on the group centre."""
    per_row = int(rng.integers(2, 5))
    offsets = []
    for index in range(count):
        row, slot = divmod(index, per_row)
        in_row = min(per_row, count - row * per_row)
        across = (slot - (in_row - 1) / 2.0) * rng.uniform(0.7, 1.0)
        along = -row * rng.uniform(0.8, 1.2)
        offsets.append((across + rng.normal(0, 0.08), along + rng.normal(0, 0.1)))
    result = np.asarray(offsets, dtype=np.float64)
    return result - result.mean(axis=0)


def walk_group(
    rng: np.random.Generator,
    count: int,
    start: FloatArray,
    heading_deg: float,
    n_frames: int,
    fps: float,
    speed_range: tuple[float, float] = (0.8, 1.6),
    stops: bool = True,
    bounds: tuple[float, float, float, float] = SQUARE_BOUNDS,
    standing: bool = False,
) -> FloatArray:
    """Simulate one group: cruising speed in ``speed_range`` (m/s), smooth random turns,
    occasional deliberate turns and stops, steering back when it nears the square's edge.

    Returns:
        ``(count, n_frames, 2)`` member positions in metres.
    """
    dt = 1.0 / fps
    cruise = rng.uniform(*speed_range)
    heading = math.radians(heading_deg)
    centre = np.asarray(start, dtype=np.float64).copy()
    speed = 0.0 if standing else cruise
    turn_rate = 0.0
    stop_left = 0.0
    planned_turn = 0.0
    centres = np.zeros((n_frames, 2))
    headings = np.zeros(n_frames)
    for frame in range(n_frames):
        centres[frame] = centre
        headings[frame] = heading
        if standing:
            continue
        # Ornstein-Uhlenbeck turn rate: a wandering, never jerky, heading.
        turn_rate += (-turn_rate / 1.5) * dt + math.radians(8.0) * math.sqrt(dt) * rng.normal()
        if rng.random() < dt / 8.0:  # a deliberate turn about every 8 s
            planned_turn = math.radians(rng.uniform(25, 80)) * rng.choice([-1.0, 1.0])
        step_turn = float(np.clip(planned_turn, -math.radians(35) * dt, math.radians(35) * dt))
        planned_turn -= step_turn
        ahead = centre + 3.0 * cruise * np.array([math.sin(heading), math.cos(heading)])
        outside = not (bounds[0] < ahead[0] < bounds[1] and bounds[2] < ahead[1] < bounds[3])
        if outside:
            middle = np.array([(bounds[0] + bounds[1]) / 2, (bounds[2] + bounds[3]) / 2])
            wanted = math.atan2(middle[0] - centre[0], middle[1] - centre[1])
            error = (wanted - heading + math.pi) % (2 * math.pi) - math.pi
            step_turn += float(np.clip(error, -math.radians(40) * dt, math.radians(40) * dt))
        heading += turn_rate * dt + step_turn
        if stops and stop_left <= 0 and rng.random() < dt / 15.0:  # a stop about every 15 s
            stop_left = rng.uniform(1.0, 3.0)
        target_speed = 0.0 if stop_left > 0 else cruise
        stop_left -= dt
        speed += (target_speed - speed) * min(1.0, dt / 0.6)
        centre = centre + speed * dt * np.array([math.sin(heading), math.cos(heading)])
    offsets = formation(rng, count)
    # Members keep their slot, with a slow personal sway so the pattern is not rigid.
    sway = np.cumsum(rng.normal(0, 0.02, size=(count, n_frames, 2)), axis=1)
    sway -= np.linspace(0, 1, n_frames)[None, :, None] * sway[:, -1:, :] * 0.5
    sway = np.clip(sway, -0.25, 0.25)
    # Low-pass the heading so the formation turns with the group, but smoothly.
    kernel = np.ones(int(fps)) / int(fps)
    smooth_heading = np.convolve(np.pad(headings, (len(kernel) // 2, len(kernel) - 1 - len(kernel) // 2),
                                        mode="edge"), kernel, mode="valid")
    cos_h, sin_h = np.cos(smooth_heading), np.sin(smooth_heading)
    # Offset x is across (to the right of the heading), y along it.
    world_x = offsets[:, 0:1] * cos_h[None] + offsets[:, 1:2] * sin_h[None]
    world_y = -offsets[:, 0:1] * sin_h[None] + offsets[:, 1:2] * cos_h[None]
    return centres[None] + np.stack([world_x, world_y], axis=2) + sway


def builtin_crowd(
    rng: np.random.Generator,
    n_frames: int,
    fps: float,
    n_targets: int,
    target_start: FloatArray,
    n_background: int,
    view_heading_deg: float,
) -> Crowd:
    """The people of interest (one group at ``target_start``) plus background walkers.

    Background people start spread over the square in front of the wearer, alone or in groups
    of 2-4, each with its own speed and heading.
    """
    heading = rng.uniform(0, 360)
    targets = walk_group(rng, n_targets, target_start, heading, n_frames, fps)
    parts = [targets]
    groups = [np.zeros(n_targets, dtype=np.int64)]
    group_number = 1
    placed = 0
    while placed < n_background:
        size = int(min(rng.choice([1, 1, 1, 2, 2, 3, 4]), n_background - placed))
        for _attempt in range(20):
            bearing = math.radians(view_heading_deg + rng.uniform(-70, 70))
            distance = rng.uniform(6.0, 40.0)
            start = np.array([math.sin(bearing) * distance, math.cos(bearing) * distance])
            start[1] = max(start[1], SQUARE_BOUNDS[2] + 1.0)
            if np.min(np.linalg.norm(targets[:, 0] - start, axis=1)) > 3.0:
                break
        members = walk_group(rng, size, start, rng.uniform(0, 360), n_frames, fps,
                             standing=bool(rng.random() < 0.12))
        parts.append(members)
        groups.append(np.full(size, group_number, dtype=np.int64))
        group_number += 1
        placed += size
    positions = np.concatenate(parts)
    is_target = np.zeros(len(positions), dtype=bool)
    is_target[:n_targets] = True
    return Crowd(positions, _heights(rng, len(positions)), is_target, np.concatenate(groups),
                 notes={"motion": "builtin"})


def standing_group(rng: np.random.Generator, count: int, centre: FloatArray, n_frames: int,
                   fps: float) -> Crowd:
    """A group chatting in place (the 'another group' an interval looks at)."""
    positions = walk_group(rng, count, centre, rng.uniform(0, 360), n_frames, fps,
                           speed_range=(0.2, 0.4), stops=True, standing=bool(rng.random() < 0.6))
    return Crowd(positions, _heights(rng, count), np.zeros(count, dtype=bool),
                 np.zeros(count, dtype=np.int64))


# ------------------------------------------------------------------------------------- ETH / UCY


def read_trajectory_file(path: Path) -> dict[int, tuple[FloatArray, FloatArray]]:
    """Read ``frame<TAB>id<TAB>x<TAB>y`` (metres) as ``{id: (frames (N,), xy (N, 2))}``."""
    tracks: dict[int, list[tuple[float, float, float]]] = {}
    for line_number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        fields = line.split()
        if not fields:
            continue
        if len(fields) != 4:
            raise UserError(
                f"{path}: line {line_number}: {len(fields)} values; expected frame, id, x, y"
                " separated by tabs."
            )
        try:
            frame, person, x, y = (float(value) for value in fields)
        except ValueError:
            raise UserError(f"{path}: line {line_number}: expected four numbers (frame id x y).") from None
        tracks.setdefault(int(person), []).append((frame, x, y))
    result = {}
    for person, rows in tracks.items():
        array = np.asarray(sorted(rows), dtype=np.float64)
        result[person] = (array[:, 0], array[:, 1:3])
    if not result:
        raise UserError(f"{path}: no trajectory rows; expected lines 'frame id x y'.")
    return result


def trajectory_files(path: Path) -> list[Path]:
    """The trajectory files named by ``--trajectories`` (a file, or the .txt files of a folder)."""
    if path.is_file():
        return [path]
    if path.is_dir():
        files = sorted(p for p in path.glob("*.txt") if not p.name.upper().startswith("LICENSE"))
        if files:
            return files
    raise UserError(f"{path}: no trajectory file; expected a 'frame id x y' .txt file or a folder of them.")


def _resample(times: FloatArray, xy: FloatArray, query: FloatArray) -> FloatArray:
    """Positions at ``query`` seconds: a cubic spline inside the track, straight-line
    continuation (at the end velocity, capped at 2 m/s) outside it. Returns ``(len(query), 2)``."""
    if len(times) == 1:
        return np.repeat(xy[:1], len(query), axis=0)
    if len(times) >= 3:
        # Imported here: scipy.interpolate would otherwise load with every CLI command (~1 s).
        from scipy.interpolate import CubicSpline

        inside = CubicSpline(times, xy, axis=0, bc_type="natural")(np.clip(query, times[0], times[-1]))
    else:
        inside = np.stack([np.interp(np.clip(query, times[0], times[-1]), times, xy[:, k])
                           for k in range(2)], axis=1)
    first_velocity = (xy[1] - xy[0]) / (times[1] - times[0])
    last_velocity = (xy[-1] - xy[-2]) / (times[-1] - times[-2])
    for velocity in (first_velocity, last_velocity):
        speed = float(np.linalg.norm(velocity))
        if speed > 2.0:
            velocity *= 2.0 / speed
    before = query < times[0]
    after = query > times[-1]
    inside[before] = xy[0] + (query[before] - times[0])[:, None] * first_velocity
    inside[after] = xy[-1] + (query[after] - times[-1])[:, None] * last_velocity
    return inside


def trajectory_crowd(
    rng: np.random.Generator,
    path: Path,
    n_frames: int,
    fps: float,
    n_targets: int,
    target_start: FloatArray,
    source_rate_hz: float = 2.5,
) -> Crowd:
    """People taken from real trajectories (ETH/UCY, 2.5 Hz), resampled to ``fps``.

    A start time and a compact group of ``n_targets`` people present at it are drawn at random;
    the scene is rotated at random and moved so that the group's centre starts at
    ``target_start``. People whose recorded track ends keep walking straight on.
    """
    source = rng.choice(np.asarray(trajectory_files(path), dtype=object))
    tracks = read_trajectory_file(Path(source))
    all_frames = np.unique(np.concatenate([frames for frames, _ in tracks.values()]))
    step = float(np.min(np.diff(all_frames))) if len(all_frames) > 1 else 1.0
    seconds = {person: (frames - all_frames[0]) / step / source_rate_hz
               for person, (frames, _) in tracks.items()}
    duration = (n_frames - 1) / fps
    candidates = []
    for start_time in (all_frames - all_frames[0]) / step / source_rate_hz:
        present = [p for p, s in seconds.items() if s[0] <= start_time <= s[-1]]
        if len(present) >= n_targets:
            candidates.append((start_time, present))
    if not candidates:
        raise UserError(
            f"{source}: no moment with {n_targets} people present at once; expected a denser"
            " trajectory file or fewer targets."
        )
    best: tuple[float, float, list[int]] | None = None
    for _attempt in range(40):
        start_time, present = candidates[int(rng.integers(len(candidates)))]
        positions_now = {p: _resample(seconds[p], tracks[p][1], np.array([start_time]))[0]
                         for p in present}
        seed_person = present[int(rng.integers(len(present)))]
        distances = sorted(present, key=lambda p: float(np.linalg.norm(positions_now[p]
                                                                        - positions_now[seed_person])))
        chosen = distances[:n_targets]
        spread = max(float(np.linalg.norm(positions_now[p] - positions_now[seed_person])) for p in chosen)
        if best is None or spread < best[1]:
            best = (start_time, spread, chosen)
        if spread < 5.0:
            break
    assert best is not None
    start_time, _spread, targets = best
    query = start_time + np.arange(n_frames) / fps
    others = [p for p in tracks if p not in targets and seconds[p][-1] >= start_time
              and seconds[p][0] <= start_time + duration]
    order = list(targets) + others
    positions = np.stack([_resample(seconds[p], tracks[p][1], query) for p in order])
    angle = rng.uniform(0, 2 * math.pi)
    turn = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    centre = positions[:n_targets, 0].mean(axis=0)
    positions = (positions - centre) @ turn.T + np.asarray(target_start)
    # Keep the people of interest on the square (in front of the wearer's building).
    lowest = positions[:n_targets, :, 1].min()
    if lowest < SQUARE_BOUNDS[2]:
        positions[..., 1] += SQUARE_BOUNDS[2] - lowest
    is_target = np.zeros(len(order), dtype=bool)
    is_target[:n_targets] = True
    group = np.arange(len(order), dtype=np.int64)
    group[:n_targets] = 0
    return Crowd(positions, _heights(rng, len(order)), is_target, group,
                 notes={"motion": "trajectories", "trajectory_file": Path(source).name,
                        "trajectory_start_s": round(float(start_time), 3),
                        "trajectory_ids": [int(p) for p in targets]})
