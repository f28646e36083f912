"""Training configuration: `TrainConfig`, the presets, and their JSON form in a run directory.

Presets (`python train.py --preset NAME`), each with the spiral contact search (`--skill spiral`,
an extension, skill/search.py; `--skill paper` trains the paper's skill as written):
- `quick` (default, `TrainConfig()`): the paper's training conditions at 44 % of its budget:
  circle + square at 50 mm, errors up to +-8 mm / +-12 deg, a 20 s trial limit, 3,584 trials.
- `paper`: the paper's training conditions (section 5.2): circle + square at 50 mm, errors up to
  +-8 mm / +-12 deg, friction 0.2-0.9; 8,192 trials (the paper's curve levels off after ~8,000).
- `transfer`: re-train a finished run (`--init-from RUN_DIR`) on the unseen triangle, same
  errors as `paper`, 800 trials (the paper's Fig. 9) in 20 iterations of 40.
- `family`: the `paper` preset on the family of parts (world/family.py: the parts suite's trained
  parts, five shapes, 10-80 mm, the paper's and tight fits), linear errors x S / 50 mm.
The paper does not give its training time limit; we train with 20 s (a failed trial that has not
settled costs the whole limit) and evaluate with the paper's 60 s.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np

from mjx_peg import file_versions
from mjx_peg.engines import ENGINES
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.errors import UsageError, validate_fields
from mjx_peg.policy.observation import DEFAULT_LAYOUT, check_layout, part_range
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.params import N_LEARNED, N_PARAMS
from mjx_peg.skill.search import LEARNED, SkillConfig, constants_record, named_skill
from mjx_peg.world import family
from mjx_peg.world.task import SHAPES, TaskConfig

PRIORS = ("baseline", "none")
OBS_STATISTICS = ("running", "context")
# How the policy's unbounded action becomes its numbers (skill/params.py): "centred" puts
# action 0 at the baseline with the sensitivity of a range's middle in both directions;
# "sigmoid" (the first runs' map) centres each number's range instead, and the
# baseline's k_t, k_theta and translational compliance sit on its flat edge there.
ACTION_MAPS = ("centred", "sigmoid")
MAX_HIDDEN = 4096  # units of a hidden layer


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """Everything that defines a training run (written to RUN_DIR/config.json); the defaults are
    the default preset, `quick`."""

    preset: str = "quick"
    shapes: tuple[str, ...] = ("circle", "square")
    size_mm: tuple[float, ...] = (50.0,)
    linear_mm: float = 8.0  # +- localization x, y and grasp z error range (the paper's)
    angular_deg: float = 12.0  # +- localization yaw and grasp tilt range (the paper's)
    # Per training trial: long enough that the baseline's trials end, not all as failures
    # (docs/design/training_presets.md)
    time_limit_s: float = 20.0
    trials: int = 3584  # budget, rounded up to whole iterations (14 of 256)
    num_envs: int = 256  # trials per iteration (split across devices)
    # One full-batch gradient step per epoch: a 38-dim contextual bandit with a noisy binary
    # outcome, where minibatches chase the noise (docs/design/training_presets.md)
    num_minibatches: int = 1
    update_epochs: int = 4
    learning_rate: float = 3e-3  # the first update's; then kl_target adapts it
    entropy_cost: float = 1e-4
    clipping_epsilon: float = 0.2
    init_noise_std: float = 0.4  # exploration std of the gains and compliance diagonal (action)
    init_noise_std_coupling: float = 0.1  # of the 30 off-diagonal couplings
    # True: the policy acts in units of those initial stds (its own std starts at 1 for every
    # number; the env and the export multiply its action by them), so that Adam's steps, which
    # move every output alike, move each number by the same fraction of its exploration and each
    # contributes alike to the update's KL; False: the raw action (config.json files without it)
    normalized_actions: bool = True
    # Under normalized_actions: the policy's first two numbers are the stiffnesses' common level
    # and their ratio, k_t at level + ratio and k_theta at level - ratio (the sigmoid map's
    # actions), explored with stds init_noise_std_level and init_noise_std; inserting needs both
    # stiff or both soft (a stiff arm on a soft wrist protective-stops), which independent
    # exploration of the two finds only in the corner of both tails. False: k_t and k_theta
    joint_stiffness: bool = False
    init_noise_std_level: float = 1.5
    # The exploration std's cap at the end of the budget, a fraction of each number's initial
    # std, decaying geometrically over the iterations (ppo.cap_exploration); 1: no cap, the std
    # as the update learns it
    std_decay: float = 1.0
    prior: str = "baseline"  # "baseline": start at the hand-tuned skill; "none": Brax's init
    # "none" only: the policy's mean head's initial kernel times this (Brax's init: 1), so the
    # first policy is the mid-range controller for every observation rather than a random
    # function of it
    head_init_scale: float = 1.0
    # Adaptive learning rate: after each iteration the rate is divided by 1.5 where the mean
    # per-number KL of the update passed 2 kl_target and multiplied by 1.5 where it stayed under
    # kl_target / 2, within [learning_rate_min, learning_rate_max]; 0: a fixed learning_rate
    kl_target: float = 0.01
    learning_rate_min: float = 1e-5
    learning_rate_max: float = 1e-2
    # "running": Brax's running statistics of the observations, updated with every iteration;
    # "context": fitted once, before the first trial, to `context_samples` observations drawn
    # from the task (a contextual bandit's observations do not depend on the policy)
    obs_statistics: str = "context"
    context_samples: int = 4096
    # Every eval_every iterations (0: never) the policy's mean, without exploration, runs
    # eval_trials held-out trials of the task (drawn once from the seed eval_seed), written to
    # eval.csv and TensorBoard as eval/...: the learning curve of the policy that is exported
    eval_every: int = 0
    eval_trials: int = 128
    eval_seed: int = 1_000_003
    action_map: str = "centred"  # ACTION_MAPS; config.json files without it were "sigmoid"
    policy_hidden: tuple[int, ...] = (64, 64)
    value_hidden: tuple[int, ...] = (64, 64)
    seed: int = 0
    engine: str = "mujoco"
    init_from: str | None = None  # run dir whose policy and value networks start this run
    # The F/T sensor randomized per trial, like the friction (TaskConfig): filter cutoff and
    # noise scaled by factors drawn log-uniformly, latency offset by whole control periods, around
    # the nominal UR5e sensor of TrialConfig.sensor (50 Hz, 1 period, 1.2 N): 25-100 Hz, 0-2
    # periods, 0.6-2.4 N. The controller is stable over all of it (skill/control_step.py).
    sensor_cutoff_scale: tuple[float, float] = (0.5, 2.0)
    sensor_noise_scale: tuple[float, float] = (0.5, 2.0)
    sensor_delay_offset: tuple[int, int] = (-1, 1)
    # True: every failed trial runs to the time limit; False: a failure that has settled ends
    # early with the same outcome (TrialConfig.end_settled)
    full_time_limit: bool = False
    # Where the grasp errors go (constants.GRASP_MODELS): the board's height and tilt (the
    # paper's); config.json files without it were "flange" (the peg in the gripper)
    grasp_model: str = "board"
    # The skill (skill.search.SKILLS): "paper", the paper's as written, or "spiral", ours;
    # config.json files without it were "paper" (file_versions)
    skill: str = "spiral"
    # Its constants (a SkillConfig, or its JSON record); None: the named skill's
    # (search.named_skill). config.json records every one.
    skill_constants: SkillConfig | None = None
    # The policy outputs the contact search's learnable constants (skill.search.LEARNED: the
    # spiral's pitch, radius, speed and press, the alignment's rate and depth, the insertion
    # press's depth and strength, the movement's duration) beside the 38, each in its physical
    # range (skill.params.SEARCH_RANGES); the skill's own values are the baseline prior's.
    # where the skill has them (the paper's has none). False: the 38 alone, the skill's constants
    # fixed (config.json files without it)
    learn_search: bool = True
    # The policy's observation layout (policy.observation.LAYOUTS): "geometry" reads the part by
    # its geometry, "names" by a one-hot of the paper's three shapes; config.json files without
    # it were "names" (file_versions)
    observation: str = DEFAULT_LAYOUT
    # A family of parts (TaskConfig.parts): ((shape, size mm, hole scale), ...), each trial one
    # drawn uniformly; shapes and size_mm then follow from it. Empty: shapes x size_mm at the
    # paper's fits
    parts: tuple[tuple[str, float, float], ...] = ()
    # The linear errors x S / 50 mm (TaskConfig.linear_per_size)
    linear_per_size: bool = False

    def __post_init__(self):
        validate_fields("TrainConfig", self._validate)

    def _validate(self):
        shapes = (self.shapes,) if isinstance(self.shapes, str) else tuple(self.shapes)
        for s in shapes:
            if s not in SHAPES:
                raise UsageError(f"unknown shape {s!r}: choose from {', '.join(SHAPES)}")
        object.__setattr__(self, "shapes", shapes)
        object.__setattr__(self, "size_mm", tuple(float(s) for s in self.size_mm))
        try:
            parts = tuple((str(a), float(b), float(c)) for a, b, c in self.parts)
        except (TypeError, ValueError):
            raise UsageError(
                f"parts holds (shape, size mm, hole scale) triples, got {self.parts!r}"
            ) from None
        object.__setattr__(self, "parts", parts)
        if parts:
            object.__setattr__(self, "shapes", tuple(dict.fromkeys(p[0] for p in parts)))
            object.__setattr__(self, "size_mm", tuple(sorted({p[1] for p in parts})))
        object.__setattr__(self, "policy_hidden", tuple(int(h) for h in self.policy_hidden))
        object.__setattr__(self, "value_hidden", tuple(int(h) for h in self.value_hidden))
        for name, kind in (("sensor_cutoff_scale", float), ("sensor_noise_scale", float),
                           ("sensor_delay_offset", int)):  # fmt: skip
            object.__setattr__(self, name, tuple(kind(v) for v in getattr(self, name)))
        if (
            isinstance(self.seed, bool)
            or not isinstance(self.seed, int)
            or not 0 <= self.seed < 2**32
        ):
            raise UsageError(f"--seed must be an integer in 0..4,294,967,295, got {self.seed!r}")
        for name in ("policy_hidden", "value_hidden"):
            if (
                not all(1 <= h <= MAX_HIDDEN for h in getattr(self, name))
                or len(getattr(self, name)) > 8
            ):
                raise UsageError(f"{name} must be at most 8 layers of 1..{MAX_HIDDEN} units")
        for name in ("preset", "engine", "grasp_model", "skill", "action_map", "prior"):
            if not isinstance(getattr(self, name), str):
                raise UsageError(f"{name} must be a name, got {getattr(self, name)!r}")
        if self.init_from is not None and not isinstance(self.init_from, str):
            raise UsageError(f"init_from must be a path, got {self.init_from!r}")
        if not isinstance(self.full_time_limit, bool):
            raise UsageError(f"full_time_limit must be true or false, got {self.full_time_limit!r}")
        if self.prior not in PRIORS:
            raise UsageError(f"unknown prior {self.prior!r}: choose from {', '.join(PRIORS)}")
        if self.obs_statistics not in OBS_STATISTICS:
            raise UsageError(
                f"unknown observation statistics {self.obs_statistics!r}: choose from "
                f"{', '.join(OBS_STATISTICS)}"
            )
        if self.action_map not in ACTION_MAPS:
            raise UsageError(
                f"unknown action map {self.action_map!r}: choose from {', '.join(ACTION_MAPS)}"
            )
        check_layout(self.observation)
        if self.engine not in ENGINES:
            raise UsageError(f"unknown engine {self.engine!r}: choose from {', '.join(ENGINES)}")
        for name in ("trials", "num_envs", "num_minibatches", "update_epochs", "context_samples",
                     "eval_trials"):  # fmt: skip
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                flag = "--" + name.replace("_", "-")
                raise UsageError(f"{flag} must be a positive integer, got {value}")
        for name in (
            "time_limit_s",
            "learning_rate",
            "init_noise_std",
            "init_noise_std_coupling",
            "clipping_epsilon",
            "head_init_scale",
            "init_noise_std_level",
            "learning_rate_min",
            "learning_rate_max",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise UsageError(f"{name} must be a positive number, got {value}")
        if not (isinstance(self.std_decay, int | float) and 0.0 < self.std_decay <= 1.0):
            raise UsageError(f"std_decay must be in (0, 1], got {self.std_decay!r}")
        if self.joint_stiffness and not self.normalized_actions:
            raise UsageError("joint_stiffness needs normalized_actions")
        if not (isinstance(self.eval_every, int) and self.eval_every >= 0):
            raise UsageError(f"--eval-every must be an integer >= 0, got {self.eval_every}")
        if not (math.isfinite(self.kl_target) and self.kl_target >= 0):
            raise UsageError(f"kl_target must be >= 0 (0: a fixed rate), got {self.kl_target}")
        if not self.learning_rate_min <= self.learning_rate <= self.learning_rate_max:
            raise UsageError(
                f"learning_rate {self.learning_rate} must lie in [learning_rate_min, "
                f"learning_rate_max] = [{self.learning_rate_min}, {self.learning_rate_max}]"
            )
        if not (math.isfinite(self.entropy_cost) and self.entropy_cost >= 0):
            raise UsageError(f"entropy_cost must be >= 0, got {self.entropy_cost}")
        if self.num_envs % self.num_minibatches:
            raise UsageError(
                f"--num-envs {self.num_envs} must be a multiple of num_minibatches "
                f"{self.num_minibatches}"
            )
        named = named_skill(self.skill, self.skill_constants)  # a known skill, valid constants
        object.__setattr__(self, "skill_constants", named.config)
        self.task()  # validates the shapes, sizes and error ranges

    @property
    def iterations(self) -> int:
        return -(-self.trials // self.num_envs)

    def task(self) -> TaskConfig:
        return TaskConfig.from_mm_deg(
            self.shapes,
            self.size_mm,
            self.linear_mm,
            self.angular_deg,
            time_limit_s=self.time_limit_s,
            grasp_model=self.grasp_model,
            sensor_cutoff_scale=tuple(self.sensor_cutoff_scale),
            sensor_noise_scale=tuple(self.sensor_noise_scale),
            sensor_delay_offset=tuple(self.sensor_delay_offset),
            parts=tuple((shape, size / 1000.0, scale) for shape, size, scale in self.parts),
            linear_per_size=self.linear_per_size,
        )

    def trial(self) -> TrialConfig:
        return TrialConfig(
            time_limit_s=self.time_limit_s,
            end_settled=not self.full_time_limit,
            search=self.skill_constants,
        )

    @property
    def learns_search(self) -> bool:
        """The policy learns the search's constants: asked to, and the skill has the spiral,
        the alignment and the insertion press they set (the paper's skill has none)."""
        search = self.skill_constants
        return self.learn_search and (
            search.spiral_speed > 0 and search.align_rate > 0 and search.insert_axial != 1.0
        )

    @property
    def action_size(self) -> int:
        """The numbers the policy outputs: 38, or 47 with the search's constants."""
        return N_LEARNED if self.learns_search else N_PARAMS

    def prior_vector(self):
        """(38,) or (47,) the hand-tuned start: the baseline's 38 and the skill's constants."""
        vector = baseline_params()
        if not self.learns_search:
            return vector
        trial = self.trial()
        values = [getattr(trial.search, name) for name in LEARNED]
        values[LEARNED.index("movement_s")] = trial.movement.duration
        return np.concatenate([vector, values])

    def map_centre(self):
        """(38,) or (47,) physical vector at action 0 of the centred map, or None for the sigmoid
        map."""
        return self.prior_vector() if self.action_map == "centred" else None

    def part_range(self, layout: str | None = None) -> np.ndarray:
        """(2, k) the range of the observation's part features (`observation.part_range`, in
        `layout`, default this config's) over the parts it trains on: each listed part, or every
        shape at the smallest and largest size and hole clearance it draws."""
        task = self.task()
        parts = task.parts or [
            (shape, size, scale)
            for shape in task.shapes
            for size in (min(task.sizes), max(task.sizes))
            for scale in task.hole_scale_range(shape)
        ]
        shape_id = np.array([SHAPES.index(p[0]) for p in parts])
        size = np.array([p[1] for p in parts], np.float64)
        scale = np.array([p[2] for p in parts], np.float64)
        return part_range(layout or self.observation, shape_id, size, scale)

    def replace(self, **changes) -> TrainConfig:
        """A copy with `changes`; another skill comes with its own constants unless given."""
        if "skill" in changes and "skill_constants" not in changes:
            changes["skill_constants"] = None
        return dataclasses.replace(self, **changes)

    def to_json(self) -> dict:
        return {
            **dataclasses.asdict(self),
            "skill_constants": constants_record(self.skill_constants),
        }

    @classmethod
    def from_json(cls, data: dict) -> TrainConfig:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise UsageError(f"config.json has unknown fields {sorted(unknown)}")
        return cls(**file_versions.train_config(data))

    def dumps(self) -> str:
        return json.dumps(self.to_json(), indent=2, sort_keys=True) + "\n"


# A start with no hand-tuned number (`--prior none`): Brax's initialization under the sigmoid map
# (every number mid-range of its physical range), the mean head's kernel shrunk so that the
# first policy is that controller for every observation, and what learning from there needs
# (docs/design/learning_from_scratch.md): exploration across the ranges, updates held to a
# KL three times the hand-tuned start's, observation statistics of the task's contexts.
GENERIC_START = {
    "prior": "none",
    "action_map": "sigmoid",
    "head_init_scale": 0.01,
    "joint_stiffness": True,
    "init_noise_std": 1.0,
    "kl_target": 0.03,
}
HAND_TUNED_START = {"prior": "baseline", "action_map": "centred", "head_init_scale": 1.0,
                    "joint_stiffness": False, "init_noise_std": 0.4, "kl_target": 0.01}  # fmt: skip
# m/N: a generic start's press while spiralling, a compliance of its own
# (SkillConfig.spiral_axial_ref: kappa c_r F_z) at the middle of C_zz's physical range rather
# than a multiple of the learned and explored C_zz (docs/design/learning_from_scratch.md)
GENERIC_PRESS_REF = 1e-3


def prior_settings(prior: str, skill_constants: SkillConfig | None = None) -> dict:
    """The TrainConfig changes of a start (`--prior`): "baseline", the hand-tuned skill, or
    "none", GENERIC_START and, for a skill that spirals (`skill_constants`, where given) and
    whose press has no compliance of its own yet, GENERIC_PRESS_REF."""
    if prior not in PRIORS:
        raise UsageError(f"unknown prior {prior!r}: choose from {', '.join(PRIORS)}")
    if prior == "baseline":
        return dict(HAND_TUNED_START)
    changes = dict(GENERIC_START)
    constants = skill_constants
    if constants is not None and constants.spiral_speed > 0 and constants.spiral_axial_ref == 0:
        changes["skill_constants"] = constants.replace(spiral_axial_ref=GENERIC_PRESS_REF)
    return changes


# The paper's training conditions (section 5.2; friction 0.2-0.9 is TaskConfig's default), with
# the spiral: every preset is the default one with a budget or a shape changed.
_PAPER = TrainConfig(preset="paper", trials=8192)

PRESETS: dict[str, TrainConfig] = {
    # 3,584 trials at the paper's error ranges: python train.py on 2 cores in minutes
    # (docs/design/training_presets.md)
    "quick": TrainConfig(),
    "paper": _PAPER,
    # The 38 learned from the source's, the skill's constants as the skill sets them: from the
    # shipped paper, the triangle grid's every quarter as quick as before, where learning the
    # constants too made it slower (docs/design/learning_from_scratch.md)
    "transfer": _PAPER.replace(
        preset="transfer",
        shapes=("triangle",),
        trials=800,
        num_envs=40,  # 20 updates of 40 trials (docs/design/training_presets.md)
        learn_search=False,
    ),
    # One policy for the family of parts (world/family.py): the suite's trained parts, five
    # shapes at 10-80 mm in both fits, the paper's training errors scaled with each part; the 38
    # controller numbers learned, the skill's constants as the skill sets them (on the suite,
    # 48 trials lost / 71 gained against learning them too, p = 0.043: docs/design/parts_family.md)
    "family": _PAPER.replace(
        preset="family",
        parts=tuple((p.shape, p.size_mm, p.hole_scale) for p in family.TRAINED),
        linear_per_size=True,
        learn_search=False,
    ),
}
