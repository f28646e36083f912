"""An evaluation's output directory: its config, one file of per-trial results per range.

    out/config.json          the resolved EvalConfig (`config.py`); resuming into a directory made
                             with another config is refused
    out/ranges/NNNNN.npz     per-trial results of range NNNNN, written atomically when it finishes
    out/grid.csv, summary.md, success_heatmap.png, time_heatmap.png, paper_comparison.png
                             the report of a finished evaluation (`report.py`)

Each finished range is saved at once, so an interrupted evaluation resumes where it stopped and
writes the same grid.csv as an uninterrupted one. Files of earlier versions are read through
`file_versions`.
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mjx_peg import errors, file_versions, inputs, outdir
from mjx_peg.engines.trial import TrialResult
from mjx_peg.errors import UsageError
from mjx_peg.evaluation.config import CONTACT_MODEL, EvalConfig
from mjx_peg.evaluation.grid_table import GridTable
from mjx_peg.outdir import OutDir, write_npz
from mjx_peg.policy.shipped import SHIPPED_DIR, shipped_names
from mjx_peg.world.constants import SHAPES

SCHEMA = "mjx-peg-eval"
SCHEMA_VERSION = 1
CONFIG_FILE, GRID_FILE, SUMMARY_FILE = "config.json", "grid.csv", "summary.md"
SUCCESS_PNG, TIME_PNG, RANGES_DIR = "success_heatmap.png", "time_heatmap.png", "ranges"
PAPER_PNG = "paper_comparison.png"  # when the paper has numbers for the condition
# The per-trial results of a range (TrialResult's fields), each (trials,), and their dtype
# kinds: booleans, counts, floats.
RESULT_KINDS = {
    "success": "b", "time_s": "f", "shape_id": "iu", "unstable": "b", "steps": "iu",
    "peak_force": "f", "reward": "f", "settled": "b", "chatter": "f", "protective_stop": "b",
}  # fmt: skip
RESULT_FIELDS = tuple(RESULT_KINDS)
CONTACT_FIELDS = ("chatter", "protective_stop")  # not recorded before contact_model 2
TIP_FIELD = "final_tip_pos"  # (trials, 3); ranges saved before the failure taxonomy lack it


def _recorded(doc: dict) -> dict:
    """The config an evaluation's config.json records, with the defaults of fields added since;
    ValueError if it is not an evaluation's."""
    if doc.get("schema") != SCHEMA or not isinstance(doc["config"], dict):
        raise ValueError(f"no {SCHEMA} config")
    return EvalConfig(**file_versions.eval_config(doc["config"])).to_json()


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
    outdir.prepare_dir(out.path / RANGES_DIR)
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
        why = f"no {e}" if isinstance(e, KeyError) else errors.message(e)[:100]
        raise UsageError(f"{path} is not an mjx-peg evaluation config ({why})") from None
    return config, policy_dir


def range_path(out: Path, index: int) -> Path:
    """Where the per-trial results of range `index` are saved."""
    return Path(out) / RANGES_DIR / f"{index:05d}.npz"


def load_range(out: Path, config: EvalConfig, index: int) -> dict[str, np.ndarray] | None:
    """Per-trial results of a finished range, or None if it has not finished."""
    path = range_path(out, index)
    if not (path.exists() or path.is_symlink()):
        return None
    n = config.trials
    members = {
        k: inputs.Member(kind, (n,), finite=k == "time_s") for k, kind in RESULT_KINDS.items()
    }
    members[TIP_FIELD] = inputs.Member("f", (n, 3), finite=False)
    try:  # each array checked by its header before it is read, only these read
        arrays = inputs.read_npz(path, members, optional=(*CONTACT_FIELDS, "settled", TIP_FIELD))
        arrays = file_versions.range_results(arrays)
        # Saved before credible contact (contact_model 1): no contact metrics.
        optional = CONTACT_FIELDS if config.contact_model < CONTACT_MODEL else ()
        missing = [k for k in RESULT_FIELDS if k not in arrays and k not in optional]
        if missing:
            raise UsageError(f"no {', '.join(missing)}")
        if np.any(arrays["time_s"] < 0) or np.any(arrays["steps"] < 0):
            raise UsageError("a time or a step count is negative")
        if not np.all(np.isin(arrays["shape_id"], [SHAPES.index(s) for s in config.shapes])):
            raise UsageError(f"shape_id names a shape other than {', '.join(config.shapes)}")
    except (OSError, ValueError) as e:
        text = errors.message(e).removeprefix(f"{path}: ")
        raise UsageError(
            f"{path} is corrupt or truncated ({text}); delete it and rerun the same command to "
            "run that range again"
        ) from None
    return arrays


def load_evaluation_grid(eval_dir) -> GridTable:
    """The grid table of a finished evaluation directory (for --compare)."""
    eval_dir = Path(eval_dir)
    if not eval_dir.exists():
        raise UsageError(f"{eval_dir} does not exist")
    if not eval_dir.is_dir():
        raise UsageError(f"{eval_dir} is not a directory")
    try:
        return GridTable.from_csv(eval_dir / GRID_FILE)
    except csv.Error as e:
        raise UsageError(f"{eval_dir / GRID_FILE} is not an evaluation grid.csv ({e})") from None


def save_range(out: Path, index: int, result: TrialResult, rows: slice, shape_id) -> Path:
    """Save range `index`'s trials, `rows` of `result`, atomically: `RESULT_FIELDS` (the shapes
    from `shape_id`, (trials,)) and where each tip ended (`TIP_FIELD`, for the failure taxonomy)."""
    arrays = {k: getattr(result, k)[rows] for k in RESULT_FIELDS if k != "shape_id"}
    arrays["shape_id"] = shape_id
    arrays[TIP_FIELD] = result.final_tip_pos[rows]
    return write_npz(range_path(out, index), arrays)


def grid_table(out_dir, config: EvalConfig) -> GridTable:
    """The grid table of a finished evaluation from its per-range results."""
    out = Path(out_dir)

    def results():
        for i in range(len(config.ranges)):
            arrays = load_range(out, config, i)
            assert arrays is not None, f"range {i} has not finished"
            yield arrays

    return GridTable.from_ranges(config.ranges, results())
