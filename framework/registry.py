"""The plugin registry: stage classes and named inputs, found through pluggy and entry points.

Built-in and third-party plugins load the same way: every module named in the ``trackfw``
entry-point group is registered with a :class:`pluggy.PluginManager`, then each implementation of
:func:`trackfw.hookspecs.trackfw_register_stages` is called with the :class:`Registry`. A plugin
whose import raises, that declares another plugin API version, or that registers something that
is not a proper stage class is recorded in :attr:`Registry.failures` and skipped; the rest of the
tool keeps working. A plugin that raises ``SystemExit`` (``sys.exit()`` at import) is such a
failure too: it cannot end the process it was loaded into.

Names are first come, first served, and the built-in plugins (those of the ``trackfw``
distribution) always come first: a third-party plugin that registers a stage, input, executor or
command under a name already taken does not replace it. That one registration is skipped and
recorded in :attr:`Registry.clashes` (``trackfw plugins`` lists them); the plugin's other names
stay registered. Third-party plugins come in the order of their entry-point names.
"""

from __future__ import annotations

import difflib
import functools
import importlib
import importlib.metadata
import inspect
import traceback
import typing
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import pluggy
from pluggy import HookImpl
from pydantic import BaseModel, ValidationError

from trackfw import PLUGIN_API_VERSION, __version__, hookspecs
from trackfw.errors import PluginError, UserError, quoted
from trackfw.stages import STAGE_BASES, Stage, StageParams

ENTRY_POINT_GROUP = "trackfw"
#: The distribution whose plugins are built in: they win every name clash.
BUILTIN_PACKAGE = "trackfw"


@dataclass(frozen=True)
class PluginSource:
    """Where a plugin comes from: entry-point name, distribution and version."""

    name: str
    package: str
    version: str

    @property
    def builtin(self) -> bool:
        """True for the plugins that ship with trackfw itself."""
        return self.package == BUILTIN_PACKAGE


@dataclass(frozen=True)
class StageEntry:
    """A registered stage class."""

    kind: str
    name: str
    cls: type[Stage[Any]]
    source: PluginSource


@dataclass(frozen=True)
class InputEntry:
    """A named input usable as ``builtin:NAME``."""

    name: str
    factory: Callable[[], Path]
    description: str
    source: PluginSource


@dataclass(frozen=True)
class ExecutorEntry:
    """A registered executor for ``trackfw bench --executor NAME``."""

    name: str
    factory: Callable[..., Any]
    source: PluginSource


@dataclass(frozen=True)
class PluginFailure:
    """A plugin that could not be loaded or registered something invalid."""

    source: PluginSource
    error: str


@dataclass(frozen=True)
class PluginClash:
    """A name a plugin registered that was already taken; the earlier registration was kept.

    Attributes:
        kind: ``detector``, ``classifier``, ..., ``input``, ``executor`` or ``command``.
        name: the contested name (``train classifier`` for a command inside a group).
        source: the plugin whose registration was ignored.
        kept: the plugin that holds the name.
    """

    kind: str
    name: str
    source: PluginSource
    kept: PluginSource


@dataclass
class Registry:
    """Every stage class and named input known to trackfw.

    Plugins receive the registry in their ``trackfw_register_stages`` hook and call
    ``add_detector``, ``add_classifier``, ``add_tracker``, ``add_gap_matcher``, ``add_predictor``,
    ``add_batch_tracker``; in ``trackfw_register_executors`` they call ``add_executor``.
    """

    stages: dict[tuple[str, str], StageEntry] = field(default_factory=dict)
    inputs: dict[str, InputEntry] = field(default_factory=dict)
    executors: dict[str, ExecutorEntry] = field(default_factory=dict)
    failures: list[PluginFailure] = field(default_factory=list)
    clashes: list[PluginClash] = field(default_factory=list)
    plugin_manager: pluggy.PluginManager | None = None
    #: pluggy plugin name -> where it came from, for every plugin that loaded.
    sources: dict[str, PluginSource] = field(default_factory=dict)
    _current: PluginSource = field(default=PluginSource("<direct>", "<direct>", ""), repr=False)

    # -------------------------------------------------------------------------- registration

    def add_detector(self, cls: type[Stage[Any]]) -> None:
        """Register a :class:`trackfw.stages.Detector` subclass."""
        self._add("detector", cls)

    def add_classifier(self, cls: type[Stage[Any]]) -> None:
        """Register a :class:`trackfw.stages.Classifier` subclass."""
        self._add("classifier", cls)

    def add_tracker(self, cls: type[Stage[Any]]) -> None:
        """Register a :class:`trackfw.stages.Tracker` subclass."""
        self._add("tracker", cls)

    def add_gap_matcher(self, cls: type[Stage[Any]]) -> None:
        """Register a :class:`trackfw.stages.GapMatcher` subclass."""
        self._add("gap_matcher", cls)

    def add_predictor(self, cls: type[Stage[Any]]) -> None:
        """Register a :class:`trackfw.stages.Predictor` subclass."""
        self._add("predictor", cls)

    def add_batch_tracker(self, cls: type[Stage[Any]]) -> None:
        """Register a :class:`trackfw.stages.BatchTracker` subclass."""
        self._add("batch_tracker", cls)

    def add_input(self, name: str, factory: Callable[[], Path], description: str = "") -> None:
        """Register a named input (``input: builtin:NAME`` in a pipeline)."""
        if not name or not callable(factory):
            raise PluginError(f"add_input needs a name and a callable factory, got {name!r}")
        if name in self.inputs:
            self._clash("input", name, self.inputs[name].source)
            return
        self.inputs[name] = InputEntry(name, factory, description, self._current)

    def add_executor(self, name: str, cls_or_factory: Callable[..., Any]) -> None:
        """Register an executor for ``trackfw bench --executor NAME``.

        ``cls_or_factory(options)`` gets a :class:`trackfw_plugins.bench.executor.ExecutorOptions` and
        returns an object with ``run(jobs, on_result)``.
        """
        if not isinstance(name, str) or not name.strip() or not callable(cls_or_factory):
            raise PluginError(
                f"add_executor needs a name and a class or callable factory, got {name!r}"
            )
        if name in self.executors:
            if self.executors[name].factory is not cls_or_factory:
                self._clash("executor", name, self.executors[name].source)
            return
        self.executors[name] = ExecutorEntry(name, cls_or_factory, self._current)

    def _add(self, kind: str, cls: Any) -> None:
        base = STAGE_BASES[kind]
        if not isinstance(cls, type) or not issubclass(cls, base):
            raise PluginError(
                f"add_{kind} expects a subclass of trackfw.stages.{base.__name__}, got {cls!r}"
            )
        if not isinstance(cls.name, str) or not cls.name.strip():
            raise PluginError(f"{cls.__qualname__} has no 'name'")
        if not (isinstance(cls.Params, type) and issubclass(cls.Params, StageParams)):
            raise PluginError(f"{cls.__qualname__}.Params must subclass trackfw.stages.StageParams")
        if getattr(cls, "__abstractmethods__", None):
            missing = ", ".join(sorted(cls.__abstractmethods__))
            raise PluginError(f"{cls.__qualname__} does not implement {missing}")
        undocumented = [n for n, f in cls.Params.model_fields.items() if not f.description]
        if undocumented:
            raise PluginError(
                f"{cls.__qualname__}.Params fields lack a description: {', '.join(undocumented)}"
            )
        key = (kind, cls.name)
        if key in self.stages:
            if self.stages[key].cls is not cls:
                self._clash(kind, cls.name, self.stages[key].source)
            return
        self.stages[key] = StageEntry(kind, cls.name, cls, self._current)

    def _clash(self, kind: str, name: str, kept: PluginSource) -> None:
        """Record that the plugin being loaded asked for a name ``kept`` already holds."""
        self.clashes.append(PluginClash(kind, name, self._current, kept))

    # -------------------------------------------------------------------------- lookup

    def names(self, kind: str) -> list[str]:
        """Registered names of one kind, sorted."""
        return sorted(name for (entry_kind, name) in self.stages if entry_kind == kind)

    def get(self, kind: str, name: str) -> StageEntry:
        """The entry for ``kind``/``name``; KeyError with close matches otherwise."""
        try:
            return self.stages[(kind, name)]
        except KeyError:
            raise KeyError(unknown_name_message(kind, name, self.names(kind))) from None

    def get_executor(self, name: str) -> ExecutorEntry:
        """The executor registered as ``name``; KeyError with close matches otherwise."""
        try:
            return self.executors[name]
        except KeyError:
            raise KeyError(unknown_name_message("executor", name, sorted(self.executors))) from None

    def build_stage(self, kind: str, spec: Mapping[str, Any]) -> Stage[Any]:
        """Build a stage from ``{"type": name, "params": {...}}`` (nested stages as in a pipeline).

        Raises:
            UserError: unknown type or bad parameters, one line per problem.
        """
        from trackfw.pipeline import resolve_stage  # the pipeline module imports this one

        problems: list[str] = []
        config = resolve_stage(self, kind, spec, kind, problems)
        if config is None:
            raise UserError(*problems)
        return config.build()


def stage_modules(package: str, *modules: str) -> Callable[[Registry], None]:
    """A ``trackfw_register_stages`` hook for a package with one stage class per module.

    Assign it in the plugin module: ``trackfw_register_stages = stage_modules(__name__, "a", "b")``.
    When the hook runs it imports ``package.a``, ``package.b`` (not before, so that loading the
    plugin stays cheap), then registers, module by module in the order given, each concrete stage
    class a module defines (a subclass of a :data:`trackfw.stages.STAGE_BASES` base) under the kind
    of its base.

    Args:
        package: the package holding the modules (``__name__`` of the plugin module).
        modules: module names inside ``package``.

    Returns:
        The hook implementation.
    """

    @hookspecs.hookimpl
    def trackfw_register_stages(registry: Registry) -> None:
        loaded = [importlib.import_module(f"{package}.{name}") for name in modules]
        for module in loaded:
            for cls in vars(module).values():
                if not isinstance(cls, type) or cls.__module__ != module.__name__:
                    continue
                for kind, base in STAGE_BASES.items():
                    if issubclass(cls, base) and not inspect.isabstract(cls):
                        registry._add(kind, cls)

    trackfw_register_stages.__doc__ = (
        f"Register the stage classes of {package}: {', '.join(modules)}."
    )
    return trackfw_register_stages


def unknown_name_message(kind: str, name: str, known: Iterable[str]) -> str:
    """``unknown detector 'orcale'; did you mean 'oracle'?`` with the list of valid names."""
    known = list(known)
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.5)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    valid = ", ".join(known) if known else "none registered"
    return f"unknown {kind.replace('_', ' ')} {quoted(name, 60)}{hint} (valid: {valid})"


def _identity(module: ModuleType) -> ModuleType:
    return module


def _source(entry_point: importlib.metadata.EntryPoint) -> PluginSource:
    distribution = getattr(entry_point, "dist", None)
    package = distribution.metadata["Name"] if distribution is not None else "<unknown>"
    version = distribution.version if distribution is not None else ""
    return PluginSource(entry_point.name, package, version)


def _one_line(error: BaseException) -> str:
    text = f"{type(error).__name__}: {error}".strip()
    return text.splitlines()[0] if text else type(error).__name__


def load_registry(
    extra_modules: Iterable[tuple[str, ModuleType]] = (), use_entry_points: bool = True
) -> Registry:
    """Discover every plugin and return the filled registry.

    Args:
        extra_modules: ``(name, module)`` pairs registered in addition to the entry points
            (tests, or a script embedding trackfw).
        use_entry_points: read the ``trackfw`` entry-point group.
    """
    manager = pluggy.PluginManager(hookspecs.PROJECT_NAME)
    manager.add_hookspecs(hookspecs)
    registry = Registry(plugin_manager=manager)
    for source, loader in _candidates(extra_modules, use_entry_points):
        _register_plugin(registry, manager, source, loader)

    for hook_name in (
        "trackfw_register_stages",
        "trackfw_register_inputs",
        "trackfw_register_executors",
    ):
        _call_each(manager, hook_name, registry, registry.sources)
    return registry


def _candidates(
    extra_modules: Iterable[tuple[str, ModuleType]], use_entry_points: bool
) -> list[tuple[PluginSource, Callable[[], ModuleType]]]:
    """Each plugin to load, with the call that imports it: entry points by name, then extras."""
    candidates: list[tuple[PluginSource, Callable[[], ModuleType]]] = []
    if use_entry_points:
        for entry_point in sorted(
            importlib.metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name
        ):
            candidates.append((_source(entry_point), entry_point.load))
    for name, module in extra_modules:
        candidates.append(
            (
                PluginSource(name, getattr(module, "__name__", name), ""),
                functools.partial(_identity, module),
            )
        )
    return candidates


def _register_plugin(
    registry: Registry,
    manager: pluggy.PluginManager,
    source: PluginSource,
    loader: Callable[[], ModuleType],
) -> None:
    """Import one plugin and register its hooks; a failure is recorded, never raised."""
    try:
        module = loader()
    except KeyboardInterrupt:
        raise
    except BaseException as error:  # a broken plugin must never break (nor end) the tool
        registry.failures.append(PluginFailure(source, f"import failed: {_one_line(error)}"))
        return
    api = getattr(module, "TRACKFW_PLUGIN_API", PLUGIN_API_VERSION)
    if api != PLUGIN_API_VERSION:
        registry.failures.append(
            PluginFailure(
                source, f"built for plugin API {api}, this trackfw speaks {PLUGIN_API_VERSION}"
            )
        )
        return
    plugin_name = f"{source.package}:{source.name}"
    if manager.is_registered(module) or manager.has_plugin(plugin_name):
        return
    try:
        manager.register(module, name=plugin_name)
    except Exception as error:
        registry.failures.append(PluginFailure(source, f"invalid hooks: {_one_line(error)}"))
        return
    registry.sources[plugin_name] = source


def _in_load_order(
    implementations: Iterable[HookImpl], sources: Mapping[str, PluginSource]
) -> list[HookImpl]:
    """Built-in plugins first, then the others in the order they loaded.

    pluggy calls the last registered plugin first; names are first come, first served, so the
    order is fixed here instead, and a plugin can never take a built-in name by loading early or
    late.
    """
    order = {name: index for index, name in enumerate(sources)}

    def key(implementation: HookImpl) -> tuple[bool, int]:
        source = sources.get(implementation.plugin_name)
        builtin = source is not None and source.builtin
        return (not builtin, order.get(implementation.plugin_name, len(order)))

    return sorted(implementations, key=key)


def _call_each(
    manager: pluggy.PluginManager,
    hook_name: str,
    registry: Registry,
    sources: dict[str, PluginSource],
) -> None:
    """Call each plugin's implementation on its own, so one failure stays with its plugin."""
    caller = getattr(manager.hook, hook_name)
    for implementation in _in_load_order(caller.get_hookimpls(), sources):
        source = sources.get(implementation.plugin_name)
        if source is None:
            continue
        registry._current = source
        snapshot = (
            dict(registry.stages),
            dict(registry.inputs),
            dict(registry.executors),
            list(registry.clashes),
        )
        try:
            implementation.function(registry=registry)
        except KeyboardInterrupt:
            raise
        except BaseException as error:  # SystemExit included: a plugin cannot end the tool
            # Roll back whatever this plugin registered before it failed: half a plugin is worse
            # than none.
            registry.stages, registry.inputs, registry.executors, registry.clashes = snapshot
            detail = _one_line(error)
            frames = traceback.extract_tb(error.__traceback__)
            if not isinstance(error, PluginError) and frames:
                detail += f" ({Path(frames[-1].filename).name}:{frames[-1].lineno})"
            registry.failures.append(PluginFailure(source, f"{hook_name} failed: {detail}"))
        finally:
            registry._current = PluginSource("<direct>", "<direct>", "")


def call_command_hooks(registry: Registry, app: Any) -> None:
    """Let every loaded plugin add its CLI commands; failures and name clashes are recorded.

    Built-in plugins go first. A command or group a plugin adds under a name that is already taken
    at that level (``run``, ``dataset``, ``train classifier``) is removed again and recorded in
    :attr:`Registry.clashes`: the earlier one keeps the name. A plugin whose hook fails (or exits)
    has everything it added removed.
    """
    if registry.plugin_manager is None:
        return
    core = PluginSource("core", BUILTIN_PACKAGE, __version__)
    owners: dict[int, tuple[Any, PluginSource]] = {}
    for _, entry, _ in _walk_commands(app):
        owners[id(entry)] = (entry, core)
    implementations = registry.plugin_manager.hook.trackfw_register_commands.get_hookimpls()
    for implementation in _in_load_order(implementations, registry.sources):
        name = implementation.plugin_name
        source = registry.sources.get(name) or PluginSource(name, name.split(":")[0], "")
        snapshot = [(holder, list(holder)) for holder in _command_lists(app)]
        try:
            implementation.function(app=app)
        except KeyboardInterrupt:
            raise
        except BaseException as error:  # SystemExit included: a plugin cannot end the tool
            for holder, content in snapshot:
                holder[:] = content
            registry.failures.append(
                PluginFailure(source, f"trackfw_register_commands failed: {_one_line(error)}")
            )
            continue
        _settle_commands(app, "", owners, source, registry.clashes)


def _command_name(info: Any) -> str:
    """The name typer gives a ``CommandInfo`` or a ``TyperInfo`` ('' for a nameless group)."""
    import typer.main

    name = getattr(info, "name", None)
    if getattr(info, "typer_instance", None) is not None:
        name = typer.main.solve_typer_info_defaults(info).name
    if isinstance(name, str) and name:
        return name
    callback = getattr(info, "callback", None)
    return typer.main.get_command_name(callback.__name__) if callable(callback) else ""


def _level(app: Any) -> list[tuple[str, Any, list[Any]]]:
    """``(name, entry, the list that holds it)`` for the commands and groups one level down.

    typer merges the commands of a group added without a name into its parent, so such a group's
    entries count at the parent's level.
    """
    entries: list[tuple[str, Any, list[Any]]] = []
    for info in app.registered_commands:
        entries.append((_command_name(info), info, app.registered_commands))
    for info in app.registered_groups:
        name = _command_name(info)
        if name or info.typer_instance is None:
            entries.append((name, info, app.registered_groups))
        else:
            entries.extend(_level(info.typer_instance))
    return entries


def _walk_commands(app: Any, path: str = "") -> list[tuple[str, Any, list[Any]]]:
    """Every command and group under ``app``, named by its full path (``train classifier``)."""
    found = []
    for name, entry, holder in _level(app):
        found.append((f"{path}{name}", entry, holder))
        instance = getattr(entry, "typer_instance", None)
        if instance is not None:
            found.extend(_walk_commands(instance, f"{path}{name} "))
    return found


def _command_lists(app: Any) -> list[list[Any]]:
    """The lists of commands and groups of ``app`` and every group under it."""
    lists = [app.registered_commands, app.registered_groups]
    for info in app.registered_groups:
        if info.typer_instance is not None:
            lists.extend(_command_lists(info.typer_instance))
    return lists


def _settle_commands(
    app: Any,
    path: str,
    owners: dict[int, tuple[Any, PluginSource]],
    source: PluginSource,
    clashes: list[PluginClash],
) -> None:
    """Remove what ``source`` just added under a taken name; take ownership of the rest."""

    def owner(entry: Any) -> PluginSource | None:
        known = owners.get(id(entry))
        return known[1] if known is not None and known[0] is entry else None

    level = _level(app)
    taken: dict[str, PluginSource] = {}
    for name, entry, _ in level:
        held_by = owner(entry)
        if held_by is not None:
            taken.setdefault(name, held_by)
    for name, entry, holder in level:
        if owner(entry) is None:
            if name in taken:
                holder.remove(entry)
                clashes.append(PluginClash("command", f"{path}{name}", source, taken[name]))
                continue
            owners[id(entry)] = (entry, source)
            taken[name] = source
        instance = getattr(entry, "typer_instance", None)
        if instance is not None:
            _settle_commands(instance, f"{path}{name} ", owners, source, clashes)


def params_schema(params_model: type[BaseModel]) -> list[tuple[str, str, str, str]]:
    """``(name, type, default, description)`` for every parameter of a stage."""
    rows = []
    for name, info in params_model.model_fields.items():
        annotation = info.annotation
        # Generic forms (Literal[...], list[int], X | None) print their arguments; plain classes
        # their name.
        plain = isinstance(annotation, type) and not typing.get_args(annotation)
        type_name = (
            annotation.__name__
            if plain and annotation is not None
            else str(annotation).replace("typing.", "")
        )
        default = (
            "required" if info.is_required() else repr(info.get_default(call_default_factory=True))
        )
        rows.append((name, type_name, default, info.description or ""))
    return rows


__all__ = [
    "BUILTIN_PACKAGE",
    "ENTRY_POINT_GROUP",
    "ExecutorEntry",
    "InputEntry",
    "PluginClash",
    "PluginFailure",
    "PluginSource",
    "Registry",
    "StageEntry",
    "ValidationError",
    "load_registry",
    "params_schema",
    "unknown_name_message",
]
