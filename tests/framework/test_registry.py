"""Plugin discovery: entry points, third-party plugins, broken plugins, documented hooks."""

from __future__ import annotations

import inspect
import json
import shutil
import textwrap
from pathlib import Path
from types import ModuleType

import pytest

from trackfw import hookspecs
from trackfw.cli import main
from trackfw.hookspecs import hookimpl
from trackfw.registry import Registry, load_registry
from trackfw.stages import Detector

REPO = Path(__file__).resolve().parents[2]


def _install_dist(
    site: Path,
    name: str,
    module: str,
    module_source: str | None = None,
    package_dir: Path | None = None,
) -> None:
    """Make an installed-looking distribution (dist-info + entry_points.txt) under ``site``."""
    dist_info = site / f"{name.replace('-', '_')}-0.1.0.dist-info"
    dist_info.mkdir(parents=True)
    (dist_info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1.0\n")
    (dist_info / "entry_points.txt").write_text(f"[trackfw]\n{name} = {module}\n")
    if package_dir is not None:
        shutil.copytree(package_dir, site / module)
    elif module_source is not None:
        (site / f"{module}.py").write_text(module_source)


def test_builtins_register_through_entry_points() -> None:
    registry = load_registry()
    assert not registry.failures, registry.failures
    entry = registry.get("tracker", "kalman")
    assert entry.source.package == "trackfw" and entry.source.name == "trackers"
    for kind in ("detector", "classifier", "tracker", "gap_matcher", "predictor"):
        assert registry.names(kind), kind


def test_third_party_plugin_is_listed_and_runs(tmp_path: Path, monkeypatch, capsys) -> None:
    site = tmp_path / "site"
    _install_dist(
        site,
        "trackfw-hello",
        "trackfw_hello",
        package_dir=REPO / "examples" / "plugin-template" / "trackfw_hello",
    )
    monkeypatch.syspath_prepend(str(site))
    registry = load_registry()
    entry = registry.get("detector", "centre")
    assert entry.source.package == "trackfw-hello" and entry.source.version == "0.1.0"
    assert main(["plugins", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    assert any(s["name"] == "centre" and s["package"] == "trackfw-hello" for s in listing["stages"])

    from trackfw_plugins.datasets.points import make_points_video

    video = make_points_video(tmp_path / "v", n_frames=20, intervals=[])
    pipeline = tmp_path / "p.yaml"
    pipeline.write_text(
        textwrap.dedent(
            """\
            name: hello
            stages:
              detector: {type: centre, params: {count: 2}}
              classifier: {type: oracle}
              tracker: {type: kalman}
              gap_matcher: {type: assignment}
            """
        )
    )
    out = tmp_path / "out"
    assert main(["run", str(pipeline), "--input", str(video), "--output", str(out), "--quiet"]) == 0
    frames = (out / "v" / "frames.csv").read_text().splitlines()
    assert frames[1].split(",")[4] == "2"  # two detections from the third-party detector


def test_broken_plugin_is_reported_and_does_not_stop_the_cli(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    site = tmp_path / "site"
    _install_dist(
        site, "trackfw-broken", "trackfw_broken", "raise RuntimeError('boom at import')\n"
    )
    _install_dist(
        site,
        "trackfw-garbage",
        "trackfw_garbage",
        "from trackfw.hookspecs import hookimpl\n\n@hookimpl\ndef trackfw_register_stages(registry):\n    registry.add_detector(object)\n",
    )
    _install_dist(site, "trackfw-future", "trackfw_future", "TRACKFW_PLUGIN_API = 99\n")
    monkeypatch.syspath_prepend(str(site))
    registry = load_registry()
    errors = {failure.source.package: failure.error for failure in registry.failures}
    assert "boom at import" in errors["trackfw-broken"]
    assert "expects a subclass" in errors["trackfw-garbage"]
    assert "plugin API 99" in errors["trackfw-future"]
    assert registry.names("tracker") == ["kalman"]
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert "failed to load" in out and "boom at import" in out

    from trackfw_plugins.datasets.points import make_points_video

    video = make_points_video(tmp_path / "v", n_frames=20, intervals=[])
    pipeline = REPO / "pipelines" / "kalman1-tr-oracle.yaml"
    output = tmp_path / "o"
    assert main(["run", str(pipeline), "--input", str(video), "--output", str(output), "-q"]) == 0


def test_failed_registration_is_rolled_back() -> None:
    class Good(Detector):
        """A fine detector."""

        name = "good"

        def detect(self, frame):  # type: ignore[no-untyped-def]
            raise NotImplementedError

    module = ModuleType("half")

    @hookimpl
    def trackfw_register_stages(registry: Registry) -> None:
        registry.add_detector(Good)
        raise ValueError("second half failed")

    module.trackfw_register_stages = trackfw_register_stages  # type: ignore[attr-defined]
    registry = load_registry(extra_modules=[("half", module)])
    assert ("detector", "good") not in registry.stages
    assert any("second half failed" in f.error for f in registry.failures)


def test_stage_modules_registers_the_classes_each_module_defines_in_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    package = tmp_path / "many_stages"
    package.mkdir()
    (package / "__init__.py").write_text(
        "from trackfw.registry import stage_modules\n"
        "trackfw_register_stages = stage_modules(__name__, 'second', 'first')\n"
    )
    detector = textwrap.dedent(
        """\
        from trackfw.stages import Detector, Predictor


        class {cls}(Detector):
            name = "{name}"

            def detect(self, frame):
                return None
        """
    )
    (package / "first.py").write_text(detector.format(cls="First", name="first"))
    (package / "other.py").write_text(detector.format(cls="Other", name="other"))
    # An imported stage class and an abstract one are not the module's own stages.
    (package / "second.py").write_text(
        detector.format(cls="Second", name="second")
        + "from many_stages.other import Other\n\n\nclass Half(Predictor):\n    name = 'half'\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    import many_stages

    registry = load_registry(extra_modules=[("many", many_stages)], use_entry_points=False)
    assert not registry.failures, registry.failures
    assert list(registry.stages) == [("detector", "second"), ("detector", "first")]
    assert "many_stages: second, first" in many_stages.trackfw_register_stages.__doc__


def test_undocumented_parameters_are_refused() -> None:
    from pydantic import Field

    from trackfw.errors import PluginError
    from trackfw.stages import StageParams

    class Params(StageParams):
        value: int = Field(1)

    class Undocumented(Detector):
        name = "undocumented"

        def detect(self, frame):  # type: ignore[no-untyped-def]
            raise NotImplementedError

    Undocumented.Params = Params
    with pytest.raises(PluginError, match="lack a description: value"):
        Registry().add_detector(Undocumented)


def test_every_hook_is_documented() -> None:
    page = (REPO / "docs" / "plugins.md").read_text()
    hooks = [
        name
        for name, value in inspect.getmembers(hookspecs)
        if name.startswith("trackfw_") and callable(value)
    ]
    assert hooks
    for name in hooks:
        assert f"### {name}" in page, f"hook {name} is missing from docs/plugins.md"
        assert inspect.getdoc(getattr(hookspecs, name)), f"hook {name} has no docstring"


def test_every_registered_stage_documents_itself() -> None:
    registry = load_registry()
    for entry in registry.stages.values():
        assert entry.cls.summary(), f"{entry.kind} {entry.name} has no docstring"


# A third-party plugin that claims the built-in detector's name, plus one name of its own.
_CLAIMS_EDGEBOX = """\
from trackfw.hookspecs import hookimpl
from trackfw.stages import Detector


class Impostor(Detector):
    \"\"\"Claims to be edgebox-cnn.\"\"\"

    name = "edgebox-cnn"

    def detect(self, frame):
        raise NotImplementedError


class Own(Detector):
    \"\"\"A detector under a name nobody else uses.\"\"\"

    name = "{own}"

    def detect(self, frame):
        raise NotImplementedError


@hookimpl
def trackfw_register_stages(registry):
    registry.add_detector(Impostor)
    registry.add_detector(Own)
"""


@pytest.mark.parametrize("entry_point", ["aaa-first", "zzz-last"])
def test_a_plugin_cannot_take_a_built_in_stage_name(
    entry_point: str, tmp_path: Path, monkeypatch, capsys
) -> None:
    """Built-ins win whatever the entry-point order; the plugin's other stages still register."""
    builtin_detectors = load_registry().names("detector")
    site = tmp_path / "site"
    _install_dist(site, "trackfw-impostor", "trackfw_impostor", _CLAIMS_EDGEBOX.format(own="own"))
    # The entry point's name decides the load order: both sides of the built-ins' names.
    entry_points = site / "trackfw_impostor-0.1.0.dist-info" / "entry_points.txt"
    entry_points.write_text(f"[trackfw]\n{entry_point} = trackfw_impostor\n")
    monkeypatch.syspath_prepend(str(site))

    registry = load_registry()
    assert registry.get("detector", "edgebox-cnn").source.package == "trackfw"
    assert registry.names("detector") == sorted([*builtin_detectors, "own"])
    assert registry.get("detector", "own").source.package == "trackfw-impostor"
    assert not registry.failures, registry.failures

    assert main(["plugins", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    assert listing["clashes"] == [
        {
            "kind": "detector",
            "name": "edgebox-cnn",
            "package": "trackfw-impostor",
            "plugin": entry_point,
            "kept": "trackfw",
        }
    ]
    assert main(["plugins"]) == 0
    text = capsys.readouterr().out
    assert "edgebox-cnn" in text and "trackfw-impostor" in text and "ignored" in text, text


def test_two_plugins_claiming_one_name_keep_the_first_and_report_the_second(
    tmp_path: Path, monkeypatch
) -> None:
    source = _CLAIMS_EDGEBOX.replace('"edgebox-cnn"', '"shared-name"')
    site = tmp_path / "site"
    _install_dist(site, "trackfw-one", "trackfw_one", source.format(own="one-own"))
    _install_dist(site, "trackfw-two", "trackfw_two", source.format(own="two-own"))
    monkeypatch.syspath_prepend(str(site))
    registry = load_registry()
    assert registry.get("detector", "shared-name").source.package == "trackfw-one"
    assert {"one-own", "two-own"} <= set(registry.names("detector"))
    assert [(c.source.package, c.name, c.kept.package) for c in registry.clashes] == [
        ("trackfw-two", "shared-name", "trackfw-one")
    ]


_CLAIMS_RUN = """\
import typer

from trackfw.hookspecs import hookimpl


def hijacked(pipeline: str) -> None:
    print("HIJACKED")
    raise typer.Exit(7)


@hookimpl
def trackfw_register_commands(app):
    app.command("run")(hijacked)
    app.command("hello")(lambda: print("hello from a plugin"))
"""


def test_a_plugin_cannot_replace_a_built_in_command(tmp_path: Path, monkeypatch, capsys) -> None:
    site = tmp_path / "site"
    _install_dist(site, "trackfw-hijack", "trackfw_hijack", _CLAIMS_RUN)
    monkeypatch.syspath_prepend(str(site))
    from trackfw_plugins.datasets.points import make_points_video

    video = make_points_video(tmp_path / "v", n_frames=20, intervals=[])
    pipeline = REPO / "pipelines" / "kalman1-tr-oracle.yaml"
    out = tmp_path / "o"
    code = main(["run", str(pipeline), "--input", str(video), "--output", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert code == 0 and "HIJACKED" not in captured.out, captured
    assert (out / "v" / "summary.json").is_file()
    # The plugin's other command is kept.
    assert main(["hello"]) == 0
    assert "hello from a plugin" in capsys.readouterr().out
    assert main(["plugins", "--json"]) == 0
    clashes = json.loads(capsys.readouterr().out)["clashes"]
    assert clashes == [
        {
            "kind": "command",
            "name": "run",
            "package": "trackfw-hijack",
            "plugin": "trackfw-hijack",
            "kept": "trackfw",
        }
    ]


@pytest.mark.parametrize(
    "module_source",
    [
        "import sys\nsys.exit(3)\n",
        "from trackfw.hookspecs import hookimpl\n\n@hookimpl\n"
        "def trackfw_register_stages(registry):\n    raise SystemExit(3)\n",
        "from trackfw.hookspecs import hookimpl\n\n@hookimpl\n"
        "def trackfw_register_commands(app):\n    raise SystemExit(3)\n",
    ],
    ids=["at-import", "in-register-stages", "in-register-commands"],
)
def test_a_plugin_that_exits_does_not_end_every_command(
    module_source: str, tmp_path: Path, monkeypatch, capsys
) -> None:
    site = tmp_path / "site"
    _install_dist(site, "trackfw-quitter", "trackfw_quitter", module_source)
    monkeypatch.syspath_prepend(str(site))
    assert main(["--help"]) == 0
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert "trackfw-quitter" in out and "SystemExit: 3" in out, out
    assert main(["validate", str(REPO / "pipelines" / "kalman1-tr-oracle.yaml")]) == 0
