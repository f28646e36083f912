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

import json
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from mjx_peg import cli
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
        try:
            return _plain(self.read(json.loads(self.config_path.read_text())))
        except (ValueError, KeyError, TypeError, AttributeError) as e:
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
