"""How a command stops on Ctrl-C (SIGINT) or SIGTERM: one line, exit 130 or 143, at any instant.

    signals.install_for_program() # mjx_peg/__init__.py: when a program of this package runs
    signals.install("train.py")   # cli.entry, when the command is the program
    ...imports, parsing, checks: a signal ends the process at once (nothing written, nothing
    started)
    signals.working()             # from here on it raises KeyboardInterrupt (Terminated)

Before `working()` a signal prints `PROG: interrupted` and exits at once: an import of a C
extension (JAX, MuJoCo) that a KeyboardInterrupt would cut in half, and crash or swallow it,
never continues. After it, the signal is raised in the main thread as KeyboardInterrupt
(`Terminated` for SIGTERM), so that what is being written is finished or removed and worker
processes are stopped; never inside an import or a garbage-collector callback (where Python
would print and drop it, or leave a module half made) or while a child process or a thread is
being started (the child would be left without its instructions; the thread could never be
joined): there it is raised again 20 ms later.
Running CPU-engine calls are asked to stop at once (`engines/interrupt.py`). Later signals of
either kind, while the command unwinds or closes (`unwinding`), are recorded and not raised. A
signal that was ignored when the process started (SIGINT in a background job) stays ignored.
"""

from __future__ import annotations

import _thread
import gc
import os
import signal
import sys

# The programs of this package (pyproject.toml's scripts, the two scripts beside the package)
PROGRAMS = ("mjx-peg-train", "mjx-peg-eval", "mjx-peg-demo", "mjx-peg-baseline", "mjx-peg-robot",
            "mjx-peg-scene", "mjx-peg-vision")  # fmt: skip
SCRIPTS = ("train.py", "eval.py")
EXIT_STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143}  # 128 + the signal's number
WORD = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated"}
RETRY_S = 0.02  # a signal that arrived in an import or a gc callback is raised again this late


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that the same clean-up runs."""


_prog: str | None = None
_working = False
_received: int | None = None
_raised = False
_previous: dict[int, object] = {}


def _in_main_thread() -> bool:
    threading = sys.modules.get("threading")  # not imported yet: only the main thread runs
    return threading is None or threading.current_thread() is threading.main_thread()


# multiprocessing's modules that start a child: interrupted between the child's start and the
# preparation data it is sent, the child reads an empty pipe and prints EOFError's traceback
_LAUNCHING = tuple(f"{os.sep}multiprocessing{os.sep}{name}.py"
                   for name in ("popen_spawn_posix", "popen_forkserver", "popen_fork"))  # fmt: skip


def threading_file() -> str | None:
    """threading.py's path, once it is imported (a thread is started only after)."""
    threading = sys.modules.get("threading")
    return getattr(threading, "__file__", None)


def _unsafe(frame) -> bool:
    """Whether raising in `frame` would be lost or leave something half made: inside an import,
    a garbage-collector callback, a finalizer, the start of a child process or of a thread."""
    callbacks = {getattr(cb, "__code__", None) for cb in gc.callbacks}
    while frame is not None:
        code = frame.f_code
        if code.co_filename.startswith("<frozen importlib") or code in callbacks:
            return True
        if code.co_filename.endswith(_LAUNCHING):
            return True
        if code.co_name == "start" and code.co_filename == threading_file():
            return True  # Thread.start: a thread not yet marked started cannot be joined
        if code.co_name == "__del__":
            return True
        frame = frame.f_back
    return False


def _handle(signum, frame) -> None:
    global _received, _raised
    if not _working:
        line = f"{_prog}: {WORD[signum]}\n"
        os.write(2, line.encode(errors="replace"))
        os._exit(EXIT_STATUS[signum])
    _received = _received or signum
    if _raised:
        return  # unwinding or closing already
    # (a module being imported may not have its functions yet)
    stop = getattr(sys.modules.get("mjx_peg.engines.interrupt"), "request", None)
    if stop is not None:
        stop()
    if _unsafe(frame):
        import threading

        timer = threading.Timer(RETRY_S, _thread.interrupt_main, (signum,))
        timer.daemon = True
        timer.start()
        return
    _raised = True
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def program() -> str | None:
    """The name of this process's program if it is one of this package's (a console script,
    train.py or eval.py beside the package, `python -m mjx_peg...`), else None."""
    # The command line the process was started with (a worker of multiprocessing's spawn has
    # its parent's sys.argv, never its command line).
    argv = list(getattr(sys, "orig_argv", sys.argv))[1:]
    while argv and argv[0].startswith("-") and argv[0] != "-m":
        if argv[0] == "-c":
            return None
        argv = argv[2:] if argv[0] in ("-X", "-W", "-Q") else argv[1:]
    if not argv:
        return None
    if argv[0] == "-m":
        module = argv[1] if len(argv) > 1 else ""
        return f"python -m {module}" if module.startswith("mjx_peg") else None
    name = os.path.basename(argv[0])
    if name in PROGRAMS:
        return name
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if name in SCRIPTS and os.path.dirname(os.path.abspath(argv[0])) == here:
        return name
    return None


def install_for_program() -> None:
    """`install` under the program's name when this process is a program of this package (the
    package's first import, before anything heavy is imported); else nothing."""
    name = program()
    if name is not None:
        install(name)


def install(prog: str) -> None:
    """Take SIGINT and SIGTERM for the command `prog` (the process is this command), each unless
    it was ignored when the process started."""
    global _prog, _working, _received, _raised
    if not _in_main_thread():
        return
    _prog, _working, _received, _raised = prog, False, None, False
    for signum in EXIT_STATUS:
        previous = signal.getsignal(signum)
        if previous is signal.SIG_IGN or previous is _handle:
            continue
        _previous[signum] = previous
        signal.signal(signum, _handle)


def working() -> None:
    """From now on a signal unwinds the command (KeyboardInterrupt, Terminated) instead of
    ending the process at once: call it before writing anything or starting any process."""
    global _working
    _working = True


def _sigterm_in(pid: int, mask: str) -> bool:
    """Whether SIGTERM is in the signal mask `mask` (`SigCgt`: caught, `SigIgn`: ignored) of
    process `pid` (Linux: /proc/PID/status; False elsewhere)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            line = next((line for line in f if line.startswith(f"{mask}:")), f"{mask}: 0")
    except OSError:
        return False
    return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)


def unwinding() -> None:
    """The command stops or closes: a KeyboardInterrupt for the signal is on its way, raised by
    other code than the handler (the engines' stop, `engines/interrupt.py`), or the command's
    work has returned and it closes (its workers stopped, its exit status settled). From now on
    a signal, or the retry of one that came in an unsafe frame, is recorded and not raised: one
    KeyboardInterrupt, a whole closing, and the command still ends as stopped, in one line."""
    global _raised
    if _in_main_thread():
        _raised = True


def taken(pid: int) -> bool:
    """Whether process `pid` has a handler for SIGTERM, which Python alone never installs: a
    program of this package has taken its signals (Linux: /proc/PID/status; False elsewhere)."""
    return _sigterm_in(pid, "SigCgt")


def done(pid: int) -> bool:
    """Whether process `pid`, having taken its signals, now ignores SIGTERM: its command has
    ended (`finished`) and the process is exiting (Linux; False elsewhere)."""
    return _sigterm_in(pid, "SigIgn")


def received() -> int | None:
    """The signal the command was stopped by (after `install`), or None."""
    return _received


def finished() -> None:
    """The command has ended and the process exits: a signal from now on is ignored (a second
    Ctrl-C must not turn a clean exit into a KeyboardInterrupt at shutdown)."""
    global _prog
    if not _in_main_thread():
        return
    for signum in _previous:
        signal.signal(signum, signal.SIG_IGN)
    _previous.clear()
    _prog = None
