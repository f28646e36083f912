"""One scene's C MuJoCo simulations as a `mujoco.batch.Batch`, and the pool that keeps them.

Each scene (a part: shape, size, hole scale) a lane meets is a `Sims`: a Batch whose model fields
that `scene.start_trial` edits per trial (board pose, grasp, friction) are expanded per simulation,
with its fields bound as NumPy arrays. Small batches keep one MjData per simulation
(persistent), larger ones one per C thread (PERSISTENT_MAX_SIMS). A step applies the torques
written to `ctrl` (mj_step2), then runs the position and velocity stages at the new state
(mj_step1): kinematics, mass matrix and bias forces are fresh for the controller while the F/T
reading (an acceleration-stage sensor) is one step old, as on a real robot. Simulations not in
use are pooled across calls, so that no batch is rebuilt.
"""

from __future__ import annotations

import threading
from typing import NamedTuple

import mujoco
import mujoco.batch
import numpy as np

from mjx_peg.engines.jacobian import chain_is_every_dof, dense_mass_index
from mjx_peg.world import constants, scene
from mjx_peg.world.task import TrialSpec

# A persistent batch (one MjData per simulation) continues each step from the position and
# velocity stages the controller read, but its simulations' memory leaves the caches as the batch
# grows. CPU time per step on this 2-core machine (the baseline jammed in the hole, 512 states):
# persistent 5.8-6.3 us at 64-256 simulations, 6.8-7.4 at 512; one MjData per C thread (which
# recomputes those stages) 8.7-9.0 at any size; mj_step on one MjData 5.4. Under other jobs'
# load the persistent batch of 512 fell to 11.3 us (the non-persistent one: 9.2). Batches of up
# to this many simulations are persistent (results are the same either way).
PERSISTENT_MAX_SIMS = 512
STAGE_VEL = int(mujoco.mjtStage.mjSTAGE_VEL)
STAGE_ACC = int(mujoco.mjtStage.mjSTAGE_ACC)
STATE = mujoco.mjtState.mjSTATE_INTEGRATION
# The model fields scene.start_trial writes; each simulation of a batch has its own values.
TRIAL_MODEL_FIELDS = ("body_pos", "body_quat", "geom_friction")


class Measured(NamedTuple):
    """What a control period reads of its live trials (one row each)."""

    time: np.ndarray  # (n,) MjData.time
    qvel: np.ndarray  # (n, 6)
    site_pos: np.ndarray  # (n, 3, 3) tcp, tip, ft
    site_rot: np.ndarray  # (n, 2, 3, 3) tcp, ft
    ft: np.ndarray  # (n, 6) force, torque sensor readings (site frame)
    mass: np.ndarray  # (n, 6, 6)
    bias: np.ndarray  # (n, 6) qfrc_bias - qfrc_passive
    cdof: np.ndarray  # (n, 6, 6)
    cdof_dot: np.ndarray  # (n, 6, 6)
    cvel: np.ndarray  # (n, 6) of the tcp's body
    com: np.ndarray  # (n, 3) subtree com of its root


class Sims:
    """One scene's simulations: a `mujoco.batch.Batch` of `nsim` and its bound fields.

    Used by one lane at a time (a Batch serves one Python thread).
    """

    def __init__(
        self, key: tuple[str, float, float], nsim: int, nthread: int, persistent: bool = True
    ):
        self.key, self.nsim, self.kind = key, nsim, (nthread, persistent)
        self.model = m = scene.load_model(*key)
        self.trial_model = scene.load_model(*key)  # start_trial edits it; its fields are copied
        self.trial_data = mujoco.MjData(self.trial_model)
        self.ids = ids = scene.scene_ids(m)
        assert m.nv == 6 and np.all(ids.dof_adr == np.arange(6)), "the arm must be all the dofs"
        assert np.all(ids.actuator_ids == np.arange(6)), "ctrl must be in joint order"
        assert m.site_bodyid[ids.tcp_site] == ids.wrist3_body, "tcp must be on the wrist-3 body"
        assert chain_is_every_dof(m, ids.wrist3_body), "the tcp must move with every dof"
        self.batch = b = mujoco.batch.Batch(m, nsim, nthread=nthread, persistent=persistent)
        self.fields = {name: b.expand(name) for name in TRIAL_MODEL_FIELDS}
        self.state = b.state
        self.time, self.qvel, self.ctrl = b.bind("time"), b.bind("qvel"), b.bind("ctrl")
        self.qpos = b.bind("qpos")
        self.site_xpos, self.site_xmat = b.bind("site_xpos"), b.bind("site_xmat")
        self.sensordata, self.mass = b.bind("sensordata"), b.bind("M")
        self.cdof, self.cdof_dot = b.bind("cdof"), b.bind("cdof_dot")
        self.cvel, self.subtree_com = b.bind("cvel"), b.bind("subtree_com")
        self.qfrc_bias, self.qfrc_passive = b.bind("qfrc_bias"), b.bind("qfrc_passive")
        self.sites = np.array([ids.tcp_site, ids.tip_site, ids.ft_site])
        self.ft = np.r_[ids.ft_force_adr : ids.ft_force_adr + 3,
                        ids.ft_torque_adr : ids.ft_torque_adr + 3]  # fmt: skip
        self.mass_index = dense_mass_index(m)
        self.body, self.root = ids.wrist3_body, m.body_rootid[ids.wrist3_body]
        self.free: list[int] = []
        self._view: tuple | None = None

    def reset(self) -> None:
        """Every simulation free (lowest first)."""
        self.free = list(range(self.nsim - 1, -1, -1))

    def load(self, sim: int, specs: TrialSpec, index: int) -> mujoco.MjData:
        """Put trial `index` in simulation `sim`; the scratch MjData at the start (its sensors are
        the tare). The caller runs `forward` on the simulations it loaded."""
        m, d = self.trial_model, self.trial_data
        scene.start_trial(specs, index, m, d, self.ids)
        for name, values in self.fields.items():
            values[sim] = getattr(m, name)
        mujoco.mj_getState(m, d, self.state[sim], STATE)
        return d

    def forward(self, ids: np.ndarray) -> None:
        """mj_forward at the loaded states (the tare reading), then (persistent batch) the
        position and velocity stages the next step continues from."""
        for stage in (STAGE_ACC, STAGE_VEL)[: 1 + self.kind[1]]:
            try:
                self.batch.forward(ids, stage=stage)
            except mujoco.batch.SimulationError:
                pass  # their time check fails: unstable

    def step(self, ids: np.ndarray, torques: np.ndarray) -> None:
        """Apply `torques` (len(ids), 6) and step simulations `ids` (sorted) once."""
        self.ctrl[ids] = torques
        try:
            self.batch.step(None if len(ids) == self.nsim else ids, stage=STAGE_VEL)
        except mujoco.batch.SimulationError:
            pass  # those simulations kept their state: their time check fails (unstable)

    def measure(self, ids: np.ndarray) -> Measured:
        """The bound fields of simulations `ids` (sorted): one gather per field (no copy of the
        fields that need none when `ids` are all the simulations)."""
        take = np.take
        if len(ids) == self.nsim:
            rows = lambda a: a  # noqa: E731
        else:
            rows = lambda a: take(a, ids, axis=0)  # noqa: E731
        bias = scene.bias_torque(rows(self.qfrc_bias), rows(self.qfrc_passive), self.ids.dof_adr)
        return Measured(
            rows(self.time),
            np.ascontiguousarray(rows(self.qvel)),  # a view of the state rows when all
            take(rows(self.site_xpos), self.sites, axis=1),
            take(rows(self.site_xmat), self.sites[[0, 2]], axis=1).reshape(-1, 2, 3, 3),
            take(rows(self.sensordata), self.ft, axis=1),
            take(rows(self.mass), self.mass_index, axis=1).reshape(-1, 6, 6),
            bias,
            rows(self.cdof),
            rows(self.cdof_dot),
            rows(self.cvel[:, self.body]),
            rows(self.subtree_com[:, self.root]),
        )

    def current(self, sim: int) -> tuple:
        """(model, data, ids) of simulation `sim` (copies, reused: for observers). A batch that
        is not persistent keeps only the state: mj_forward recomputes the rest."""
        if self._view is None:
            self._view = (scene.load_model(*self.key), mujoco.MjData(self.model))
        m, d = self._view
        self.batch.get_model(sim, m)
        self.batch.get_data(sim, d)
        if not self.kind[1]:
            mujoco.mj_forward(m, d)
        return m, d, self.ids


# Simulations not in use, by (scene, batch threads): kept across calls so that no batch is rebuilt.
_FREE: dict[tuple, list[Sims]] = {}
_FREE_LOCK = threading.Lock()


def take_sims(key: tuple[str, float, float], nsim: int, kind: tuple) -> Sims:
    """Simulations for `key` from the pool, or new ones; kind: (C threads, persistent or None
    for persistent up to PERSISTENT_MAX_SIMS simulations)."""
    nthread, persistent = kind
    if persistent is None:
        persistent = nsim <= PERSISTENT_MAX_SIMS
    kind = (nthread, persistent)
    with _FREE_LOCK:
        free = _FREE.get((key, kind), [])
        fits = [s for s in free if s.nsim >= nsim]
        if fits:
            sims = min(fits, key=lambda s: s.nsim)
            free.remove(sims)
            sims.reset()
            return sims
    sims = Sims(key, nsim, *kind)
    sims.reset()
    return sims


def give_sims(sims: Sims) -> None:
    """Return `sims` to the pool."""
    with _FREE_LOCK:
        _FREE.setdefault((sims.key, sims.kind), []).append(sims)


def keep_sims(keys: set) -> None:
    """Drop the free simulations of scenes other than `keys`."""
    with _FREE_LOCK:
        for cached in [k for k in _FREE if k[0] not in keys]:
            del _FREE[cached]


def pooled() -> list[Sims]:
    """The simulations in the pool now."""
    with _FREE_LOCK:
        return [s for free in _FREE.values() for s in free]


def scene_key(specs: TrialSpec, index: int) -> tuple[str, float, float]:
    """(shape, size, hole scale) of trial `index`: the part whose scene its simulation loads."""
    shape = constants.SHAPES[int(specs.shape_id[index])]
    return shape, float(specs.size[index]), float(specs.hole_scale[index])
