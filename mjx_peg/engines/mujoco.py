"""The CPU engine: C MuJoCo on a pool of threads, the controller batched in NumPy.

Each worker thread owns `slots` environments (one MjModel copy and MjData per slot and scene, so
board pose, grasp and friction are per trial). Every control period it runs `mj_step1` (fresh
kinematics, mass matrix, bias forces; the force sensor still holds the previous step's reading,
as on a real robot) on each live slot, computes the torques of all its slots in one batched NumPy
call of `controller.skill_torque`, then runs `mj_step2`. MuJoCo releases the GIL inside its
calls, so threads overlap their physics, but the Python part of each step holds the GIL: one
thread is the default (DEFAULT_THREADS). A slot whose trial ends takes the next spec from a
shared queue at once, so cost follows the simulated time actually used.
"""

from __future__ import annotations

import copy
import os
import threading
from collections.abc import Callable

import mujoco
import numpy as np

from mjx_peg import scene
from mjx_peg.controller import (
    Skill,
    make_skill,
    skill_torque,
    start_state,
    wrench_in_goal_frame,
)
from mjx_peg.params import ControllerParams
from mjx_peg.task import TrialSpec
from mjx_peg.trial import (
    TrialConfig,
    TrialResult,
    destination,
    fitted_basis,
    is_success,
    trial_goals,
    trial_reward,
)

SLOTS_PER_THREAD = 32
# One thread by default: measured on 2 cores, a second thread makes the engine slower (32.6k vs
# 23.4k physics steps/s), because the per-slot Python work (copies, the batched NumPy controller)
# holds the GIL for ~3/4 of each step and the threads fight over it. Spreading across cores needs
# worker processes; see BENCHMARKS.md.
DEFAULT_THREADS = 1


def available_cores() -> int:
    """Cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _layout(model: mujoco.MjModel) -> scene.SceneIds:
    """The scene's ids, checked for what this engine assumes (the arm is all the dofs)."""
    ids = scene.scene_ids(model)
    assert model.nv == 6 and np.all(ids.dof_adr == np.arange(6)), "the arm must be the only dofs"
    assert model.site_bodyid[ids.tcp_site] == ids.wrist3_body, "tcp must be on the wrist-3 body"
    return ids


class _Queue:
    """Thread-safe hand-out of spec indices and collection of results."""

    def __init__(self, n: int, progress: Callable[[int], None] | None):
        self._next = 0
        self._n = n
        self._lock = threading.Lock()
        self._progress = progress
        self.error: BaseException | None = None

    def take(self) -> int | None:
        with self._lock:
            if self._next >= self._n or self.error is not None:
                return None
            self._next += 1
            return self._next - 1

    def done(self, count: int = 1) -> None:
        if self._progress is not None:
            with self._lock:
                self._progress(count)


class _Results:
    def __init__(self, n: int):
        self.success = np.zeros(n, dtype=bool)
        self.time_s = np.zeros(n)
        self.final_tip_pos = np.zeros((n, 3))
        self.peak_force = np.zeros(n)
        self.reward = np.zeros(n)
        self.unstable = np.zeros(n, dtype=bool)
        self.steps = np.zeros(n, dtype=np.int64)

    def result(self) -> TrialResult:
        return TrialResult(**vars(self))


class _Worker:
    """`slots` environments stepped together by one thread."""

    def __init__(self, specs: TrialSpec, params: ControllerParams, config: TrialConfig, slots: int):
        self.specs, self.params, self.config = specs, params, config
        self.basis = fitted_basis(config.dmp)
        self.envs: list[dict] = [{} for _ in range(slots)]  # per slot: scene key -> (m, d, layout)
        self.current: list[tuple | None] = [None] * slots
        self.spec_index = np.full(slots, -1)
        b = slots
        # Per-slot constants of the current trial.
        self.goal_pos, self.goal_rot = np.zeros((b, 3)), np.tile(np.eye(3), (b, 1, 1))
        self.y0, self.k_y, self.d_y = np.zeros((b, 6)), np.ones((b, 6)), np.ones((b, 6))
        self.compliance = np.zeros((b, 6, 6))
        self.tare = np.zeros((b, 6))
        self.board_pos, self.size = np.zeros((b, 2)), np.ones(b)
        self.start_distance, self.peak_force = np.ones(b), np.zeros(b)
        self.step = np.zeros(b, dtype=np.int64)
        # Per-step measurements, written in place by MuJoCo or copied from MjData.
        self.jac = np.zeros((b, 6, 6))
        self.jac_dot = np.zeros((b, 6, 6))
        self.mass = np.tile(np.eye(6), (b, 1, 1))
        self.bias, self.qvel = np.zeros((b, 6)), np.zeros((b, 6))
        self.tcp_pos, self.tcp_rot = np.zeros((b, 3)), np.tile(np.eye(3), (b, 1, 1))
        self.tip_pos, self.sim_time = np.zeros((b, 3)), np.zeros(b)
        self.force, self.torque = np.zeros((b, 3)), np.zeros((b, 3))
        self.ft_rot = np.tile(np.eye(3), (b, 1, 1))
        self.ft_lever = np.zeros((b, 3))  # p_ft - p_tcp, world
        self.torque_limits = np.asarray(scene.TORQUE_LIMITS, dtype=np.float64)

    def _env(self, slot: int, shape: str, size: float):
        key = (shape, round(size, 9))
        env = self.envs[slot].get(key)
        if env is None:
            model = copy.deepcopy(scene.load_model(shape, size))
            env = (model, mujoco.MjData(model), _layout(model))
            self.envs[slot][key] = env
        return env

    def load(self, slot: int, index: int) -> None:
        """Start trial `index` in `slot`: place board and peg, start pose, tare the sensor."""
        s, cfg = self.specs, self.config
        shape = scene.SHAPES[int(s.shape_id[index])]
        m, d, lay = self._env(slot, shape, float(s.size[index]))
        scene.set_board_pose(m, *s.board_pos[index], s.board_yaw[index])
        scene.set_grasp(m, *s.grasp_error[index])
        scene.set_friction(m, s.friction[index])
        mujoco.mj_resetData(m, d)
        d.qpos[lay.qpos_adr] = s.q0[index]
        mujoco.mj_forward(m, d)
        d.ctrl[:] = (
            d.qfrc_bias[lay.dof_adr] - d.qfrc_passive[lay.dof_adr]
        )  # hold still (gravity compensation) and tare
        mujoco.mj_forward(m, d)
        self.tare[slot, :3] = d.sensordata[lay.ft_force_adr : lay.ft_force_adr + 3]
        self.tare[slot, 3:] = d.sensordata[lay.ft_torque_adr : lay.ft_torque_adr + 3]
        goal_pos, goal_rot = trial_goals(
            s.hole_est_pos[index : index + 1], s.hole_est_yaw[index : index + 1], cfg
        )
        tcp_pos = d.site_xpos[lay.tcp_site].copy()
        tcp_rot = d.site_xmat[lay.tcp_site].reshape(3, 3).copy()
        y0 = start_state(goal_pos[0], goal_rot[0], tcp_pos, tcp_rot)
        p = self.params
        skill = make_skill(
            ControllerParams(p.k_t[index], p.k_theta[index], p.compliance[index]),
            goal_pos[0],
            goal_rot[0],
            y0,
            cfg.dmp.tau,
        )
        self.goal_pos[slot], self.goal_rot[slot] = skill.goal_pos, skill.goal_rot
        self.y0[slot], self.k_y[slot], self.d_y[slot] = skill.y0, skill.k_y, skill.d_y
        self.compliance[slot] = skill.compliance
        self.board_pos[slot], self.size[slot] = s.board_pos[index], s.size[index]
        tip = d.site_xpos[lay.tip_site]
        self.start_distance[slot] = np.linalg.norm(tip - destination(s.board_pos[index]))
        self.peak_force[slot] = 0.0
        self.step[slot] = 0
        self.current[slot] = (m, d, lay)
        self.spec_index[slot] = index

    def sense(self, slot: int) -> None:
        """mj_step1 and copy what the controller needs into the batch arrays."""
        m, d, lay = self.current[slot]
        mujoco.mj_step1(m, d)
        mujoco.mj_jacSite(m, d, self.jac[slot, :3], self.jac[slot, 3:], lay.tcp_site)
        self.tcp_pos[slot] = d.site_xpos[lay.tcp_site]
        mujoco.mj_jacDot(
            m,
            d,
            self.jac_dot[slot, :3],
            self.jac_dot[slot, 3:],
            self.tcp_pos[slot],
            lay.wrist3_body,
        )
        mujoco.mj_fullM(m, d, self.mass[slot])
        self.tcp_rot[slot] = d.site_xmat[lay.tcp_site].reshape(3, 3)
        self.ft_rot[slot] = d.site_xmat[lay.ft_site].reshape(3, 3)
        self.ft_lever[slot] = d.site_xpos[lay.ft_site] - self.tcp_pos[slot]
        self.tip_pos[slot] = d.site_xpos[lay.tip_site]
        self.qvel[slot] = d.qvel
        self.bias[slot] = d.qfrc_bias - d.qfrc_passive  # h: Coriolis, gravity, joint damping
        sd = d.sensordata
        self.force[slot] = sd[lay.ft_force_adr : lay.ft_force_adr + 3]
        self.torque[slot] = sd[lay.ft_torque_adr : lay.ft_torque_adr + 3]
        self.sim_time[slot] = d.time

    def run(self, queue: _Queue, results: _Results, observer=None) -> None:
        """Step until the queue is empty; `observer(worker, rows, wrench)` sees every step."""
        cfg = self.config
        slots = len(self.envs)
        for slot in range(slots):
            index = queue.take()
            if index is None:
                break
            self.load(slot, index)
        dt, max_steps = cfg.timestep, cfg.max_steps
        while True:
            live = [i for i in range(slots) if self.current[i] is not None]
            if not live:
                return
            for i in live:
                self.sense(i)
            rows = np.asarray(live)
            success = is_success(self.tip_pos, self.board_pos, self.size, cfg.success_height)
            speed_ok = np.all(np.abs(self.qvel) < cfg.max_joint_speed, axis=-1)
            finite = np.isfinite(self.tip_pos).all(-1) & np.isfinite(self.qvel).all(-1)
            # MuJoCo resets MjData (time back to 0) when its accelerations blow up.
            reset = np.abs(self.sim_time - self.step * dt) > 0.5 * dt
            unstable = ~(speed_ok & finite) | reset
            ended = success | unstable | (self.step >= max_steps)
            for i in rows[ended[rows]]:
                self._finish(i, bool(success[i]), bool(unstable[i]), results)
                queue.done()
                index = queue.take()
                if index is None:
                    self.current[i] = None
                    self.spec_index[i] = -1
                else:
                    self.load(i, index)
                    self.sense(i)
            live = [i for i in range(slots) if self.current[i] is not None]
            if not live:
                return
            rows = np.asarray(live)
            wrench = wrench_in_goal_frame(
                self.force, self.torque, self.tare, self.ft_rot, self.ft_lever, self.goal_rot
            )
            force = np.linalg.norm(wrench[:, :3], axis=-1)
            self.peak_force[rows] = np.maximum(self.peak_force[rows], force[rows])
            if observer is not None:
                observer(self, rows, wrench)
            torques = skill_torque(
                Skill(self.goal_pos, self.goal_rot, self.y0, self.k_y, self.d_y, self.compliance),
                self.basis,
                self.step * dt,
                self.tcp_pos,
                self.tcp_rot,
                self.jac,
                (self.jac_dot @ self.qvel[..., None])[..., 0],
                self.qvel,
                self.mass,
                self.bias,
                wrench,
                self.torque_limits,
                cfg.dmp.tau,
                cfg.dmp.alpha_s,
                cfg.dmp.k_ref,
                cfg.pinv_damping,
            )
            torques = np.where(np.isfinite(torques), torques, 0.0)
            for i in live:
                m, d, _ = self.current[i]
                d.ctrl[:] = torques[i]
                mujoco.mj_step2(m, d)
            self.step[rows] += 1

    def _finish(self, slot: int, success: bool, unstable: bool, results: _Results) -> None:
        index = self.spec_index[slot]
        tip = self.tip_pos[slot]
        results.success[index] = success and not unstable
        results.unstable[index] = unstable
        results.time_s[index] = self.step[slot] * self.config.timestep
        results.final_tip_pos[index] = tip
        results.peak_force[index] = self.peak_force[slot]
        results.steps[index] = self.step[slot]
        results.reward[index] = trial_reward(
            np.asarray(results.success[index]),
            tip,
            self.board_pos[slot],
            self.start_distance[slot],
            self.config.reward,
        )


def run_trials(
    specs: TrialSpec,
    params: ControllerParams,
    config: TrialConfig,
    threads: int | None = None,
    slots_per_thread: int | None = None,
    progress: Callable[[int], None] | None = None,
    observer: Callable | None = None,
) -> TrialResult:
    """Run every trial of `specs` with per-trial `params` (batched, validated) on C MuJoCo.

    observer(worker, rows, wrench), if given, is called every control period with the worker,
    its live slot indices and their wrenches (for demos and benchmarks; it runs in the workers'
    threads).
    """
    n = len(specs)
    threads = max(1, min(threads or DEFAULT_THREADS, n))
    slots = slots_per_thread or max(1, min(SLOTS_PER_THREAD, -(-n // threads)))
    queue, results = _Queue(n, progress), _Results(n)

    def work():
        try:
            _Worker(specs, params, config, slots).run(queue, results, observer)
        except BaseException as exc:  # re-raised in the caller's thread
            queue.error = exc

    pool = [threading.Thread(target=work, daemon=True) for _ in range(threads)]
    for t in pool:
        t.start()
    for t in pool:
        t.join()
    if queue.error is not None:
        raise queue.error
    return results.result()
