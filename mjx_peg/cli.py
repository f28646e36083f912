"""The command-line boundary every CLI shares: bad input is one line on stderr and exit status 2.

    parser = cli.Parser(prog="eval.py", description=...)   # argparse errors: one line, exit 2
    parser.add_argument("--size", type=cli.SIZE_MM, ...)   # a documented range, in the flag's unit

    @cli.entry(PROG)                                       # ValueError / OSError anywhere: one
    def main(argv=None) -> int: ...                        # line, exit 2; Ctrl-C: one line, 130

The output location of every CLI follows the same rules (`check_apart`, `move_aside`,
`prepare_dir`, `write_atomic`): it is checked and created before any work, it is never one of the
command's inputs, results are written atomically as they are produced, and an earlier result is
replaced only with --force, which moves it aside (NAME.replaced-YYYYmmdd-HHMMSS), never deletes it.

Imports nothing of the package, so a CLI can parse its arguments before importing MuJoCo or JAX.
"""

from __future__ import annotations

import argparse
import errno
import functools
import math
import os
import re
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from mjx_peg import signals
from mjx_peg.cores import cores
from mjx_peg.errors import UsageError

EXIT_USAGE = 2  # bad input, as argparse
EXIT_INTERRUPTED = 130  # Ctrl-C (128 + SIGINT)
# What a user can cause (a bad value, an unreadable or unwritable path): one line, never a trace.
USER_ERRORS: tuple[type[BaseException], ...] = (UsageError, OSError)
_SHOWN = 60  # characters of a bad value quoted in a message


def _shown(text) -> str:
    text = repr(text) if isinstance(text, str) else f"{text:g}"
    return text if len(text) <= _SHOWN else text[: _SHOWN - 5] + "...'"


def number_text(x: float) -> str:
    """`x` as short as it reads back exactly: 500.0001 stays 500.0001, 50.0 is 50."""
    return f"{x:g}" if float(f"{x:g}") == x else repr(x)


def shown_path(path, limit: int = 120) -> str:
    """`path` as text, its middle cut out if longer than `limit` characters."""
    text = str(path)
    if len(text) <= limit:
        return text
    return f"{text[: limit // 2]}...{text[-(limit // 2 - 3) :]} ({len(text):,} characters)"


def message(error) -> str:
    """One line for an exception or a message: OS errors name their file."""
    if isinstance(error, OSError) and error.strerror:
        files = (error.filename, error.filename2)
        where = " -> ".join(shown_path(f) for f in files if f is not None)
        error = f"{where}: {error.strerror}" if where else error.strerror
    return " ".join(str(error).split()) or type(error).__name__


def fail(prog: str, error) -> int:
    """Print `PROG: error: MESSAGE` (one line) on stderr and return the usage exit status."""
    print(f"{prog}: error: {message(error)}", file=sys.stderr)
    return EXIT_USAGE


def note(prog: str, text: str) -> None:
    """A one-line notice on stderr (`PROG: TEXT`): what --force moved aside, a fallback."""
    print(f"{prog}: {' '.join(text.split())}", file=sys.stderr)


def entry(prog: str, interrupted: str = "interrupted") -> Callable:
    """Decorate a CLI's main(argv) -> int: every user error is one line and exit status 2, an
    argparse exit returns its status, Ctrl-C is one line and 130 (SIGTERM: 143). Other
    exceptions (bugs) keep their traceback. Called as the program (argv None), the command takes
    SIGINT and SIGTERM first thing (`signals`): until it starts working a signal ends it at
    once, after that it unwinds. The CPU engine's worker processes, if the command started them,
    stop when it returns (a main() called from Python leaves none behind)."""

    def wrap(main: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(main)
        def run(argv=None) -> int:
            program = argv is None
            if program:
                signals.install(prog)
                _printable_streams()
            code = None
            try:
                code = main(argv)
            except SystemExit as exc:  # argparse: --help (0) or Parser.error (2, printed)
                code = exc.code if isinstance(exc.code, int) else fail(prog, exc.code)
            except USER_ERRORS as exc:
                code = fail(prog, exc)
            except KeyboardInterrupt as exc:
                stopped = isinstance(exc, signals.Terminated)
                print(f"{prog}: {'terminated' if stopped else interrupted}", file=sys.stderr)
                code = signals.EXIT_STATUS[signal.SIGTERM if stopped else signal.SIGINT]
            finally:
                workers = sys.modules.get("mjx_peg.engines.processes")
                if workers is not None:
                    workers.shutdown()
                if program:
                    code = _after_signal(prog, code)
                    signals.uninstall()
            return code

        return run

    return wrap


def _printable_streams() -> None:
    """stdout and stderr write what their encoding cannot (a "±" under PYTHONIOENCODING=ascii)
    as an escape instead of failing."""
    for stream in (sys.stdout, sys.stderr):
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")


def _after_signal(prog: str, code: int | None) -> int | None:
    """The exit status of a command that a signal stopped: one a KeyboardInterrupt swallowed
    somewhere below still ends as stopped, saying so once."""
    got = signals.received()
    if got is None:
        return code
    if code not in signals.EXIT_STATUS.values():
        print(f"{prog}: {signals.WORD[got]}", file=sys.stderr)
    return signals.EXIT_STATUS[got]


class Parser(argparse.ArgumentParser):
    """argparse whose errors are one stderr line, `PROG: error: MESSAGE`, and exit status 2.

    A flag whose type is a range (`integer`, `number`) gets its range appended to its help."""

    def error(self, message: str):
        # "argument --size: must be ..." reads "--size must be ..."
        message = re.sub(r"^argument (\S+?)(?:/\S+)?: (?=must )", r"\1 ", message)
        # "--hole -450,120,30": argparse takes the value for an option and wants one
        message = re.sub(
            r"^argument (--\S+?)(?:/\S+)?: expected one argument$",
            r"\1 expects a value; one that starts with '-' is written \1=-VALUE",
            message,
        )
        raise SystemExit(fail(self.prog, message))

    def add_argument(self, *args, **kwargs):
        text = getattr(kwargs.get("type"), "range_text", None)
        if text and kwargs.get("help") != argparse.SUPPRESS:
            kwargs["help"] = f"{kwargs['help']}; {text}" if kwargs.get("help") else text
        return super().add_argument(*args, **kwargs)


# -- numeric flags: one range per quantity, in the flag's own unit, the same in every CLI ---------


def integer(lo: int, hi: int, why: str = "") -> Callable[[str], int]:
    """argparse type: an integer in lo..hi (inclusive)."""
    text = f"{lo:,}..{hi:,}" + (f" ({why})" if why else "")

    def parse(value: str) -> int:
        try:
            number = int(str(value).strip())
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"must be an integer in {text}, got {_shown(value)}"
            ) from None
        if not lo <= number <= hi:
            raise argparse.ArgumentTypeError(f"must be an integer in {text}, got {number}")
        return number

    parse.range_text = f"an integer in {text}"
    return parse


def number(lo: float, hi: float, unit: str, lo_open: bool = False) -> Callable[[str], float]:
    """argparse type: a finite number in [lo, hi] (or (lo, hi] with lo_open), in `unit`."""
    text = f"{'(' if lo_open else '['}{lo:g}, {hi:g}] {unit}"

    def parse(value: str) -> float:
        try:
            x = float(str(value).strip())
        except ValueError:
            x = math.nan
        ok = math.isfinite(x) and (lo < x if lo_open else lo <= x) and x <= hi
        if not ok:
            got = _shown(value) if not math.isfinite(x) else number_text(x)
            raise argparse.ArgumentTypeError(f"must be a number in {text}, got {got}")
        return x

    parse.range_text = f"a number in {text}"
    return parse


# The ranges of the flags several CLIs share.
SIZE_MM = number(10.0, 100.0, "mm")  # characteristic size S (the paper: 25, 50, 60 mm)
LINEAR_MM = number(0.0, 50.0, "mm")  # +- localization x, y and grasp z error range
ANGULAR_DEG = number(0.0, 45.0, "deg")  # +- localization yaw and grasp tilt range
TIME_LIMIT_S = number(0.01, 600.0, "s")  # simulated time per trial (the paper's: 60 s)
SEED = integer(0, 2**32 - 1)  # NumPy's and JAX's seeds
TRIALS = integer(1, 100_000)  # trials in one call of a CLI that holds them all at once
WORKERS = integer(1, cores(), "the cores this process may use")  # engine worker processes


PROCESSES = integer(0, cores(), "0: lanes as threads of this process; at most the cores")


def add_processes_option(parser: argparse.ArgumentParser, lanes_flag: str) -> None:
    """--processes: the CPU engine's lanes in worker processes (train.py, eval.py)."""
    parser.add_argument(
        "--processes",
        type=PROCESSES,
        help=f"CPU engine: its lanes in this many worker processes, {lanes_flag} lanes each "
        f"(default: one per core, {cores()} here; processes scale past the GIL, the same "
        "results); 0: lanes as threads of this process",
    )


def add_grasp_model_option(parser: argparse.ArgumentParser, models, default: str | None) -> None:
    """--grasp-model: where a trial's grasp errors go (world.constants.GRASP_MODELS)."""
    parser.add_argument(
        "--grasp-model",
        default=default,
        choices=models,
        help="where the grasp errors (height, tilt) go: board (the default), the paper's: the "
        "board raised and tilted about its hole's entrance; flange, ours and harder: the peg "
        "tilted in the gripper, its tip moved by 150 mm x sin(tilt) before contact",
    )


def add_skill_option(parser: argparse.ArgumentParser, skills, default: str | None,
                     default_text: str = "") -> None:  # fmt: skip
    """--skill: the skill's contact search (skill.search.SKILLS)."""
    parser.add_argument(
        "--skill",
        default=default,
        choices=skills,
        help="paper: the paper's compliant DMP as written; search: with the contact search, the "
        "goal moved away from the centre of pressure of a peg resting on the board top "
        f"(skill/search.py); default: {default_text or default}",
    )


def ray_address(text: str) -> str:
    """argparse type of --ray: `auto`, `local` or HOST:PORT (a port in 1..65535, in ASCII
    digits); the address as given."""
    text = str(text).strip()
    if text in ("auto", "local"):
        return text
    host, _, port = text.rpartition(":")
    shown = _shown(text)
    if not host or not port:
        raise argparse.ArgumentTypeError(f"must be auto, local or HOST:PORT, got {shown}")
    if not (port.isascii() and port.isdigit() and 1 <= int(port) <= 65535):
        raise argparse.ArgumentTypeError(f"must end in a port 1..65535, got {shown}")
    return text


ray_address.range_text = "auto, local or HOST:PORT with a port in 1..65535"


def add_ray_option(parser: argparse.ArgumentParser) -> None:
    """--ray [ADDRESS]: the CPU engine's trials on a Ray cluster (train.py, eval.py)."""
    parser.add_argument(
        "--ray",
        nargs="?",
        const="local",
        type=ray_address,
        metavar="ADDRESS",
        help="CPU engine: run the trials on a Ray cluster, one lane per CPU, the same results "
        "(auto: the cluster `ray start` runs on this node; HOST:PORT: another; no address: a "
        'local one on this machine); needs the cluster extra: pip install -e ".[cluster]"',
    )


def ray_options(args: argparse.Namespace, engine: str, lane_flags: tuple[str, ...]) -> dict:
    """The engine options of --ray (`{"ray": ADDRESS}`), after refusing what it replaces."""
    if engine != "mujoco":
        raise UsageError(f"--ray runs the mujoco engine's trials, not {engine}'s")
    for flag in ("--processes", *lane_flags):
        if getattr(args, flag.lstrip("-").replace("-", "_"), None):
            raise UsageError(f"--ray runs one lane per cluster CPU: drop {flag}")
    return {"ray": args.ray}


def resolve_processes(value: int | None, engine: str) -> int | None:
    """--processes as the engine option `processes`: None where the lanes stay in this process.

    Unset: one worker process per core on the mujoco engine (1.14-1.56x over threads on 2 cores,
    bit-identical results, BENCHMARKS.md "Where the CPU engine's time goes"), none on a single
    core or on another engine.
    """
    if engine != "mujoco":
        if value:
            raise UsageError(f"--processes is an option of the mujoco engine, not of {engine}")
        return None
    if value is None:
        value = cores() if cores() > 1 else 0
    return value or None


def check_jax() -> None:
    """UsageError naming JAX_PLATFORMS if JAX cannot start a back-end (a GPU asked for where
    there is none, an unknown name): training runs on JAX."""
    import jax

    try:
        jax.devices()
    except Exception as e:  # JAX raises RuntimeError, or fails an assertion, for these
        platforms = os.environ.get("JAX_PLATFORMS")
        why = " ".join(str(e).split())[:200] or type(e).__name__
        where = f"JAX_PLATFORMS={platforms!r}" if platforms is not None else "JAX"
        raise UsageError(
            f"{where}: JAX cannot start a back-end ({why}); set JAX_PLATFORMS=cpu or leave it unset"
        ) from None


MAX_RANGES = 10_000  # error ranges in one evaluation grid (the paper's has 350)
MAX_AXIS = 1_000  # values of one grid axis
MAX_GRID_TRIALS = 10_000_000  # trials in one evaluation grid (the paper's has 70,000)


# -- the output location ----------------------------------------------------------------------


def nonempty_path(text: str) -> Path:
    """argparse type of a path flag (--out, --policy, ...): a non-empty path."""
    if not str(text).strip():
        raise argparse.ArgumentTypeError("must be a path, got an empty string")
    if "\0" in text:
        raise argparse.ArgumentTypeError("must be a path without NUL characters")
    path = Path(text)
    try:
        path.resolve()  # Python 3.11 raises RuntimeError on a symlink loop, 3.13 OSError
        path.exists()
    except RuntimeError:
        raise argparse.ArgumentTypeError(f"{shown_path(text)!r} is a symbolic link loop") from None
    except OSError as e:
        why = (
            "is a symbolic link loop"
            if e.errno == errno.ELOOP
            else f"cannot be used ({e.strerror})"
        )
        raise argparse.ArgumentTypeError(f"{shown_path(text)!r} {why}") from None
    return path


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


def refuse_or_move(paths, force: bool, prog: str, hint: str = "") -> None:
    """Before any work: ValueError if any of `paths` (earlier results) exists, unless `force`,
    which moves each aside (and says where)."""
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
        note(prog, f"--force: moved {p} aside to {move_aside(p)}")
