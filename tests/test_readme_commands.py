"""The README's test command is the contributor's (editable); CI keeps testing a real install."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bash_blocks(text: str) -> list[str]:
    return re.findall(r"```bash\n(.*?)```", text, flags=re.DOTALL)


def test_readme_test_command_installs_the_checkout_editable() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    commands = [block for block in _bash_blocks(readme) if "pytest" in block]
    assert commands, "the README gives no test command"
    # An edit must be what the tests run: the checkout itself, not a copy in site-packages.
    assert 'pip install -e ".[test]"' in commands[0], commands[0]


def test_ci_still_tests_a_non_editable_install_and_the_readme_says_why() -> None:
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    installs = [line for line in ci.splitlines() if "pip install" in line and "[test]" in line]
    assert installs and all(" -e " not in line for line in installs), installs
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert ".ci/run" in readme and "wheel" in readme
