"""Run trials on either physics engine: `run_trials(specs, params, engine=...)`.

`mujoco`: C MuJoCo on MuJoCo's batched thread pool (`mujoco.batch`), the controller batched in
NumPy (the default without an accelerator). `mjx`: the
whole trial jitted and vmapped in MJX (GPUs/TPUs). `auto` picks `mjx` when JAX sees an accelerator.
The engines are imported lazily so that the CPU engine never pays for importing JAX.
"""

from __future__ import annotations

from collections.abc import Callable

from mjx_peg.engines.trial import TrialConfig, TrialResult, as_controller_params
from mjx_peg.errors import UsageError
from mjx_peg.world.task import TrialSpec

ENGINES = ("auto", "mujoco", "mjx")


def resolve_engine(engine: str) -> str:
    """'auto' -> 'mjx' if JAX has a GPU/TPU, else 'mujoco'; unknown names raise ValueError."""
    if engine not in ENGINES:
        raise UsageError(f"unknown engine {engine!r}: choose from {', '.join(ENGINES)}")
    if engine != "auto":
        return engine
    try:
        import jax

        accelerated = any(d.platform in ("gpu", "tpu", "cuda", "rocm") for d in jax.devices())
    except Exception:  # no usable JAX backend: the CPU engine still works
        accelerated = False
    return "mjx" if accelerated else "mujoco"


def run_trials(
    specs: TrialSpec,
    params,
    engine: str = "auto",
    config: TrialConfig | None = None,
    progress: Callable[[int], None] | None = None,
    **engine_options,
) -> TrialResult:
    """Run every trial in `specs` and return the results in spec order.

    params: `ControllerParams` (batched or not) or physical 38-vectors, shape (38,) or (B, 38).
    engine_options: `threads` (lanes, default every core),
    `slots_per_thread`, `batch_threads`, `persistent`, `processes` (lanes in that many worker
    processes, `engines/processes.py`) (mujoco); `batch`, `recycle_every` (mjx).
    """
    name = resolve_engine(engine)
    if not isinstance(specs, TrialSpec):
        raise UsageError(f"specs must be a TrialSpec, got {type(specs).__name__}")
    specs.validate()
    if len(specs) == 0:
        raise UsageError("specs holds no trials")
    config = config or TrialConfig()
    params = as_controller_params(params, len(specs))
    return engine_runner(name)(specs, params, config, progress=progress, **engine_options)


def engine_runner(engine: str) -> Callable[..., TrialResult]:
    """The function that runs a batch of trials on a resolved engine: `mujoco.run_on_cpu` (lanes
    in this process, worker processes or a Ray cluster) or `mjx.run_on_device` (jitted on JAX's
    device). Imported on first use, so that the CPU engine never pays for importing JAX."""
    if engine == "mujoco":
        from mjx_peg.engines import mujoco

        return mujoco.run_on_cpu
    if engine == "mjx":
        from mjx_peg.engines import mjx

        return mjx.run_on_device
    raise UsageError(f"unknown engine {engine!r}: choose mujoco or mjx")
