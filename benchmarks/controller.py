"""Cost of one compliant-DMP controller step per environment, NumPy vs JAX (jit + vmap).

    python benchmarks/controller.py [--batches 1 64 256] [--seconds 0.5] [--write]

One step = task_state + phase + forcing + compliance offset + modified goal + DMP acceleration
+ world_from_task_accel + osc_torque (damped pseudo-inverse, one 6x6 solve) + clamp_torque, on
random but well-conditioned inputs (6 joints). NumPy runs float64 batched over the environments;
JAX runs float32 (its default, as the MJX engine does) under jax.jit(jax.vmap(step)), timed after
a warm-up call with jax.block_until_ready. Reports microseconds per environment-step (the call's
time divided by the batch). `--write` replaces the "## Controller step" section of BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import os
import time

import jax
import jax.numpy as jnp
import numpy as np
from _report import ROOT, cpu_name, time_calls, write_section  # benchmarks/ on sys.path

from mjx_peg.skill import dmp, osc, params

HEADING = "## Controller step"
CONFIG = dmp.DMPConfig()
CENTERS, WIDTHS = dmp.basis_centers(CONFIG.n_basis, CONFIG.phase_span)
WEIGHTS = dmp.fit_forcing_weights(CONFIG)
LIMITS = np.array([150.0, 150.0, 150.0, 28.0, 28.0, 28.0])


def controller_step(
    t,
    pos,
    rot,
    vel,
    goal_pos,
    goal_rot,
    y0,
    k_y,
    d_y,
    compliance,
    wrench,
    jac,
    jdot_qdot,
    mass,
    bias,
):
    """(..., 6) joint torques of one compliant-DMP step (the composition timed here)."""
    y, yd = osc.task_state(pos, rot, vel[..., :3], vel[..., 3:], goal_pos, goal_rot)
    s = dmp.phase(t, CONFIG.tau, CONFIG.alpha_s)
    f = dmp.forcing(s, WEIGHTS, CENTERS, WIDTHS)
    dy = dmp.compliance_offset(compliance, wrench)
    g_m = dmp.scaled_modified_goal(0.0 * y0, y0, f, CONFIG.k_ref, dy)
    ydd = dmp.dmp_acceleration(y, yd, g_m, k_y, d_y, CONFIG.tau)
    u = osc.osc_torque(mass, jac, jdot_qdot, bias, osc.world_from_task_accel(ydd, goal_rot), 0.01)
    return osc.clamp_torque(u, LIMITS)


def make_inputs(batch: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    from mjx_peg.world.rotations import matrix_from_rotvec

    p = params.controller_from_action(rng.normal(size=(batch, 38)))
    k_y = dmp.stiffness_diag(p.k_t, p.k_theta)
    u, _, vt = np.linalg.svd(rng.normal(size=(batch, 6, 6)))
    jac = u @ (rng.uniform(0.3, 1.5, (batch, 6, 1)) * vt)
    a = rng.normal(size=(batch, 6, 6))
    return [
        rng.uniform(0.0, 3.0, batch),
        rng.normal(size=(batch, 3)),
        matrix_from_rotvec(rng.normal(size=(batch, 3))),
        rng.normal(size=(batch, 6)),
        rng.normal(size=(batch, 3)),
        matrix_from_rotvec(rng.normal(size=(batch, 3))),
        rng.normal(size=(batch, 6)),
        k_y,
        dmp.critical_damping(k_y, CONFIG.tau),
        p.compliance,
        10.0 * rng.normal(size=(batch, 6)),
        jac,
        rng.normal(size=(batch, 6)),
        a @ np.swapaxes(a, -1, -2) / 6 + 0.5 * np.eye(6),
        rng.normal(size=(batch, 6)),
    ]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--batches", type=int, nargs="+", default=[1, 64, 256])
    p.add_argument("--seconds", type=float, default=0.5, help="timing budget per measurement")
    p.add_argument("--write", action="store_true", help="update BENCHMARKS.md")
    args = p.parse_args()

    step_jax = jax.jit(jax.vmap(controller_step))
    rows = []
    for batch in args.batches:
        inputs = make_inputs(batch)
        np_s = time_calls(lambda inputs=inputs: controller_step(*inputs), args.seconds)
        jax_inputs = [jnp.asarray(x, dtype=jnp.float32) for x in inputs]
        start = time.perf_counter()
        jax.block_until_ready(step_jax(*jax_inputs))
        compile_s = time.perf_counter() - start
        jax_s = time_calls(lambda a=jax_inputs: jax.block_until_ready(step_jax(*a)), args.seconds)
        rows.append((batch, 1e6 * np_s / batch, 1e6 * jax_s / batch, compile_s))

    threads = os.environ.get("OMP_NUM_THREADS", "unset")
    device = f"{cpu_name()}, {os.cpu_count()} logical cores"
    table = [
        "| batch | NumPy float64 (us / env-step) | JAX float32 jit+vmap (us / env-step) "
        "| JAX compile (s) |",
        "|---:|---:|---:|---:|",
    ]
    table += [f"| {b} | {n:.2f} | {j:.2f} | {c:.2f} |" for b, n, j, c in rows]
    section = "\n".join(
        [
            HEADING,
            "",
            "One compliant-DMP control step per environment (task state, forcing, modified goal,",
            "acceleration, OSC torque with a damped pseudo-inverse, clamp), 6 joints, one process.",
            f"Device: {device}; JAX {jax.__version__} on {jax.default_backend()}, NumPy "
            f"{np.__version__}; OMP_NUM_THREADS={threads} (NumPy/XLA use their default threads).",
            "Median of 5 rounds after a warm-up call; JAX timed with `jax.block_until_ready`.",
            "On a shared 2-core machine repeated runs differ by up to 2x at batch 1.",
            "",
            *table,
            "",
            "Reproduce: `python benchmarks/controller.py --write`",
            "",
        ]
    )
    print(section)
    if args.write:
        write_section(ROOT / "BENCHMARKS.md", HEADING, section)


if __name__ == "__main__":
    main()
