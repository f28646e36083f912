"""Ctrl-C and SIGTERM at any instant (`mjx_peg/signals.py`): one line on stderr, exit 130 (143),
whether the command is importing JAX, parsing or running.

The signal goes to the command's whole process group, as a terminal's Ctrl-C does. The
commands start with SIGINT at its default (a test suite run as a background job has it
ignored, and an ignored SIGINT stays ignored). An instant is counted from the start of the
process, or from the moment the program's own code took the signals if that is later: until
then the signal meets the interpreter's own start-up (its `site` import), not this package.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mjx_peg import signals

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def _commands(tmp: Path) -> dict[str, list[str]]:
    py = sys.executable
    return {
        "train.py": [py, "train.py", "--trials", "48", "--num-envs", "8", "--time-limit", "1",
                     "--no-progress", "--out", str(tmp / "train")],
        "eval.py": [py, "eval.py", "--policy", "baseline", "--grid", "custom", "--linear-mm", "1",
                    "--angular-deg", "1", "--trials", "8", "--no-progress", "--out",
                    str(tmp / "eval")],
        "mjx-peg-baseline": [str(BIN / "mjx-peg-baseline"), "--trials", "20"],
        "python -m mjx_peg.robot": [py, "-m", "mjx_peg.robot", "--trials", "5", "--no-progress",
                                    "--out", str(tmp / "robot")],
        "mjx-peg-vision": [str(BIN / "mjx-peg-vision"), "render", "--out", str(tmp / "split"),
                           "--count", "50", "--width", "64", "--height", "64", "--no-progress"],
        "mjx-peg-demo": [str(BIN / "mjx-peg-demo"), "--frames", "0", "--out", str(tmp / "demo")],
    }  # fmt: skip


def _stop(command: list[str], at_s: float, signum: int) -> tuple[int, list[str]]:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "JAX_PLATFORMS": "cpu"}
    start = time.monotonic()
    child = subprocess.Popen(
        command, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        text=True, start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    while not signals.taken(child.pid) and child.poll() is None:
        time.sleep(0.002)
    time.sleep(max(0.0, at_s - (time.monotonic() - start)))
    os.killpg(child.pid, signum)
    _, err = child.communicate(timeout=120)
    return child.returncode, [line for line in err.splitlines() if line.strip()]


@pytest.mark.slow
@pytest.mark.serial
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc (Linux)")
@pytest.mark.parametrize("at_s", [0.1, 0.5, 1.5])
@pytest.mark.parametrize("prog", list(_commands(Path("/"))))
def test_ctrl_c_at_any_instant_is_one_line_and_130(prog, at_s, tmp_path):
    code, lines = _stop(_commands(tmp_path)[prog], at_s, signal.SIGINT)
    assert code == 130 and len(lines) == 1 and lines[0].startswith(prog), (code, lines)
    assert "interrupted" in lines[0]


@pytest.mark.slow
@pytest.mark.serial
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc (Linux)")
@pytest.mark.parametrize("prog", ["train.py", "eval.py", "mjx-peg-vision"])
def test_sigterm_is_one_line_and_143(prog, tmp_path):
    code, lines = _stop(_commands(tmp_path)[prog], 1.5, signal.SIGTERM)
    assert code == 143 and len(lines) == 1 and lines[0].startswith(prog), (code, lines)


@pytest.mark.parametrize(
    "argv, program",
    [
        (["/usr/bin/python3", "/elsewhere/train.py"], None),  # not the one beside the package
        (["/usr/bin/python3", str(ROOT / "train.py"), "--seed", "1"], "train.py"),
        (["/usr/bin/python3", "-X", "importtime", str(ROOT / "eval.py")], "eval.py"),
        (["python", "-m", "mjx_peg.robot", "--dry-run"], "python -m mjx_peg.robot"),
        (["python", "-m", "pytest", "tests"], None),
        (["/venv/bin/python3.11", "/venv/bin/mjx-peg-vision", "render"], "mjx-peg-vision"),
        (["python", "-c", "from multiprocessing.spawn import spawn_main", "train.py"], None),
    ],
)
def test_a_program_of_the_package_is_told_by_its_command_line(argv, program, monkeypatch):
    monkeypatch.setattr(sys, "orig_argv", argv)
    assert signals.program() == program


def test_a_signal_waits_while_a_child_process_or_a_thread_is_started_and_inside_an_import():
    """Raised there, KeyboardInterrupt would leave a spawned child without its preparation data
    (it prints EOFError's traceback), a thread that cannot be joined or a module half made: those
    frames are unsafe, others not."""
    import multiprocessing.popen_spawn_posix as launching

    def frame_in(filename: str):
        scope = {}
        exec(compile("import sys\nframe = sys._getframe()", filename, "exec"), scope)
        return scope["frame"]

    assert signals._unsafe(frame_in(launching.__file__))
    assert signals._unsafe(frame_in("<frozen importlib._bootstrap>"))
    import threading

    scope = {}
    exec(compile("import sys\ndef start():\n    return sys._getframe()\nframe = start()",
                 threading.__file__, "exec"), scope)  # fmt: skip
    assert signals._unsafe(scope["frame"])  # Thread.start
    assert not signals._unsafe(frame_in(__file__))
    assert not signals._unsafe(sys._getframe())


def test_a_signal_while_the_engines_stop_flag_is_being_imported_is_still_one_interrupt(
    monkeypatch,
):
    """The handler asks running engine calls to stop through engines/interrupt.py; a module
    still being imported has no `request` yet: the signal is still the command's interrupt."""
    import types

    monkeypatch.setitem(sys.modules, "mjx_peg.engines.interrupt", types.ModuleType("partial"))
    for name, value in (("_prog", "eval.py"), ("_working", True), ("_raised", False),
                        ("_received", None)):  # fmt: skip
        monkeypatch.setattr(signals, name, value)
    with pytest.raises(KeyboardInterrupt):
        signals._handle(signal.SIGINT, sys._getframe())
    assert signals.received() == signal.SIGINT


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc (Linux)")
def test_a_finished_command_is_told_from_one_still_working_by_its_signal_masks():
    """`taken` once a command holds its signals, `done` once it has ended and ignores them: a
    signal sent after that meets a command whose work is whole (the catalogue does not count it)."""
    code = (
        "import sys, time\nfrom mjx_peg import signals\nsignals.install('t')\n"
        "print('in', flush=True); sys.stdin.readline()\n"
        "signals.finished()\nprint('out', flush=True); time.sleep(30)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    child = subprocess.Popen([sys.executable, "-c", code], env=env, text=True,
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE)  # fmt: skip
    try:
        assert child.stdout.readline() == "in\n"
        assert signals.taken(child.pid) and not signals.done(child.pid)
        child.stdin.write("\n")
        child.stdin.flush()
        assert child.stdout.readline() == "out\n"
        assert signals.done(child.pid) and not signals.taken(child.pid)
    finally:
        child.kill()
        child.wait()
    assert not signals.taken(child.pid) and not signals.done(child.pid)


def _run_command(source: str) -> tuple[int, list[str], str]:
    """Run `source` as a program with SIGINT at its default: (exit status, stderr's lines,
    stdout)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run(
        [sys.executable, "-c", source], env=env, capture_output=True, text=True, timeout=60,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    return run.returncode, [line for line in run.stderr.splitlines() if line.strip()], run.stdout


def test_a_signal_while_a_command_closes_after_its_work_is_one_line_and_130():
    """Main has returned and the command stops its workers: a Ctrl-C that lands there is not
    raised out of the closing (a traceback, then death by SIGINT) but ends the command as
    stopped, in one line."""
    source = (
        "import os, signal, sys, time, types\n"
        "from mjx_peg import cli, signals\n"
        "workers = types.ModuleType('mjx_peg.engines.processes')\n"
        "def shutdown():\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
        "    time.sleep(0.2)\n"
        "    print('closed', flush=True)\n"
        "workers.shutdown = shutdown\n"
        "sys.modules['mjx_peg.engines.processes'] = workers\n"
        "@cli.entry('t')\n"
        "def main(argv=None):\n"
        "    signals.working()\n"
        "    return 0\n"
        "sys.exit(main())\n"
    )
    code, lines, out = _run_command(source)
    assert (code, lines, out) == (130, ["t: interrupted"], "closed\n"), lines


def test_a_retried_signal_after_the_engines_stop_raised_is_not_raised_again():
    """A Ctrl-C that came in an unsafe frame is raised again 20 ms later; if the engines' stop
    request raised KeyboardInterrupt first, the retry must not raise a second one while the
    command prints its line and closes (it did: a traceback, then death by SIGINT)."""
    source = (
        "import signal, sys, time\n"
        "from mjx_peg import cli, signals\n"
        "from mjx_peg.engines import interrupt\n"
        "class Slow:\n"
        "    def __init__(self, stream): self.stream = stream\n"
        "    def write(self, text): time.sleep(0.1); return self.stream.write(text)\n"
        "    def flush(self): self.stream.flush()\n"
        "sys.stderr = Slow(sys.stderr)\n"
        "scope = {}\n"
        "exec(compile('import sys\\nframe = sys._getframe()', '<frozen importlib._bootstrap>',"
        " 'exec'), scope)\n"
        "@cli.entry('t')\n"
        "def main(argv=None):\n"
        "    signals.working()\n"
        "    signals._handle(signal.SIGINT, scope['frame'])  # in an import: retried 20 ms on\n"
        "    interrupt.check()  # the engines stopped first\n"
        "    return 0\n"
        "sys.exit(main())\n"
    )
    code, lines, _ = _run_command(source)
    assert (code, lines) == (130, ["t: interrupted"]), lines
