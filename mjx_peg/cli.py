"""The command-line boundary every CLI shares: bad input is one line on stderr and exit status 2.

    parser = cli.Parser(prog="eval.py", description=...)   # argparse errors: one line, exit 2
    parser.add_argument("--size", type=cli.SIZE_MM, ...)   # a documented range, in the flag's unit

    @cli.entry(PROG)                                       # ValueError / OSError anywhere: one
    def main(argv=None) -> int: ...                        # line, exit 2; Ctrl-C: one line, 130

Where a command writes, and how, is `outdir`'s; only the command-line modules import this one.
It imports nothing of the package but `errors`, `cores` and `signals`, so a CLI can parse its
arguments (and take Ctrl-C) before importing MuJoCo or JAX.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import functools
import math
import os
import re
import signal
import sys
from collections.abc import Callable, Mapping
from pathlib import Path

from mjx_peg import errors, signals
from mjx_peg.cores import cores
from mjx_peg.errors import UsageError

EXIT_USAGE = 2  # bad input, as argparse
EXIT_INTERRUPTED = 130  # Ctrl-C (128 + SIGINT)
# What a user can cause (a bad value, an unreadable or unwritable path): one line, never a trace.
USER_ERRORS: tuple[type[BaseException], ...] = (UsageError, OSError)
_SHOWN = 60  # characters of a bad value quoted in a message


def shown(text) -> str:
    """A bad value as a message quotes it: a string's repr, a number by %g, cut to 60 characters."""
    text = repr(text) if isinstance(text, str) else f"{text:g}"
    return text if len(text) <= _SHOWN else text[: _SHOWN - 5] + "...'"


def number_text(x: float) -> str:
    """`x` as short as it reads back exactly: 500.0001 stays 500.0001, 50.0 is 50."""
    return f"{x:g}" if float(f"{x:g}") == x else repr(x)


def fail(prog: str, error) -> int:
    """Print `PROG: error: MESSAGE` (one line) on stderr and return the usage exit status."""
    print(f"{prog}: error: {errors.message(error)}", file=sys.stderr)
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
                if program:
                    signals.unwinding()
                workers = sys.modules.get("mjx_peg.engines.processes")
                if workers is not None:
                    workers.shutdown()
                if program:
                    code = _after_signal(prog, code)
                    signals.finished()
            if program and signals.received() is not None:
                _exit_stopped(code)
            return code

        return run

    return wrap


def _printable_streams() -> None:
    """stdout and stderr write what their encoding cannot (a "±" under PYTHONIOENCODING=ascii)
    as an escape instead of failing."""
    for stream in (sys.stdout, sys.stderr):
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")


def _exit_stopped(code: int) -> None:
    """End a command that a signal stopped, once it has unwound (what it wrote finished or
    removed, its workers stopped), without the interpreter's finalization: native threads (XLA's)
    still running there can abort the exit (SIGABRT). multiprocessing's finalizers run first, so
    that no semaphore of a worker pool is reported leaked; with Ray connected, its own exit runs
    (it stops the processes it started)."""
    if "ray" in sys.modules:
        return
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
    util = sys.modules.get("multiprocessing.util")
    if util is not None:
        util._run_finalizers()
    os._exit(code)


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
                f"must be an integer in {text}, got {shown(value)}"
            ) from None
        if not lo <= number <= hi:
            raise argparse.ArgumentTypeError(f"must be an integer in {text}, got {number}")
        return number

    parse.range_text = f"an integer in {text}"
    return parse


def number(lo: float, hi: float, unit: str, lo_open: bool = False) -> Callable[[str], float]:
    """argparse type: a finite number in [lo, hi] (or (lo, hi] with lo_open), in `unit`."""
    text = f"{'(' if lo_open else '['}{lo:g}, {hi:g}]" + (f" {unit}" if unit else "")

    def parse(value: str) -> float:
        try:
            x = float(str(value).strip())
        except ValueError:
            x = math.nan
        ok = math.isfinite(x) and (lo < x if lo_open else lo <= x) and x <= hi
        if not ok:
            got = shown(value) if not math.isfinite(x) else number_text(x)
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


def SEED_LIST(value: str) -> tuple[int, ...]:  # noqa: N802 (a flag type, like SEED)
    """Distinct seeds separated by commas, e.g. 0,1,2 (each a SEED)."""
    seeds = tuple(SEED(part.strip()) for part in str(value).split(","))
    if len(set(seeds)) != len(seeds):
        raise argparse.ArgumentTypeError(f"must name distinct seeds, got {shown(value)}")
    return seeds


SEED_LIST.range_text = f"distinct seeds separated by commas, each in 0..{2**32 - 1:,}"
TRIALS = integer(1, 100_000)  # trials in one call of a CLI that holds them all at once
THREADS = integer(1, cores(), "the cores this process may use")  # the CPU engine's lanes


PROCESSES = integer(0, cores(), "0: lanes as threads of this process; at most the cores")


def add_processes_option(parser: argparse.ArgumentParser, lanes_flag: str) -> None:
    """--processes: the CPU engine's lanes in worker processes (train.py, eval.py)."""
    parser.add_argument(
        "--processes",
        type=PROCESSES,
        help=f"CPU engine: its lanes in this many worker processes, {lanes_flag} lanes each "
        f"(default: one per core, {cores()} here; processes scale past the GIL, the same "
        "results but for a few trials' last bits); 0: lanes as threads of this process",
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


def add_skill_option(parser: argparse.ArgumentParser, skills: Mapping[str, str],
                     default: str | None = None, default_text: str = "") -> None:  # fmt: skip
    """--skill: one of `skills` (name -> what it is: skill.search.SKILL_DESCRIPTIONS); default
    None: the policy's."""
    described = "; ".join(f"{name}: {text}" for name, text in skills.items())
    if not default_text:
        default_text = default or "the one the policy's manifest names, paper for the baseline"
    parser.add_argument(
        "--skill",
        default=default,
        choices=tuple(skills),
        help=f"{described}; default: {default_text}",
    )


def add_skill_constant_option(parser: argparse.ArgumentParser, parse: Callable) -> None:
    """--skill-constant NAME=VALUE (repeatable): train.py's, eval.py's, the arm's; parse: its
    type, NAME=VALUE to (name, value) (`skill.skill_cli.skill_constant`)."""
    parser.add_argument(
        "--skill-constant",
        action="append",
        type=parse,
        metavar="NAME=VALUE",
        help="one of the skill's constants set (skill/search.py SkillConfig, SI units, e.g. "
        "spiral_axial_ref=0.001), each in the range SkillConfig accepts for it; repeatable; "
        "the run's record (config.json, skill.json) holds them",
    )


def ray_address(text: str) -> str:
    """argparse type of --ray: `auto`, `local` or HOST:PORT (a host name or address, a port in
    1..65535, in ASCII digits); the address as given."""
    text = str(text).strip()
    if text in ("auto", "local"):
        return text
    host, _, port = text.rpartition(":")
    quoted = shown(text)
    if not host or not port:
        raise argparse.ArgumentTypeError(f"must be auto, local or HOST:PORT, got {quoted}")
    try:
        host.strip("[]").encode("idna")  # a label over 63 characters, an empty label
    except UnicodeError:
        raise argparse.ArgumentTypeError(f"must start with a host name, got {quoted}") from None
    if not (port.isascii() and port.isdigit() and 1 <= int(port) <= 65535):
        raise argparse.ArgumentTypeError(f"must end in a port 1..65535, got {quoted}")
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
        "but for a few trials' last bits (auto: the cluster `ray start` runs on this node; "
        "HOST:PORT: another; no address: a local one on this machine); needs the cluster "
        'extra: pip install -e ".[cluster]"',
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

    Unset: one worker process per core on the mujoco engine (faster than threads, the same
    results: docs/design/worker_processes.md), none on a single core or on another engine.
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


def parse_ranges(text: str, name: str, limit: int = MAX_AXIS) -> tuple[float, ...]:
    """The values of a grid axis flag `name`: '0.5,1,2' or 'START:STOP:STEP' (inclusive) or a mix;
    UsageError if empty, not finite or more than `limit` values (counted before any is made)."""
    values: list[float] = []
    try:
        for item in (s.strip() for s in text.split(",")):
            if not item:
                continue
            parts = [float(p) for p in item.split(":")]
            if not all(math.isfinite(v) for v in parts) or len(parts) not in (1, 3):
                raise ValueError
            if len(parts) == 3:
                start, stop, step = parts
                if not step > 0:
                    raise UsageError(f"{name}: step of {item!r} must be positive")
                count = (stop - start) / step + 1e-9
                if count + 1 + len(values) > limit:
                    raise UsageError(
                        f"{name}: {item!r} gives more than {limit:,} values, the most a grid axis "
                        "takes"
                    )
                count = math.floor(count) + 1
                values += [round(start + k * step, 9) for k in range(max(count, 0))]
            else:
                values.append(parts[0])
            if len(values) > limit:
                raise UsageError(f"{name}: more than {limit:,} values, the most a grid axis takes")
    except ValueError as exc:
        if str(exc).startswith(name):
            raise
        shown = text if len(text) <= 40 else text[:37] + "..."
        raise UsageError(f"{name}: cannot read {shown!r} (give 0.5,1,2 or 1:8:1)") from None
    if not values:
        raise UsageError(f"{name} is empty: give comma-separated values or START:STOP:STEP")
    seen, repeated = set(), []
    for v in values:
        if v in seen and v not in repeated:
            repeated.append(v)
        seen.add(v)
    if repeated:
        shown = ", ".join(f"{v:g}" for v in repeated[:3]) + (", ..." if len(repeated) > 3 else "")
        raise UsageError(
            f"{name} repeats {len(repeated):,} value{'s' * (len(repeated) > 1)} ({shown}): ranges "
            "are rounded to 1e-9, give distinct values"
        )
    return tuple(values)


# -- path flags ---------------------------------------------------------------------------------


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
        shown = errors.shown_path(text)
        raise argparse.ArgumentTypeError(f"{shown!r} is a symbolic link loop") from None
    except OSError as e:
        why = (
            "is a symbolic link loop"
            if e.errno == errno.ELOOP
            else f"cannot be used ({e.strerror})"
        )
        raise argparse.ArgumentTypeError(f"{errors.shown_path(text)!r} {why}") from None
    return path
