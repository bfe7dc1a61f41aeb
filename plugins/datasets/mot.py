"""Read a MOTChallenge sequence: ``seqinfo.ini``, the frames in ``img1/`` and ``gt/gt.txt``.

Supported ground-truth layouts (one box per line, 1-based frames)::

    MOT15     frame,id,left,top,width,height,flag,wx,wy,wz        10 columns, every row kept
    MOT16/17  frame,id,left,top,width,height,flag,class,visibility 9 columns
    (also 6, 7 and 8 columns: the leading fields of the MOT16/17 layout)

Where the ``flag`` and ``class`` columns of the MOT16/17 layout exist, only rows with flag 1
(consider the box) and class 1 (pedestrian) are kept; MOT15 has no class column and its 7th
column is a confidence, so no row is dropped there.

Every error names the file and the line and says what was expected.
"""

from __future__ import annotations

import configparser
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from trackfw.errors import UserError

SEQINFO_FILE = "seqinfo.ini"
GROUND_TRUTH_FILE = Path("gt") / "gt.txt"
DEFAULT_IMAGE_FOLDER = "img1"
DEFAULT_FPS = 25.0
IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp")

#: Head-centre proxy from a whole-body box: ``(left + width / 2, top + HEAD_Y_FRACTION * height)``.
HEAD_Y_FRACTION = 0.08
#: Head size (pixels) from a whole-body box: ``HEAD_SIZE_FRACTION * height``. An adult head is about
#: 1/7.5 of the body height; the height is used rather than the width because a box's width varies
#: with the stride and the arms while its height does not.
HEAD_SIZE_FRACTION = 0.13


@dataclass
class MotSequence:
    """One MOTChallenge sequence.

    Attributes:
        path: the sequence folder.
        name: the sequence name (``seqinfo.ini`` ``name`` or the folder name).
        frame_paths: image file of each frame; index ``t`` is 0-based frame ``t``.
        width: frame width in pixels.
        height: frame height in pixels.
        fps: frames per second.
        boxes: 0-based frame -> ``(M, 5)`` float array of ``id, left, top, width, height``.
    """

    path: Path
    name: str
    frame_paths: list[Path]
    width: int
    height: int
    fps: float
    boxes: dict[int, np.ndarray] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return len(self.frame_paths)

    def boxes_at(self, frame: int) -> np.ndarray:
        """``(M, 5)`` boxes (``id, left, top, width, height``) of 0-based ``frame``, maybe none."""
        return self.boxes.get(frame, np.zeros((0, 5), dtype=np.float64))


def head_proxies(boxes: np.ndarray) -> np.ndarray:
    """Head centre and size from whole-body boxes.

    Args:
        boxes: ``(M, 5)`` array of ``id, left, top, width, height``.

    Returns:
        ``(M, 3)`` array of ``x, y, head_size`` in the same pixels.

    >>> head_proxies(np.array([[7, 10.0, 20.0, 40.0, 100.0]])).tolist()
    [[30.0, 28.0, 13.0]]
    """
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 5)
    x = boxes[:, 1] + boxes[:, 3] / 2.0
    y = boxes[:, 2] + HEAD_Y_FRACTION * boxes[:, 4]
    return np.stack([x, y, HEAD_SIZE_FRACTION * boxes[:, 4]], axis=1)


def read_seqinfo(path: Path) -> dict[str, str]:
    """The ``[Sequence]`` section of a ``seqinfo.ini`` as lower-case keys (empty when absent)."""
    if not path.is_file():
        return {}
    parser = configparser.ConfigParser(interpolation=None)
    try:
        parser.read_string(path.read_text(encoding="utf-8"), source=str(path))
    except (configparser.Error, UnicodeDecodeError) as error:
        message = str(error).splitlines()[0]
        raise UserError(f"{path}: not a valid INI file ({message}).") from None
    if not parser.has_section("Sequence"):
        raise UserError(
            f"{path}: no [Sequence] section; expected the MOTChallenge seqinfo.ini layout."
        )
    return {key.lower(): value.strip() for key, value in parser.items("Sequence")}


def _seqinfo_number(path: Path, info: dict[str, str], key: str, integer: bool) -> float | None:
    if key.lower() not in info:
        return None
    text = info[key.lower()]
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        expected = "an integer" if integer else "a number"
        raise UserError(f"{path}: {key} is {text!r}; expected {expected}.") from None
    if not math.isfinite(value) or value <= 0:
        raise UserError(f"{path}: {key} is {text!r}; expected a positive number.")
    return value


def read_mot_ground_truth(path: Path, n_frames: int | None = None) -> dict[int, np.ndarray]:
    """Parse a MOTChallenge ``gt.txt``.

    Args:
        path: the ``gt.txt`` file.
        n_frames: number of frames of the sequence; rows beyond it are errors when given.

    Returns:
        0-based frame -> ``(M, 5)`` float array of ``id, left, top, width, height``, rows sorted
        by id. Rows removed by the flag/class filter (see the module docstring) are absent.

    Raises:
        UserError: a malformed line (naming the file and the line), or an id twice in a frame.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: no such file; expected the MOTChallenge ground truth.") from None
    except UnicodeDecodeError as error:
        raise UserError(f"{path}: not UTF-8 text ({error.reason}).") from None
    grouped: dict[int, dict[int, tuple[float, float, float, float]]] = {}
    n_columns: int | None = None
    for line_number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        fields = [value.strip() for value in line.replace(" ", "").split(",")]
        if n_columns is None:
            n_columns = len(fields)
            if not 6 <= n_columns <= 10:
                raise UserError(
                    f"{path}: line {line_number}: {n_columns} values; expected 6 to 10"
                    " (frame,id,left,top,width,height,...)."
                )
        if len(fields) != n_columns:
            raise UserError(
                f"{path}: line {line_number}: {len(fields)} values;"
                f" expected {n_columns} like the first line."
            )
        try:
            values = [float(value) for value in fields]
        except ValueError:
            bad = next(value for value in fields if not _is_number(value))
            raise UserError(
                f"{path}: line {line_number}: {bad!r} is not a number; expected numeric columns."
            ) from None
        if not all(math.isfinite(value) for value in values[:6]):
            raise UserError(
                f"{path}: line {line_number}: frame, id and box must be finite numbers."
            )
        frame, identity, left, top, width, height = values[:6]
        if frame != int(frame) or identity != int(identity):
            raise UserError(f"{path}: line {line_number}: frame and id must be integers.")
        if frame < 1 or (n_frames is not None and frame > n_frames):
            limit = f"1..{n_frames}" if n_frames is not None else ">= 1"
            raise UserError(
                f"{path}: line {line_number}: frame {int(frame)} is outside the sequence;"
                f" expected {limit}."
            )
        if width <= 0 or height <= 0:
            raise UserError(
                f"{path}: line {line_number}: box {width}x{height}; expected a positive size."
            )
        # MOT16/17 layout: flag (consider) then class; keep pedestrians that count.
        if n_columns in (7, 8, 9) and values[6] != 1:
            continue
        if n_columns in (8, 9) and values[7] != 1:
            continue
        frame_boxes = grouped.setdefault(int(frame) - 1, {})
        if int(identity) in frame_boxes:
            raise UserError(
                f"{path}: line {line_number}: id {int(identity)} appears twice"
                f" in frame {int(frame)}."
            )
        frame_boxes[int(identity)] = (left, top, width, height)
    return {
        frame: np.array(
            [(identity, *box) for identity, box in sorted(rows.items())], dtype=np.float64
        )
        for frame, rows in sorted(grouped.items())
    }


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def load_mot_sequence(directory: Path) -> MotSequence:
    """Read a MOTChallenge sequence folder (``img1/`` + ``gt/gt.txt``, ``seqinfo.ini`` optional).

    Args:
        directory: the sequence folder.

    Returns:
        The sequence with its frame list, size, frame rate and ground-truth boxes.

    Raises:
        UserError: the folder, the images or the ground truth are missing or malformed.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise UserError(f"{directory}: no such folder; expected a MOTChallenge sequence folder.")
    seqinfo_path = directory / SEQINFO_FILE
    info = read_seqinfo(seqinfo_path)
    image_dir = directory / info.get("imdir", DEFAULT_IMAGE_FOLDER)
    if not image_dir.is_dir():
        raise UserError(f"{image_dir}: no such folder; expected the sequence's frames there.")
    extension = info.get("imext", "").lower()
    extensions = (extension,) if extension else IMAGE_EXTENSIONS
    frame_paths = sorted(
        child for child in image_dir.iterdir() if child.suffix.lower() in extensions
    )
    if not frame_paths:
        raise UserError(f"{image_dir}: no {'/'.join(extensions)} image; expected the frames.")
    length = _seqinfo_number(seqinfo_path, info, "seqLength", integer=True)
    if length is not None:
        if len(frame_paths) < length:
            raise UserError(
                f"{seqinfo_path}: seqLength is {int(length)} but {image_dir} holds"
                f" {len(frame_paths)} images; expected at least as many images."
            )
        frame_paths = frame_paths[: int(length)]
    width = _seqinfo_number(seqinfo_path, info, "imWidth", integer=True)
    height = _seqinfo_number(seqinfo_path, info, "imHeight", integer=True)
    if width is None or height is None:
        width, height = _image_size(frame_paths[0])
    fps = _seqinfo_number(seqinfo_path, info, "frameRate", integer=False) or DEFAULT_FPS
    boxes = read_mot_ground_truth(directory / GROUND_TRUTH_FILE, len(frame_paths))
    if not boxes:
        raise UserError(f"{directory / GROUND_TRUTH_FILE}: no usable box; expected pedestrians.")
    return MotSequence(
        path=directory,
        name=info.get("name", directory.name) or directory.name,
        frame_paths=frame_paths,
        width=int(width),
        height=int(height),
        fps=float(fps),
        boxes=boxes,
    )


def _image_size(path: Path) -> tuple[int, int]:
    import cv2

    image = cv2.imread(str(path))
    if image is None:
        raise UserError(f"{path}: cannot read the image; expected a JPEG or PNG frame.")
    return int(image.shape[1]), int(image.shape[0])


def read_frame(sequence: MotSequence, frame: int, raw: bool = False) -> np.ndarray:
    """The ``(height, width, 3)`` BGR uint8 image of 0-based ``frame``.

    Unless ``raw``, the outermost lines are replaced by their inner neighbour (see
    :func:`trim_edges`): warped or zoomed, a dark border line would cross the image.
    """
    import cv2

    path = sequence.frame_paths[frame]
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise UserError(f"{path}: cannot read the image; expected a JPEG or PNG frame.")
    if image.shape[1] != sequence.width or image.shape[0] != sequence.height:
        raise UserError(
            f"{path}: image is {image.shape[1]}x{image.shape[0]}; expected"
            f" {sequence.width}x{sequence.height} like the sequence (seqinfo.ini or frame 1)."
        )
    image = np.asarray(image, dtype=np.uint8)
    return image if raw else trim_edges(image)


#: Lines replaced at each edge: TUD frames have 2-3 dark rows at the top, one at the bottom and
#: darker first/last columns, common camera and codec artefacts.
EDGE_LINES = 3


def trim_edges(image: np.ndarray, lines: int = EDGE_LINES) -> np.ndarray:
    """Replace the ``lines`` outermost rows and columns by the first line inside them.

    Args:
        image: ``(H, W, 3)`` uint8 image.
        lines: lines to replace at each of the four edges.

    Returns:
        ``(H, W, 3)`` uint8 copy; unchanged content except the edges.

    >>> frame = np.full((8, 8, 3), 100, np.uint8); frame[0] = 0; frame[:, -1] = 5
    >>> int(trim_edges(frame, 2).min())
    100
    """
    trimmed = image.copy()
    height, width = image.shape[:2]
    if height > 2 * lines:
        trimmed[:lines] = trimmed[lines]
        trimmed[height - lines :] = trimmed[height - lines - 1]
    if width > 2 * lines:
        trimmed[:, :lines] = trimmed[:, lines : lines + 1]
        trimmed[:, width - lines :] = trimmed[:, width - lines - 1 : width - lines]
    return trimmed
