"""Bad batch-tracker parameters are one-line errors of ``trackfw validate`` (exit code 2).

Negative costs, a zero window, K < 1 and non-finite values, for every batch tracker.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from trackfw.cli import main

CASES = [
    ("dpnms", "birth_cost", "-1", "expected greater than or equal to 0, got -1"),
    ("dpnms", "betta", "-0.2", "expected greater than or equal to 0"),
    ("dpnms", "stop_cost", ".inf", "expected a finite number, got inf"),
    ("smot", "horizon", "0", "expected greater than or equal to 2, got 0"),
    ("smot", "eta_max", ".nan", "expected a finite number, got nan"),
    ("cem", "existence", "-0.1", "expected greater than or equal to 0"),
    ("cem", "merge_max_gap", "0", "expected greater than or equal to 1, got 0"),
    ("cem", "target_size", ".nan", "expected a finite number, got nan"),
    ("gtcsa", "groups", "0", "expected greater than or equal to 1, got 0"),
    ("gtcsa", "gate_px_at_1080", "-inf", "expected a finite number"),
    ("bytetrack", "lost_buffer_s", "0", "expected greater than 0"),
    ("bytetrack", "high_threshold", ".nan", "expected a finite number, got nan"),
]


@pytest.mark.parametrize(("tracker", "key", "value", "message"), CASES)
def test_a_bad_parameter_is_one_line_at_validate_time(
    tracker: str,
    key: str,
    value: str,
    message: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(
        "name: bad\nstages:\n  detector: {type: oracle}\n"
        f"  batch_tracker: {{type: {tracker}, params: {{{key}: {value}}}}}\n"
    )
    code = main(["validate", str(path)])
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    assert f"stages.batch_tracker.params.{key}: {message}" in lines[0], lines[0]


@pytest.mark.parametrize("tracker", sorted({case[0] for case in CASES}))
def test_the_defaults_validate(
    tracker: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "good.yaml"
    path.write_text(
        f"name: good\nstages:\n  detector: {{type: oracle}}\n  batch_tracker: {{type: {tracker}}}\n"
    )
    assert main(["validate", str(path)]) == 0, capsys.readouterr().err
