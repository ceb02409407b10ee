"""The files the command line writes: checked before any work, written whole or not at all.

Every command that writes a file or a folder of files (``sweep``, ``render``, ``plot``,
``bench``) names it here first, so a path that cannot be written fails in one line before
a simulation starts, and the same rules hold everywhere:

- an empty name, ``-`` (standard output, which no command writes to), a folder, a device
  or pipe (``/dev/null``), a folder that is missing or not a folder, or one where nothing
  can be created (``/proc``, a read-only mount, no permission, a name longer than the file
  system takes) is an :class:`OutputError`;
- an existing file is replaced only with ``overwrite`` (the ``--overwrite`` option);
- :func:`replacing` writes into a new file beside the target and moves it into place at
  the end, so a failed or interrupted write leaves the old file (or none), never half a
  file, and a file that appeared meanwhile is still not replaced without ``overwrite``.
"""
from __future__ import annotations

import argparse
import contextlib
import errno
import os
import secrets
import stat
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Optional, Union

__all__ = ["OutputError", "file_path", "check_file", "check_folder", "replacing",
           "path_argument"]

PathText = Union[str, "os.PathLike[str]"]


class OutputError(ValueError):
    """An output path that cannot or may not be written; the message names the option."""


def _reason(error: OSError) -> str:
    return error.strerror or str(error)


def _name_error(option: str, text: str, noun: str = "file") -> Optional[str]:
    """Why ``text`` names no file or folder at all, or None."""
    if not text:
        return f"{option} '': give a {noun} name"
    if "\0" in text:
        return f"{option} {text!r}: a path cannot hold a NUL character"
    if text == "-":  # the shell's name for standard output, not a name to write a file by
        return f"{option} -: cannot write to standard output; give a {noun} name"
    return None


def path_argument(text: str) -> str:
    """The command line's ``type`` of the arguments that name a scene, a bag or another
    file it reads, and a bag it writes (the files above are checked by :func:`file_path`
    and :func:`check_folder`): ``text``, unless it is empty (an unset shell variable),
    which names none; read as a path, it is the working folder, which a command would
    then read or write."""
    if not text:
        raise argparse.ArgumentTypeError("an empty path names no file or folder")
    return text


def _check_parent(option: str, path: Path) -> None:
    """The folder ``path`` goes into must exist and be a folder."""
    parent = path.parent
    try:
        info = os.stat(parent)
    except FileNotFoundError:
        raise OutputError(f"{option} {path}: the folder {parent} does not exist") from None
    except OSError as error:
        raise OutputError(f"{option} {path}: cannot use the folder {parent}: "
                          f"{_reason(error)}") from None
    if not stat.S_ISDIR(info.st_mode):
        raise OutputError(f"{option} {path}: {parent} is not a folder")


def _existing(label: str, path: Path, overwrite: bool) -> bool:
    """Whether ``path`` exists (a file that ``overwrite`` lets us replace); raises for
    anything else there, the message starting with ``label``."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):  # a dangling link is still a name in use
            info = os.lstat(path)
        else:
            return False
    except OSError as error:
        raise OutputError(f"{label}: {_reason(error)}") from None
    if stat.S_ISDIR(info.st_mode):
        raise OutputError(f"{label}: is a folder, not a file")
    if not (stat.S_ISREG(info.st_mode) or stat.S_ISLNK(info.st_mode)):
        raise OutputError(f"{label}: is not a regular file (a device, pipe or socket); "
                          "give a file name")
    if not overwrite:
        raise OutputError(f"{label}: exists; give --overwrite to replace it")
    return True


def _can_create(option: str, label: str, folder: Path) -> None:
    """Make a scratch file in ``folder`` and remove it: the one sure test that files can
    be made there (permissions, read-only mounts and /proc all answer it)."""
    try:
        handle, scratch = tempfile.mkstemp(dir=folder, prefix=".hd-")
        os.close(handle)
        os.unlink(scratch)
    except OSError as error:
        raise OutputError(f"{option} {label}: cannot create a file in {folder}: "
                          f"{_reason(error)}") from None


def file_path(text: PathText, *, option: str = "-o") -> Path:
    """``text`` as the name of a file: refused when it is empty, names a folder, is in no
    folder, or names something that is there and is not a regular file (whether one may
    replace a file is :func:`check_file`'s question)."""
    raw = os.fspath(text)
    problem = _name_error(option, raw)
    if problem:
        raise OutputError(problem)
    path = Path(raw)
    if raw.endswith(os.sep) or path.name in ("", ".", ".."):
        raise OutputError(f"{option} {raw}: names a folder, not a file")
    _check_parent(option, path)
    _existing(f"{option} {raw}", path, overwrite=True)
    return path


def check_file(text: PathText, *, option: str = "-o", overwrite: bool = False,
               also: Iterable[tuple[Path, str]] = ()) -> Path:
    """The path of a file to write, checked as the module docstring says.

    ``also`` names files written beside it, ``(path, what they are)``, that must not exist
    either unless ``overwrite``.
    """
    path = file_path(text, option=option)
    raw = os.fspath(text)
    exists = _existing(f"{option} {raw}", path, overwrite)
    for other, what in also:
        _existing(f"{option} {raw}: {other} ({what})", other, overwrite)
    _can_create(option, raw, path.parent)
    if not exists:  # the name itself: too long, or refused by the file system
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            os.unlink(path)
        except OSError as error:
            raise OutputError(f"{option} {raw}: cannot create it: {_reason(error)}") from None
    return path


def check_folder(text: PathText, *, option: str, names: Iterable[str] = (),
                 overwrite: bool = False) -> Path:
    """The path of a folder to write ``names`` into (made, with its parents, by the
    writer): an existing folder, or a new one under a folder where one can be made. A
    name already in it is refused unless ``overwrite``."""
    raw = os.fspath(text)
    problem = _name_error(option, raw, "folder")
    if problem:
        raise OutputError(problem)
    path = Path(raw)
    if path.is_dir():
        for name in names:
            if os.path.lexists(path / name) and not overwrite:
                raise OutputError(f"{option} {raw}: {path / name} exists; give --overwrite "
                                  "to replace it")
        _can_create(option, raw, path)
        return path
    ancestor = path
    while True:
        try:
            info = os.stat(ancestor)
        except (FileNotFoundError, NotADirectoryError):
            if ancestor == ancestor.parent:
                raise OutputError(f"{option} {raw}: no folder on this path exists") from None
            ancestor = ancestor.parent
            continue
        except OSError as error:
            raise OutputError(f"{option} {raw}: {_reason(error)}") from None
        break
    if not stat.S_ISDIR(info.st_mode):
        what = "is" if ancestor == path else f"is inside {ancestor}, which is"
        raise OutputError(f"{option} {raw}: {what} not a folder")
    try:
        os.rmdir(tempfile.mkdtemp(dir=ancestor, prefix=".hd-"))
    except OSError as error:
        raise OutputError(f"{option} {raw}: cannot create a folder in {ancestor}: "
                          f"{_reason(error)}") from None
    return path


def _scratch(path: Path) -> Path:
    """A new empty file beside ``path`` with its suffix (writers pick the format by it),
    made with the usual permissions (the umask's, as the target would have)."""
    for _ in range(100):
        scratch = path.with_name(f".hd-{secrets.token_hex(4)}{path.suffix[:16]}")
        try:
            os.close(os.open(scratch, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        return scratch
    raise FileExistsError(errno.EEXIST, "no free scratch name", str(path.parent))


def _move(scratch: Path, path: Path, overwrite: bool) -> None:
    """``scratch`` to ``path``; without ``overwrite``, never over a file there now."""
    if not overwrite:
        try:  # a hard link fails if the name is taken: no window for a file to appear
            os.link(scratch, path)
            return
        except FileExistsError:
            raise
        except OSError:  # a file system without hard links: the next best thing
            if os.path.lexists(path):
                raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST),
                                      str(path)) from None
    os.replace(scratch, path)


@contextmanager
def replacing(path: Path, *, option: str = "-o", overwrite: bool = False) -> Iterator[Path]:
    """Yield a scratch file beside ``path`` to write; at the end move it to ``path``.

    Any failure (of the writer, or an :class:`OSError` such as a full disk) removes the
    scratch file; an :class:`OSError` becomes an :class:`OutputError`.
    """
    try:
        scratch = _scratch(path)
    except OSError as error:
        raise OutputError(f"{option} {path}: cannot write: {_reason(error)}") from None
    try:
        yield scratch
        _move(scratch, path, overwrite)
    except FileExistsError:
        raise OutputError(f"{option} {path}: exists (made while this ran); give "
                          "--overwrite to replace it") from None
    except OSError as error:
        raise OutputError(f"{option} {path}: cannot write: {_reason(error)}") from None
    finally:
        with contextlib.suppress(FileNotFoundError):  # left after a failure or a hard link
            os.unlink(scratch)
