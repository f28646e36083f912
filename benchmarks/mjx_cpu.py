"""The MJX engine on the CPU: one slot's kinematics under each XLA emitter, and the trial
program's compile, stepping rate and memory per slot by batch size.

    python benchmarks/mjx_cpu.py [--batches 8,32,128] [--time-limit 2]

First `mjx.kinematics` of the square's scene, one slot, jitted with XLA's CPU fusion emitters
(jax's default) and without them (`engines.mjx.CPU_COMPILER_OPTIONS`, what the engine runs),
timed after its compile (median of 5 rounds). Then for each batch size the engine's program
(`engines.mjx._Program`) on that many squares (50 mm, +-3 mm / +-3 deg, seed 52, the shipped
spiral with `paper`'s vectors) with as many slots: its trace and compile, one run (every slot
stepped until the last trial ends, in chunks of 50 steps), batch steps/s, trial steps/s (the
steps of live trials) and the program's temporary memory from XLA's `memory_analysis()`. Run
with an empty `JAX_COMPILATION_CACHE_DIR` for compile times. Results: BENCHMARKS.md, "MJX on the
CPU".
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np
from _report import cpu_name, time_calls  # benchmarks/ is on sys.path when run
from mujoco import mjx
from mujoco.mjx._src import smooth

from mjx_peg.engines import mjx as engine
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.policy.export import load_policy
from mjx_peg.skill.search import skill_config
from mjx_peg.world import scene
from mjx_peg.world.task import TaskConfig, sample_trials


def kinematics_ms() -> dict[str, float]:
    """One slot's `mjx.kinematics` (square scene), ms per call, by emitter."""
    mx = mjx.put_model(scene.load_model("square", 0.05))
    d = mjx.make_data(mx)
    return {
        name: 1e3 * time_calls(lambda f=fn: jax.block_until_ready(f(mx, d)), 1.0)
        for name, fn in (
            ("fusion emitters (jax's default)", jax.jit(smooth.kinematics)),
            ("loop emitters (the engine's)", engine.jit(smooth.kinematics)),
        )
    }


def program_row(batch: int, time_limit: float) -> str:
    """The engine's program on `batch` squares in `batch` slots, one markdown table row."""
    task = TaskConfig(shapes=("square",), linear_error=0.003, angular_error=np.deg2rad(3.0))
    specs = sample_trials(task, 52, batch)
    params = as_controller_params(load_policy("paper").controller_vectors(specs), batch)
    config = TrialConfig(time_limit_s=time_limit, search=skill_config("spiral"))
    inputs = {k: jnp.asarray(v) for k, v in engine._slot_inputs(specs, params, config).items()}
    program = engine._Program(scene.load_model("square", 0.05), config, batch, 50)
    start = time.perf_counter()
    compiled = program.run.lower(inputs).compile()
    compile_s = time.perf_counter() - start
    start = time.perf_counter()
    out = jax.device_get(compiled(inputs))
    run_s = time.perf_counter() - start
    steps = np.asarray(out.steps)
    batch_steps = int(np.ceil(steps.max() / 50) * 50)
    temp = compiled.memory_analysis().temp_size_in_bytes
    return (
        f"| {batch} | {compile_s:.1f} s | {run_s:.2f} s | {batch_steps / run_s:,.0f} | "
        f"{steps.sum() / run_s:,.0f} | {temp / 1e6:.2f} MB | {temp / batch / 1e3:.0f} kB | "
        f"{int(out.success.sum())} / {batch} |"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--batches", default="8,32,128", help="slots (= trials) per program")
    p.add_argument("--time-limit", type=float, default=2.0, help="simulated s per trial")
    args = p.parse_args()
    print(f"device: {cpu_name()} (JAX {jax.default_backend()})")
    for name, ms in kinematics_ms().items():
        print(f"one slot's mjx.kinematics, {name}: {ms:.2f} ms a call")
    print("\n| slots | trace + compile | run | batch steps/s | trial steps/s | temporary memory "
          "| per slot | inserted |\n|---:|---:|---:|---:|---:|---:|---:|---:|")  # fmt: skip
    for batch in (int(b) for b in args.batches.split(",")):
        print(program_row(batch, args.time_limit), flush=True)


if __name__ == "__main__":
    main()
