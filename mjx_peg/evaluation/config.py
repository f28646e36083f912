"""An evaluation's config and its grids of error ranges (paper section 6).

A grid is a set of (linear, angular) error ranges; every range gets N trials whose errors are
uniform within +- the range (`world.task.sample_trials`), split evenly between the shapes. A
range's trials come from a seed derived only from (seed, range index), so a grid is the same
whether it runs at once, in chunks or resumed. The presets are the paper's grids: `paper`
(section 6.2, 25 x 14 ranges up to 8 mm / 12 deg, N = 200) and `paper-small` (sections 6.3-6.5,
10 x 10 ranges, N = 50); their linear ranges are given at S = 50 mm and scale with S (the paper
states them as a percent of S/2).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from mjx_peg.engines.trial import TrialConfig
from mjx_peg.errors import UsageError, validate_fields
from mjx_peg.skill.search import SkillConfig, constants_record, named_skill
from mjx_peg.world.constants import GRASP_MODELS
from mjx_peg.world.task import SHAPES, TaskConfig, TrialSpec, sample_trials

GRIDS = ("paper", "paper-small", "custom")
PRESET_SIZE_MM = 50.0  # preset linear ranges are given at S = 50 mm (percent of S/2 in the paper)
# name -> (linear ranges (mm at S = 50 mm), angular ranges (deg), trials per range)
PRESETS: dict[str, tuple[tuple[float, ...], tuple[float, ...], int]] = {
    # Section 6.2: 350 ranges up to 8 mm / 12 deg, N = 200; the 25 x 14 split is our reading.
    "paper": (
        tuple(round(0.32 * k, 9) for k in range(1, 26)),
        tuple(round(12.0 * k / 14.0, 9) for k in range(1, 15)),
        200,
    ),
    # Sections 6.3-6.5: 100 ranges, N = 50.
    "paper-small": (
        tuple(round(0.8 * k, 9) for k in range(1, 11)),
        tuple(round(1.2 * k, 9) for k in range(1, 11)),
        50,
    ),
}
DEFAULT_SHAPES = ("circle", "square")  # the paper's nominal conditions
MAX_ERROR = {"linear_mm": (0.0, 50.0), "angular_deg": (0.0, 45.0)}  # TaskConfig's, mm and deg
CONTACT_MODEL = 2  # the trial's physics and sensing (EvalConfig.contact_model)


@dataclasses.dataclass(frozen=True)
class EvalConfig:
    """Everything that determines an evaluation's results (config.json). Units: mm, deg, s."""

    policy: str  # "baseline" or "sha256:<digest of policy.npz>"
    grid: str  # paper, paper-small or custom
    linear_mm: tuple[float, ...]  # +- linear error ranges, the grid's columns (mm)
    angular_deg: tuple[float, ...]  # +- angular error ranges, the grid's rows (deg)
    trials: int  # per range, split evenly between the shapes
    shapes: tuple[str, ...]
    size_mm: float  # characteristic size S
    time_limit_s: float = 60.0  # per trial, the paper's
    seed: int = 0
    engine: str = "mujoco"  # resolved: mujoco or mjx
    # True: every failure runs to the time limit (the paper's protocol); False: a failure that
    # has settled ends early (TrialConfig.end_settled), with the same outcome
    full_time_limit: bool = False
    # The trial's physics and sensing: 2 since credible contact (the F/T pipeline, protective
    # stop and compliance damping); an evaluation made with 1 cannot be resumed.
    contact_model: int = CONTACT_MODEL
    # Where the grasp errors go (constants.GRASP_MODELS): "board", the paper's, or "flange"
    grasp_model: str = "board"
    # The skill (skill.search.SKILLS): "paper", the paper's as written, or "spiral", ours
    skill: str = "paper"
    # Its constants (a SkillConfig, or its JSON record); None: the named skill's
    # (search.named_skill). config.json records every one: a rerun with other constants is
    # refused, not resumed.
    skill_constants: SkillConfig | None = None
    # The hole's clearance (hole size / peg size) of every shape: None, the paper's fit of each
    # shape; a fit's name ("paper", "tight": constants.HOLE_FITS); or one number for all
    hole_scale: float | str | None = None

    def __post_init__(self):
        validate_fields("EvalConfig", self._validate)

    def _validate(self):
        if self.grid not in GRIDS:
            raise UsageError(f"unknown grid {self.grid!r}: choose from {', '.join(GRIDS)}")
        for name in ("linear_mm", "angular_deg"):
            values = tuple(float(v) for v in getattr(self, name))
            if not values:
                raise UsageError(f"{name} is empty: the grid needs at least one range")
            lower, upper = MAX_ERROR[name]
            if not all(math.isfinite(v) and lower <= v <= upper for v in values):
                raise UsageError(f"{name} must lie in [{lower:g}, {upper:g}], got {values}")
            if len(set(values)) != len(values):
                raise UsageError(f"{name} repeats a value: {values}")
            object.__setattr__(self, name, tuple(sorted(values)))
        if isinstance(self.trials, bool) or not isinstance(self.trials, int) or self.trials < 1:
            raise UsageError(f"trials per range must be a positive integer, got {self.trials!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise UsageError(f"seed must be an integer >= 0, got {self.seed!r}")
        shapes = (self.shapes,) if isinstance(self.shapes, str) else tuple(self.shapes)
        if not shapes or len(set(shapes)) != len(shapes):
            raise UsageError(f"shapes must be distinct names from {', '.join(SHAPES)}")
        object.__setattr__(self, "shapes", shapes)
        if not (math.isfinite(self.size_mm) and self.size_mm > 0):
            raise UsageError(f"size must be a positive number of mm, got {self.size_mm!r}")
        if isinstance(self.hole_scale, int | float) and not isinstance(self.hole_scale, bool):
            object.__setattr__(self, "hole_scale", float(self.hole_scale))
        elif self.hole_scale is not None and not isinstance(self.hole_scale, str):
            raise UsageError(
                f"hole_scale must be a number or a fit's name, got {self.hole_scale!r}"
            )
        if self.engine not in ("mujoco", "mjx"):
            raise UsageError(f"engine must be resolved to mujoco or mjx, got {self.engine!r}")
        if self.grasp_model not in GRASP_MODELS:
            raise UsageError(
                f"unknown grasp model {self.grasp_model!r}: choose from {', '.join(GRASP_MODELS)}"
            )
        named = named_skill(self.skill, self.skill_constants)  # a known skill, valid constants
        object.__setattr__(self, "skill_constants", named.config)
        if not isinstance(self.full_time_limit, bool):
            raise UsageError(f"full_time_limit must be true or false, got {self.full_time_limit!r}")
        self.trial_config()  # validates the time limit
        # Validates shapes, size and the largest errors (reach of the workspace) once, up front.
        task_config(self, self.shapes[0], self.linear_mm[-1], self.angular_deg[-1])
        for shape in self.shapes[1:]:
            task_config(self, shape, 0.0, 0.0)

    def trial_config(self) -> TrialConfig:
        return TrialConfig(
            time_limit_s=self.time_limit_s,
            end_settled=not self.full_time_limit,
            search=self.skill_constants,
        )

    @property
    def ranges(self) -> list[tuple[float, float]]:
        """(linear mm, angular deg) per range index, linear-major."""
        return [(lin, ang) for lin in self.linear_mm for ang in self.angular_deg]

    def shape_counts(self) -> list[int]:
        """Trials per shape in every range: an even split, the first shapes take the remainder."""
        base, extra = divmod(self.trials, len(self.shapes))
        return [base + (i < extra) for i in range(len(self.shapes))]

    def to_json(self) -> dict:
        return {
            **{
                f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v
                for f in dataclasses.fields(self)
            },
            "skill_constants": constants_record(self.skill_constants),
        }


def task_config(config: EvalConfig, shape: str, linear_mm: float, angular_deg: float):
    """The TaskConfig of one shape and error range of an evaluation (SI units)."""
    return TaskConfig.from_mm_deg(
        (shape,), config.size_mm, linear_mm, angular_deg, time_limit_s=config.time_limit_s,
        grasp_model=config.grasp_model, hole_scale=config.hole_scale,
    )  # fmt: skip


def grid_axes(
    grid: str,
    size_mm: float,
    linear_mm: Sequence[float] | None = None,
    angular_deg: Sequence[float] | None = None,
    linear_absolute: bool = False,
) -> tuple[tuple[float, ...], tuple[float, ...], int | None]:
    """(linear ranges mm, angular ranges deg, default trials) of a grid.

    Preset linear ranges are given at S = 50 mm and scale with S (the paper states them as a
    percent of S/2) unless linear_absolute; custom grids take explicit ranges as given.
    """
    if grid == "custom":
        if linear_mm is None or angular_deg is None:
            raise UsageError("--grid custom needs --linear-mm and --angular-deg")
        return tuple(linear_mm), tuple(angular_deg), None
    if grid not in PRESETS:
        raise UsageError(f"unknown grid {grid!r}: choose from {', '.join(GRIDS)}")
    if linear_mm is not None or angular_deg is not None:
        raise UsageError("--linear-mm and --angular-deg are for --grid custom only")
    linear, angular, trials = PRESETS[grid]
    scale = 1.0 if linear_absolute else size_mm / PRESET_SIZE_MM
    return tuple(round(v * scale, 9) for v in linear), angular, trials


def range_specs(config: EvalConfig, index: int) -> TrialSpec:
    """The trials of range `index`, from a seed derived only from (config.seed, index)."""
    linear_mm, angular_deg = config.ranges[index]
    rng = np.random.default_rng([config.seed, index])
    parts = [
        sample_trials(task_config(config, shape, linear_mm, angular_deg), rng, count)
        for shape, count in zip(config.shapes, config.shape_counts(), strict=True)
        if count > 0
    ]
    return TrialSpec.concat(parts)
