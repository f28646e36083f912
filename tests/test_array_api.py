"""One source, two array libraries: NumPy and JAX agree; jit, vmap and grad work; no JAX needed.

Every public array function of rotations, dmp, control and params runs on random batched inputs
in NumPy (float64, the reference) and in JAX: float64 within 1e-6, float32 within 1e-4 (relative
to the output's scale), under jit and under vmap over the batch.
"""

import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from mjx_peg.skill import dmp, osc, params
from mjx_peg.world import rotations

TOL64 = 1e-6
TOL32 = 1e-4
BATCH = 8


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rotations(rng, n):
    return rotations.matrix_from_rotvec(_unit(rng.normal(size=(n, 3))) * rng.uniform(0, 3, (n, 1)))


def _jacobian(rng, n):
    """(n, 6, 6) well-conditioned Jacobians (singular values 0.3-1.5)."""
    u, _, vt = np.linalg.svd(rng.normal(size=(n, 6, 6)))
    return u @ (rng.uniform(0.3, 1.5, (n, 6, 1)) * vt)


def _mass(rng, n):
    a = rng.normal(size=(n, 6, 6))
    return a @ np.swapaxes(a, -1, -2) / 6 + 0.5 * np.eye(6)


_CENTERS, _WIDTHS = dmp.basis_centers(dmp.DMPConfig().n_basis, dmp.DMPConfig().phase_span)
_WEIGHTS = dmp.fit_forcing_weights(dmp.DMPConfig())


def _cases():
    """name -> (function of arrays only, input builder rng -> tuple, vmap in_axes)."""
    b = BATCH

    def quat(rng):
        return _unit(rng.normal(size=(b, 4)))

    def stiffness(rng):
        return dmp.stiffness_diag(rng.uniform(10, 1000, b), rng.uniform(10, 1000, b))

    def controller_inputs(rng):
        return (
            rng.normal(size=(b, 3)),
            _rotations(rng, b),
            rng.normal(size=(b, 3)),
            rng.normal(size=(b, 3)),
            rng.normal(size=(b, 3)),
            _rotations(rng, b),
        )

    all_batched = 0
    return {
        "quat_mul": (rotations.quat_mul, lambda r: (quat(r), quat(r)), all_batched),
        "quat_conj": (rotations.quat_conj, lambda r: (quat(r),), all_batched),
        "quat_from_rotvec": (
            rotations.quat_from_rotvec,
            lambda r: (r.normal(size=(b, 3)),),
            all_batched,
        ),
        "rotvec_from_quat": (rotations.rotvec_from_quat, lambda r: (quat(r),), all_batched),
        "matrix_from_quat": (rotations.matrix_from_quat, lambda r: (quat(r),), all_batched),
        "quat_from_matrix": (rotations.quat_from_matrix, lambda r: (_rotations(r, b),), 0),
        "matrix_from_rotvec": (
            rotations.matrix_from_rotvec,
            lambda r: (r.normal(size=(b, 3)),),
            all_batched,
        ),
        "rotvec_from_matrix": (rotations.rotvec_from_matrix, lambda r: (_rotations(r, b),), 0),
        "quat_from_yaw": (rotations.quat_from_yaw, lambda r: (r.uniform(-3, 3, b),), 0),
        "skew": (rotations.skew, lambda r: (r.normal(size=(b, 3)),), 0),
        "phase": (lambda t: dmp.phase(t, 0.8, 4.0), lambda r: (r.uniform(0, 3, b),), 0),
        "forcing": (
            dmp.forcing,
            lambda r: (r.uniform(0, 1, b), _WEIGHTS, _CENTERS, _WIDTHS),
            (0, None, None, None),
        ),
        "minimum_jerk": (lambda t: dmp.minimum_jerk(t, 0.9), lambda r: (r.uniform(-1, 2, b),), 0),
        "cruise_profile": (
            lambda t: dmp.cruise_profile(t, 0.9, 0.5),
            lambda r: (r.uniform(-1, 2, b),),
            0,
        ),
        "critical_damping": (
            lambda k: dmp.critical_damping(k, 0.7),
            lambda r: (stiffness(r),),
            all_batched,
        ),
        "stiffness_diag": (
            dmp.stiffness_diag,
            lambda r: (r.uniform(10, 1000, b), r.uniform(10, 1000, b)),
            all_batched,
        ),
        "compliance_offset": (
            dmp.compliance_offset,
            lambda r: (1e-3 * r.normal(size=(b, 6, 6)), 10 * r.normal(size=(b, 6))),
            all_batched,
        ),
        "coupling_term": (
            dmp.coupling_term,
            lambda r: (stiffness(r), 1e-3 * r.normal(size=(b, 6, 6)), 10 * r.normal(size=(b, 6))),
            all_batched,
        ),
        "scaled_modified_goal": (
            lambda g, y0, f, dy: dmp.scaled_modified_goal(g, y0, f, 250.0, dy),
            lambda r: (
                r.normal(size=(b, 6)),
                r.normal(size=(b, 6)),
                r.normal(size=b),
                r.normal(size=(b, 6)),
            ),
            all_batched,
        ),
        "dmp_acceleration": (
            lambda y, yd, g_m, k, d: dmp.dmp_acceleration(y, yd, g_m, k, d, 0.9),
            lambda r: (*r.normal(size=(3, b, 6)), stiffness(r), 20 * r.uniform(1, 2, (b, 6))),
            all_batched,
        ),
        "task_state": (osc.task_state, controller_inputs, all_batched),
        "world_from_task_accel": (
            osc.world_from_task_accel,
            lambda r: (r.normal(size=(b, 6)), _rotations(r, b)),
            all_batched,
        ),
        "damped_pinv": (lambda j: osc.damped_pinv(j, 0.01), lambda r: (_jacobian(r, b),), 0),
        "osc_torque": (
            lambda m, j, jd, h, ydd: osc.osc_torque(m, j, jd, h, ydd, 0.01),
            lambda r: (
                _mass(r, b),
                _jacobian(r, b),
                r.normal(size=(b, 6)),
                10 * r.normal(size=(b, 6)),
                r.normal(size=(b, 6)),
            ),
            all_batched,
        ),
        "clamp_torque": (
            osc.clamp_torque,
            lambda r: (200 * r.normal(size=(b, 6)), np.array([150.0, 150, 150, 28, 28, 28])),
            (0, None),
        ),
        "controller_from_action": (
            params.controller_from_action,
            lambda r: (3 * r.normal(size=(b, 38)),),
            0,
        ),
        "action_from_controller": (
            lambda kt, kth, c: params.action_from_controller(params.ControllerParams(kt, kth, c)),
            # atanh amplifies float32 rounding by cosh(a)^2: stay in a moderate box
            lambda r: tuple(params.controller_from_action(r.uniform(-3, 3, (b, 38))))[:3],
            all_batched,
        ),
        "vector_from_controller": (
            lambda kt, kth, c: params.vector_from_controller(params.ControllerParams(kt, kth, c)),
            lambda r: tuple(params.controller_from_action(r.normal(size=(b, 38))))[:3],
            all_batched,
        ),
        "controller_from_vector": (
            params.controller_from_vector,
            lambda r: (r.normal(size=(b, 38)),),
            0,
        ),
    }


CASES = _cases()


def _leaves(out):
    return [np.asarray(x, dtype=np.float64) for x in jax.tree_util.tree_leaves(out)]


def _compare(name, got, ref, tol):
    """Max error relative to each output's scale; asserts it is below tol, returns it."""
    worst = 0.0
    for g, r in zip(_leaves(got), _leaves(ref), strict=True):
        assert g.shape == r.shape, f"{name}: shape {g.shape} != {r.shape}"
        scale = max(1.0, float(np.max(np.abs(r))))
        worst = max(worst, float(np.max(np.abs(g - r))) / scale)
    assert worst < tol, f"{name}: max scaled difference {worst:.2e} >= {tol}"
    return worst


def _inputs(name):
    return CASES[name][1](np.random.default_rng(sum(map(ord, name))))


@pytest.mark.parametrize("name", sorted(CASES))
def test_numpy_and_jax_float64_agree(name, x64):
    fn, _, _ = CASES[name]
    inputs = _inputs(name)
    ref = fn(*inputs)
    got = fn(*[jnp.asarray(x, dtype=jnp.float64) for x in inputs])
    assert all(isinstance(x, jax.Array) for x in jax.tree_util.tree_leaves(got))
    err = _compare(name, got, ref, TOL64)
    print(f"{name}: float64 {err:.1e}")


@pytest.mark.parametrize("name", sorted(CASES))
def test_numpy_and_jax_float32_agree_under_jit_and_vmap(name):
    fn, _, in_axes = CASES[name]
    inputs = _inputs(name)
    ref = fn(*inputs)
    args = [jnp.asarray(x, dtype=jnp.float32) for x in inputs]
    eager = _compare(name, fn(*args), ref, TOL32)
    jitted = _compare(name, jax.jit(fn)(*args), ref, TOL32)
    vmapped = _compare(name, jax.jit(jax.vmap(fn, in_axes=in_axes))(*args), ref, TOL32)
    print(f"{name}: float32 eager {eager:.1e}, jit {jitted:.1e}, vmap {vmapped:.1e}")


def test_numpy_float32_stays_float32():
    rng = np.random.default_rng(0)
    p = params.controller_from_action(rng.normal(size=(4, 38)).astype(np.float32))
    assert p.compliance.dtype == np.float32 and p.k_t.dtype == np.float32
    q = rotations.quat_from_rotvec(rng.normal(size=(4, 3)).astype(np.float32))
    assert q.dtype == np.float32


def _torque_from_action(action, wrench, y, yd, y0, s):
    """A whole controller step as a function of the policy's action (all JAX)."""
    p = params.controller_from_action(action)
    k_y = dmp.stiffness_diag(p.k_t, p.k_theta)
    d_y = dmp.critical_damping(k_y, 1.0)
    f = dmp.forcing(s, _WEIGHTS, _CENTERS, _WIDTHS)
    dy = dmp.compliance_offset(p.compliance, wrench)
    g_m = dmp.scaled_modified_goal(jnp.zeros_like(y0), y0, f, 300.0, dy)
    ydd = dmp.dmp_acceleration(y, yd, g_m, k_y, d_y, 1.0)
    rng = np.random.default_rng(5)
    mass, jac = jnp.asarray(_mass(rng, 1)[0]), jnp.asarray(_jacobian(rng, 1)[0])
    u = osc.osc_torque(mass, jac, jnp.zeros(6), jnp.ones(6), ydd, 0.01)
    return jnp.sum(u**2)


@pytest.mark.parametrize("scale", [1.0, 1e6])
def test_grad_through_the_parameter_map_to_the_torque_is_finite(scale):
    rng = np.random.default_rng(6)
    action = jnp.asarray(scale * np.sign(rng.normal(size=38)), dtype=jnp.float32)
    args = [jnp.asarray(rng.normal(size=6), dtype=jnp.float32) for _ in range(4)]
    grad = jax.jit(jax.grad(_torque_from_action))(action, *args, jnp.float32(0.5))
    assert grad.shape == (38,) and bool(jnp.all(jnp.isfinite(grad)))
    if scale == 1.0:
        assert float(jnp.max(jnp.abs(grad))) > 0.0


def test_grad_of_rotations_is_finite_at_identity_and_half_turn():
    def loss(v):
        r = rotations.matrix_from_rotvec(v)
        return jnp.sum(rotations.rotvec_from_matrix(r) ** 2) + jnp.sum(
            rotations.rotvec_from_quat(rotations.quat_from_rotvec(v))
        )

    grad = jax.jit(jax.grad(loss))
    for v in (jnp.zeros(3), jnp.array([1e-5, 0.0, 0.0]), jnp.array([0.0, 0.0, 3.1])):
        g = grad(v)
        assert bool(jnp.all(jnp.isfinite(g))), (v, g)


_NO_JAX = textwrap.dedent(
    """
    import sys
    sys.modules["jax"] = None  # `import jax` now raises ImportError
    import mjx_peg.world.rotations, mjx_peg.skill.dmp, mjx_peg.skill.osc, mjx_peg.skill.params
    import mjx_peg.skill.search, mjx_peg.skill.sensor
    assert "numpy" not in sys.modules, "a module imported numpy at top level"
    import numpy as np
    from mjx_peg.skill import osc
    from mjx_peg.skill import dmp
    from mjx_peg.skill import params
    from mjx_peg.world import rotations
    p = params.controller_from_action(np.zeros((2, 38)))
    k_y = dmp.stiffness_diag(p.k_t, p.k_theta)
    config = dmp.DMPConfig()
    w = dmp.fit_forcing_weights(config)
    c, wd = dmp.basis_centers(config.n_basis, config.phase_span)
    f = dmp.forcing(dmp.phase(np.array([0.1, 0.2]), 1.0, 4.0), w, c, wd)
    g_m = dmp.scaled_modified_goal(np.zeros(6), np.ones((2, 6)), f, 300.0, np.zeros(6))
    ydd = dmp.dmp_acceleration(np.ones((2, 6)), np.zeros(6), g_m, k_y,
                               dmp.critical_damping(k_y, 1.0), 1.0)
    u = osc.osc_torque(np.eye(6), np.eye(6), np.zeros(6), np.zeros(6), ydd, 0.01)
    assert u.shape == (2, 6) and np.all(np.isfinite(u))
    assert rotations.rotvec_from_matrix(np.eye(3)).shape == (3,)
    assert not any(m.startswith("jax") for m, v in sys.modules.items() if v is not None)
    print("ok")
    """
)


def test_modules_import_and_run_without_jax():
    result = subprocess.run(
        [sys.executable, "-c", _NO_JAX], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "ok"
