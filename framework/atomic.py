"""Atomic file writes: a temporary name in the same folder, then ``os.replace``.

An interrupted run therefore never leaves a truncated file that looks complete.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import IO, Any


@contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w") -> Iterator[IO[Any]]:
    """Open a temporary file next to ``path``; on success, rename it onto ``path``.

    On any exception the temporary file is removed and ``path`` is left as it was.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(
        prefix=f".{target.name}.", suffix=".tmp", dir=target.parent
    )
    # mkstemp creates 0600 files; outputs should get the permissions open() would give them.
    os.chmod(temporary, 0o666 & ~_umask())
    try:
        binary = "b" in mode
        stream: IO[Any] = (
            os.fdopen(handle, mode)
            if binary
            else os.fdopen(handle, mode, encoding="utf-8", newline="")
        )
        with stream:
            yield stream
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, target)
    except BaseException:
        with suppress(FileNotFoundError):
            os.unlink(temporary)
        raise


@contextmanager
def replacing_folder(partial: Path, final: Path) -> Iterator[Path]:
    """Fill the folder ``partial`` in the block, then rename it to ``final`` in one step.

    An older ``final`` is removed just before the rename. If anything raises (Ctrl-C included),
    ``partial`` is removed and ``final`` left as it was, so an interrupted writer never leaves a
    folder that looks finished.
    """
    try:
        yield partial
        if final.exists():
            shutil.rmtree(final)
        os.replace(partial, final)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise


def _umask() -> int:
    current = os.umask(0)
    os.umask(current)
    return current


def write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` atomically."""
    with atomic_open(path) as stream:
        stream.write(text)


def write_json(path: str | os.PathLike[str], data: Any, allow_nan: bool = True) -> None:
    """Write ``data`` as indented JSON atomically.

    With ``allow_nan=False`` a non-finite float is a ValueError instead of ``Infinity`` or
    ``NaN``, which most JSON readers refuse.
    """
    text = json.dumps(data, indent=2, sort_keys=False, default=_json_default, allow_nan=allow_nan)
    write_text(path, text + "\n")


def _json_default(value: Any) -> Any:
    # numpy scalars and arrays show up in diagnostics; JSON has no type for them.
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def check_output_folder(path: str | os.PathLike[str], field: str) -> None:
    """Fail early, before any work, when ``path`` cannot become a folder of outputs.

    The folder itself need not exist (it is created when the first file is written), but it must
    not be a file, and the nearest existing folder on the way to it must be writable.

    Raises:
        UserError: naming ``field`` (the option or setting that gave the path) and the path.
    """
    from trackfw.errors import UserError

    target = Path(path)
    if target.exists() and not target.is_dir():
        raise UserError(
            f"{field}: {target} is an existing file; expected a folder (created when missing)."
        )
    _check_writable_above(target, target, field)


def check_output_file(path: str | os.PathLike[str], field: str) -> None:
    """Fail early when ``path`` cannot be written as a file (it may exist: it is replaced).

    Raises:
        UserError: when ``path`` is a folder, lies inside a file or its folder cannot be written.
    """
    from trackfw.errors import UserError

    target = Path(path)
    if target.is_dir():
        raise UserError(f"{field}: {target} is a folder; expected a file name.")
    _check_writable_above(target.parent, target, field)


def _check_writable_above(folder: Path, target: Path, field: str) -> None:
    """The nearest existing folder on the way to ``folder`` is a writable folder."""
    from trackfw.errors import UserError

    existing = folder
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(
            f"{field}: {target}: {existing} is a file, not a folder; expected a path in a folder."
        )
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UserError(
            f"{field}: {target}: the folder {existing} is not writable; expected a folder you can"
            " write to."
        )
