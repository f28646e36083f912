"""Reading a file someone gave us: refused in one line, naming the file, before it is used.

    doc = read_json(path, "a policy manifest")            # a regular file, bounded size and depth
    arrays = read_npz(path, {"obs_mean": Member("f", (8,))})  # headers checked, then loaded

A path that is not a regular file (a FIFO, a directory, a device) is refused without being
opened for reading, so it never blocks; JSON is bounded in size and nesting depth; an npz member
is checked by its .npy header (dtype kind, shape, size) before any of its data is read, and only
the members asked for are loaded. Objects are never unpickled. Every failure is one `UsageError`
(or the `error` class given) whose message starts with the file's path.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import stat
import zipfile
import zlib
from pathlib import Path

from mjx_peg.errors import UsageError

MAX_JSON_BYTES = 16 * 2**20  # a manifest or config is a few kB
MAX_JSON_DEPTH = 32  # our files nest 4 deep
MAX_NPY_HEADER = 10_000  # bytes of an .npy header (NumPy's own default limit)
# What a damaged zip or .npy raises while being read.
READ_ERRORS = (zipfile.BadZipFile, zlib.error, EOFError, ValueError, OSError, NotImplementedError)
_KINDS = {"f": "real floats", "b": "booleans", "i": "integers", "u": "integers", "U": "text"}


def _refuse(error, path, why: str):
    raise error(f"{path}: {why}")


def _open_regular(path, error) -> int:
    """A read-only descriptor of the regular file `path`, opened so that a FIFO never blocks."""
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        _refuse(error, path, "no such file")
    except IsADirectoryError:
        _refuse(error, path, "is a directory, not a file")
    except OSError as e:
        _refuse(error, path, f"cannot be read ({e.strerror or e})")
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        if stat.S_ISDIR(info.st_mode):
            _refuse(error, path, "is a directory, not a file")
        _refuse(error, path, "is not a regular file (a FIFO, socket or device is never read)")
    os.set_blocking(fd, True)
    return fd


def regular_file(path, error: type[Exception] = UsageError) -> Path:
    """`path` if it is a regular file (after symbolic links); one line naming it if not."""
    os.close(_open_regular(path, error))
    return Path(path)


def read_bytes(path, limit: int, error: type[Exception] = UsageError) -> bytes:
    """The content of the regular file `path`, at most `limit` bytes (more is refused)."""
    fd = _open_regular(path, error)
    try:
        size = os.fstat(fd).st_size
        if size > limit:
            _refuse(error, path, f"is {size:,} bytes, more than the {limit:,} it may hold")
        with os.fdopen(os.dup(fd), "rb") as f:
            data = f.read(limit + 1)
    except OSError as e:
        _refuse(error, path, f"cannot be read ({e.strerror or e})")
    finally:
        os.close(fd)
    if len(data) > limit:
        _refuse(error, path, f"holds more than the {limit:,} bytes it may hold")
    return data


def read_text(path, limit: int = MAX_JSON_BYTES, error: type[Exception] = UsageError) -> str:
    """The UTF-8 text of the regular file `path` (at most `limit` bytes)."""
    try:
        return read_bytes(path, limit, error).decode("utf-8")
    except UnicodeDecodeError as e:
        _refuse(error, path, f"is not UTF-8 text (byte {e.start})")


def depth(doc) -> int:
    """How deep `doc` (parsed JSON) nests: 0 for a scalar, 1 for a flat list or object."""
    deepest, stack = 0, [(doc, 0)]
    while stack:
        node, level = stack.pop()
        if isinstance(node, dict):
            node = list(node.values())
        if isinstance(node, list):
            deepest = max(deepest, level + 1)
            stack.extend((child, level + 1) for child in node)
    return deepest


def _no_constant(name: str):
    raise ValueError(f"{name} is not a JSON number")


def read_json(
    path,
    what: str = "JSON",
    limit: int = MAX_JSON_BYTES,
    max_depth: int = MAX_JSON_DEPTH,
    error: type[Exception] = UsageError,
    allow_nan: bool = False,
):
    """The JSON document in `path`: a regular UTF-8 file of at most `limit` bytes, nesting at
    most `max_depth` deep, without NaN or Infinity (unless `allow_nan`); `what` names it in the
    message."""
    text = read_text(path, limit, error)
    too_deep = error(f"{path} is not {what} (nested deeper than {max_depth} levels)")
    try:
        doc = json.loads(text, **({} if allow_nan else {"parse_constant": _no_constant}))
    except RecursionError:
        raise too_deep from None
    except ValueError as e:
        raise error(f"{path} is not {what} ({' '.join(str(e).split())})") from None
    if depth(doc) > max_depth:
        raise too_deep
    return doc


@dataclasses.dataclass(frozen=True)
class Member:
    """What one npz member must be: dtype kinds (NumPy's `dtype.kind` letters, "f": real
    floats), a shape (None: any length on that axis; no shape: any), at most `max_size`
    elements, and (floats, if `finite`) no NaN or infinity."""

    kinds: str = "f"
    shape: tuple[int | None, ...] | None = None
    max_size: int = 10_000_000
    finite: bool = True

    def problem(self, shape: tuple[int, ...], dtype) -> str | None:
        if dtype.hasobject or dtype.kind not in self.kinds:
            wanted = " or ".join(dict.fromkeys(_KINDS.get(k, k) for k in self.kinds))
            return f"holds {dtype} (dtype kind {dtype.kind!r}), not {wanted}"
        if dtype.kind == "f" and dtype.itemsize > 8:
            return f"holds {dtype}, wider than float64"
        size = math.prod(shape)
        if size > self.max_size:
            return f"has shape {shape} ({size:,} values), more than the {self.max_size:,} it may"
        if self.shape is not None and (
            len(shape) != len(self.shape)
            or any(w is not None and w != s for w, s in zip(self.shape, shape, strict=True))
        ):
            want = "(" + ", ".join("any" if w is None else str(w) for w in self.shape) + ")"
            return f"has shape {shape}, not {want}"
        return None


def _header(f):
    import numpy as np

    version = np.lib.format.read_magic(f)
    fmt = np.lib.format
    read = {(1, 0): fmt.read_array_header_1_0, (2, 0): fmt.read_array_header_2_0}
    if version not in read:
        raise ValueError(f".npy format version {version} is not read here")
    return read[version](f, max_header_size=MAX_NPY_HEADER)


def read_npz(
    path,
    members: dict[str, Member],
    optional: tuple[str, ...] = (),
    error: type[Exception] = UsageError,
) -> dict:
    """The arrays `members` names from the .npz file `path`, each checked by its header before
    its data is read (dtype, shape, size) and, if floats, for NaN and infinities after.
    Members in `optional` may be absent; members not asked for are never read."""
    import numpy as np

    fd = _open_regular(path, error)
    arrays = {}
    try:
        with os.fdopen(fd, "rb") as raw, zipfile.ZipFile(raw) as npz:
            names = set(npz.namelist())
            for name, member in members.items():
                entry = f"{name}.npy"
                if entry not in names:
                    if name in optional:
                        continue
                    _refuse(error, path, f"lacks the array {name!r}")
                with npz.open(entry) as f:
                    shape, fortran, dtype = _header(f)
                    why = member.problem(tuple(shape), dtype)
                    if why:
                        _refuse(error, path, f"array {name!r} {why}")
                    needed = f.tell() + math.prod(shape) * dtype.itemsize
                    if npz.getinfo(entry).file_size != needed:
                        _refuse(error, path, f"array {name!r} is truncated or padded")
                with npz.open(entry) as f:
                    array = np.lib.format.read_array(
                        f, allow_pickle=False, max_header_size=MAX_NPY_HEADER
                    )
                if member.finite and array.dtype.kind == "f" and not np.all(np.isfinite(array)):
                    _refuse(error, path, f"array {name!r} holds NaN or infinite values")
                arrays[name] = array
    except READ_ERRORS as e:
        if isinstance(e, UsageError):
            raise
        text = " ".join(str(e).split()) or type(e).__name__
        _refuse(error, path, f"is corrupt or truncated ({type(e).__name__}: {text[:200]})")
    return arrays


def npz_names(path, error: type[Exception] = UsageError) -> list[str]:
    """The array names of the .npz file `path` (its directory only; no data is read)."""
    fd = _open_regular(path, error)
    try:
        with os.fdopen(fd, "rb") as raw, zipfile.ZipFile(raw) as npz:
            return [n[:-4] for n in npz.namelist() if n.endswith(".npy")]
    except READ_ERRORS as e:
        _refuse(error, path, f"is corrupt or truncated ({type(e).__name__}: {e})")
