"""Output directories: checked and created before any work, written atomically, never deleted.

    check_apart(out, {"--policy": policy})     # an output never is, holds or lies in an input
    with exclusive(out):                       # one process at a time holds `out`
        write_atomic(out / "grid.csv", text)   # a partial file beside the target, then a rename
    refuse_or_move([out / "a.png"], force, note)   # earlier results: refused, or moved aside

    out = OutDir("eval/quick", "config.json", "evaluation", read=recorded_config)
    plan = out.plan(config, force)             # "new", "resume" or "replace"; touches nothing
    moved = out.prepare(plan, document, note)  # move aside, create, write the config file
    write_json(out.path / "summary.json", doc); write_npz(out.path / "r.npz", arrays)

An earlier result is replaced only with force, which moves it aside to
NAME.replaced-YYYYmmdd-HHMMSS, never deletes it. An `OutDir` is new (absent or empty), resumed
(its config file records the same config, keys in `ignore` apart) or, with force, replaced.
Everything else is one UsageError line: a file, a non-empty directory without the config file
(force replaces only this kind of output), a config file that does not read, a different config
(naming the keys that differ). Library modules write through this module; the command lines
(`cli`) only turn its errors into one line and an exit status.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import stat
import tempfile
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from mjx_peg import inputs, signals
from mjx_peg.errors import UsageError, message

_SHOWN = 60  # characters of a differing value quoted in a message


def _inside(path: Path, other: Path) -> bool:
    return path == other or other in path.parents


def check_apart(out, sources: dict[str, object | None], out_flag: str = "--out") -> None:
    """ValueError if `out` is, contains or lies inside an input of the command (by flag)."""
    mine = Path(out).resolve()
    for flag, source in sources.items():
        if source is None or str(source) == "baseline":
            continue
        theirs = Path(source).resolve()
        if _inside(mine, theirs) or _inside(theirs, mine):
            how = "is" if mine == theirs else "overlaps"
            raise UsageError(
                f"{out_flag} {out} {how} the {flag} {source}: an output never replaces an input; "
                f"choose another {out_flag}"
            )


def move_aside(path) -> Path:
    """Rename `path` (a file or a directory) to NAME.replaced-YYYYmmdd-HHMMSS beside it (with a
    -2, -3, ... suffix if taken); returns the new path. Nothing is deleted."""
    path = Path(path)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    for k in range(1, 1000):
        target = path.with_name(f"{path.name}.replaced-{stamp}" + (f"-{k}" if k > 1 else ""))
        if not target.exists() and not target.is_symlink():
            os.rename(path, target)
            return target
    raise UsageError(f"cannot move {path} aside: too many earlier copies beside it")


def prepare_dir(path) -> Path:
    """Create the directory `path` (and its parents) and prove that it is writable; OSError or
    ValueError (one line) if not."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UsageError(f"{path} exists and is not a directory")
    path.mkdir(parents=True, exist_ok=True)
    try:
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError as e:
        raise UsageError(f"cannot write in {path} ({e.strerror or e})") from None
    return path


def check_out(out, flag: str = "--out") -> None:
    """UsageError naming `flag` if `out`, or a folder above it, exists and is not a directory."""
    out = Path(out)
    for folder in (out, *out.parents):
        if folder.exists():
            if not folder.is_dir():
                where = "" if folder == out else f": {folder} is a file"
                raise UsageError(f"{flag} {out} is not a directory{where}")
            return


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
    check_out(out, flag)  # a file where a folder must be: one line naming the flag
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


def partial_path(path) -> Path:
    """Where `path` is written before it is renamed into place (same suffix, hidden)."""
    path = Path(path)
    return path.with_name(f".{path.stem}.partial{path.suffix}")


def write_atomic(path, data: bytes | str | Callable[[Path], object]) -> Path:
    """Write `path` whole or not at all: into a partial file beside it, then rename. `data` is
    the content, or a function that writes a given path (it keeps the suffix, for plotters)."""
    path = Path(path)
    tmp = partial_path(path)
    try:
        if callable(data):
            data(tmp)
        else:
            with open(tmp, "wb") as f:
                f.write(data.encode() if isinstance(data, str) else data)
        os.replace(tmp, path)
    except OSError as e:  # a full disk: the error names the file, not its partial copy
        tmp.unlink(missing_ok=True)
        raise OSError(e.errno, e.strerror or str(e), str(path)) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_all_atomic(files) -> list[Path]:
    """Write each (path, data) of `files` with `write_atomic`, all or none: if one fails, the
    ones written before it are removed again (a rerun is then not refused for them)."""
    written: list[Path] = []
    try:
        for path, data in files:
            written.append(write_atomic(path, data))
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        raise
    return written


def refuse_or_move(
    paths, force: bool, note: Callable[[str], None] | None = None, hint: str = ""
) -> None:
    """Before any work: UsageError if any of `paths` (earlier results) exists, unless `force`,
    which moves each aside (and tells `note` where)."""
    found = [Path(p) for p in paths if Path(p).exists() or Path(p).is_symlink()]
    if not found:
        return
    if not force:
        names = ", ".join(str(p) for p in found)
        raise UsageError(
            f"{names} already exist{'s' if len(found) == 1 else ''}: choose another --out, or "
            f"pass --force to move {'it' if len(found) == 1 else 'them'} aside{hint}"
        )
    for p in found:
        moved = move_aside(p)
        if note is not None:
            note(f"--force: moved {p} aside to {moved}")


def write_json(path, doc, indent: int | None = 2) -> Path:
    """Write `doc` as JSON (and a newline) to `path` atomically."""
    return write_atomic(path, json.dumps(doc, indent=indent) + "\n")


def write_npz(path, arrays: Mapping[str, np.ndarray]) -> Path:
    """Write `arrays` as an uncompressed .npz (readable with allow_pickle=False) atomically."""
    return write_atomic(path, lambda tmp: np.savez(tmp, **arrays))


def _plain(doc) -> dict:
    """`doc` as JSON gives it back (tuples are lists), so that two configs compare as saved."""
    return json.loads(json.dumps(doc))


def _differing(key: str, saved, wanted) -> tuple[str, object, object]:
    """(dotted key, saved value, wanted value) of the first difference under `key`, descending
    into objects (a skill's constants name the constant)."""
    if isinstance(saved, dict) and isinstance(wanted, dict):
        for k in [*wanted, *(k for k in saved if k not in wanted)]:
            if saved.get(k) != wanted.get(k):
                return _differing(f"{key}.{k}", saved.get(k), wanted.get(k))
    return key, saved, wanted


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
            why = f"no {e}" if isinstance(e, KeyError) else message(e)
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
            where_k, there, now = _differing(k, saved.get(k), wanted.get(k))
            detail = f"{where_k}: {_shown(there)} there, {_shown(now)} now"
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
            moved = move_aside(self.path)
            if note is not None:
                note(f"--force: moved the earlier {self.noun} in {self.path} aside to {moved}")
        if plan != "resume":
            prepare_dir(self.path)
        if document is None:
            if plan != "resume":
                raise ValueError(f"a {plan} directory needs the document of its config file")
            document = self.config_path.read_bytes()
        elif isinstance(document, Mapping):
            document = json.dumps(document, indent=2) + "\n"
        write_atomic(self.config_path, document)
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
