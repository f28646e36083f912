"""The CPU engine's trials on a Ray cluster: one actor per CPU, each a lane of C MuJoCo.

`mujoco.run_on_cpu(..., ray=ADDRESS)` joins a cluster (`"auto"`: the one `ray start` runs on
this node; `"local"`: starts one on this machine; else `HOST:PORT`), keeps one actor per CPU the
cluster offers (`Lane`: each runs `threaded.run_in_threads` on its share in-process, keeping its
`mujoco.batch` simulations warm between calls, as a worker process of `engines/processes.py`
does), splits the trials into interleaved pieces (trial k to piece k mod P: one per actor,
up to four per actor for large calls), hands each actor the next piece as it finishes one, and
merges the results in spec order. A trial's result depends on its spec and parameters only, so
the results are bit-identical to a local run (the compiled pass: but for the last bits of a
trial in the last slots of a program, docs/design/compiled_period.md). An actor lost with its
node is restarted and its call retried by Ray (`max_restarts`, `max_task_retries`), with the
same result. Arguments and results travel through Ray's object store between this package's own
processes; nothing is read from disk. Ray is imported only here, and only when asked for
(`pip install -e ".[cluster]"`).
"""

from __future__ import annotations

import importlib
import sys
import warnings
from collections.abc import Callable

from mjx_peg.engines.processes import interleaved, merge, take_params
from mjx_peg.engines.trial import TrialConfig, TrialResult
from mjx_peg.errors import UsageError
from mjx_peg.skill.params import ControllerParams
from mjx_peg.world.task import TrialSpec

INSTALL = 'pip install -e ".[cluster]"'
RETRIES = 3  # a lost actor's call is retried this many times (on its restarted actor)
# The trials of one call go out in 1 to PIECES_PER_ACTOR pieces per actor, as many as keep
# MIN_PIECE_TRIALS trials each: a piece ends with its slowest trial in a draining batch, so small
# pieces cost (docs/design/ray_pieces.md).
PIECES_PER_ACTOR = 4
MIN_PIECE_TRIALS = 512
_actors: list = []  # one Lane per CPU of the cluster joined


class ClusterError(UsageError):
    """Ray is missing, or the cluster cannot be reached or used (one line says why)."""


def _ray():
    try:
        return importlib.import_module("ray")
    except ImportError:
        raise ClusterError(f"running on a Ray cluster needs Ray: {INSTALL}") from None


class Lane:
    """A Ray actor's body: trials of this package's CPU engine, one lane, in the actor's
    process (its simulations stay warm between calls)."""

    def run(self, specs: TrialSpec, params: ControllerParams, config: TrialConfig, options):
        from mjx_peg.engines import threaded

        return threaded.run_in_threads(specs, params, config, threads=1, **options)

    def pid(self) -> int:
        import os

        return os.getpid()


def connect(address: str) -> list:
    """Join (or start) the cluster at `address` once, and its actors: one per CPU."""
    ray = _ray()
    if not ray.is_initialized():
        target = None if address == "local" else address
        if target not in (None, "auto"):
            _reachable(target)
        try:
            with warnings.catch_warnings():  # Ray starts its daemons by fork + exec, which is
                # safe; JAX's at-fork hook warns of a fork without exec
                warnings.filterwarnings("ignore", "os.fork", RuntimeWarning)
                ray.init(address=target, include_dashboard=False, log_to_driver=False,
                         configure_logging=False)  # fmt: skip
        except (ConnectionError, RuntimeError, ValueError) as error:
            first = str(error).strip().splitlines()[0] if str(error).strip() else type(error)
            raise ClusterError(f"cannot join the Ray cluster at {address!r}: {first}") from None
    if not _actors:
        cpus = int(ray.cluster_resources().get("CPU", 0))
        if cpus < 1:
            raise ClusterError(f"the Ray cluster at {address!r} offers no CPU")
        remote = ray.remote(num_cpus=1, max_restarts=-1, max_task_retries=RETRIES)(Lane)
        _actors.extend(remote.remote() for _ in range(cpus))
        try:
            ray.get([a.pid.remote() for a in _actors])  # every actor up, or one clear error
        except ray.exceptions.RayError as error:
            shutdown()
            raise ClusterError(
                f"the Ray workers cannot run this package ({type(error).__name__}): install it "
                "on every node (pip install -e . in the same version)"
            ) from None
    return _actors


def _reachable(address: str, timeout_s: float = 5.0) -> None:
    """ClusterError unless HOST:PORT accepts a TCP connection (Ray itself waits minutes)."""
    import socket

    host, _, port = address.rpartition(":")
    if not host or not (port.isascii() and port.isdigit() and 1 <= int(port) <= 65535):
        raise ClusterError(f"a Ray address is auto, local or HOST:PORT, got {address[:60]!r}")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s).close()
    except (OSError, UnicodeError) as error:  # UnicodeError: not a host name
        raise ClusterError(f"cannot reach the Ray cluster at {address}: {error}") from None


def shutdown() -> None:
    """Drop the actors and leave the cluster (a local one stops)."""
    _actors.clear()
    ray = sys.modules.get("ray")  # never imported: nothing to leave
    if ray is not None and ray.is_initialized():
        ray.shutdown()


def run_on_cluster(
    specs: TrialSpec,
    params: ControllerParams,
    config: TrialConfig,
    address: str,
    progress: Callable[[int], None] | None = None,
    **options,
) -> TrialResult:
    """Every trial of `specs` on the cluster's actors; `options`: the in-process engine's
    slots_per_thread, batch_threads, persistent.

    The trials go out in interleaved pieces (see PIECES_PER_ACTOR), each actor taking the next
    piece as it finishes one: a slow node takes fewer, and progress comes piece by piece.
    """
    ray = _ray()
    actors = connect(address)
    n = len(specs)
    per_actor = max(1, min(PIECES_PER_ACTOR, n // (MIN_PIECE_TRIALS * len(actors))))
    pieces = interleaved(n, per_actor * len(actors))  # a multiple of the actors: balanced
    todo = list(range(len(pieces)))[::-1]
    running: dict = {}  # future -> (actor, piece index)
    parts: list = [None] * len(pieces)

    def submit(actor) -> None:
        k = todo.pop()
        rows = pieces[k]
        future = actor.run.remote(specs.take(rows), take_params(params, rows), config, options)
        running[future] = (actor, k)

    try:
        for actor in actors[: len(pieces)]:
            submit(actor)
        while running:
            (done,), _ = ray.wait(list(running), num_returns=1)
            actor, k = running.pop(done)
            parts[k] = ray.get(done)
            if todo:
                submit(actor)
            if progress is not None:
                progress(len(pieces[k]))
    except ray.exceptions.RayError as error:
        raise RuntimeError(
            f"a Ray task of the CPU engine failed after {RETRIES} retries: {error}"
        ) from None
    except BaseException:  # Ctrl-C: the actors drop this call, nothing of it is kept
        for future in running:
            ray.cancel(future)
        raise
    return merge(n, pieces, parts)
