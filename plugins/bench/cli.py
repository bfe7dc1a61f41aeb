"""The ``trackfw bench`` command: every (pipeline, video) job, evaluated, as one table."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer


def register(app: typer.Typer) -> None:
    """Add ``bench`` to the root ``trackfw`` application."""
    app.command(name="bench")(bench_command)


# The options of ``bench_command``, one alias each (typer reads them from the signature).
PipelinesArgument = Annotated[
    list[Path],
    typer.Argument(
        help="Pipeline YAML files, one table row each, or table files listing them"
        " (pipelines/tables/table1.yaml: the paper's Table 1 and our rows)."
    ),
]
DatasetOption = Annotated[
    Path, typer.Option("--dataset", "-d", help="Dataset folder (one sub-folder per video).")
]
JobsOption = Annotated[
    int, typer.Option("--jobs", "-j", min=1, help="Jobs at once (worker processes).")
]
ExecutorOption = Annotated[
    str, typer.Option("--executor", help="Where jobs run: local, dask, or a plugin's.")
]
AddressOption = Annotated[
    str | None,
    typer.Option("--address", help="Scheduler address for --executor dask (tcp://host:8786)."),
]
OutOption = Annotated[
    Path, typer.Option("--out", "-o", help="Output folder (runs, cache, tables).")
]
NoCacheOption = Annotated[
    bool, typer.Option("--no-cache", help="Do not read or write the stage cache.")
]
CacheDirOption = Annotated[
    Path | None,
    typer.Option("--cache-dir", help="Stage cache folder (default: OUT/cache)."),
]
TimeoutOption = Annotated[
    float | None,
    typer.Option("--timeout", help="Time limit per job in seconds; a job past it fails."),
]
OverridesOption = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        help="Override a value in every pipeline (PATH=VALUE) or in one (NAME:PATH=VALUE).",
    ),
]
DistOption = Annotated[
    float, typer.Option("--dist", help="CLEAR MOT / IDF1 match threshold in pixels.")
]
RetriesOption = Annotated[
    int, typer.Option("--retries", min=0, help="Retries of a job whose worker was lost.")
]
QuietOption = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")]


def bench_command(
    pipelines: PipelinesArgument,
    dataset: DatasetOption,
    jobs: JobsOption = 1,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
    out: OutOption = Path("bench"),
    no_cache: NoCacheOption = False,
    cache_dir: CacheDirOption = None,
    timeout: TimeoutOption = None,
    overrides: OverridesOption = None,
    dist: DistOption = 40.0,
    retries: RetriesOption = 1,
    quiet: QuietOption = False,
) -> None:
    """Run pipelines over a dataset and write the benchmark table (Markdown, CSV, PNG).

    Finished jobs are skipped on a rerun; failed ones go to OUT/failures.json (exit code 2).
    """
    from rich.console import Console

    from trackfw.cli import get_registry
    from trackfw.errors import UserError
    from trackfw_plugins.bench.executor import ExecutorOptions, make_executor
    from trackfw_plugins.bench.sweep import plan_sweep
    from trackfw_plugins.bench.table_file import expand_tables

    error_console = Console(stderr=True)
    # The table is built after every job ran; a bad threshold must not wait for that.
    if not (math.isfinite(dist) and dist > 0):
        raise UserError(f"--dist is {dist}; expected a positive number of pixels.")
    registry = get_registry()
    expanded = expand_tables(pipelines)
    plan = plan_sweep(
        registry,
        expanded.files,
        dataset,
        out,
        overrides or [],
        cache_dir=cache_dir,
        use_cache=not no_cache,
        timeout_s=timeout,
    )
    runner = make_executor(
        registry,
        executor,
        ExecutorOptions(jobs=jobs, address=address, retries=retries, registry=registry),
    )
    sweep = _run_with_progress(plan, runner, executor, quiet, error_console)
    _write_outputs(plan, sweep, out, dist, error_console, expanded.paper)


def _write_outputs(
    plan: Any,
    sweep: Any,
    out: Path,
    dist: float,
    error_console: Any,
    paper: dict[Path, dict[str, float]],
) -> None:
    """Write the table (Markdown on stdout too) and the sweep's counts; exit 2 when a job failed.

    ``paper``: the paper's figures per pipeline file, quoted by table files.
    """
    from trackfw_plugins.bench.report import build_table, markdown_table, write_table

    rows = build_table(plan, distance_px=dist, paper=paper)
    paths = write_table(rows, out, distance_px=dist)
    typer.echo(markdown_table(rows, distance_px=dist), nl=False)
    error_console.print(
        f"{sweep.count('done')} run, {sweep.count('skipped')} already done,"
        f" {sweep.count('failed')} failed in {sweep.seconds:.1f} s;"
        f" wrote {paths['markdown']}, {paths['csv']}, {paths['png']}",
        highlight=False,
        soft_wrap=True,
    )
    if sweep.failures:
        _report_failures(sweep, out, error_console)


def _report_failures(sweep: Any, out: Path, console: Any) -> None:
    """Name the first failed jobs on stderr, then stop with exit code 2."""
    from trackfw.errors import UserError

    console.print(f"[red]{len(sweep.failures)} job(s) failed[/red]; see {out / 'failures.json'}")
    for failure in sweep.failures[:5]:
        console.print(
            f"  {failure.pipeline} / {failure.video}: {failure.error_type}:"
            f" {failure.error_message}",
            markup=False,
            highlight=False,
        )
    # trackfw.cli.main turns a UserError into exit code 2 (it does not pass typer.Exit codes on).
    raise UserError(
        f"{len(sweep.failures)} of {len(sweep.results)} jobs failed; see"
        f" {out / 'failures.json'} (the table covers the completed jobs)."
    )


def _run_with_progress(
    plan: Any, runner: Any, executor_name: str, quiet: bool, console: Any
) -> Any:
    from trackfw_plugins.bench.sweep import run_sweep

    if quiet:
        return run_sweep(plan, runner, executor_name=executor_name)
    from trackfw.progress import progress_bar

    with progress_bar(console, "jobs", "elapsed") as progress:
        task = progress.add_task("bench", total=len(plan.jobs))

        def advance(result: Any) -> None:
            progress.update(
                task,
                advance=1,
                description=f"{result.pipeline}/{result.video} {result.status}",
            )

        return run_sweep(plan, runner, on_result=advance, executor_name=executor_name)


__all__ = ["bench_command", "register"]
