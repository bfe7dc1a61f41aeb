"""The real console script in a fresh virtual environment made by ``pip install .`` alone.

The test and dev extras bring packages the plain install does not have (click used to be one, via
typer < 0.26); only a fresh environment shows what a new user gets. The wheels come from a folder
in pytest's cache, filled from the package index the first time (or when a dependency changes),
so later runs need no network (about 45 s for the install on an idle machine, mostly pip
unpacking the wheels).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

PIPELINE = textwrap.dedent(
    """\
    name: fresh
    stages:
      detector:    {type: oracle}
      classifier:  {type: oracle}
      tracker:     {type: kalman, params: {association: hungarian}}
      gap_matcher: {type: assignment, params: {method: hungarian, predictor: {type: kalman}}}
    """
)


def _pip(python: Path | str, *arguments: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(python), "-m", "pip", "--disable-pip-version-check", *map(str, arguments)],
        capture_output=True,
        text=True,
        check=False,
    )


@pytest.fixture(scope="session")
def fresh_trackfw(tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest) -> Path:
    """The ``trackfw`` console script of a fresh venv where only ``pip install .`` ran."""
    root = tmp_path_factory.mktemp("fresh-install")
    # A clean copy of what `pip install .` packages: no build/, egg-info or caches of this tree.
    source = root / "source"
    source.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md"):
        shutil.copy2(REPO / name, source / name)
    for folder in ("framework", "plugins"):
        shutil.copytree(
            REPO / folder,
            source / folder,
            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info", "build"),
        )
    # The pytest cache keeps the wheels between sessions; without it (-p no:cacheprovider)
    # this session's own folder does.
    cache = getattr(request.config, "cache", None)
    wheelhouse = (
        cache.mkdir("trackfw-wheelhouse")
        if cache is not None
        else tmp_path_factory.mktemp("trackfw-wheelhouse")
    )
    venv = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    python = venv / "bin" / "python"
    # --no-index: everything, the build backend included, from the wheelhouse; --no-compile skips
    # byte-compiling some 200 MB of dependencies (a third of the time, and nothing to check).
    install = ("install", "-q", "--no-compile", "--no-index", "--find-links", wheelhouse, source)
    result = _pip(python, *install)
    if result.returncode != 0:
        filled = _pip(sys.executable, "download", "-q", "-d", wheelhouse, "setuptools>=68", "wheel")
        if filled.returncode == 0:
            filled = _pip(sys.executable, "wheel", "-q", "-w", wheelhouse, source)
        for built in wheelhouse.glob("trackfw-*.whl"):
            built.unlink()  # this tree's own wheel: built afresh by every install
        if filled.returncode != 0:
            pytest.skip(f"cannot fetch the dependencies' wheels: {filled.stderr.strip()[-300:]}")
        result = _pip(python, *install)
    assert result.returncode == 0, result.stderr
    script = venv / "bin" / "trackfw"
    assert script.is_file()
    return script


def _trackfw(script: Path, cwd: Path, *arguments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(script), *arguments], cwd=cwd, capture_output=True, text=True, timeout=120
    )


@pytest.mark.slow
def test_the_issue_cases_exit_2_with_one_line_in_a_plain_install(
    fresh_trackfw: Path, tmp_path: Path
) -> None:
    (tmp_path / "pipeline.yaml").write_text(PIPELINE, encoding="utf-8")
    (tmp_path / "results.txt").write_text("keep\n", encoding="utf-8")
    (tmp_path / "clip.mp4").write_text("this is text, not a video\n", encoding="utf-8")
    cases = {
        ("frobnicate",): "No such command 'frobnicate'",
        ("run",): "Missing argument",
        ("run", "pipeline.yaml", "--output", "results.txt"): "results.txt is an existing file",
        ("run", "pipeline.yaml", "--input", "clip.mp4"): "clip.mp4: not a video",
    }
    for arguments, fragment in cases.items():
        result = _trackfw(fresh_trackfw, tmp_path, *arguments)
        lines = result.stderr.splitlines()
        assert result.returncode == 2, (arguments, result.stderr)
        assert "Traceback" not in result.stderr, (arguments, result.stderr)
        assert len(lines) == 1 and lines[0].startswith("error: "), (arguments, result.stderr)
        assert fragment in lines[0], (arguments, lines[0])
        assert result.stdout == "", (arguments, result.stdout)
    assert (tmp_path / "results.txt").read_text(encoding="utf-8") == "keep\n"
    assert not (tmp_path / "runs").exists()


@pytest.mark.slow
def test_every_plugin_loads_and_runs_in_a_plain_install(
    fresh_trackfw: Path, tmp_path: Path
) -> None:
    # A plugin importing a package that only an extra provides fails to load here.
    import json

    listing = _trackfw(fresh_trackfw, tmp_path, "plugins", "--json")
    assert listing.returncode == 0, listing.stderr
    data = json.loads(listing.stdout)
    assert data["failures"] == []
    assert {stage["kind"] for stage in data["stages"]} >= {
        "detector",
        "classifier",
        "tracker",
        "gap_matcher",
    }
    # A run end to end: stages import some packages only when they run.
    from trackfw_plugins.datasets.points import make_points_video

    make_points_video(tmp_path / "video", n_frames=60, intervals=((20, 30),))
    (tmp_path / "pipeline.yaml").write_text(PIPELINE, encoding="utf-8")
    arguments = ("run", "pipeline.yaml", "--input", "video", "--output", "out", "--quiet")
    run = _trackfw(fresh_trackfw, tmp_path, *arguments)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "out" / "video" / "summary.json").is_file()


@pytest.mark.slow
def test_the_plain_install_carries_the_models_and_their_licences(
    fresh_trackfw: Path, tmp_path: Path
) -> None:
    """Every shipped model, licence text and NOTICE is in the wheel, byte for byte (no download)."""
    import hashlib
    import json

    packages = ("detectors", "maths", "classifiers")
    listing = textwrap.dedent(
        f"""\
        import hashlib, json
        from importlib import resources
        print(json.dumps({{
            package: {{
                item.name: hashlib.sha256(item.read_bytes()).hexdigest()
                for item in resources.files("trackfw_plugins." + package).joinpath("models").iterdir()
                if item.is_file() and not item.name.endswith((".py", ".pyc"))
            }}
            for package in {packages!r}
        }}))
        """
    )
    python = fresh_trackfw.parent / "python"
    result = subprocess.run(
        [str(python), "-c", listing], cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    installed = json.loads(result.stdout)
    for package in packages:
        folder = REPO / "plugins" / package / "models"
        shipped = {
            path.name: hashlib.sha256(path.read_bytes()).hexdigest()
            for path in folder.iterdir()
            if path.is_file() and path.suffix not in (".py", ".pyc")
        }
        assert installed[package] == shipped, package
    names = set(installed["detectors"]) | set(installed["maths"])
    assert {"yolox_nano_416_coco.onnx", "light_person_detector_192.onnx"} <= names
    assert {"person-reidentification-retail-0287.onnx", "NOTICE"} <= names
    assert sum(name.endswith("LICENSE-Apache-2.0") for name in names) >= 3
    # The real-footage pipeline loads its models (and checks their shapes) from the install.
    check = _trackfw(fresh_trackfw, tmp_path, "validate", str(REPO / "pipelines" / "real.yaml"))
    assert check.returncode == 0, check.stderr
