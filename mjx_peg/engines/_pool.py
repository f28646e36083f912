"""Worker processes for the CPU engine: one GIL per core, started once and reused.

Each worker is a fresh interpreter (`python -c`, started with subprocess, never a fork of the
caller, which may hold JAX's threads) that imports only NumPy, MuJoCo and the engine, never
`__main__` and never JAX. It keeps its environments (model copies, MjData) between calls, so a
call costs a few messages. One socket pair per worker carries length-framed byte messages
(`multiprocessing.connection.Connection`), no pickle:

    parent -> worker  b"R" + JSON header (config, slots, threads, array layout, first indices),
                      then every spec and parameter array as raw bytes, one message
                      b"C" + int64 spec indices: more work, answering b"M"
                      b"E": no more work in this call, answering b"M"
                      b"Q": exit
    worker -> parent  b"M": asks for more work (before it runs dry)
                      b"D" + RESULT_DTYPE records: trials that just finished
                      b"F": the call is done on this worker
                      b"X" + traceback text: the call failed on this worker

Trials differ a lot in length, so each worker first gets an interleaved share (FIRST_SHARE of
the trials, at most its slots) and then small chunks on demand. A worker that dies or fails
breaks the call with one RuntimeError in the caller, and the pool is discarded (the next call
starts a new one). A worker whose caller dies (even by SIGKILL) exits within PARENT_CHECK_S.
"""

from __future__ import annotations

import atexit
import collections
import dataclasses
import json
import os
import signal
import subprocess
import sys
import threading
import time
import traceback
from multiprocessing import Pipe
from multiprocessing.connection import Connection, wait
from pathlib import Path

import numpy as np

from mjx_peg.engines.trial import TrialConfig, TrialResult
from mjx_peg.skill.params import ControllerParams
from mjx_peg.world.task import TrialSpec

# One finished trial, as workers send it back.
RESULT_DTYPE = np.dtype(
    [
        ("index", "<i8"),
        ("success", "?"),
        ("time_s", "<f8"),
        ("final_tip_pos", "<f8", (3,)),
        ("peak_force", "<f8"),
        ("reward", "<f8"),
        ("unstable", "?"),
        ("steps", "<i8"),
        ("chatter", "<f8"),
        ("protective_stop", "?"),
    ]
)
# Trials differ a lot in length (a failure runs to the time limit): the workers first get this
# share of the trials, interleaved, then take the rest CHUNK by CHUNK as their trials end, so
# that they finish together.
FIRST_SHARE = 0.75
CHUNK = 4
# A worker checks this often (s) whether its parent is still alive.
PARENT_CHECK_S = 0.5
_PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])


def to_result(records: np.ndarray) -> TrialResult:
    """TrialResult from RESULT_DTYPE records in spec order."""
    return TrialResult(**{name: records[name].copy() for name in RESULT_DTYPE.names[1:]})


def _encode(specs: TrialSpec, params: ControllerParams, config: TrialConfig):
    """(JSON-able layout and config, bytes of every array) for a worker."""
    arrays = {**specs.to_arrays(), **params._asdict()}
    layout, blobs = [], []
    for name, value in arrays.items():
        value = np.ascontiguousarray(value)
        layout.append([name, value.dtype.str, list(value.shape)])
        blobs.append(value.tobytes())
    return {"arrays": layout, "config": dataclasses.asdict(config)}, b"".join(blobs)


def _plain(value):
    """NumPy scalars in a config, for JSON."""
    return value.item()


def _decode(header: dict, blob: bytes):
    arrays, offset = {}, 0
    for name, dtype, shape in header["arrays"]:
        dtype, count = np.dtype(dtype), int(np.prod(shape))
        arrays[name] = np.frombuffer(blob, dtype, count, offset).reshape(shape)
        offset += dtype.itemsize * count
    params = ControllerParams(*(arrays.pop(k) for k in ControllerParams._fields))
    fields = header["config"]
    default = TrialConfig()
    for name, value in fields.items():  # nested dataclasses (dmp, reward) from their dicts
        if dataclasses.is_dataclass(getattr(default, name)):
            fields[name] = type(getattr(default, name))(**value)
    return TrialSpec(**arrays), params, TrialConfig(**fields)


# -- parent side --------------------------------------------------------------------------------


class _Worker:
    def __init__(self):
        self.conn, child = Pipe(duplex=True)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [_PACKAGE_ROOT, env.get("PYTHONPATH")]))
        for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            env.setdefault(var, "1")  # one core per worker
        code = "import sys; from mjx_peg.engines._pool import serve; serve(*map(int, sys.argv[1:]))"
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-c", code, str(child.fileno()), str(os.getpid())],
                pass_fds=(child.fileno(),),
                stdin=subprocess.DEVNULL,
                env=env,
            )
        finally:
            child.close()

    def send(self, data: bytes) -> None:
        try:
            self.conn.send_bytes(data)
        except OSError:
            raise self.died() from None

    def died(self) -> RuntimeError:
        try:
            code = self.proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            code = None
        how = f"signal {-code}" if code is not None and code < 0 else f"exit code {code}"
        return RuntimeError(
            f"mujoco engine worker process {self.proc.pid} died ({how}) while running trials"
        )

    def close(self, timeout: float) -> None:
        try:
            self.conn.send_bytes(b"Q")
        except OSError:
            pass
        self.conn.close()
        try:
            self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


class Pool:
    """Persistent worker processes of this process (see the module docstring)."""

    def __init__(self):
        self.pid = os.getpid()
        self.workers: list[_Worker] = []
        self.lock = threading.Lock()

    def close(self, timeout: float = 5.0) -> None:
        workers, self.workers = self.workers, []
        for w in workers:
            w.close(timeout)

    def run(self, specs, params, config, count, threads, slots, progress) -> TrialResult:
        with self.lock:
            while len(self.workers) < count:
                self.workers.append(_Worker())
            try:
                return self._run(self.workers[:count], specs, params, config, threads, slots,
                                 progress)  # fmt: skip
            except BaseException:
                self.close(timeout=0.0)  # a call broken off leaves the workers mid-call
                raise

    def _run(self, workers, specs, params, config, threads, slots, progress) -> TrialResult:
        n = len(specs)
        header, blob = _encode(specs, params, config)
        header.update(slots=slots, threads=threads)
        share = max(len(workers), int(FIRST_SHARE * n))
        first = min(n, len(workers) * slots * threads, share)
        for k, w in enumerate(workers):
            header["first"] = list(range(k, first, len(workers)))
            w.send(b"R" + json.dumps(header, default=_plain).encode())
            w.send(blob)
        records = np.zeros(n, RESULT_DTYPE)
        received, handed = np.zeros(n, dtype=bool), first
        by_conn = {w.conn: w for w in workers}
        running = set(by_conn)
        while running:
            ready = wait(list(running), timeout=1.0)
            if not ready:
                for w in workers:
                    if w.conn in running and w.proc.poll() is not None:
                        raise w.died()
            for conn in ready:
                try:
                    msg = conn.recv_bytes()
                except (EOFError, OSError):
                    raise by_conn[conn].died() from None
                tag = msg[:1]
                if tag == b"D":
                    done = np.frombuffer(msg, RESULT_DTYPE, offset=1)
                    records[done["index"]] = done
                    received[done["index"]] = True
                    if progress is not None:
                        progress(len(done))
                elif tag == b"M":
                    size = max(1, min(CHUNK, (n - handed) // len(workers)))
                    chunk = np.arange(handed, min(n, handed + size), dtype="<i8")
                    handed += chunk.size
                    by_conn[conn].send(b"C" + chunk.tobytes() if chunk.size else b"E")
                elif tag == b"F":
                    running.discard(conn)
                elif tag == b"X":
                    raise RuntimeError(
                        f"mujoco engine worker process {by_conn[conn].proc.pid} failed:\n"
                        + msg[1:].decode(errors="replace")
                    )
                else:
                    raise RuntimeError(f"mujoco engine worker sent an unknown message {tag!r}")
        if not received.all():
            raise RuntimeError(f"mujoco engine workers returned {received.sum()} of {n} trials")
        return to_result(records)


_POOL: Pool | None = None
_POOL_LOCK = threading.Lock()


def run(specs, params, config, workers, threads, slots, progress) -> TrialResult:
    """Run the trials on `workers` worker processes (started on first use, then reused)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None or _POOL.pid != os.getpid():  # a forked child starts its own
            _POOL = Pool()
        pool = _POOL
    return pool.run(specs, params, config, workers, threads, slots, progress)


def shutdown() -> None:
    """Stop the worker processes (at exit; a later call starts new ones)."""
    global _POOL
    with _POOL_LOCK:
        pool, _POOL = _POOL, None
    if pool is not None and pool.pid == os.getpid():
        if pool.lock.acquire(timeout=1.0):  # else a call is under way in another thread
            try:
                pool.close()
            finally:
                pool.lock.release()
        else:
            pool.close(timeout=0.0)


atexit.register(shutdown)


# -- worker side --------------------------------------------------------------------------------


class _Source:
    """Hands this worker's spec indices to its batches; sends results (thread-safe)."""

    def __init__(self, conn: Connection, first: list[int]):
        self.conn = conn
        self.queue = collections.deque(first)
        self.ended = self.asked = self.stopped = False
        self.done: list[tuple] = []
        self.lock = threading.Lock()

    def _ask(self) -> None:
        if not (self.asked or self.ended):
            self.conn.send_bytes(b"M")
            self.asked = True

    def take(self, wait: bool = True) -> int | None:
        """The next spec index; None when there is no more work (or none at hand, if not wait)."""
        with self.lock:
            while wait and not self.queue and not self.ended and not self.stopped:
                self._ask()
                msg = self.conn.recv_bytes()
                self.asked = False
                if msg[:1] == b"C":
                    self.queue.extend(np.frombuffer(msg, "<i8", offset=1).tolist())
                elif msg[:1] == b"E":
                    self.ended = True
                else:
                    raise RuntimeError(f"unexpected message {msg[:1]!r} during a call")
            if not self.queue or self.stopped:
                return None
            index = self.queue.popleft()
            if not self.queue:
                self._ask()  # before this worker runs dry
            return index

    def finish(self, record: tuple) -> None:
        with self.lock:
            self.done.append(record)

    def flush(self) -> None:
        with self.lock:
            if self.done:
                self.conn.send_bytes(b"D" + np.array(self.done, RESULT_DTYPE).tobytes())
                self.done = []

    def stop(self) -> None:
        self.stopped = True


def _exit_with_parent(parent: int, period_s: float = PARENT_CHECK_S) -> None:
    """Exit this worker at once when its parent dies, even mid-trial (a killed caller leaves
    no workers running): the parent is gone when this process is re-parented."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(period_s)
        os._exit(0)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def serve(fd: int, parent: int) -> None:
    """A worker process's main loop: run calls until told to quit or the parent goes away."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when workers stop
    _exit_with_parent(parent)
    from mjx_peg.engines import mujoco as engine

    conn = Connection(fd)
    while True:
        try:
            msg = conn.recv_bytes()
            if msg[:1] == b"Q":
                return
            header, blob = json.loads(msg[1:]), conn.recv_bytes()
        except (EOFError, OSError):
            return
        try:
            specs, params, config = _decode(header, blob)
            source = _Source(conn, header["first"])
            engine.run_batches(specs, params, config, header["threads"], header["slots"], source)
            source.flush()
            conn.send_bytes(b"F")
        except (EOFError, BrokenPipeError):
            return
        except BaseException:
            try:
                conn.send_bytes(b"X" + traceback.format_exc().encode())
            except OSError:
                return
