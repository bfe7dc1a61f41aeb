"""The ``trackfw`` command line (typer).

Core commands live here (``run``, ``validate``, ``plugins``); plugins add theirs through the
``trackfw_register_commands`` hook (``eval``, ``dataset``, ``train``, ...). Errors a user can fix
print one line each and exit with code 2, without a traceback unless ``--debug`` is given.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from trackfw import __version__
from trackfw.errors import UserError
from trackfw.registry import Registry, call_command_hooks, load_registry, params_schema

console = Console()
error_console = Console(stderr=True)

_state: dict[str, Any] = {"debug": False, "registry": None}


def get_registry() -> Registry:
    """The registry loaded at start-up (loaded on demand when used as a library)."""
    if _state["registry"] is None:
        _state["registry"] = load_registry()
    registry = _state["registry"]
    assert isinstance(registry, Registry)
    return registry


def _version(value: bool) -> None:
    if value:
        console.print(f"trackfw {__version__}")
        raise typer.Exit()


def _root(
    debug: Annotated[
        bool, typer.Option("--debug", help="Show tracebacks for unexpected errors.")
    ] = False,
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Print the version.")
    ] = False,
) -> None:
    """Track people through head-worn-camera video across info-less intervals."""
    _state["debug"] = debug


def run_command(
    pipeline: Annotated[Path, typer.Argument(help="Pipeline YAML file.")],
    input_path: Annotated[
        str | None,
        typer.Option(
            "--input",
            "-i",
            help="Video file, video folder or dataset folder (default: the pipeline's input).",
        ),
    ] = None,
    output: Annotated[
        Path | None,
        typer.Option("--output", "-o", help="Output folder (default: runs/<pipeline name>)."),
    ] = None,
    overrides: Annotated[
        list[str] | None,
        typer.Option(
            "--set", help="Override a value: stages.gap_matcher.params.lambda2=0.5 (repeatable)."
        ),
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")] = False,
) -> None:
    """Track the targets through a video or every video of a dataset."""
    from trackfw.formats.run import unread_warning
    from trackfw.runner import prepare_run, run_prepared

    registry = get_registry()
    prepared = prepare_run(registry, pipeline, input_path, output, overrides or [])
    results = run_prepared(prepared, registry, show_progress=not quiet, console=error_console)
    table = Table(title=f"pipeline {prepared.pipeline.name}")
    # A video's name may fold; numbers never do. "proc. fps" is how fast trackfw processed the
    # video (not the video's frame rate); the intervals are those the run detected.
    table.add_column("video", overflow="fold")
    for column in ("frames", "proc. fps", "detected intervals", "targets"):
        table.add_column(column, justify="right", no_wrap=True)
    for run, _ in results:
        table.add_row(
            run.video.name,
            str(run.video.n_frames),
            f"{run.frames_per_second:.0f}",
            str(len(run.gaps)),
            str(len(run.target_ids)),
        )
    console.print(table)
    # Output folders go below the table, one per line and never cut or folded, so that they can
    # be copied from the terminal whole.
    for _, directory in results:
        console.print(f"wrote {directory}", markup=False, highlight=False, soft_wrap=True)
    for run, _ in results:
        warning = unread_warning(run)
        if warning is not None:
            error_console.print(f"warning: {warning}", markup=False, highlight=False, soft_wrap=True)


def validate_command(
    pipeline: Annotated[Path, typer.Argument(help="Pipeline YAML file.")],
    overrides: Annotated[
        list[str] | None, typer.Option("--set", help="Override a value (repeatable).")
    ] = None,
) -> None:
    """Check a pipeline (plugins, parameters, model files) without running it."""
    from trackfw.pipeline import load_pipeline

    loaded = load_pipeline(pipeline, get_registry(), overrides or [])
    console.print(
        f"[green]ok[/green] {pipeline}: pipeline {loaded.name!r} (hash {loaded.content_hash})"
    )
    for kind, spec in loaded.stages.items():
        data = spec.as_data()
        console.print(f"  {kind}: {data['type']} {json.dumps(data['params'], sort_keys=True)}")


def plugins_command(
    as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False,
) -> None:
    """List every registered stage with its parameters, and plugins that failed to load."""
    registry = get_registry()
    entries = sorted(registry.stages.values(), key=lambda e: (e.kind, e.name))
    if as_json:
        data = {
            "stages": [
                {
                    "kind": e.kind,
                    "name": e.name,
                    "package": e.source.package,
                    "version": e.source.version,
                    "plugin": e.source.name,
                    "summary": e.cls.summary(),
                    "params": [
                        {"name": n, "type": t, "default": d, "description": s}
                        for n, t, d, s in params_schema(e.cls.Params)
                    ],
                }
                for e in entries
            ],
            "inputs": [
                {"name": i.name, "description": i.description, "package": i.source.package}
                for i in registry.inputs.values()
            ],
            "failures": [
                {"plugin": f.source.name, "package": f.source.package, "error": f.error}
                for f in registry.failures
            ],
            "clashes": [
                {
                    "kind": c.kind,
                    "name": c.name,
                    "package": c.source.package,
                    "plugin": c.source.name,
                    "kept": c.kept.package,
                }
                for c in registry.clashes
            ],
        }
        console.print_json(json.dumps(data))
        return
    table = Table(title="trackfw stages", show_lines=True)
    for column in ("kind", "name", "package", "parameters"):
        table.add_column(column, overflow="fold")
    for entry in entries:
        params = "\n".join(f"{n}: {t} = {d}" for n, t, d, _ in params_schema(entry.cls.Params))
        nested = "\n".join(f"{key}: <{kind}>" for key, kind in entry.cls.nested.items())
        table.add_row(
            entry.kind,
            f"{entry.name}\n[dim]{entry.cls.summary()}[/dim]",
            f"{entry.source.package} {entry.source.version}".strip(),
            "\n".join(part for part in (params, nested) if part) or "-",
        )
    console.print(table)
    if registry.inputs:
        console.print("inputs: " + ", ".join(f"builtin:{name}" for name in sorted(registry.inputs)))
    if registry.failures:
        console.print("[red]plugins that failed to load:[/red]")
        for failure in registry.failures:
            console.print(
                f"  {failure.source.name} ({failure.source.package}): {failure.error}",
                markup=False,
                highlight=False,
                soft_wrap=True,
            )
    if registry.clashes:
        console.print("[yellow]names already taken (the earlier registration is kept):[/yellow]")
        for clash in registry.clashes:
            console.print(
                f"  {clash.kind} {clash.name!r} from {clash.source.name}"
                f" ({clash.source.package}) ignored: {clash.kept.package} holds it",
                markup=False,
                highlight=False,
                soft_wrap=True,
            )


def command_group(app: typer.Typer, name: str, help_text: str) -> typer.Typer:
    """The sub-command group ``name`` of ``app``, created on first use.

    Several plugins may add commands to one group (``trackfw train classifier`` and
    ``trackfw train detector`` come from different plugins).
    """
    for info in app.registered_groups:
        if info.name == name and isinstance(info.typer_instance, typer.Typer):
            return info.typer_instance
    group = typer.Typer(help=help_text, no_args_is_help=True)
    app.add_typer(group, name=name)
    return group


def build_app(registry: Registry | None = None) -> typer.Typer:
    """The root typer application with core and plugin commands."""
    app = typer.Typer(
        name="trackfw",
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
        rich_markup_mode="rich",
    )
    app.callback()(_root)
    app.command("run")(run_command)
    app.command("validate")(validate_command)
    app.command("plugins")(plugins_command)
    if registry is not None:
        _state["registry"] = registry
    call_command_hooks(get_registry(), app)
    return app


def main(argv: list[str] | None = None) -> int:
    """Console-script entry point; returns the exit code."""
    arguments = sys.argv[1:] if argv is None else argv
    _state["debug"] = "--debug" in arguments
    _state["registry"] = None  # plugins are discovered afresh for every invocation
    try:
        app = build_app()
        # Without standalone mode click returns a command's typer.Exit code instead of exiting.
        result = app(args=arguments, prog_name="trackfw", standalone_mode=False)
        if isinstance(result, int):
            return result
    except UserError as error:
        for line in error.lines:
            error_console.print(f"error: {line}", markup=False, highlight=False, soft_wrap=True)
        return 2
    except typer.Exit as done:
        return int(done.exit_code or 0)
    except typer.Abort:
        error_console.print("aborted")
        return 130
    except Exception as error:  # click usage errors and bugs
        import click

        if isinstance(error, click.exceptions.ClickException):
            error.show()
            return 2
        if _state["debug"]:
            raise
        error_console.print(
            f"error: {type(error).__name__}: {error} (run with --debug for the traceback)",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
        return 1
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
