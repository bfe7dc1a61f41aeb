"""Read a MOTChallenge sequence: ``seqinfo.ini``, the frames in ``img1/`` and ``gt/gt.txt``.

The ground truth is read by :func:`trackfw.formats.read_mot_ground_truth` (MOT15 10-column and
MOT16/17 9-column layouts; only the boxes that count are kept), and a body box's head by
:func:`trackfw.formats.body_heads`, the project's one head-point rule.

Every error names the file and the line and says what was expected.
"""

from __future__ import annotations

import configparser
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from trackfw.errors import UserError
from trackfw.formats import boxes_by_frame, read_mot_ground_truth

SEQINFO_FILE = "seqinfo.ini"
GROUND_TRUTH_FILE = Path("gt") / "gt.txt"
DEFAULT_IMAGE_FOLDER = "img1"
DEFAULT_FPS = 25.0
IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp")


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
    boxes = boxes_by_frame(read_mot_ground_truth(directory / GROUND_TRUTH_FILE, len(frame_paths)))
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
