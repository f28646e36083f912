"""An output directory that remembers the config it was made for, and atomic writes into it.

    out = OutDir("eval/quick", "config.json", "evaluation", read=recorded_config)
    plan = out.plan(config, force)             # "new", "resume" or "replace"; touches nothing
    moved = out.prepare(plan, document, note)  # move aside, create, write the config file
    write_json(out.path / "summary.json", doc); write_npz(out.path / "r.npz", arrays)

A directory is new (absent or empty), resumed (its config file records the same config, keys in
`ignore` apart) or, with force, replaced: moved aside to NAME.replaced-YYYYmmdd-HHMMSS, never
deleted. Everything else is one UsageError line: a file, a non-empty directory without the
config file (force replaces only this kind of output), a config file that does not read, a
different config (naming the keys that differ). Files are written whole or not at all
(`cli.write_atomic`: a partial file beside the target, then a rename).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import stat
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from mjx_peg import cli, inputs, signals
from mjx_peg.errors import UsageError

_SHOWN = 60  # characters of a differing value quoted in a message


def write_json(path, doc, indent: int | None = 2) -> Path:
    """Write `doc` as JSON (and a newline) to `path` atomically."""
    return cli.write_atomic(path, json.dumps(doc, indent=indent) + "\n")


def write_npz(path, arrays: Mapping[str, np.ndarray]) -> Path:
    """Write `arrays` as an uncompressed .npz (readable with allow_pickle=False) atomically."""
    return cli.write_atomic(path, lambda tmp: np.savez(tmp, **arrays))


def _plain(doc) -> dict:
    """`doc` as JSON gives it back (tuples are lists), so that two configs compare as saved."""
    return json.loads(json.dumps(doc))


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= _SHOWN else text[: _SHOWN - 3] + "..."


class OutDir:
    """One output directory keyed by the config recorded in its `config_file`.

    `noun` names what it holds in messages ("training run"); `read` turns the config file's
    JSON into the config it records (raising ValueError, KeyError or TypeError when the file is
    not one); keys in `ignore` may change between runs (a split's image count)."""

    def __init__(
        self,
        path,
        config_file: str,
        noun: str,
        read: Callable[[object], dict] = dict,
        ignore: tuple[str, ...] = (),
        flag: str = "--out",
    ):
        self.path = Path(path)
        self.config_path = self.path / config_file
        self.noun = noun
        self.read = read
        self.ignore = frozenset(ignore)
        self.flag = flag

    @property
    def _a_noun(self) -> str:
        return f"{'an' if self.noun[0] in 'aeiou' else 'a'} {self.noun}"

    def recorded(self) -> dict:
        """The config recorded in the config file; UsageError if the file is not one."""
        doc = inputs.read_json(self.config_path, f"{self._a_noun} config")
        try:
            return _plain(self.read(doc))
        except (ValueError, KeyError, TypeError, AttributeError, RecursionError) as e:
            why = f"no {e}" if isinstance(e, KeyError) else cli.message(e)
            raise UsageError(
                f"{self.config_path} is not {self._a_noun} config{f' ({why})' if why else ''}; "
                f"choose another {self.flag}"
            ) from None

    def plan(self, config: Mapping, force: bool) -> str:
        """What `prepare` will do for `config` (JSON-able), decided without touching anything:
        "new", "resume" or "replace" (force on a directory of this kind); UsageError else."""
        where = f"{self.flag} {self.path}"
        if self.path.exists() and not self.path.is_dir():
            raise UsageError(f"{where} exists and is not a directory; choose another {self.flag}")
        if not self.path.is_dir() or not any(self.path.iterdir()):
            return "new"
        if not self.config_path.is_file():
            raise UsageError(
                f"{where} is not {self._a_noun} directory (it is not empty and holds no "
                f"{self.noun}); choose another {self.flag} (--force replaces only {self._a_noun})"
            )
        saved = self.recorded()
        if force:
            return "replace"
        wanted = _plain(dict(config))
        keys = [*wanted, *(k for k in saved if k not in wanted)]
        differ = [k for k in keys if k not in self.ignore and saved.get(k) != wanted.get(k)]
        if differ:
            k, rest = differ[0], differ[1:]
            detail = f"{k}: {_shown(saved.get(k))} there, {_shown(wanted.get(k))} now"
            if rest:
                detail += f"; {', '.join(rest)} differ{'s' if len(rest) == 1 else ''} too"
            raise UsageError(
                f"{where} holds {self._a_noun} with a different config ({detail}); rerun it with "
                f"the same options, choose another {self.flag}, or pass --force to move it aside "
                "and start over"
            )
        return "resume"

    def prepare(
        self,
        plan: str,
        document: str | bytes | Mapping | None = None,
        note: Callable[[str], None] | None = None,
    ) -> Path | None:
        """Carry out `plan` (from `plan()`): move a replaced directory aside (`note` is told
        where), create the directory, write the config file atomically, which proves the
        directory writable. `document` is the file's content (a mapping is written as indented
        JSON); None on a resume keeps the file as it is. Returns where a replaced one went."""
        moved = None
        if plan == "replace":
            moved = cli.move_aside(self.path)
            if note is not None:
                note(f"--force: moved the earlier {self.noun} in {self.path} aside to {moved}")
        if plan != "resume":
            cli.prepare_dir(self.path)
        if document is None:
            if plan != "resume":
                raise ValueError(f"a {plan} directory needs the document of its config file")
            document = self.config_path.read_bytes()
        elif isinstance(document, Mapping):
            document = json.dumps(document, indent=2) + "\n"
        cli.write_atomic(self.config_path, document)
        return moved

    def open(
        self,
        config: Mapping,
        force: bool = False,
        document: str | bytes | Mapping | None = None,
        note: Callable[[str], None] | None = None,
    ) -> str:
        """`plan` then `prepare`, the document being `config` itself unless given; returns the
        plan that was carried out."""
        plan = self.plan(config, force)
        self.prepare(plan, config if document is None and plan != "resume" else document, note)
        return plan


# -- one writer per output directory ------------------------------------------------------------


def lock_path(out) -> Path:
    """The lock of output directory `out`: `.NAME.lock` beside it (so that --force can move
    `out` itself aside while it is held)."""
    out = Path(out)
    return out.parent / f".{out.name}.lock"


def _make_folders(folder: Path) -> list[Path]:
    """Create `folder` and its missing parents; the ones this call made, outermost first."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    made = []
    for path in reversed(missing):
        try:
            path.mkdir()
            made.append(path)
        except FileExistsError:  # made meanwhile by another process
            pass
    return made


def _remove_if_empty(folders) -> None:
    for folder in folders:
        try:
            folder.rmdir()
        except OSError:  # not empty (or gone): kept
            pass


def _take_lock(lock: Path, where: str, flag: str) -> int:
    """An open descriptor of `lock` holding its flock; UsageError if another process holds it
    or if `lock` is not a lock file this command would make (a symbolic link, a file with other
    hard links or of another user, a folder, a FIFO): nothing is written through those."""
    import fcntl

    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
    not_ours = f"{where}: its lock {lock} is not a lock file of this program"
    while True:
        try:
            fd = os.open(lock, flags, 0o644)
        except OSError as e:
            if e.errno in (errno.ELOOP, errno.EISDIR, errno.ENXIO, errno.EMLINK):
                raise UsageError(f"{not_ours} ({e.strerror}); remove it") from None
            raise OSError(e.errno, e.strerror, str(lock)) from None
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1 or info.st_uid != os.geteuid():
            os.close(fd)
            why = (
                "not a regular file"
                if not stat.S_ISREG(info.st_mode)
                else ("it has other hard links" if info.st_nlink != 1 else "another user's")
            )
            raise UsageError(f"{not_ours} ({why}); remove it")
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise UsageError(
                f"{where} is in use by another process (pid {holder[:12]}): wait for it to end "
                f"or give another {flag}"
            ) from None
        try:  # the path may have been removed (or replaced) by a holder that just ended
            now = os.stat(lock, follow_symlinks=False)
        except FileNotFoundError:
            now = None
        if now is not None and (now.st_dev, now.st_ino) == (info.st_dev, info.st_ino):
            return fd
        os.close(fd)


@contextlib.contextmanager
def exclusive(out, flag: str = "--out"):
    """Hold output directory `out` for this process while the block runs: a second process
    asking for it gets one UsageError line naming `flag` and the process that holds it.

    The lock (`lock_path`) is an flock: the system drops it when its holder ends, crashed or
    killed, so it never stays stuck; it is opened without following a symbolic link, and only
    a regular file of one link that this user owns is ever written (its holder's pid). It is
    removed when the block ends. If the block fails, the folders made for the lock and an `out`
    it made are removed again if empty: a refused input leaves nothing behind. From the moment
    it is held the command is working (`signals.working`): a Ctrl-C unwinds, keeping what was
    written."""
    out = Path(out)
    cli.check_out(out, flag)  # a file where a folder must be: one line naming the flag
    where = f"{flag} {out}"
    lock = lock_path(out)
    made = _make_folders(lock.parent)
    made_out = not out.exists()
    fd, failed = None, True
    try:
        fd = _take_lock(lock, where, flag)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        signals.working()
        yield out
        failed = False
    finally:
        if fd is not None:
            with contextlib.suppress(OSError):
                mine, now = os.fstat(fd), os.stat(lock, follow_symlinks=False)
                if (mine.st_dev, mine.st_ino) == (now.st_dev, now.st_ino):
                    lock.unlink()
            os.close(fd)
        if failed:
            _remove_if_empty([out] if made_out else [])
            _remove_if_empty(reversed(made))
