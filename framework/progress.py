"""One progress bar for every long command (run, bench, eval, dataset wear).

A transient rich bar on the given console: ``description [bar] done/total unit clock``. rich is
imported when a bar is made, so that ``trackfw --help`` stays fast.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress


def progress_bar(
    console: Console,
    unit: str | None = None,
    clock: Literal["elapsed", "remaining"] | None = None,
) -> Progress:
    """A transient progress bar; use it as a context manager.

    Args:
        console: where it is drawn (stderr for commands whose stdout is data).
        unit: what is counted (``frames``, ``jobs``), printed after ``done/total``; None: nothing.
        clock: also show the time elapsed or the estimated time remaining.
    """
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        ProgressColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns: list[ProgressColumn] = [
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
    ]
    if unit is not None:
        columns.append(TextColumn(unit))
    if clock == "elapsed":
        columns.append(TimeElapsedColumn())
    elif clock == "remaining":
        columns.append(TimeRemainingColumn())
    return Progress(*columns, console=console, transient=True)
