"""benchmarks/wear_sets.py: the 27 TUD wear sets and the table of their bench runs."""

from __future__ import annotations

import doctest
from pathlib import Path
from types import ModuleType

import pytest

from .conftest import load_script


def _script() -> ModuleType:
    return load_script("wear_sets")


def _bench(out: Path, rows: dict[str, tuple[float, float]]) -> None:
    """A bench folder's table.csv with MOTA / MOTA-In per pipeline (info-less 99 / 100 %)."""
    out.mkdir(parents=True)
    lines = [
        "pipeline,pipeline_hash,videos_done,videos_total,MOTA,MOTA-In,IL-Precision,IL-Recall,Captured-%"
    ]
    lines += [
        f"{name},h,16,16,{mota},{mota_in},99.0,100.0,2.5" for name, (mota, mota_in) in rows.items()
    ]
    (out / "table.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_doctests() -> None:
    result = doctest.testmod(_script())
    assert result.attempted > 0 and result.failed == 0


def test_set_names_parse_to_their_sequence_seed_and_targets() -> None:
    script = _script()
    names = script.set_names()
    assert len(set(names)) == 27
    assert script._parse("S101-St-2") == (101, "TUD-Stadtmitte", 2)
    assert script._parse("S21-Campus") == (21, "TUD-Campus", None)
    assert sum(name.endswith("-2") for name in names) == 14


def test_table_marks_the_targets_the_floor_and_the_change(tmp_path: Path) -> None:
    script = _script()
    _bench(tmp_path / "new" / "S21-St", {"real": (80.0, 65.0), "real-tr": (79.0, 66.0)})
    _bench(tmp_path / "new" / "S21-Campus", {"real": (70.0, 61.0), "real-tr": (70.0, 61.0)})
    _bench(tmp_path / "old" / "S21-St", {"real": (78.0, 60.0)})
    _bench(tmp_path / "old" / "S21-Campus", {"real": (71.0, 62.0)})
    names = ["S21-St", "S21-Campus", "S31-St"]  # S31-St was not run: left out
    text = script.table(tmp_path / "new", ["real", "real-tr"], names, tmp_path / "old")
    rows = {
        line.split(" | ")[0].strip("| "): line
        for line in text.splitlines()
        if line.startswith("| S")
    }
    assert set(rows) == {"S21-St", "S21-Campus"}
    assert rows["S21-St"].endswith(
        "| 78.0 / 60.0 | 80.0 / 65.0 | 79.0 / 66.0 | 0.990 / 1.000 | 2.5 | yes | **no** |"
    )
    assert rows["S21-Campus"].endswith("| **no** | yes |")
    assert "real: 75 / 60 met on 1 of 2 sets; MOTA-In >= real-tr on 1 of 2" in text
    assert "mean +0.50 / +2.00 over 2 sets, MOTA-In up on 1, down on 1" in text


def test_an_unknown_set_name_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stopped:
        _script().main(["table", "--out", "x", "--only", "S22-St"])
    assert stopped.value.code == 2
    assert "unknown set(s) S22-St" in capsys.readouterr().err
