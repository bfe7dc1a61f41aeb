"""The plugin registry: stage classes and named inputs, found through pluggy and entry points.

Built-in and third-party plugins load the same way: every module named in the ``trackfw``
entry-point group is registered with a :class:`pluggy.PluginManager`, then each implementation of
:func:`trackfw.hookspecs.trackfw_register_stages` is called with the :class:`Registry`. A plugin
whose import raises, that declares another plugin API version, or that registers something that
is not a proper stage class is recorded in :attr:`Registry.failures` and skipped; the rest of the
tool keeps working.
"""

from __future__ import annotations

import difflib
import functools
import importlib.metadata
import traceback
import typing
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import pluggy
from pydantic import BaseModel, ValidationError

from trackfw import PLUGIN_API_VERSION, hookspecs
from trackfw.errors import PluginError
from trackfw.stages import STAGE_BASES, Stage, StageParams

ENTRY_POINT_GROUP = "trackfw"


@dataclass(frozen=True)
class PluginSource:
    """Where a plugin comes from: entry-point name, distribution and version."""

    name: str
    package: str
    version: str


@dataclass(frozen=True)
class StageEntry:
    """A registered stage class."""

    kind: str
    name: str
    cls: type[Stage]
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


@dataclass
class Registry:
    """Every stage class and named input known to trackfw.

    Plugins receive the registry in their ``trackfw_register_stages`` hook and call
    ``add_detector``, ``add_classifier``, ``add_tracker``, ``add_gap_matcher``, ``add_predictor``;
    in ``trackfw_register_executors`` they call ``add_executor``.
    """

    stages: dict[tuple[str, str], StageEntry] = field(default_factory=dict)
    inputs: dict[str, InputEntry] = field(default_factory=dict)
    executors: dict[str, ExecutorEntry] = field(default_factory=dict)
    failures: list[PluginFailure] = field(default_factory=list)
    plugin_manager: pluggy.PluginManager | None = None
    #: pluggy plugin name -> where it came from, for every plugin that loaded.
    sources: dict[str, PluginSource] = field(default_factory=dict)
    _current: PluginSource = field(default=PluginSource("<direct>", "<direct>", ""), repr=False)

    # -------------------------------------------------------------------------- registration

    def add_detector(self, cls: type[Stage]) -> None:
        """Register a :class:`trackfw.stages.Detector` subclass."""
        self._add("detector", cls)

    def add_classifier(self, cls: type[Stage]) -> None:
        """Register a :class:`trackfw.stages.Classifier` subclass."""
        self._add("classifier", cls)

    def add_tracker(self, cls: type[Stage]) -> None:
        """Register a :class:`trackfw.stages.Tracker` subclass."""
        self._add("tracker", cls)

    def add_gap_matcher(self, cls: type[Stage]) -> None:
        """Register a :class:`trackfw.stages.GapMatcher` subclass."""
        self._add("gap_matcher", cls)

    def add_predictor(self, cls: type[Stage]) -> None:
        """Register a :class:`trackfw.stages.Predictor` subclass."""
        self._add("predictor", cls)

    def add_input(self, name: str, factory: Callable[[], Path], description: str = "") -> None:
        """Register a named input (``input: builtin:NAME`` in a pipeline)."""
        if not name or not callable(factory):
            raise PluginError(f"add_input needs a name and a callable factory, got {name!r}")
        if name in self.inputs:
            raise PluginError(
                f"input {name!r} is already registered by {self.inputs[name].source.package}"
            )
        self.inputs[name] = InputEntry(name, factory, description, self._current)

    def add_executor(self, name: str, cls_or_factory: Callable[..., Any]) -> None:
        """Register an executor for ``trackfw bench --executor NAME``.

        ``cls_or_factory(options)`` gets a :class:`trackfw.bench.executor.ExecutorOptions` and
        returns an object with ``run(jobs, on_result)``.
        """
        if not isinstance(name, str) or not name.strip() or not callable(cls_or_factory):
            raise PluginError(
                f"add_executor needs a name and a class or callable factory, got {name!r}"
            )
        if name in self.executors and self.executors[name].factory is not cls_or_factory:
            raise PluginError(
                f"executor {name!r} is already registered by {self.executors[name].source.package}"
            )
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
        if key in self.stages and self.stages[key].cls is not cls:
            other = self.stages[key].source.package
            raise PluginError(f"{kind} {cls.name!r} is already registered by {other}")
        self.stages[key] = StageEntry(kind, cls.name, cls, self._current)

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

    def build_stage(self, kind: str, spec: Mapping[str, Any]) -> Stage:
        """Build a stage from ``{"type": name, "params": {...}}`` (nested stages inline).

        Raises:
            KeyError: unknown type. ValidationError: bad parameters.
        """
        entry = self.get(kind, str(spec.get("type")))
        params = dict(spec.get("params") or {})
        nested: dict[str, Stage] = {}
        for key, nested_kind in entry.cls.nested.items():
            nested_spec = dict(params.pop(key, None) or {"type": _default_nested(entry.cls, key)})
            nested_type = nested_spec.pop("type", None)
            nested[key] = self.build_stage(
                nested_kind, {"type": nested_type, "params": nested_spec}
            )
        return entry.cls(entry.cls.Params(**params), **nested)


def _default_nested(cls: type[Stage], key: str) -> str:
    default = getattr(cls, f"default_{key}", None)
    if not isinstance(default, str):
        raise KeyError(f"{cls.name!r} needs a {key!r} with a 'type'")
    return default


def unknown_name_message(kind: str, name: str, known: Iterable[str]) -> str:
    """``unknown detector 'orcale'; did you mean 'oracle'?`` with the list of valid names."""
    known = list(known)
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.5)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    valid = ", ".join(known) if known else "none registered"
    return f"unknown {kind.replace('_', ' ')} {name!r}{hint} (valid: {valid})"


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
    sources = registry.sources

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

    for source, loader in candidates:
        try:
            module = loader()
        except Exception as error:  # a broken plugin must never break the tool
            registry.failures.append(PluginFailure(source, f"import failed: {_one_line(error)}"))
            continue
        api = getattr(module, "TRACKFW_PLUGIN_API", PLUGIN_API_VERSION)
        if api != PLUGIN_API_VERSION:
            registry.failures.append(
                PluginFailure(
                    source, f"built for plugin API {api}, this trackfw speaks {PLUGIN_API_VERSION}"
                )
            )
            continue
        plugin_name = f"{source.package}:{source.name}"
        if manager.is_registered(module) or manager.has_plugin(plugin_name):
            continue
        try:
            manager.register(module, name=plugin_name)
        except Exception as error:
            registry.failures.append(PluginFailure(source, f"invalid hooks: {_one_line(error)}"))
            continue
        sources[plugin_name] = source

    for hook_name in (
        "trackfw_register_stages",
        "trackfw_register_inputs",
        "trackfw_register_executors",
    ):
        _call_each(manager, hook_name, registry, sources)
    return registry


def _call_each(
    manager: pluggy.PluginManager,
    hook_name: str,
    registry: Registry,
    sources: dict[str, PluginSource],
) -> None:
    """Call each plugin's implementation on its own, so one failure stays with its plugin."""
    caller = getattr(manager.hook, hook_name)
    for implementation in caller.get_hookimpls():
        source = sources.get(implementation.plugin_name)
        if source is None:
            continue
        registry._current = source
        snapshot = (dict(registry.stages), dict(registry.inputs), dict(registry.executors))
        try:
            implementation.function(registry=registry)
        except Exception as error:
            # Roll back whatever this plugin registered before it failed: half a plugin is worse
            # than none.
            registry.stages, registry.inputs, registry.executors = snapshot
            detail = _one_line(error)
            if not isinstance(error, PluginError):
                frame = traceback.extract_tb(error.__traceback__)[-1]
                detail += f" ({Path(frame.filename).name}:{frame.lineno})"
            registry.failures.append(PluginFailure(source, f"{hook_name} failed: {detail}"))
        finally:
            registry._current = PluginSource("<direct>", "<direct>", "")


def call_command_hooks(registry: Registry, app: Any) -> None:
    """Let every loaded plugin add its CLI commands; failures are recorded, not raised."""
    if registry.plugin_manager is None:
        return
    for implementation in registry.plugin_manager.hook.trackfw_register_commands.get_hookimpls():
        try:
            implementation.function(app=app)
        except Exception as error:
            name = implementation.plugin_name
            source = registry.sources.get(name) or PluginSource(name, name.split(":")[0], "")
            registry.failures.append(
                PluginFailure(source, f"trackfw_register_commands failed: {_one_line(error)}")
            )


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
    "ENTRY_POINT_GROUP",
    "ExecutorEntry",
    "InputEntry",
    "PluginFailure",
    "PluginSource",
    "Registry",
    "StageEntry",
    "ValidationError",
    "load_registry",
    "params_schema",
    "unknown_name_message",
]
