"""A file set's report (pipeline.io.file_set): each file written with whether it replaced one, and
a content given as a function, called once the other files are on disk."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipeline.io.file_set import WrittenFile, write_file_set


def test_each_file_says_whether_it_replaced_one(tmp_path: Path) -> None:
    (tmp_path / "b.json").write_text("old")
    written = write_file_set(tmp_path, {"a.json": "A", "b.json": b"B", "c.json": None})
    assert written == (WrittenFile(tmp_path / "a.json", False), WrittenFile(tmp_path / "b.json", True))
    assert [str(w) for w in written] == [f"wrote {tmp_path / 'a.json'}", f"replaced {tmp_path / 'b.json'}"]
    assert repr(written[1]) == f"WrittenFile({str(tmp_path / 'b.json')!r}, replaced=True)"
    assert (written[0].path.read_text(), written[1].path.read_text()) == ("A", "B")


def test_a_function_content_is_called_once_the_others_are_staged(tmp_path: Path) -> None:
    calls = []

    def report() -> str:
        staged = sorted(p.name for p in tmp_path.iterdir())
        calls.append(staged)
        return f"staged before me: {len(staged)}"

    written = write_file_set(tmp_path, {"timing.json": report, "a.json": "A", "b.json": "B"})
    assert [w.path.name for w in written] == ["timing.json", "a.json", "b.json"]  # in the order given
    assert len(calls) == 1 and len(calls[0]) == 2 and all(name.endswith(".tmp") for name in calls[0])
    assert (tmp_path / "timing.json").read_text() == "staged before me: 2"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.json", "timing.json"]


def test_a_failing_function_content_leaves_the_folder_as_it_was(tmp_path: Path) -> None:
    (tmp_path / "a.json").write_text("old")

    def fail() -> str:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_file_set(tmp_path, {"a.json": "new", "timing.json": fail})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]
    assert (tmp_path / "a.json").read_text() == "old"
