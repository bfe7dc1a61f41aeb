"""replacing_folder: a finished folder replaces the old one; an interrupted one leaves no trace."""

from __future__ import annotations

from pathlib import Path

import pytest

from trackfw.atomic import replacing_folder


def test_a_finished_folder_replaces_the_old_one(tmp_path: Path) -> None:
    final, partial = tmp_path / "video", tmp_path / ".video.partial"
    final.mkdir()
    (final / "old.txt").write_text("old", encoding="utf-8")
    with replacing_folder(partial, final) as folder:
        folder.mkdir()
        (folder / "new.txt").write_text("new", encoding="utf-8")
    assert sorted(path.name for path in tmp_path.iterdir()) == ["video"]
    assert [path.name for path in final.iterdir()] == ["new.txt"]


def test_an_interrupted_folder_is_removed_and_the_old_one_kept(tmp_path: Path) -> None:
    final, partial = tmp_path / "video", tmp_path / ".video.partial"
    final.mkdir()
    (final / "old.txt").write_text("old", encoding="utf-8")
    with pytest.raises(KeyboardInterrupt), replacing_folder(partial, final) as folder:
        folder.mkdir()
        raise KeyboardInterrupt
    assert sorted(path.name for path in tmp_path.iterdir()) == ["video"]
    assert [path.name for path in final.iterdir()] == ["old.txt"]
