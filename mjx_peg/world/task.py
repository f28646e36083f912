"""The insertion task (paper section 5.2): `TaskConfig` randomization -> `TrialSpec` arrays.

Per trial (CONVENTIONS.md "Trial quantities"): a part (its shape, size S and the hole's
clearance `hole_scale`, the hole's size over the peg's: fixed per shape, or drawn from a range
over evenly spaced values at most `constants.HOLE_SCALE_STEP` apart, so that trials share
compiled scenes), the board (true hole centre uniform in area over an annular sector of the
workspace, yaw uniform), the peg-board friction, a localization error (dx, dy, dyaw) and a grasp
error (dz, tilt_x, tilt_y), each uniform within +- its range and applied as
`TaskConfig.grasp_model` says (the board's height and tilt about its hole's entrance centre, the
paper's; or the peg's pose in the flange), and a start: the nominal tip (`tcp`) above the
estimated hole, with a random horizontal offset, height and small tilt, and the arm
configuration reaching it (analytic IK, the branch nearest `kinematics.HOME_Q`). Trials whose
start or goal configuration is out of reach or near-singular are drawn again (rejection
sampling).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np

from mjx_peg import file_versions
from mjx_peg.errors import UsageError
from mjx_peg.world import kinematics
from mjx_peg.world.constants import (
    GOAL_HEIGHT,
    GRASP_MODELS,
    HOLE_DEPTH,
    HOLE_SCALE,
    HOLE_SCALE_RANGE,
    PEG_LENGTH,
    SHAPES,
    TRAINING_SIZE,
)
from mjx_peg.world.parts import HoleScaleRanges, hole_scale_ranges, hole_scale_values
from mjx_peg.world.rotations import (
    matrix_from_quat,
    matrix_from_rotvec,
    quat_from_yaw,
    quat_mul,
    tool_down_rotation,
)

MAX_REJECTION_FACTOR = 1000  # sample_trials gives up after drawing this many candidates per trial


def _number(name: str, value) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise UsageError(f"TaskConfig.{name} must be a number, got {value!r}") from None


def _range(name: str, value, lo_min: float = -math.inf, positive: bool = False) -> tuple:
    """Validate a (lo, hi) range of finite floats with lo_min <= lo <= hi; return it as a tuple."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise UsageError(f"TaskConfig.{name} must be a (low, high) pair, got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise UsageError(f"TaskConfig.{name} must be finite with low <= high, got ({lo}, {hi})")
    if lo < lo_min or (positive and lo <= 0.0):
        bound = f"> {lo_min}" if positive else f">= {lo_min}"
        raise UsageError(f"TaskConfig.{name} low end must be {bound}, got ({lo}, {hi})")
    return lo, hi


@dataclasses.dataclass(frozen=True)
class TaskConfig:
    """How trials are randomized. SI units: m, rad, s. Ranges are (low, high)."""

    shapes: tuple[str, ...] = ("circle", "square")  # the paper trains on these
    sizes: tuple[float, ...] = (0.05,)  # characteristic size S = D = L (m)
    friction_range: tuple[float, float] = (0.2, 0.9)  # peg-board friction, uniform
    linear_error: float = 0.004  # +- range of localization x, y and grasp z errors (m)
    angular_error: float = math.radians(6.0)  # +- range of localization yaw, grasp tilts (rad)
    board_yaw_range: tuple[float, float] = (0.0, math.pi / 2)  # board yaw about z (rad)
    workspace_radius: tuple[float, float] = (0.35, 0.65)  # hole centre distance from base (m)
    workspace_angle: tuple[float, float] = (-math.pi / 3, math.pi / 3)  # about +x (rad)
    start_height: tuple[float, float] = (0.04, 0.08)  # nominal tip above the board top (m)
    # The DMP moves in a straight line from the start to the goal, so any start offset that is
    # left when the tip reaches the board top must fit the clearance (0.75 mm at 50 mm): by
    # default the tip starts exactly above the estimated hole, tool down; the arm configuration
    # still varies with the board pose, yaw and start height.
    start_xy_jitter: float = 0.0  # start tip offset from the estimated hole, within a disc (m)
    start_tilt_jitter: float = 0.0  # start orientation from tool-down (rad)
    time_limit_s: float = 60.0  # the paper's evaluation limit
    # Where the grasp errors go (constants.GRASP_MODELS): "board" (the paper's) or "flange".
    grasp_model: str = "board"
    # F/T sensor randomization per trial, like the friction (training; skill/sensor.py has the
    # UR5e pipeline in TrialConfig.sensor): the filter cutoff and the noise are scaled by factors
    # drawn log-uniformly, the latency is offset by an integer number of control periods drawn
    # uniformly (inclusive). The defaults leave the nominal sensor.
    sensor_cutoff_scale: tuple[float, float] = (1.0, 1.0)
    sensor_noise_scale: tuple[float, float] = (1.0, 1.0)
    sensor_delay_offset: tuple[int, int] = (0, 0)
    # The hole's clearance, hole size / peg size, per shape (`parts.hole_scale_ranges`: None, a
    # fit's name "paper" or "tight", a number or (low, high) range for every shape, or a mapping
    # by shape); normalized to ((shape, low, high), ...); a shape not named takes its paper fit.
    hole_scale: HoleScaleRanges = ()
    # A list of parts instead of every shape with every size: ((shape, size S in m, hole scale),
    # ...), each trial one of them drawn uniformly (world/family.py); `shapes`, `sizes` and
    # `hole_scale` then follow from the list. Empty: shapes x sizes.
    parts: tuple[tuple[str, float, float], ...] = ()
    # True: the linear errors (localization x, y, grasp height) scale with the part, linear_error
    # x S / 50 mm, as the preset evaluation grids scale them; the angles do not (an angle is the
    # same error for a part of any size)
    linear_per_size: bool = False
    # Bound on kinematics.condition_number(q, PEG_LENGTH, "full") (6x6 tcp Jacobian, linear
    # rows in m, angular in rad) of the start and goal configurations. The default workspace
    # sits at 7-12; the bound rejects the folded elbow near the base and the stretched arm.
    max_condition: float = 20.0

    def __post_init__(self):
        shapes = (self.shapes,) if isinstance(self.shapes, str) else tuple(self.shapes)
        if not shapes:
            raise UsageError(f"TaskConfig.shapes is empty: choose from {', '.join(SHAPES)}")
        for shape in shapes:
            if shape not in SHAPES:
                raise UsageError(f"unknown shape {shape!r}: choose from {', '.join(SHAPES)}")
        object.__setattr__(self, "shapes", shapes)
        if self.parts:
            self._take_parts()
        try:
            sizes = tuple(float(s) for s in np.atleast_1d(self.sizes))
        except (TypeError, ValueError):
            raise UsageError(f"TaskConfig.sizes must be numbers (m), got {self.sizes!r}") from None
        if not sizes or not all(math.isfinite(s) and s > 0.0 for s in sizes):
            raise UsageError(f"TaskConfig.sizes must be positive numbers (m), got {sizes}")
        object.__setattr__(self, "sizes", sizes)
        object.__setattr__(self, "hole_scale", hole_scale_ranges(self.hole_scale))
        if self.grasp_model not in GRASP_MODELS:
            raise UsageError(
                f"unknown grasp model {self.grasp_model!r}: choose from {', '.join(GRASP_MODELS)}"
            )
        for name, upper in (
            ("linear_error", 0.05),
            ("angular_error", math.pi / 4),
            ("start_xy_jitter", 0.1),
            ("start_tilt_jitter", math.pi / 4),
        ):
            value = _number(name, getattr(self, name))
            if not (math.isfinite(value) and 0.0 <= value <= upper):
                raise UsageError(f"TaskConfig.{name} must be in [0, {upper:g}], got {value!r}")
            object.__setattr__(self, name, value)
        ranges = {
            "friction_range": dict(positive=True),
            "board_yaw_range": dict(lo_min=-math.pi),
            "workspace_radius": dict(positive=True),
            "workspace_angle": dict(lo_min=-math.pi),
            "start_height": dict(positive=True),
            "sensor_cutoff_scale": dict(positive=True),
            "sensor_noise_scale": dict(positive=True),
        }
        for name, kwargs in ranges.items():
            object.__setattr__(self, name, _range(name, getattr(self, name), **kwargs))
        try:
            lo, hi = (int(v) for v in self.sensor_delay_offset)
            if (lo, hi) != tuple(self.sensor_delay_offset) or lo > hi:
                raise ValueError
        except (TypeError, ValueError):
            raise UsageError(
                "TaskConfig.sensor_delay_offset must be a (low, high) pair of integers, low <= "
                f"high, got {self.sensor_delay_offset!r}"
            ) from None
        object.__setattr__(self, "sensor_delay_offset", (lo, hi))
        if self.workspace_angle[1] > math.pi or self.board_yaw_range[1] > math.pi:
            raise UsageError("TaskConfig.workspace_angle and board_yaw_range must lie in [-pi, pi]")
        for name, lower in (("time_limit_s", 0.0), ("max_condition", 1.0)):
            value = _number(name, getattr(self, name))
            if not (math.isfinite(value) and value > lower):
                raise UsageError(
                    f"TaskConfig.{name} must be a finite number > {lower:g}, got {value!r}"
                )
            object.__setattr__(self, name, value)
        self._check_workspace()

    def _check_workspace(self) -> None:
        """ValueError unless the arm reaches the sector, tool down, away from singularities."""
        heights = (
            GOAL_HEIGHT,
            HOLE_DEPTH + self.start_height[0],
            HOLE_DEPTH + self.start_height[1],
        )
        outer = self.workspace_radius[1] + self.linear_error + self.start_xy_jitter
        reach = min(kinematics.max_tool_down_radius(h, PEG_LENGTH) for h in heights)
        if outer > reach:
            raise UsageError(
                f"TaskConfig.workspace_radius outer edge {outer:.3f} m (with errors and jitter) is "
                f"beyond the UR5e's tool-down reach of {reach:.3f} m at the board"
            )
        radius = np.linspace(*self.workspace_radius, 5)
        angle = np.linspace(*self.workspace_angle, 7)
        yaw = np.linspace(self.board_yaw_range[0], self.board_yaw_range[1], 3)
        r, a, h, y = (g.ravel() for g in np.meshgrid(radius, angle, heights, yaw, indexing="ij"))
        pos = np.stack([r * np.cos(a), r * np.sin(a), h], axis=-1)
        q, found = kinematics.ik_tcp_closest(pos, tool_down_rotation(y), PEG_LENGTH)
        cond = np.where(found, kinematics.condition_number(np.nan_to_num(q), PEG_LENGTH), np.inf)
        where = "radius {:.3f} m, angle {:.1f} deg, tip height {:.3f} m"
        if not np.all(found):
            i = int(np.argmin(found))
            raise UsageError(
                "TaskConfig workspace is out of the UR5e's reach with the tool down at "
                + where.format(r[i], math.degrees(a[i]), h[i])
            )
        worst = int(np.argmax(cond))
        if cond[worst] > self.max_condition:
            raise UsageError(
                "TaskConfig workspace is near-singular at "
                + where.format(r[worst], math.degrees(a[worst]), h[worst])
                + f": condition number {cond[worst]:.3g} > max_condition {self.max_condition:g}"
            )

    @classmethod
    def from_mm_deg(
        cls,
        shapes: Sequence[str],
        size_mm: float | Sequence[float],
        linear_mm: float,
        angular_deg: float,
        **others,
    ) -> TaskConfig:
        """A TaskConfig from the units of the CLIs: sizes and linear range in mm, angles in deg."""
        sizes = (size_mm,) if isinstance(size_mm, int | float) else tuple(size_mm)
        return cls(
            shapes=tuple(shapes),
            sizes=tuple(s / 1000.0 for s in sizes),
            linear_error=linear_mm / 1000.0,
            angular_error=math.radians(angular_deg),
            **others,
        )

    def _take_parts(self) -> None:
        """Validate `parts` and derive the shapes, sizes and hole scales from them."""
        parts = []
        for part in self.parts:
            try:
                shape, size, scale = part
                size, scale = float(size), float(scale)
            except (TypeError, ValueError):
                raise UsageError(
                    f"TaskConfig.parts holds (shape, size m, hole scale) triples, got {part!r}"
                ) from None
            if shape not in SHAPES:
                raise UsageError(f"unknown shape {shape!r}: choose from {', '.join(SHAPES)}")
            parts.append((shape, size, scale))
        object.__setattr__(self, "parts", tuple(parts))
        object.__setattr__(self, "shapes", tuple(dict.fromkeys(p[0] for p in parts)))
        object.__setattr__(self, "sizes", tuple(sorted({p[1] for p in parts})))
        scales = {}
        for shape, _, scale in parts:
            lo, hi = scales.get(shape, (scale, scale))
            scales[shape] = (min(lo, scale), max(hi, scale))
        object.__setattr__(self, "hole_scale", scales)

    def replace(self, **changes) -> TaskConfig:
        return dataclasses.replace(self, **changes)

    def hole_scale_range(self, shape: str) -> tuple[float, float]:
        """(low, high) hole scale (hole size / peg size) of `shape`'s trials."""
        for name, lo, hi in self.hole_scale:
            if name == shape:
                return lo, hi
        return HOLE_SCALE[shape], HOLE_SCALE[shape]


# name -> (trailing shape, dtype) of every TrialSpec array; leading dim B.
_SPEC_FIELDS: dict[str, tuple[tuple[int, ...], type]] = {
    "shape_id": ((), np.int32),
    "size": ((), np.float64),
    "hole_scale": ((), np.float64),  # the hole's size over the peg's
    "board_pos": ((2,), np.float64),
    "board_yaw": ((), np.float64),
    "friction": ((), np.float64),
    "loc_error": ((3,), np.float64),
    "grasp_error": ((3,), np.float64),
    "board_height": ((), np.float64),
    "board_tilt": ((2,), np.float64),
    "hole_est_pos": ((2,), np.float64),
    "hole_est_yaw": ((), np.float64),
    "tcp0_pos": ((3,), np.float64),
    "tcp0_rot": ((3, 3), np.float64),
    "q0": ((6,), np.float64),
    "linear_range": ((), np.float64),
    "angular_range": ((), np.float64),
    "sensor_seed": ((), np.uint32),  # key of the F/T pipeline's random draws (skill/sensor.py)
    "sensor_cutoff_scale": ((), np.float64),  # filter cutoff / the nominal one
    "sensor_noise_scale": ((), np.float64),  # noise / the nominal one
    "sensor_delay_offset": ((), np.int32),  # control periods added to the nominal latency
}


@dataclasses.dataclass(frozen=True, eq=False)
class TrialSpec:
    """B trials, world frame, SI units (NumPy arrays, leading dim B)."""

    shape_id: np.ndarray  # (B,) int32 index into SHAPES
    size: np.ndarray  # (B,) characteristic size S (m)
    hole_scale: np.ndarray  # (B,) the hole's clearance: hole size / peg size (constants.HOLE_SCALE)
    board_pos: np.ndarray  # (B, 2) true hole centre x, y
    board_yaw: np.ndarray  # (B,) true board yaw about z (rad)
    friction: np.ndarray  # (B,) peg-board friction
    loc_error: np.ndarray  # (B, 3) localization error (dx, dy, dyaw): estimate - true
    grasp_error: np.ndarray  # (B, 3) peg in the flange frame: (dz, tilt_x, tilt_y)
    board_height: np.ndarray  # (B,) the hole's entrance above its nominal height (m)
    board_tilt: np.ndarray  # (B, 2) board tilt (x, y) about its hole's entrance centre (rad)
    hole_est_pos: np.ndarray  # (B, 2) estimated hole centre = board_pos + loc_error[:, :2]
    hole_est_yaw: np.ndarray  # (B,) estimated yaw = board_yaw + loc_error[:, 2]
    tcp0_pos: np.ndarray  # (B, 3) start position of the nominal tip (site `tcp`)
    tcp0_rot: np.ndarray  # (B, 3, 3) start orientation of the tcp
    q0: np.ndarray  # (B, 6) start joint configuration, wrapped to (-pi, pi]
    linear_range: np.ndarray  # (B,) +- range the linear errors were drawn from (m)
    angular_range: np.ndarray  # (B,) +- range the angular errors were drawn from (rad)
    sensor_seed: np.ndarray  # (B,) uint32 key of the F/T sensor's noise and bias (skill/sensor.py)
    sensor_cutoff_scale: np.ndarray  # (B,) F/T filter cutoff relative to TrialConfig.sensor's
    sensor_noise_scale: np.ndarray  # (B,) F/T noise relative to TrialConfig.sensor's
    sensor_delay_offset: np.ndarray  # (B,) int32 F/T latency added to TrialConfig.sensor's

    def __len__(self) -> int:
        return int(np.shape(self.shape_id)[0])

    def take(self, indices) -> TrialSpec:
        """The trials at `indices` (integer array or boolean mask)."""
        return TrialSpec(**{n: np.asarray(v)[indices] for n, v in self.to_arrays().items()})

    @classmethod
    def concat(cls, specs: Sequence[TrialSpec]) -> TrialSpec:
        if not specs:
            raise UsageError("TrialSpec.concat needs at least one TrialSpec")
        return cls(**{n: np.concatenate([getattr(s, n) for s in specs]) for n in _SPEC_FIELDS})

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Plain arrays by field name (np.savez-able, loads with allow_pickle=False)."""
        return {name: getattr(self, name) for name in _SPEC_FIELDS}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> TrialSpec:
        arrays = file_versions.spec_arrays(arrays)
        missing = [name for name in _SPEC_FIELDS if name not in arrays]
        if missing:
            raise UsageError(f"TrialSpec arrays lack {', '.join(missing)}")
        return cls(**{n: np.asarray(arrays[n], dtype=dt) for n, (_, dt) in _SPEC_FIELDS.items()})

    def validate(self) -> TrialSpec:
        """Raise ValueError (one line) unless every array has its shape, dtype and finite values."""
        batch = len(self)
        for name, (trailing, dtype) in _SPEC_FIELDS.items():
            value = getattr(self, name)
            if not isinstance(value, np.ndarray):
                raise UsageError(
                    f"TrialSpec.{name} must be a NumPy array, got {type(value).__name__}"
                )
            if value.shape != (batch, *trailing):
                raise UsageError(
                    f"TrialSpec.{name} has shape {value.shape}, expected {(batch, *trailing)}"
                )
            if value.dtype != dtype:
                raise UsageError(
                    f"TrialSpec.{name} has dtype {value.dtype}, expected {np.dtype(dtype)}"
                )
            if not np.all(np.isfinite(value)):
                raise UsageError(f"TrialSpec.{name} has non-finite values")
        if np.any((self.shape_id < 0) | (self.shape_id >= len(SHAPES))):
            raise UsageError(f"TrialSpec.shape_id must index SHAPES {SHAPES}")
        if np.any(self.size <= 0.0):
            raise UsageError("TrialSpec.size must be positive")
        lo, hi = HOLE_SCALE_RANGE
        if np.any((self.hole_scale < lo) | (self.hole_scale > hi)):
            raise UsageError(f"TrialSpec.hole_scale must lie in [{lo:g}, {hi:g}]")
        rtr = self.tcp0_rot @ np.swapaxes(self.tcp0_rot, -1, -2)
        if np.any(np.abs(rtr - np.eye(3)) > 1e-6):
            raise UsageError("TrialSpec.tcp0_rot must hold rotation matrices")
        return self


def board_pose(board_pos, board_yaw, board_height, board_tilt) -> tuple[np.ndarray, np.ndarray]:
    """The board body's pose: pos (..., 3), quat (..., 4) (w, x, y, z) in the world.

    R = Ry(tilt_y) Rx(tilt_x) Rz(yaw) (tilts about world axes) and the hole's entrance centre,
    (0, 0, HOLE_DEPTH) in the board frame, at (x, y, HOLE_DEPTH + height): the pivot of the tilt.
    With no height and tilt this is (x, y, 0) and the yaw quaternion exactly.
    """
    tilt = np.asarray(board_tilt, dtype=np.float64)
    cx, sx = np.cos(0.5 * tilt[..., 0]), np.sin(0.5 * tilt[..., 0])
    cy, sy = np.cos(0.5 * tilt[..., 1]), np.sin(0.5 * tilt[..., 1])
    # (cy, 0, sy, 0) (cx, sx, 0, 0), as scene.grasp_quat
    q_tilt = np.stack([cy * cx, cy * sx, sy * cx, -sy * sx], axis=-1)
    quat = quat_mul(q_tilt, quat_from_yaw(np.asarray(board_yaw, dtype=np.float64)))
    height = HOLE_DEPTH + np.asarray(board_height, dtype=np.float64)
    entrance = np.concatenate([np.asarray(board_pos, dtype=np.float64), height[..., None]], axis=-1)
    return entrance - HOLE_DEPTH * matrix_from_quat(quat)[..., :, 2], quat


def hole_frame(specs: TrialSpec) -> tuple[np.ndarray, np.ndarray]:
    """Each trial's true hole: origin (B, 3) on its axis at the board's bottom, axis (B, 3)."""
    pos, quat = board_pose(specs.board_pos, specs.board_yaw, specs.board_height, specs.board_tilt)
    return pos, matrix_from_quat(quat)[..., :, 2]


def candidate_trials(config: TaskConfig, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """n trials drawn before the rejection of ill-conditioned ones: every TrialSpec field but the
    start configuration q0, and the start pose of the tcp (`tcp0_pos`, `tcp0_rot`) it solves."""
    lin, ang = config.linear_error, config.angular_error
    if config.parts:
        part = rng.integers(len(config.parts), size=n)
        shape_id = np.array([SHAPES.index(p[0]) for p in config.parts], np.int32)[part]
        size = np.array([p[1] for p in config.parts])[part]
    else:
        combo = rng.integers(len(config.shapes) * len(config.sizes), size=n)
        shape_ids = np.array([SHAPES.index(s) for s in config.shapes], dtype=np.int32)
        shape_id = shape_ids[combo // len(config.sizes)]
        size = np.asarray(config.sizes, dtype=np.float64)[combo % len(config.sizes)]
    lin = lin * (size / TRAINING_SIZE if config.linear_per_size else np.ones(n))
    r0, r1 = config.workspace_radius
    radius = np.sqrt(rng.uniform(r0**2, r1**2, n))  # uniform in area
    angle = rng.uniform(*config.workspace_angle, n)
    board_pos = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1)
    board_yaw = rng.uniform(*config.board_yaw_range, n)
    friction = rng.uniform(*config.friction_range, n)
    loc_error = rng.uniform(-1.0, 1.0, (n, 3)) * np.stack([lin, lin, np.full(n, ang)], axis=-1)
    grasp = rng.uniform(-1.0, 1.0, (n, 3)) * np.stack([lin, np.full(n, ang), np.full(n, ang)], -1)
    on_board = config.grasp_model == "board"
    grasp_error = np.zeros_like(grasp) if on_board else grasp
    board_height = grasp[:, 0] if on_board else np.zeros(n)
    board_tilt = grasp[:, 1:] if on_board else np.zeros((n, 2))
    hole_est_pos = board_pos + loc_error[:, :2]
    hole_est_yaw = board_yaw + loc_error[:, 2]
    # Start: tip over the estimated hole, offset uniformly within a disc, tilted by a rotation
    # vector uniform in the ball of radius start_tilt_jitter (world frame).
    jitter_r = config.start_xy_jitter * np.sqrt(rng.uniform(0.0, 1.0, n))
    jitter_a = rng.uniform(-np.pi, np.pi, n)
    height = HOLE_DEPTH + rng.uniform(*config.start_height, n)
    tcp0_pos = np.stack(
        [
            hole_est_pos[:, 0] + jitter_r * np.cos(jitter_a),
            hole_est_pos[:, 1] + jitter_r * np.sin(jitter_a),
            height,
        ],
        axis=-1,
    )
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    tilt = direction * (config.start_tilt_jitter * np.cbrt(rng.uniform(0.0, 1.0, n)))[:, None]
    tcp0_rot = matrix_from_rotvec(tilt) @ tool_down_rotation(hole_est_yaw)
    extra = {"hole_scale": np.array([p[2] for p in config.parts])[part]} if config.parts else {}
    return dict(
        shape_id=shape_id,
        size=size,
        board_pos=board_pos,
        board_yaw=board_yaw,
        friction=friction,
        loc_error=loc_error,
        grasp_error=grasp_error,
        board_height=board_height,
        board_tilt=board_tilt,
        hole_est_pos=hole_est_pos,
        hole_est_yaw=hole_est_yaw,
        tcp0_pos=tcp0_pos,
        tcp0_rot=tcp0_rot,
        linear_range=lin,
        angular_range=np.full(n, ang),
        **extra,
    )


def _sensor_draws(config: TaskConfig, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """The F/T sensor's per-trial draws: its key and the randomization of TaskConfig."""

    def log_uniform(bounds):
        return np.exp(rng.uniform(np.log(bounds[0]), np.log(bounds[1]), n))

    low, high = config.sensor_delay_offset
    return dict(
        sensor_seed=rng.integers(0, 2**32, n, dtype=np.uint32),
        sensor_cutoff_scale=log_uniform(config.sensor_cutoff_scale),
        sensor_noise_scale=log_uniform(config.sensor_noise_scale),
        sensor_delay_offset=rng.integers(low, high + 1, n, dtype=np.int32),
    )


def goal_pose(hole_est_pos: np.ndarray, hole_est_yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nominal goal of the tcp: the estimated hole centre at the table top, tool down, aligned.

    hole_est_pos (..., 2), hole_est_yaw (...,) -> pos (..., 3), rot (..., 3, 3).
    """
    hole_est_pos = np.asarray(hole_est_pos, dtype=np.float64)
    height = np.full(hole_est_pos.shape[:-1] + (1,), GOAL_HEIGHT)
    return np.concatenate([hole_est_pos, height], axis=-1), tool_down_rotation(hole_est_yaw)


def feasible_configuration(
    pos: np.ndarray, rot: np.ndarray, max_condition: float
) -> tuple[np.ndarray, np.ndarray]:
    """IK of tcp poses (..., 3), (..., 3, 3) nearest HOME_Q: q (..., 6), ok (...,).

    ok: a branch exists, |q| <= 2 pi (the joint limits) and the full-Jacobian condition number is
    at most max_condition.
    """
    q, found = kinematics.ik_tcp_closest(pos, rot, PEG_LENGTH)
    q_safe = np.where(found[..., None], q, kinematics.HOME_Q)
    cond = kinematics.condition_number(q_safe, PEG_LENGTH, "full")
    ok = found & np.all(np.abs(q_safe) <= 2.0 * np.pi, axis=-1) & (cond <= max_condition)
    return q, ok


def sample_trials(
    config: TaskConfig, seed_or_rng: int | np.random.Generator, batch: int
) -> TrialSpec:
    """`batch` random trials of `config`; the same seed gives identical specs.

    Candidates whose start configuration (q0 at tcp0) or goal configuration (tcp at the estimated
    hole centre, table top, tool down) is out of reach, beyond the joint limits or has a condition
    number above config.max_condition are drawn again.
    """
    if not isinstance(config, TaskConfig):
        raise UsageError(f"config must be a TaskConfig, got {type(config).__name__}")
    if isinstance(seed_or_rng, bool) or not isinstance(batch, int | np.integer) or batch < 0:
        raise UsageError(f"sample_trials needs a seed and a batch size >= 0, got {batch!r}")
    if isinstance(seed_or_rng, np.random.Generator):
        rng = seed_or_rng
    elif isinstance(seed_or_rng, int | np.integer):
        rng = np.random.default_rng(int(seed_or_rng))
    else:
        raise UsageError(f"seed_or_rng must be an int or np.random.Generator, not {seed_or_rng!r}")
    accepted: list[dict[str, np.ndarray]] = []
    have, drawn = 0, 0
    while have < batch:
        if drawn >= MAX_REJECTION_FACTOR * max(batch, 1):
            raise UsageError(
                f"sample_trials rejected {drawn - have} of {drawn} candidates (start or goal "
                f"configuration unreachable or condition number > {config.max_condition:g}): "
                "shrink the workspace or relax max_condition"
            )
        n = (batch - have) + (batch - have) // 8 + 16
        cand = candidate_trials(config, rng, n)
        q0, ok0 = feasible_configuration(cand["tcp0_pos"], cand["tcp0_rot"], config.max_condition)
        _, ok_goal = feasible_configuration(
            *goal_pose(cand["hole_est_pos"], cand["hole_est_yaw"]), config.max_condition
        )
        keep = np.flatnonzero(ok0 & ok_goal)[: batch - have]
        cand["q0"] = q0
        accepted.append({name: value[keep] for name, value in cand.items()})
        have += keep.size
        drawn += n
    if not accepted:
        accepted.append({n: v[:0] for n, v in candidate_trials(config, rng, 0).items()})
        accepted[0]["q0"] = np.zeros((0, 6))
    arrays = {name: np.concatenate([a[name] for a in accepted]) for name in accepted[0]}
    # The sensor's draws come from a child stream: the trials of a seed stay what they were
    # before the sensor was randomized.
    arrays.update(_sensor_draws(config, rng.spawn(1)[0], batch))
    if "hole_scale" not in arrays:  # a list of parts carries its own
        arrays["hole_scale"] = _hole_scales(config, arrays["shape_id"], rng)
    return TrialSpec.from_arrays(arrays).validate()


def _hole_scales(config: TaskConfig, shape_id: np.ndarray, rng: np.random.Generator):
    """(B,) each trial's hole scale: its shape's fixed value, or one drawn uniformly from the
    values of its range (`parts.hole_scale_values`) from a child stream, spawned only then:
    trials with fixed clearances are those of before the clearance was a parameter."""
    scales = np.zeros(len(shape_id))
    ranges = {SHAPES.index(s): config.hole_scale_range(s) for s in config.shapes}
    child = None
    for i, (lo, hi) in ranges.items():
        mine = shape_id == i
        if lo == hi:
            scales[mine] = lo
            continue
        child = child or rng.spawn(1)[0]
        values = hole_scale_values(lo, hi)
        scales[mine] = values[child.integers(len(values), size=int(mine.sum()))]
    return scales
