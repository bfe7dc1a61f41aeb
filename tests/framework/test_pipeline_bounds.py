"""Pipelines that try to exhaust the machine: YAML alias bombs and what error messages quote."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from trackfw.cli import main
from trackfw.errors import UserError
from trackfw.pipeline import parse_assignments
from trackfw.yaml_loading import parse_yaml

#: Each level repeats the previous one nine times: LEVELS levels expand to 9**LEVELS scalars.
BOMB_LEVELS = 9
VALID_STAGES = textwrap.dedent(
    """\
    stages:
      detector:    {type: oracle}
      classifier:  {type: oracle}
      tracker:     {type: kalman}
      gap_matcher: {type: assignment}
    """
)


def _alias_bomb(levels: int) -> str:
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for level in range(1, levels):
        previous = f"*a{level - 1}"
        lines.append(f"a{level}: &a{level} [{', '.join([previous] * 9)}]")
    return "\n".join(lines) + "\n"


def _bomb_pipeline(tmp_path: Path, levels: int) -> Path:
    # The anchors sit in the description, the one free-text field.
    body = textwrap.indent(_alias_bomb(levels), "  ")
    path = tmp_path / "bomb.yaml"
    path.write_text(f"name: bomb\ndescription:\n{body}{VALID_STAGES}", encoding="utf-8")
    return path


def test_moderate_alias_expansion_is_rejected_in_one_short_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # 9**6 = 531441 scalars: small enough to run before the fix, large enough to be refused.
    path = _bomb_pipeline(tmp_path, 6)
    assert main(["validate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and len(lines[0]) < 400, (len(lines), len(lines[0]))
    assert str(path) in lines[0] and "alias" in lines[0]


def test_full_alias_bomb_is_refused_quickly_within_bounded_memory(tmp_path: Path) -> None:
    # 9**9 (387 million) scalars: formatting that took 41 s and 3 GB before it died.
    path = _bomb_pipeline(tmp_path, BOMB_LEVELS)
    script = textwrap.dedent(
        f"""\
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (1 << 31, 1 << 31))  # 2 GiB
        from trackfw.cli import main
        sys.exit(main(["validate", {str(path)!r}]))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 2, done.stderr[-2000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "alias" in lines[0] and len(lines[0]) < 400, lines


def test_plain_anchors_and_aliases_still_work() -> None:
    data = parse_yaml("base: &b {gate: 40}\nuse: *b\nlist: [*b, *b]\n", "x.yaml")
    assert data["use"] == {"gate": 40} and data["list"] == [{"gate": 40}, {"gate": 40}]


def test_set_values_are_bounded_too() -> None:
    bomb = "[" + ", ".join(["&x [1, 1, 1, 1, 1, 1, 1, 1, 1]"] + ["*x"] * 3) + "]"
    assert parse_assignments([f"k={bomb}"], "--set")["k"][1] == [1] * 9
    deep = "&a0 [1,1,1,1,1,1,1,1,1]"
    text = (
        "["
        + deep
        + "".join(f", &a{i} [{', '.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 7))
        + "]"
    )
    with pytest.raises(UserError, match="alias"):
        parse_assignments([f"k={text}"], "--set")


def test_error_messages_quote_long_values_cut_short(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    long_list = "[" + ", ".join(str(i) for i in range(5000)) + "]"
    path = tmp_path / "long.yaml"
    path.write_text(f"name: long\ndescription: {long_list}\n{VALID_STAGES}", encoding="utf-8")
    assert main(["validate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "description: expected a string" in lines[0]
    assert len(lines[0]) < 400 and "..." in lines[0], lines[0][:500]
