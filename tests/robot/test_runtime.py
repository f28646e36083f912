"""The robot runtime (`mjx_peg.robot`): the engine's trial on the simulated arm, command rates,
safety stops, the policy's numbers, no JAX, and one-line errors."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from mjx_peg.engines import mujoco as cpu_engine
from mjx_peg.engines.trial import TrialConfig, as_controller_params
from mjx_peg.policy.export import load_policy, save_policy
from mjx_peg.robot.runtime import (
    HoleEstimate,
    SafetyStop,
    SkillRuntime,
    controller_vector,
    run_skill,
)
from mjx_peg.robot.sim_arm import SimArm
from mjx_peg.skill import search
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.search import skill_config
from mjx_peg.world.task import TaskConfig, sample_trials

SHORT = TrialConfig(time_limit_s=3.0)


def _specs(n=4, seed=3, linear_mm=2.0, angular_deg=2.0):
    task = TaskConfig(
        shapes=("circle", "square"),
        linear_error=linear_mm / 1000.0,
        angular_error=np.deg2rad(angular_deg),
    )
    return sample_trials(task, seed, n)


@pytest.mark.parametrize("skill", ["paper", "spiral"])
def test_simulated_arm_runs_the_engines_trial(skill):
    """At 500 Hz the runtime on SimArm is the C engine's trial, each skill: the runtime runs the
    engines' period on a batch of one, so every command's tcp position follows the engine's
    trial (run alone) within 1e-9 m to the end, contact included, and the trial ends as in the
    engine's batch: the same outcome, time and commands, the tip within 1e-9 m."""
    specs, vec = _specs(), baseline_params()
    config = SHORT.replace(search=skill_config(skill))
    batch = cpu_engine.run_on_cpu(specs, as_controller_params(vec, len(specs)), config, threads=1)
    assert batch.success.any() and not batch.success.all()  # both outcomes are compared
    for i in range(len(specs)):
        engine_tcp, engine_wrench = [], []

        def observe(lane, rows, wrench, tcp=engine_tcp, wrenches=engine_wrench):
            tcp.append(lane.tcp_pos[0].copy())
            wrenches.append(wrench[0].copy())

        alone = cpu_engine.run_on_cpu(specs.take([i]), as_controller_params(vec, 1), config,
                                      threads=1, observer=observe)  # fmt: skip
        arm = SimArm(specs, i)
        runtime = SkillRuntime(vec, HoleEstimate.of_trial(specs, i), config)
        run = run_skill(arm, runtime, done=arm.inserted)
        assert run.success == batch.success[i] == alone.success[0] and run.stopped == ""
        assert run.time_s == pytest.approx(batch.time_s[i], abs=1e-9)
        assert run.commands == batch.steps[i] == alone.steps[0] == len(engine_tcp)
        np.testing.assert_allclose(run.log["tcp_pos"], engine_tcp, atol=1e-9, rtol=0)
        np.testing.assert_allclose(arm.tip_pos(), batch.final_tip_pos[i], atol=1e-9, rtol=0)
        # The same F/T readings: the trial's noise and bias, latency, filter, damping.
        np.testing.assert_allclose(run.log["wrench"], engine_wrench, atol=1e-9, rtol=0)
        assert np.abs(run.log["wrench"][1:200]).max() > 1e-3  # the noise is there


def test_simulated_arm_runs_the_engines_spiral():
    """The spiral's state is carried by the runtime as by the engine: a peg that the shipped
    `paper` policy leaves on the rim with the spiral skill's spiral off (trial 155 of the 500 of
    experiments/contact.py, +-4 mm / +-6 deg, seed 1) inserts with it, with the same outcome,
    time and commands on the simulated arm."""
    task = TaskConfig(shapes=("circle", "square"), sizes=(0.05,), linear_error=0.004,
                      angular_error=np.deg2rad(6.0))  # fmt: skip
    specs = sample_trials(task, 1, 500).take([155])
    vectors = load_policy("paper").controller_vectors(specs)
    spiral = skill_config("spiral")
    runs = {
        name: cpu_engine.run_on_cpu(specs, as_controller_params(vectors, 1), threads=1,
                                    config=TrialConfig(time_limit_s=8.0, search=search))
        for name, search in (("still", spiral.replace(spiral_speed=0.0)), ("spiral", spiral))
    }  # fmt: skip
    assert not runs["still"].success[0] and runs["spiral"].success[0]
    config = TrialConfig(time_limit_s=8.0, search=spiral)
    arm = SimArm(specs, 0)
    run = run_skill(arm, SkillRuntime(vectors[0], HoleEstimate.of_trial(specs, 0), config),
                    done=arm.inserted)  # fmt: skip
    assert run.success and run.commands == runs["spiral"].steps[0]
    assert run.time_s == pytest.approx(runs["spiral"].time_s[0], abs=1e-9)


def test_simulated_arm_stops_a_settled_skill_as_the_engine_ends_it():
    """A failure that settles (almost no translational stiffness: the arm hovers at rest, the
    wrench it senses steady) stops the runtime with "settled" at the control period at which the
    engine ends the trial."""
    task = TaskConfig(shapes=("circle",), sizes=(0.05,), linear_error=0.002,
                      angular_error=np.deg2rad(3.0))  # fmt: skip
    specs, vec = sample_trials(task, 3, 6).take([0]), baseline_params().copy()
    vec[0] = 1e-6  # k_t
    config = TrialConfig(time_limit_s=10.0)
    result = cpu_engine.run_on_cpu(specs, as_controller_params(vec, 1), config, threads=1)
    assert result.settled[0], result.summary()
    arm = SimArm(specs, 0)
    run = run_skill(arm, SkillRuntime(vec, HoleEstimate.of_trial(specs, 0), config))
    assert run.stopped == "settled" and not run.success
    assert abs(run.commands - result.steps[0]) <= config.settle_steps // 10


def test_at_125_hz_the_filter_and_damping_keep_their_time_constants(paper_38):
    """Commands every 8 ms: the runtime's F/T filter and compliance damping take their 2 ms poles
    to the 4th power, so the touchdown is sensed as at 500 Hz. Before (the 2 ms poles once per
    command, four times too slow) all four of these circles protective-stopped at touchdown
    (measured: peaks 150-152 N); now none stops and each peaks under 120 N (measured: 76-91 N).
    The policy these were measured with: the `paper` shipped until 2026-12 (docs/design/data)."""
    task = TaskConfig.from_mm_deg(("circle",), 50.0, 4.0, 6.0)
    specs = sample_trials(task, 0, 4)
    vectors = load_policy(paper_38).controller_vectors(specs)
    for i in range(len(specs)):
        arm = SimArm(specs, i, command_steps=4)
        runtime = SkillRuntime(vectors[i], HoleEstimate.of_trial(specs, i),
                               TrialConfig(time_limit_s=3.0))  # fmt: skip
        run = run_skill(arm, runtime, done=arm.inserted)
        assert arm.period == pytest.approx(0.008) and "protective stop" not in run.stopped
        assert run.peak_force < 120.0


class _FakeArm:
    """Replays one good reading; `spoil(state, k)` alters the k-th."""

    period = 0.002

    def __init__(self, spoil):
        specs = _specs(n=1)
        sim = SimArm(specs, 0)
        self.state, self.spoil, self.k, self.held = sim.read(), spoil, 0, False
        self.hole = HoleEstimate.of_trial(specs, 0)

    def read(self):
        state = self.state._replace(t=self.k * self.period)
        state = self.spoil(state, self.k)
        self.k += 1
        return state

    def send(self, torque):
        assert np.all(np.isfinite(torque)) and np.all(np.abs(torque) <= 150.0)

    def hold(self):
        self.held = True


@pytest.mark.parametrize(
    "spoil, message",
    [
        (lambda s, k: s._replace(qd=s.qd + (7.0 if k == 3 else 0.0)),
         "joint speed 7.00 rad/s reached the limit 6.28"),
        (lambda s, k: s._replace(force=s.force * (np.nan if k == 5 else 1.0)),
         "a measurement is NaN or infinite"),
        (lambda s, k: s._replace(t=0.0 if k == 4 else s.t),
         "the arm's clock went back from 0.006 s to 0.000 s"),
    ],
)  # fmt: skip
def test_safety_stop_holds_the_arm(spoil, message):
    arm = _FakeArm(spoil)
    run = run_skill(arm, SkillRuntime(baseline_params(), arm.hole, SHORT), done=lambda s: False)
    assert not run.success and run.stopped == message and arm.held
    assert run.commands == arm.k - 1  # no command after the bad reading


def test_runtime_defaults_to_the_evaluation_trial():
    """Without a config the runtime uses TrialConfig() (as the README's example does)."""
    arm = _FakeArm(lambda s, k: s)
    default = SkillRuntime(baseline_params(), arm.hole)
    explicit = SkillRuntime(baseline_params(), arm.hole, TrialConfig())
    first = arm.read()
    default.start(first), explicit.start(first)
    reading = arm.read()
    np.testing.assert_array_equal(default.torque(reading), explicit.torque(reading))


def test_protective_stop_on_the_sensed_tool_force():
    """A sensed force beyond TrialConfig.max_tool_force stops the skill at the next reading, and
    the engine flags the same trial `protective_stop` after the same number of commands."""
    specs, vec = _specs(n=1, linear_mm=3.0, angular_deg=4.0), baseline_params()
    config = SHORT.replace(max_tool_force=15.0)
    result = cpu_engine.run_on_cpu(specs, as_controller_params(vec, 1), config, threads=1)
    assert result.protective_stop[0] and not result.success[0]
    arm = SimArm(specs, 0, config=config)
    run = run_skill(arm, SkillRuntime(vec, HoleEstimate.of_trial(specs, 0), config))
    assert not run.success and run.stopped.startswith("protective stop: sensed tool force")
    assert run.commands == result.steps[0]


def test_runtime_stops_on_a_non_finite_torque(monkeypatch):
    from mjx_peg.engines import period

    arm = _FakeArm(lambda s, k: s)
    runtime = SkillRuntime(baseline_params(), arm.hole, SHORT)
    runtime.start(arm.read())
    assert np.all(np.isfinite(runtime.torque(arm.read())))
    monkeypatch.setattr(period, "skill_torque", lambda *a: np.full((1, 6), np.nan))
    with pytest.raises(SafetyStop, match="the controller returned a non-finite torque"):
        runtime.torque(arm.read())


def test_policy_numbers_are_the_evaluations(tmp_path):
    """Asked with the hole estimate alone, the policy gives the robot the evaluation's numbers."""
    rng = np.random.default_rng(0)
    layers = [(rng.normal(size=(8, 16)) * 0.3, rng.normal(size=16) * 0.1),
              (rng.normal(size=(16, 38)) * 0.3, rng.normal(size=38) * 0.1)]  # fmt: skip
    save_policy(tmp_path, layers=layers, obs_mean=np.zeros(8), obs_std=np.ones(8), config={})
    specs = _specs(n=5)
    loaded = load_policy(tmp_path)
    expected = loaded.controller_vectors(specs)
    for i in range(len(specs)):  # to rounding: a batch of 1 takes other BLAS kernels than 5
        hole = HoleEstimate.of_trial(specs, i)
        got = controller_vector(str(tmp_path), hole)
        np.testing.assert_allclose(got, expected[i], rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(controller_vector(loaded, hole), got)
    baseline = controller_vector("baseline", HoleEstimate.of_trial(specs, 0))
    np.testing.assert_array_equal(baseline, baseline_params())


def test_runtime_inserted_uses_the_estimated_hole():
    hole = HoleEstimate(0.4, 0.1, 0.0, "circle", 0.05)
    runtime = SkillRuntime(baseline_params(), hole, SHORT)
    state = _FakeArm(lambda s, k: s).state
    assert runtime.inserted(state._replace(tcp_pos=np.array([0.42, 0.1, 0.019])))
    assert not runtime.inserted(state._replace(tcp_pos=np.array([0.42, 0.1, 0.021])))
    assert not runtime.inserted(state._replace(tcp_pos=np.array([0.46, 0.1, 0.0])))


def test_robot_runtime_imports_no_jax(tmp_path):
    """The robot's computer runs the runtime without JAX, Flax, Brax, Optax or Orbax."""
    code = (
        "import sys\n"
        "from mjx_peg.robot import cli\n"
        f"assert cli.main(['--trials', '1', '--time-limit', '0.05', '--no-progress', "
        f"'--out', {str(tmp_path)!r}]) == 0\n"
        "bad = sorted({m.split('.')[0] for m in sys.modules} & "
        "{'jax', 'jaxlib', 'flax', 'brax', 'optax', 'orbax'})\n"
        "assert not bad, bad\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "runs.csv").read_text().startswith("trial,success,time_s,commands,stopped")


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"shape": "octagon"}, "hole shape must be one of"),
        ({"size": 0.0}, "hole size must be positive"),
        ({"x": float("nan")}, "hole x must be a finite number"),
        ({"hole_scale": 1.5}, r"hole scale \(hole size / peg size\) must lie in \[1.01, 1.25\]"),
    ],
)
def test_hole_estimate_rejects_bad_values(kwargs, message):
    good = {"x": 0.4, "y": 0.1, "yaw": 0.0, "shape": "circle", "size": 0.05}
    with pytest.raises(ValueError, match=message):
        HoleEstimate(**{**good, **kwargs})


def test_a_policys_own_search_constants_reach_the_arm():
    """A 47-number vector (the controller and the contact search's learned constants) runs on
    the arm as the engine runs it: the constants of the skill's config give the 38-vector's run
    bit for bit, other constants another run, the engine's to 1e-9 m."""
    specs = _specs(n=1, linear_mm=6.0, angular_deg=4.0)
    config = SHORT.replace(search=skill_config("spiral"))
    own = np.array([getattr(config.search, name) for name in search.LEARNED])
    own[search.LEARNED.index("movement_s")] = config.movement.duration
    base = baseline_params()
    runs = {}
    for name, vec in (("38", base), ("47", np.concatenate([base, own])),
                      ("slow", np.concatenate([base, own * np.r_[[1.0] * 8, 2.0]]))):  # fmt: skip
        arm = SimArm(specs, 0)
        runs[name] = run_skill(arm, SkillRuntime(vec, HoleEstimate.of_trial(specs, 0), config),
                               done=arm.inserted)  # fmt: skip
    np.testing.assert_array_equal(runs["47"].log["tcp_pos"], runs["38"].log["tcp_pos"])
    slow = runs["slow"].log["tcp_pos"]
    assert not np.array_equal(slow[:200], runs["38"].log["tcp_pos"][:200])  # T doubled: slower
    engine = cpu_engine.run_on_cpu(specs, as_controller_params(np.concatenate([base, own * np.r_[
        [1.0] * 8, 2.0]]), 1), config, threads=1)  # fmt: skip
    assert engine.steps[0] == runs["slow"].commands


def test_the_declared_yaw_uncertainty_widens_the_sweep_on_the_arm_as_in_the_engine():
    """A skill whose yaw sweep follows the estimate's declared uncertainty (yaw_scale
    "uncertainty"): the hole estimate of a trial declares the range its yaw error was drawn from,
    and the arm's run of a +-15 deg trial ends as the engine's, each command's tcp within 1e-9 m;
    the sweep then turns the peg otherwise than the skill as set."""
    specs = _specs(n=1, seed=7, linear_mm=10.0, angular_deg=15.0)  # a square
    hole = HoleEstimate.of_trial(specs, 0)
    assert hole.yaw_uncertainty == pytest.approx(np.radians(15.0))
    vec = baseline_params()
    runs = {}
    for scale in ("absolute", "uncertainty"):
        config = SHORT.replace(search=skill_config("spiral").replace(yaw_scale=scale))
        arm = SimArm(specs, 0)
        runs[scale] = run_skill(arm, SkillRuntime(vec, hole, config), done=arm.inserted)
        engine = cpu_engine.run_on_cpu(specs, as_controller_params(vec, 1), config, threads=1)
        assert runs[scale].commands == engine.steps[0]
        np.testing.assert_allclose(arm.tip_pos(), engine.final_tip_pos[0], atol=1e-9, rtol=0)
    wide, narrow = runs["uncertainty"].log["torque"], runs["absolute"].log["torque"]
    n = min(len(wide), len(narrow))
    assert not np.array_equal(wide[:n], narrow[:n])
    with pytest.raises(Exception, match="yaw uncertainty"):
        HoleEstimate(0.4, 0.0, 0.0, "square", 0.05, yaw_uncertainty=-0.1)


def test_a_hole_estimate_gives_either_observation_of_its_part():
    """The hole's clearance defaults to the shape's paper fit; the estimate observes itself in
    the names layout (the shipped policies') or the geometry one, as the policy asks."""
    from mjx_peg.policy import observation

    hole = HoleEstimate(0.45, -0.1, 0.3, "rectangle", 0.03)
    assert hole.hole_scale == 1.08
    tight = HoleEstimate(0.45, -0.1, 0.3, "rectangle", 0.03, 1.02)
    args = (np.array([4]), np.array([0.03]), np.array([1.02]), np.array([[0.45, -0.1]]))
    np.testing.assert_array_equal(
        tight.observation("geometry"), observation.observe_geometry(*args, np.array([0.3]))
    )
    assert tight.observation().shape == (1, 8) and tight.observation("geometry").shape == (1, 9)
    assert tight.observation("geometry")[0, 7] == pytest.approx(0.02 * 0.0075 / 0.001)
