"""Where ``toolpath smooth`` writes, checked before anything is written, and written so that nothing is lost.

Every path the command writes (the program, ``--report``, ``--plot``, the ``--in-place`` backup) is checked
against the input and against each other by real path (symlinks resolved, hard links by inode), and
against what is already there: an existing file is replaced only with ``--force`` (a backup of a
different content only with ``--force-backup``), and a symlink, FIFO, device or folder in an output's
place is refused, never replaced by a regular file.  Each file is written beside its place and renamed
into it when complete, so a reader never sees half a file and a failure (or SIGINT / SIGTERM) leaves the
place as it was; an ``--in-place`` run writes its backup, report and plot first and replaces the input last.
"""

from __future__ import annotations

import contextlib
import filecmp
import os
import secrets
import stat
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path


class PathProblem(Exception):
    """A path the command must not write (the caller turns it into a usage error, exit code 2)."""


@dataclass(frozen=True)
class Outputs:
    """The files one run writes; ``program`` is the input itself with ``--in-place``."""

    program: Path
    backup: Path | None = None
    report: Path | None = None
    plot: Path | None = None

    def named(self) -> list[tuple[str, Path]]:
        return [(what, path) for what, path in (("output", self.program), ("backup", self.backup),
                                                ("--report", self.report), ("--plot", self.plot)) if path is not None]


def _same_file(a: Path, b: Path) -> bool:
    """The same file: one real path, or (both there) one inode."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _writable_place(what: str, path: Path, force: bool) -> None:
    """A place a regular file may be written to: not a symlink, FIFO, device or folder; its folder there;
    an existing file only with ``force``."""
    if path.is_symlink():
        raise PathProblem(f"{path}: {what} is a symbolic link; name the file itself (nothing is written "
                          "through a link)")
    if path.exists():
        mode = path.stat().st_mode
        if not stat.S_ISREG(mode):
            kind = "a folder" if stat.S_ISDIR(mode) else "a FIFO" if stat.S_ISFIFO(mode) else "not a regular file"
            raise PathProblem(f"{path}: {what} is {kind}; it is never replaced")
        if not force:
            raise PathProblem(f"{path}: exists; pass --force to overwrite it")
    if not path.parent.is_dir():
        raise PathProblem(f"{path.parent}: no such directory (for {what} {path.name})")


def plan(input_path: Path, output: Path | None, in_place: bool, report: Path | None, plot: Path | None,
         force: bool, force_backup: bool) -> Outputs:
    """The run's outputs, every one checked (see the module docstring); raises :class:`PathProblem`."""
    if in_place:
        if output is not None:
            raise PathProblem("--in-place writes the input itself; leave out -o")
        if input_path.is_symlink():
            raise PathProblem(f"{input_path}: a symbolic link; --in-place rewrites the file itself, name it")
        backup = input_path.with_name(input_path.name + ".bak")
        if backup.is_symlink() or (backup.exists() and not backup.is_file()):
            raise PathProblem(f"{backup}: the backup's place holds something that is not a regular file")
        if backup.exists() and not filecmp.cmp(backup, input_path, shallow=False) and not force_backup:
            raise PathProblem(f"{backup}: the backup of an earlier --in-place run holds another program; move it, "
                              "or pass --force-backup to replace it with a copy of this input")
        outputs = Outputs(input_path, backup, report, plot)
    else:
        if output is None:
            raise PathProblem("say where to write: -o OUT (or --in-place)")
        if _same_file(output, input_path):
            raise PathProblem(f"{output}: that is the input; use --in-place to rewrite it (a backup is kept)")
        _writable_place("the output", output, force)
        outputs = Outputs(output, None, report, plot)
    for what, path in (("the --report", report), ("the --plot", plot)):
        if path is None:
            continue
        if _same_file(path, input_path):
            raise PathProblem(f"{path}: {what} would overwrite the input program")
        _writable_place(what, path, force)
    named = outputs.named()
    for i, (what, path) in enumerate(named):
        for other, other_path in named[i + 1:]:
            if _same_file(path, other_path):
                raise PathProblem(f"{path}: named both as the {what.lstrip('-')} and the {other.lstrip('-')}")
    return outputs


PENDING: set[str] = set()  # temporaries of atomic() not yet renamed or removed


@contextlib.contextmanager
def atomic(path: Path) -> Iterator:
    """A file beside ``path`` to write, renamed to ``path`` when the block ends without an error (or a
    signal): a reader never sees half a file, and a failure leaves ``path`` as it was."""
    handle, temporary = _new_temporary(path)
    try:
        with os.fdopen(handle, "wb") as fh:
            yield fh
        # the temporary is private (0600); give it the mode the file had, or a plain new file's
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, path.stat().st_mode & 0o7777 if path.exists() else 0o666 & ~umask)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    finally:
        PENDING.discard(temporary)


def _new_temporary(path: Path) -> tuple[int, str]:
    """A new private file beside ``path``, its name noted in PENDING before the file exists: a signal
    between making the file and noting it would leave it behind (seen once in the suite)."""
    while True:
        temporary = str(path.parent / f".{path.name}.{secrets.token_hex(6)}")
        PENDING.add(temporary)
        try:
            return os.open(temporary, os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o600), temporary
        except FileExistsError:
            PENDING.discard(temporary)
        except BaseException:
            PENDING.discard(temporary)
            raise


def remove_pending() -> None:
    """Remove every temporary :func:`atomic` has open (a signal handler's last act before exiting)."""
    for temporary in list(PENDING):
        with contextlib.suppress(OSError):
            os.unlink(temporary)
