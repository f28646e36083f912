"""The evaluation grid (paper section 6): success rate and time to complete per error range.

A grid is a set of (linear, angular) error ranges; every range gets N trials whose errors are
uniform within +- the range (task.sample_trials), split evenly between the shapes. All trials of
a chunk of ranges go through the engine's trial queue in one `run_trials` call, so cost follows
the simulated time actually used (60 s limit per trial, as in the paper). Each finished range is
saved at once (`ranges/NNNNN.npz`, written atomically), so an interrupted evaluation resumes
where it stopped; a range's trials come from a seed derived only from (seed, range index), so a
resumed run writes the same grid.csv as an uninterrupted one.

    python eval.py --policy runs/quick --grid paper-small --out eval/quick

Outputs in --out: config.json (the resolved config; resuming into a directory made with another
config is refused), grid.csv, success_heatmap.png, time_heatmap.png, summary.md and, where the
paper has numbers for the condition, paper_comparison.png.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import math
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from mjx_peg import cli, file_versions, inputs
from mjx_peg.engines import run_trials
from mjx_peg.engines.trial import TrialConfig
from mjx_peg.errors import UsageError
from mjx_peg.evaluation import stats as es
from mjx_peg.outdir import OutDir, write_npz
from mjx_peg.policy.export import POLICY_FILE, load_policy
from mjx_peg.policy.shipped import SHIPPED_DIR, resolve_policy, shipped_names
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.search import SKILL_DESCRIPTIONS, skill_config
from mjx_peg.world.constants import GRASP_MODELS
from mjx_peg.world.task import SHAPES, TaskConfig, TrialSpec, sample_trials

SCHEMA = "mjx-peg-eval"
SCHEMA_VERSION = 1
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
DEFAULT_CHUNK_TRIALS = 10_000  # trials per run_trials call: results saved this often. A call
# ends by draining its slots: its last trials run with the slots around them empty, as long as a
# failure lasts (60 s). With 1,000 trials per call and 1,024 slots (2 lanes x 512) nothing was
# ever refilled; 10,000 keep the slots full for most of the call (BENCHMARKS.md "Early ending")
CONFIG_FILE, GRID_FILE, SUMMARY_FILE = "config.json", "grid.csv", "summary.md"
SUCCESS_PNG, TIME_PNG, RANGES_DIR = "success_heatmap.png", "time_heatmap.png", "ranges"
PAPER_PNG = "paper_comparison.png"  # when the paper has numbers for the condition
MAX_ERROR = {"linear_mm": (0.0, 50.0), "angular_deg": (0.0, 45.0)}  # TaskConfig's, mm and deg
# The dtype kinds of each saved field: booleans, counts, floats
_RESULT_KINDS = {
    "success": "b", "time_s": "f", "shape_id": "iu", "unstable": "b", "steps": "iu",
    "peak_force": "f", "reward": "f", "settled": "b", "chatter": "f", "protective_stop": "b",
}  # fmt: skip
_RESULT_FIELDS = tuple(_RESULT_KINDS)
_CONTACT_FIELDS = ("chatter", "protective_stop")  # not recorded before contact_model 2
_TIP_FIELD = "final_tip_pos"  # (trials, 3); ranges saved before the failure taxonomy lack it
CONTACT_MODEL = 2  # the trial's physics and sensing (EvalConfig.contact_model)
GRASP_DESCRIPTION = {
    "board": "the board's height and tilt about its hole's entrance (the paper's model)",
    "flange": "the peg's height and tilt in the flange (--grasp-model flange, harder than the "
    "paper's)",
}


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
    # The skill (skill.search.SKILLS): "paper", the paper's as written, or "search"
    skill: str = "paper"

    def __post_init__(self):
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
        if self.engine not in ("mujoco", "mjx"):
            raise UsageError(f"engine must be resolved to mujoco or mjx, got {self.engine!r}")
        if self.grasp_model not in GRASP_MODELS:
            raise UsageError(
                f"unknown grasp model {self.grasp_model!r}: choose from {', '.join(GRASP_MODELS)}"
            )
        skill_config(self.skill)  # a known skill
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
            search=skill_config(self.skill),
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
            f.name: list(v) if isinstance(v := getattr(self, f.name), tuple) else v
            for f in dataclasses.fields(self)
        }


def task_config(config: EvalConfig, shape: str, linear_mm: float, angular_deg: float):
    """The TaskConfig of one shape and error range of an evaluation (SI units)."""
    return TaskConfig.from_mm_deg(
        (shape,), config.size_mm, linear_mm, angular_deg, time_limit_s=config.time_limit_s,
        grasp_model=config.grasp_model,
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


def parse_ranges(text: str, name: str, limit: int = cli.MAX_AXIS) -> tuple[float, ...]:
    """'0.5,1,2' or 'START:STOP:STEP' (inclusive) or a mix -> the values; ValueError if empty,
    not finite or more than `limit` values (counted before any is made)."""
    values: list[float] = []
    try:
        for item in (s.strip() for s in text.split(",")):
            if not item:
                continue
            parts = [float(p) for p in item.split(":")]
            if not all(math.isfinite(v) for v in parts) or len(parts) not in (1, 3):
                raise ValueError
            if len(parts) == 3:
                start, stop, step = parts
                if not step > 0:
                    raise UsageError(f"{name}: step of {item!r} must be positive")
                count = (stop - start) / step + 1e-9
                if count + 1 + len(values) > limit:
                    raise UsageError(
                        f"{name}: {item!r} gives more than {limit:,} values, the most a grid axis "
                        "takes"
                    )
                count = math.floor(count) + 1
                values += [round(start + k * step, 9) for k in range(max(count, 0))]
            else:
                values.append(parts[0])
            if len(values) > limit:
                raise UsageError(f"{name}: more than {limit:,} values, the most a grid axis takes")
    except ValueError as exc:
        if str(exc).startswith(name):
            raise
        shown = text if len(text) <= 40 else text[:37] + "..."
        raise UsageError(f"{name}: cannot read {shown!r} (give 0.5,1,2 or 1:8:1)") from None
    if not values:
        raise UsageError(f"{name} is empty: give comma-separated values or START:STOP:STEP")
    seen, repeated = set(), []
    for v in values:
        if v in seen and v not in repeated:
            repeated.append(v)
        seen.add(v)
    if repeated:
        shown = ", ".join(f"{v:g}" for v in repeated[:3]) + (", ..." if len(repeated) > 3 else "")
        raise UsageError(
            f"{name} repeats {len(repeated):,} value{'s' * (len(repeated) > 1)} ({shown}): ranges "
            "are rounded to 1e-9, give distinct values"
        )
    return tuple(values)


# ---------------------------------------------------------------------------------------------
# Policies: 38 controller numbers per trial.

Controller = Callable[[TrialSpec], np.ndarray]


def load_controller(policy: str) -> tuple[str, Controller]:
    """('baseline' or 'sha256:<digest>', specs -> (B, 38)) for --policy; PolicyError if bad."""
    if policy == "baseline":
        vector = baseline_params()
        return "baseline", lambda specs: np.tile(vector, (len(specs), 1))
    policy = resolve_policy(policy)  # a shipped policy's name: its directory
    loaded = load_policy(policy)
    path = Path(policy)
    npz = path if path.name == POLICY_FILE else path / POLICY_FILE
    digest = hashlib.sha256(npz.read_bytes()).hexdigest()
    return f"sha256:{digest}", loaded.controller_vectors


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


# ---------------------------------------------------------------------------------------------
# The output directory.


def _recorded(doc: dict) -> dict:
    """The config an evaluation's config.json records, with the defaults of fields added since;
    ValueError if it is not an evaluation's."""
    if doc.get("schema") != SCHEMA or not isinstance(doc["config"], dict):
        raise ValueError(f"no {SCHEMA} config")
    return file_versions.eval_config(doc["config"])


def prepare_out_dir(
    out_dir,
    config: EvalConfig,
    policy_dir: str | None = None,
    force: bool = False,
    note: Callable[[str], None] | None = None,
) -> Path:
    """Create out_dir with config.json, or check that its config.json equals `config` and that
    every range it holds reads (resume). With `force`, an evaluation directory (whatever its
    config) is moved aside and started anew; nothing else is ever replaced."""
    out = OutDir(out_dir, CONFIG_FILE, "evaluation", read=_recorded)
    plan = out.plan(config.to_json(), force)
    if plan == "resume":
        for i in range(len(config.ranges)):
            load_range(out.path, config, i)  # a corrupt file: one line naming it, up front
        out.prepare(plan)  # config.json rewritten unchanged: writable (or one line)
        return out.path
    doc = {"schema": SCHEMA, "schema_version": SCHEMA_VERSION, "config": config.to_json()}
    if policy_dir is not None:  # a shipped policy by its name: the same on every checkout
        path = Path(policy_dir).resolve()
        shipped = path.parent == SHIPPED_DIR and path.name in shipped_names()
        doc["policy_dir"] = path.name if shipped else str(path)
    out.prepare(plan, doc, note)
    cli.prepare_dir(out.path / RANGES_DIR)
    return out.path


def read_eval_dir(eval_dir) -> tuple[EvalConfig, str | None]:
    """(config, policy run directory or None for the baseline) of an evaluation directory."""
    path = Path(eval_dir) / CONFIG_FILE
    if not path.is_file():
        raise UsageError(f"{eval_dir} holds no {CONFIG_FILE}: not an evaluation directory")
    doc = inputs.read_json(path, "an mjx-peg evaluation config")
    try:
        config = EvalConfig(**_recorded(doc))
        policy_dir = doc.get("policy_dir")
        if policy_dir is not None and not isinstance(policy_dir, str):
            raise TypeError("policy_dir is not a path")
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        why = f"no {e}" if isinstance(e, KeyError) else cli.message(e)[:100]
        raise UsageError(f"{path} is not an mjx-peg evaluation config ({why})") from None
    return config, policy_dir


def range_path(out: Path, index: int) -> Path:
    return out / RANGES_DIR / f"{index:05d}.npz"


def load_range(out: Path, config: EvalConfig, index: int) -> dict[str, np.ndarray] | None:
    """Per-trial results of a finished range, or None if it has not finished."""
    path = range_path(out, index)
    if not (path.exists() or path.is_symlink()):
        return None
    n = config.trials
    members = {
        k: inputs.Member(kind, (n,), finite=k == "time_s") for k, kind in _RESULT_KINDS.items()
    }
    members[_TIP_FIELD] = inputs.Member("f", (n, 3), finite=False)
    optional = (*_CONTACT_FIELDS, "settled", _TIP_FIELD)
    try:
        arrays = inputs.read_npz(path, members, optional=optional)
        arrays = file_versions.range_results(arrays)
        # Saved before credible contact (contact_model 1): no contact metrics.
        optional = _CONTACT_FIELDS if config.contact_model < CONTACT_MODEL else ()
        missing = [k for k in _RESULT_FIELDS if k not in arrays and k not in optional]
        if missing:
            raise UsageError(f"no {', '.join(missing)}")
        if np.any(arrays["time_s"] < 0) or np.any(arrays["steps"] < 0):
            raise UsageError("a time or a step count is negative")
        if not np.all(np.isin(arrays["shape_id"], [SHAPES.index(s) for s in config.shapes])):
            raise UsageError(f"shape_id names a shape other than {', '.join(config.shapes)}")
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        text = cli.message(e).removeprefix(f"{path}: ")
        raise UsageError(
            f"{path} is corrupt or truncated ({text}); delete it and rerun the same command to "
            "run that range again"
        ) from None
    return arrays


def run_evaluation(
    config: EvalConfig,
    out_dir,
    controller: Controller,
    engine_options: dict | None = None,
    chunk_trials: int = DEFAULT_CHUNK_TRIALS,
    show_progress: bool = True,
) -> int:
    """Run every range of `config` not yet finished in out_dir; return the trials run.

    Ranges run in chunks of about `chunk_trials` trials, all trials of a chunk in one
    `run_trials` call; each range's results are saved as soon as its chunk ends.
    """
    from tqdm import tqdm

    out = Path(out_dir)
    n_ranges = len(config.ranges)
    done = {i for i in range(n_ranges) if range_path(out, i).is_file()}
    per_chunk = max(1, chunk_trials // config.trials)
    chunks = [range(s, min(s + per_chunk, n_ranges)) for s in range(0, n_ranges, per_chunk)]
    trial_config = config.trial_config()
    ran = 0
    with tqdm(
        total=n_ranges * config.trials,
        initial=len(done) * config.trials,
        unit="trial",
        desc="evaluating",
        smoothing=0.0,
        dynamic_ncols=True,
        disable=not show_progress,
    ) as bar:
        for chunk in chunks:
            todo = [i for i in chunk if i not in done]
            if not todo:
                continue
            specs = [range_specs(config, i) for i in todo]
            params = np.concatenate([controller(s) for s in specs])  # per range: batch-stable
            result = run_trials(
                TrialSpec.concat(specs),
                params,
                engine=config.engine,
                config=trial_config,
                progress=bar.update,
                **(engine_options or {}),
            )
            start = 0
            for i, s in zip(todo, specs, strict=True):
                rows = slice(start, start + len(s))
                arrays = {k: getattr(result, k)[rows] for k in _RESULT_FIELDS if k != "shape_id"}
                arrays["shape_id"] = s.shape_id
                arrays[_TIP_FIELD] = result.final_tip_pos[rows]  # for the failure taxonomy
                write_npz(range_path(out, i), arrays)
                start += len(s)
            ran += len(result)
    return ran


def grid_table(out_dir, config: EvalConfig) -> es.GridTable:
    """The grid table of a finished evaluation from its per-range results."""
    out = Path(out_dir)
    lin, ang = np.array(config.ranges).T
    rows = {k: [] for k in ("trials", "successes", "mean", "min", "max", "settled", "stops",
                            "peak", "smooth")}  # fmt: skip
    for i in range(len(config.ranges)):
        arrays = load_range(out, config, i)
        assert arrays is not None, f"range {i} has not finished"
        times = arrays["time_s"][arrays["success"]]
        rows["trials"].append(arrays["success"].size)
        rows["successes"].append(int(arrays["success"].sum()))
        for stat, fn in (("mean", np.mean), ("min", np.min), ("max", np.max)):
            rows[stat].append(float(fn(times)) if times.size else math.nan)
        rows["settled"].append(int(arrays["settled"].sum()))
        contact = all(k in arrays for k in _CONTACT_FIELDS)  # not before credible contact
        rows["stops"].append(int(arrays["protective_stop"].sum()) if contact else math.nan)
        rows["peak"].append(float(np.median(arrays["peak_force"])) if contact else math.nan)
        long = arrays["chatter"][arrays["time_s"] > 1.2] if contact else np.zeros(0)
        rows["smooth"].append(100.0 * float((long < 5.0).mean()) if long.size else math.nan)
    return es.GridTable(
        linear_mm=lin,
        angular_deg=ang,
        trials=np.array(rows["trials"]),
        successes=np.array(rows["successes"]),
        time_mean_s=np.array(rows["mean"]),
        time_min_s=np.array(rows["min"]),
        time_max_s=np.array(rows["max"]),
        settled=np.array(rows["settled"]),
        protective_stops=np.array(rows["stops"], dtype=float),
        peak_force_median_n=np.array(rows["peak"]),
        chatter_under_5n_pct=np.array(rows["smooth"]),
    )


def load_evaluation_grid(eval_dir) -> es.GridTable:
    """The grid table of a finished evaluation directory (for --compare)."""
    eval_dir = Path(eval_dir)
    if not eval_dir.exists():
        raise UsageError(f"{eval_dir} does not exist")
    if not eval_dir.is_dir():
        raise UsageError(f"{eval_dir} is not a directory")
    try:
        return es.GridTable.from_csv(eval_dir / GRID_FILE)
    except csv.Error as e:
        raise UsageError(f"{eval_dir / GRID_FILE} is not an evaluation grid.csv ({e})") from None


def _header(out: Path, config: EvalConfig, grid: es.GridTable, policy_label: str) -> list[str]:
    per_shape = {s: [0, 0] for s in config.shapes}
    steps = settled = 0
    contact = {k: [] for k in ("peak_force", "chatter", "protective_stop", "time_s")}
    for i in range(len(config.ranges)):
        arrays = load_range(out, config, i)
        steps += int(arrays["steps"].sum())
        settled += int(arrays["settled"].sum())
        for k in contact:
            if k in arrays:  # evaluations from before the sensor pipeline lack them
                contact[k].append(arrays[k])
        for s in config.shapes:
            mine = arrays["shape_id"] == SHAPES.index(s)
            per_shape[s][0] += int(arrays["success"][mine].sum())
            per_shape[s][1] += int(mine.sum())
    total, ok = int(grid.trials.sum()), int(grid.successes.sum())
    shapes = ", ".join(
        f"{s} {100.0 * k / max(n, 1):.1f} % of {n}" for s, (k, n) in per_shape.items()
    )
    lin, ang = config.linear_mm, config.angular_deg
    return [
        f"policy: {policy_label}",
        f"grid: {config.grid}, {len(lin)} linear x {len(ang)} angular = {len(config.ranges)} "
        f"ranges; linear +-{lin[0]:g}..{lin[-1]:g} mm, angular +-{ang[0]:g}..{ang[-1]:g} deg",
        f"shapes: {', '.join(config.shapes)} (trials split evenly); size S = {config.size_mm:g} mm",
        f"trials per range: {config.trials}; time limit {config.time_limit_s:g} s per trial; "
        + (
            "every failure ran to the time limit (--full-time-limit)"
            if config.full_time_limit
            else f"{settled} failures ended early, settled (TrialConfig.end_settled)"
        ),
        f"grasp errors: {GRASP_DESCRIPTION[config.grasp_model]}",
        f"skill: {config.skill} ({SKILL_DESCRIPTIONS[config.skill]})",
        f"seed {config.seed}; engine {config.engine}",
        f"all trials: {ok} / {total} succeeded ({100.0 * ok / max(total, 1):.2f} %); per shape: "
        + shapes,
        f"simulated: {steps} physics steps = {steps * TrialConfig().timestep:.0f} s",
    ] + _contact_lines({k: np.concatenate(v) for k, v in contact.items() if v})


def _contact_lines(arrays: dict[str, np.ndarray]) -> list[str]:
    """The contact metrics of all trials (TrialResult.contact_summary), if they were recorded."""
    if not {"peak_force", "chatter", "protective_stop", "time_s"} <= set(arrays):
        return []
    n = arrays["peak_force"].size
    long = arrays["chatter"][arrays["time_s"] > 1.2]
    p50, p99 = np.percentile(arrays["peak_force"], [50, 99])
    return [
        f"contact: peak sensed force median {p50:.0f} N, p99 {p99:.0f} N; protective stops "
        f"{int(arrays['protective_stop'].sum())} ({100.0 * arrays['protective_stop'].mean():.1f} "
        f"%); chatter (mean |dF| of the axial force over a trial's last second) under 5 N in "
        f"{100.0 * (long < 5.0).mean() if long.size else math.nan:.1f} % of the {long.size} "
        f"trials longer than 1.2 s, median {np.median(long) if long.size else math.nan:.2f} N"
        f" (of {n} trials)"
    ]


def write_outputs(
    out_dir,
    config: EvalConfig,
    policy_label: str,
    paper_name: str | None,
    other: es.GridTable | None = None,
    other_name: str = "",
    alternative: str = "less",
) -> es.GridTable:
    """grid.csv, the two heatmaps, summary.md and (with a paper condition) the paper
    comparison plot of a finished evaluation."""
    from mjx_peg.evaluation import plots

    out = Path(out_dir)
    grid = grid_table(out, config)
    cli.write_atomic(out / GRID_FILE, grid.csv_text())
    what = f"{', '.join(config.shapes)}, S = {config.size_mm:g} mm, N = {config.trials}"
    plots.success_heatmap(grid, out / SUCCESS_PNG, f"Success rate (%): {what}")
    plots.time_heatmap(grid, out / TIME_PNG, f"Mean time to complete (s): {what}")
    if paper_name is not None:
        paper = es.PAPER[paper_name]
        plots.paper_bars(grid, paper, out / PAPER_PNG, f"{what}; paper: {paper.title}")
    header = _header(out, config, grid, policy_label)
    text = es.summary_markdown(grid, header, paper_name, other, other_name, alternative)
    cli.write_atomic(out / SUMMARY_FILE, text + _failures_section(out, config))
    return grid


def _failures_section(out: Path, config: EvalConfig) -> str:
    """summary.md's failure taxonomy over every trial of the grid (`taxonomy`), if the ranges
    recorded where each tip ended."""
    from mjx_peg.evaluation import taxonomy

    specs, arrays = [], []
    for i in range(len(config.ranges)):
        saved = load_range(out, config, i)
        if _TIP_FIELD not in saved:
            return ""
        specs.append(range_specs(config, i))
        arrays.append(saved)
    fields = ("success", "unstable", "protective_stop", "settled", "steps", _TIP_FIELD)
    merged = {k: np.concatenate([a[k] for a in arrays]) for k in fields}
    trial = config.trial_config()
    rows = taxonomy.table(TrialSpec.concat(specs), merged, trial.time_limit_s, trial.timestep)
    return "\n## Failures\n\n" + taxonomy.markdown(rows, merged["success"].size)


# ---------------------------------------------------------------------------------------------
# The CLI (eval.py).
