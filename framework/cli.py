"""The ``trackfw`` command line (typer).

Core commands live here (``run``, ``validate``, ``plugins``); plugins add theirs through the
``trackfw_register_commands`` hook (``eval``, ``dataset``, ``train``, ...). Errors a user can fix
print one line each and exit with code 2, without a traceback unless ``--debug`` is given.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from trackfw import __version__
from trackfw.errors import UserError
from trackfw.registry import (
    Registry,
    StageEntry,
    call_command_hooks,
    load_registry,
    params_schema,
)

console = Console()
error_console = Console(stderr=True)

_state: dict[str, Any] = {"debug": False, "registry": None, "signal": None}


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
    region: Annotated[
        str | None,
        typer.Option(
            "--region",
            help="Targets: the detections inside this box x,y,w,h (pixels) on the start frame"
            " (engine.init: region).",
        ),
    ] = None,
    targets: Annotated[
        Path | None,
        typer.Option(
            "--targets",
            help="Targets from a file: rows frame,id,x,y under that header, or MOTChallenge text"
            " whose boxes become head points; the run starts on its first frame"
            " (engine.init: targets).",
        ),
    ] = None,
) -> None:
    """Track the targets through a video or every video of a dataset."""
    from trackfw.formats.run import unread_warning
    from trackfw.runner import prepare_run, replaced_runs, run_prepared

    registry = get_registry()
    overrides = [*(overrides or []), *_target_overrides(region, targets)]
    prepared = prepare_run(registry, pipeline, input_path, output, overrides)
    for message in replaced_runs(prepared):
        error_console.print(f"warning: {message}", markup=False, highlight=False, soft_wrap=True)
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
            error_console.print(
                f"warning: {warning}", markup=False, highlight=False, soft_wrap=True
            )


def _target_overrides(region: str | None, targets: Path | None) -> list[str]:
    """``--set`` overrides for ``--region`` or ``--targets`` (validated here, one line each)."""
    from trackfw.targets import parse_region

    if region is not None and targets is not None:
        raise UserError(
            "--region and --targets both given; expected one way to choose the targets."
        )
    if region is not None:
        box = ", ".join(f"{value!r}" for value in parse_region(region))
        return ["engine.init=region", f"engine.region=[{box}]", "engine.targets=null"]
    if targets is not None:
        return [
            "engine.init=targets",
            f"engine.targets={json.dumps(str(targets))}",
            "engine.region=null",
        ]
    return []


def validate_command(
    pipeline: Annotated[
        Path, typer.Argument(help="Pipeline YAML file (or a bench table file: its pipelines).")
    ],
    overrides: Annotated[
        list[str] | None, typer.Option("--set", help="Override a value (repeatable).")
    ] = None,
) -> None:
    """Check a pipeline (plugins, parameters, model files) without running it."""
    listed = _table_pipelines(pipeline)
    if listed is None:
        _validate_pipeline(pipeline, overrides or [])
        return
    console.print(
        f"{pipeline} is a bench table file (it has `rows`), not a pipeline: run it with "
        f"`trackfw bench`; validating the {len(listed)} pipelines it lists.",
        markup=False,
        highlight=False,
        soft_wrap=True,
    )
    failed = 0
    for path in listed:
        try:
            _validate_pipeline(path, overrides or [])
        except UserError as error:
            failed += 1
            for line in error.lines:
                _print_error(line)
    if failed:
        _print_error(f"{pipeline}: {failed} of the {len(listed)} pipelines it lists are not valid.")
        raise typer.Exit(2)


def _validate_pipeline(path: Path, overrides: list[str]) -> None:
    """Load one pipeline file and print what it resolves to (UserError when it is not valid)."""
    from trackfw.pipeline import load_pipeline

    loaded = load_pipeline(path, get_registry(), overrides)
    console.print(
        f"[green]ok[/green] {path}: pipeline {loaded.name!r} (hash {loaded.content_hash})"
    )
    for kind, spec in loaded.stages.items():
        data = spec.as_data()
        console.print(f"  {kind}: {data['type']} {json.dumps(data['params'], sort_keys=True)}")


def _table_pipelines(path: Path) -> list[Path] | None:
    """The pipeline files a bench table file lists (``rows: [{pipeline: PATH}, ...]``, relative
    to the file); None when ``path`` is not a readable table file (the pipeline loader then
    says what it is). The table format belongs to the bench plugin; the core only reads the
    ``rows`` key, so that validate can say what the file is.
    """
    from trackfw.yaml_loading import parse_yaml

    try:
        document = parse_yaml(path.read_text(encoding="utf-8"), str(path))
    except (OSError, UnicodeDecodeError, UserError):
        return None
    if not isinstance(document, dict) or "rows" not in document or "stages" in document:
        return None
    rows = document["rows"]
    what = f"{path} is a bench table file (it has `rows`), not a pipeline, and its"
    if not isinstance(rows, list) or not rows:
        raise UserError(f"{what} rows is not a non-empty list of {{pipeline, paper}}.")
    listed = []
    for index, row in enumerate(rows):
        if not isinstance(row, dict) or not isinstance(row.get("pipeline"), str):
            raise UserError(f"{what} rows[{index}] is not a mapping with a pipeline path.")
        listed.append(Path(os.path.normpath(path.parent / row["pipeline"])))
    return listed


def plugins_command(
    as_json: Annotated[bool, typer.Option("--json", help="Machine-readable output.")] = False,
) -> None:
    """List every registered stage with its parameters, and plugins that failed to load."""
    registry = get_registry()
    entries = sorted(registry.stages.values(), key=lambda e: (e.kind, e.name))
    if as_json:
        console.print_json(json.dumps(_plugins_data(registry, entries)))
        return
    _print_stage_table(registry, entries)
    _print_load_problems(registry)


def _plugins_data(registry: Registry, entries: list[StageEntry]) -> dict[str, Any]:
    """What ``trackfw plugins --json`` prints."""
    return {
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


def _print_stage_table(registry: Registry, entries: list[StageEntry]) -> None:
    """The stages as a table (parameters and nested stages in one cell), then the inputs."""
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


def _print_load_problems(registry: Registry) -> None:
    """Plugins that failed to load and names already taken, one line each."""
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
    """Console-script entry point; returns the exit code.

    0 on success, 2 for anything the user can fix (bad input, usage errors, files that cannot be
    written), 130 after Ctrl-C (143 after SIGTERM), 1 for a bug (one line; ``--debug`` shows the
    traceback).
    """
    arguments = sys.argv[1:] if argv is None else argv
    _state["debug"] = "--debug" in arguments
    _state["registry"] = None  # plugins are discovered afresh for every invocation
    _state["signal"] = None
    with _signals_as_interrupts():
        try:
            app = build_app()
            # Without standalone mode typer returns a command's typer.Exit code instead of exiting
            # and raises usage errors instead of printing them, so they are all printed here.
            result = app(args=arguments, prog_name="trackfw", standalone_mode=False)
            code = result if isinstance(result, int) else 0
        except UserError as error:
            for line in error.lines:
                _print_error(line)
            return 2
        except typer.Exit as done:
            code = int(done.exit_code or 0)
        except typer.Abort:
            _print_error("aborted.")
            return 130
        except typer.TyperException as error:  # usage errors: unknown command, missing argument...
            _print_usage_error(error)
            return 2
        except KeyboardInterrupt:  # outside a command (typer turns it into exit code 130 inside)
            code = 130
        except OSError as error:
            # Files the user named or the disk they are on (permissions, a full disk, a file
            # where a folder should be): the system's reason is the message.
            if _state["debug"]:
                raise
            _print_error(_os_error_message(error))
            return 2
        except Exception as error:  # bugs
            if _state["debug"]:
                raise
            _print_error(f"{type(error).__name__}: {error} (run with --debug for the traceback)")
            return 1
    if code == 130 or _state["signal"] is not None:
        signum = _state["signal"] or signal.SIGINT
        _print_error(
            f"interrupted by {signal.Signals(signum).name}; the files written so far are complete"
            " (each is written whole or not at all)."
        )
        return 128 + int(signum)
    return code


def _print_error(line: str) -> None:
    error_console.print(f"error: {line}", markup=False, highlight=False, soft_wrap=True)


def _print_usage_error(error: typer.TyperException) -> None:
    """One line: typer's message, the usage of the command and where its help is."""
    if type(error).__name__ == "NoArgsIsHelpError":
        return  # typer has printed the help already; there is no error to add
    message = error.format_message().strip()
    if not message.endswith((".", "!", "?")):
        message += "."
    context = getattr(error, "ctx", None)
    get_usage = getattr(context, "get_usage", None)
    if callable(get_usage):
        usage = " ".join(str(get_usage()).split())  # usage may wrap on narrow terminals
        help_option = (getattr(context, "help_option_names", None) or ["--help"])[0]
        command = getattr(context, "command_path", "trackfw")
        message += f" {usage}; see '{command} {help_option}'."
    _print_error(message)


def _os_error_message(error: OSError) -> str:
    reason = error.strerror or str(error)
    if error.filename is None:
        return f"{reason}."
    if error.filename2 is not None:
        return f"{error.filename} -> {error.filename2}: {reason}."
    return f"{error.filename}: {reason}."


@contextmanager
def _signals_as_interrupts() -> Iterator[None]:
    """SIGINT and SIGTERM raise KeyboardInterrupt in the main thread while the CLI runs.

    Both then unwind through the atomic writers (framework/atomic.py), which remove their
    temporary files, so an interrupted command leaves only complete files; ``_state["signal"]``
    says which signal it was, for the exit code (128 + signal number).
    """

    def interrupt(signum: int, _frame: object) -> None:
        _state["signal"] = signum
        raise KeyboardInterrupt

    if threading.current_thread() is not threading.main_thread():
        yield  # signal handlers can only be set from the main thread (e.g. tests in threads)
        return
    previous = {signum: signal.getsignal(signum) for signum in (signal.SIGINT, signal.SIGTERM)}
    for signum, handler in previous.items():
        # An ignored signal stays ignored: a shell script's `trackfw run ... &` must not stop
        # when the user presses Ctrl-C for the script's foreground command.
        if handler is not signal.SIG_IGN:
            signal.signal(signum, interrupt)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
