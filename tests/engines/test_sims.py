"""engines/sims.py: a batch of simulations steps as C MuJoCo does, to the bit, and a trial edits
only the model fields each simulation owns."""

import numpy as np
import pytest


@pytest.mark.parametrize("persistent", [True, False])
def test_batch_step_is_mj_step2_then_mj_step1(persistent, mixed_specs):
    """The engine's physics: Batch.step(stage=mjSTAGE_VEL) from forward(ACC), forward(VEL) is
    C MuJoCo's start_trial, mj_step1, then (ctrl, mj_step2, mj_step1) per step, to the bit."""
    import mujoco

    from mjx_peg.engines.sims import Sims
    from mjx_peg.world import scene

    specs, n = mixed_specs(40, seed=9), 4
    specs = specs.take(np.flatnonzero(specs.shape_id == 1)[:n])  # squares
    sims = Sims(("square", float(specs.size[0])), n, nthread=2, persistent=persistent)
    models = [scene.load_model("square", float(specs.size[0])) for _ in range(n)]
    datas = [mujoco.MjData(m) for m in models]
    for i in range(n):
        sims.load(i, specs, i)
        scene.start_trial(specs, i, models[i], datas[i], sims.ids)
        mujoco.mj_step1(models[i], datas[i])
    ids = np.arange(n, dtype=np.int32)
    sims.forward(ids)
    rng = np.random.default_rng(0)
    for _ in range(200):
        torques = rng.normal(size=(n, 6)) * 5.0 + np.array([d.qfrc_bias for d in datas])
        for m, d, u in zip(models, datas, torques, strict=True):
            d.ctrl[:] = u
            mujoco.mj_step2(m, d)
            mujoco.mj_step1(m, d)
        sims.step(ids, torques)
        for i, d in enumerate(datas):
            for field in ("qpos", "qvel", "site_xpos", "site_xmat", "sensordata", "qfrc_bias"):
                got = sims.batch.bind(field)[i]
                np.testing.assert_array_equal(got, getattr(d, field), err_msg=field)
            assert sims.time[i] == d.time


def test_start_trial_edits_only_the_fields_the_engine_expands(mixed_specs):
    """The batch gives each simulation its own TRIAL_MODEL_FIELDS; scene.start_trial must edit
    no other model field."""
    import mujoco

    from mjx_peg.engines import sims
    from mjx_peg.world import scene

    specs = mixed_specs(6, seed=10)
    for i in range(len(specs)):
        key = sims.scene_key(specs, i)
        before, m = scene.load_model(*key), scene.load_model(*key)
        scene.start_trial(specs, i, m, mujoco.MjData(m), scene.scene_ids(m))
        changed = {
            name for name in dir(m)
            if isinstance(getattr(m, name, None), np.ndarray)
            and not np.array_equal(getattr(m, name), getattr(before, name))
        }  # fmt: skip
        assert changed <= set(sims.TRIAL_MODEL_FIELDS), changed
