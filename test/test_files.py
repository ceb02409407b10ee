"""The one check of every output path (:mod:`hecker_dynamics.files`): what may be written,
and a write that is whole or nothing, never over a file without ``overwrite``."""
from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from hecker_dynamics.files import OutputError, check_file, check_folder, file_path, replacing


@pytest.fixture
def place(tmp_path, monkeypatch):
    """A folder with a file ``old.csv`` (text "old") and a folder ``sub``, made current."""
    (tmp_path / "old.csv").write_text("old")
    (tmp_path / "sub").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _listing(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else b"<dir>"
            for p in sorted(folder.rglob("*"))}


@pytest.mark.parametrize("text, problem", [
    ("", "give a file name"),
    (".", "names a folder"),
    ("..", "names a folder"),
    ("sub", "is a folder"),
    ("sub/", "names a folder"),
    ("sub/..", "names a folder"),
    ("/dev/null", "not a regular file"),
    ("missing/x.csv", "the folder missing does not exist"),
    ("old.csv/x.csv", "old.csv is not a folder"),
    ("old.csv", "exists; give --overwrite"),
    ("/proc/x.csv", "cannot create a file in /proc"),
    ("x" * 300 + ".csv", "too long"),
    ("a\0b.csv", "NUL"),
])
def test_a_file_that_cannot_or_may_not_be_written_is_refused_and_nothing_changes(
        place, text, problem):
    if text.startswith("/proc") and not os.path.isdir("/proc"):
        pytest.skip("no /proc here")
    before = _listing(place)
    with pytest.raises(OutputError, match=problem) as caught:
        check_file(text, option="-o")
    assert str(caught.value).startswith("-o ") and "\n" not in str(caught.value)
    assert _listing(place) == before


def test_a_read_only_folder_is_refused(place):
    if os.geteuid() == 0:
        pytest.skip("root writes into a read-only folder")
    (place / "sub").chmod(0o555)
    try:
        with pytest.raises(OutputError, match="cannot create a file in sub"):
            check_file("sub/x.csv")
    finally:
        (place / "sub").chmod(0o755)


def test_a_new_file_and_an_existing_one_with_overwrite_are_accepted(place):
    assert check_file("new.csv") == Path("new.csv")
    assert not (place / "new.csv").exists()  # the check made and removed it
    assert check_file("old.csv", overwrite=True) == Path("old.csv")
    assert (place / "old.csv").read_text() == "old"


def test_a_dangling_link_is_a_name_in_use(place):
    (place / "link.csv").symlink_to(place / "nowhere")
    with pytest.raises(OutputError, match="exists"):
        check_file("link.csv")


def test_files_written_beside_must_not_exist_either(place):
    with pytest.raises(OutputError, match=r"old\.csv \(the partial rows\): exists"):
        check_file("new.csv", also=[(Path("old.csv"), "the partial rows")])


def test_file_path_refuses_only_what_is_no_file(place):
    assert file_path("old.csv") == Path("old.csv")  # replacing it is check_file's question
    for text in ("", "sub", "/dev/null", "missing/x"):
        with pytest.raises(OutputError):
            file_path(text)


@pytest.mark.parametrize("text, problem", [
    ("", "give a folder name"),
    ("old.csv", "is not a folder"),
    ("old.csv/deeper/still", "is inside old.csv, which is not a folder"),
    ("/proc/x/y", "cannot create a folder in /proc"),
])
def test_a_folder_that_cannot_be_made_is_refused(place, text, problem):
    with pytest.raises(OutputError, match=problem):
        check_folder(text, option="--out")


def test_a_folder_is_checked_for_the_names_it_would_replace(place):
    assert check_folder("new/deeper", option="--out") == Path("new/deeper")
    assert not (place / "new").exists()  # made by the writer, not by the check
    assert check_folder(".", option="--out", names=["fresh.csv"]) == Path(".")
    with pytest.raises(OutputError, match=r"old\.csv exists; give --overwrite"):
        check_folder(".", option="--out", names=["fresh.csv", "old.csv"])
    with pytest.raises(OutputError, match="sub exists"):  # a folder of that name too
        check_folder(".", option="--out", names=["sub"])
    assert check_folder(".", option="--out", names=["old.csv"], overwrite=True) == Path(".")


def test_replacing_writes_whole_files_with_the_usual_permissions(place):
    target = check_file("new.csv")
    with replacing(target) as scratch:
        assert scratch.parent == target.parent and scratch.suffix == ".csv"
        scratch.write_text("new")
        assert not target.exists()  # nothing there until the end
    assert target.read_text() == "new"
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask
    assert sorted(p.name for p in place.iterdir()) == ["new.csv", "old.csv", "sub"]


def test_a_failed_write_leaves_the_old_file_and_no_scratch(place):
    with pytest.raises(RuntimeError), replacing(Path("old.csv"), overwrite=True) as scratch:
        scratch.write_text("half")
        raise RuntimeError("the writer failed")
    assert (place / "old.csv").read_text() == "old"
    assert sorted(p.name for p in place.iterdir()) == ["old.csv", "sub"]


def test_a_file_that_appears_while_writing_is_not_replaced(place):
    target = check_file("new.csv")
    with pytest.raises(OutputError, match="made while this ran"), replacing(target) as scratch:
        scratch.write_text("ours")
        target.write_text("someone else's")
    assert target.read_text() == "someone else's"
    with replacing(target, overwrite=True) as scratch:
        scratch.write_text("ours")
    assert target.read_text() == "ours"
    assert sorted(p.name for p in place.iterdir()) == ["new.csv", "old.csv", "sub"]


def test_an_os_error_while_writing_is_an_output_error(place):
    with pytest.raises(OutputError, match="-o new.csv: cannot write"), \
            replacing(Path("new.csv")) as scratch:
        raise OSError(28, "No space left on device", str(scratch))
    assert sorted(p.name for p in place.iterdir()) == ["old.csv", "sub"]
