"""Reading files that earlier versions wrote: the value each field had before it existed.

One place for every such rule, so that a reader of an old run, evaluation, policy or spec file
finds here what it meant:

- evaluations (config.json) from before early ending ran every failure to the time limit; those
  from before credible contact (the F/T pipeline, the protective stop, the compliance damping)
  ran another physics (contact_model 1) and recorded no contact metrics; all of them, and every
  one from before the board error model, put the grasp errors on the peg in the flange;
- per-range results from before early ending have no `settled` (no trial had settled);
- training runs (config.json) from before the centred action map used the sigmoid map, from
  before the board error model the flange one, from before the skills the paper's skill, from
  before the geometry observation the `names` one; exported manifests without a "map" or an
  observation "layout" likewise; a config that leaves out the error ranges or the budget
  meant TrainConfig's defaults before they became the `quick` preset's (+-4 mm / +-6 deg, 12,288
  trials); runs from before the learned search constants learned the 38 alone, updated the raw
  action at a fixed rate of 1e-3 and ran Brax's running observation statistics, and those from
  before the geometry observation read the part by the names of the paper's three shapes;
- trial specs from before the board error model have a flat board at its nominal height, those
  from before the hole's clearance was a parameter the paper's clearance of their shape;
- evaluations, training runs and manifests that name a skill without its constants ran that
  skill's: one that no CLI offers now (`search`, `align`) with its constants as they were
  (`FORMER_SKILLS`), any other with its constants as they are today (`skill.search.SKILLS`);
  constants recorded before a constant existed had it off (its default);
- manifests without a skill to run them with run the skill they were trained with.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Mapping

# The skill's constants of a file that names its skill only (None): the named skill's.
EVAL_CONFIG = {
    "full_time_limit": True,
    "contact_model": 1,
    "grasp_model": "flange",
    "skill": "paper",
    "skill_constants": None,
}
TRAIN_CONFIG = {
    "action_map": "sigmoid",
    "grasp_model": "flange",
    "skill": "paper",
    "skill_constants": None,
    "linear_mm": 4.0,
    "angular_deg": 6.0,
    "trials": 12288,
    "learn_search": False,
    "learning_rate": 1e-3,
    "normalized_actions": False,
    "kl_target": 0.0,
    "obs_statistics": "running",
    "observation": "names",
}
MANIFEST_ACTION_MAP = "sigmoid"
MANIFEST_OBSERVATION = "names"  # the observation layout of manifests that name none
# The hole's clearance (hole size / peg size) of trial specs that predate it: the paper's fits of
# the shapes there were then (shape ids 0-2: circle 1.03 D, square and triangle 1.08 L).
SPEC_HOLE_SCALE = (1.03, 1.08, 1.08)

# SkillConfig's fields as they were at commit 0e346f7, the last that offered `search` and
# `align` on the CLIs (skill/search.py's SKILLS then)
_SKILL_FIELDS_0E346F7 = {
    "press_accel": 0.0,
    "lateral_scale": 1.0,
    "centre_gain": 0.0,
    "force_on": 10.0,
    "force_full": 20.0,
    "align_rate": 0.0,
    "align_max": 0.35,
    "align_max_yaw": 0.0,
    "align_depth": 0.02,
    "spiral_speed": 0.0,
    "spiral_pitch": 0.01,
    "spiral_radius": 0.025,
    "spiral_wait": 0.3,
    "spiral_ramp": 0.5,
    "spiral_axial": 2.0,
    "spiral_lateral": 0.0,
    "spiral_centre": 0.25,
    "entry_depth": 0.0015,
    "entry_follow": 1.0,
    "movement_s": 0.0,
    "movement_cruise": 0.0,
    "insert_axial": 1.0,
    "insert_depth": 0.035,
    "insert_ramp": 0.015,
    "search_budget": math.inf,
    "withdraw_height": 0.02,
    "withdraw_s": 1.0,
}
# The skills earlier versions offered by name and no CLI offers now (the spiral's ancestors,
# experiments/ablations.py): a file naming one ran these constants (SkillConfig's fields).
FORMER_SKILLS = {
    "search": {**_SKILL_FIELDS_0E346F7, "centre_gain": 1.0},
    "align": {**_SKILL_FIELDS_0E346F7, "centre_gain": 1.0, "align_rate": 1.0},
}


def eval_config(saved: Mapping) -> dict:
    """An evaluation's saved config with the fields it predates filled in."""
    return {**EVAL_CONFIG, **saved}


def train_config(saved: Mapping) -> dict:
    """A training run's saved config with the fields it predates filled in."""
    return {**TRAIN_CONFIG, **saved}


def manifest_skill(manifest: Mapping) -> dict:
    """{"name", "constants"} of the skill a policy manifest runs unless told otherwise: its
    "skill", else the one its training config names (constants None: the named skill's)."""
    if "skill" in manifest:
        return manifest["skill"]
    trained = train_config(manifest.get("config", {}))
    return {"name": trained["skill"], "constants": trained["skill_constants"]}


def range_results(arrays: dict) -> dict:
    """One evaluation range's saved results (NumPy arrays) with `settled` if it predates it."""
    if "success" in arrays and "settled" not in arrays:
        np = importlib.import_module("numpy")  # not at the top: skill/ reads FORMER_SKILLS
        arrays["settled"] = np.zeros(np.shape(arrays["success"]), bool)
    return arrays


def spec_arrays(arrays: Mapping):
    """TrialSpec arrays with the fields they predate: the board's height and tilt (zero), the
    hole's clearance (the paper's fit of each shape, `SPEC_HOLE_SCALE`)."""
    if "shape_id" not in arrays:
        return arrays
    np = importlib.import_module("numpy")
    n = np.shape(arrays["shape_id"])[0]
    filled = dict(arrays)
    if "board_height" not in arrays:
        filled.update(board_height=np.zeros(n), board_tilt=np.zeros((n, 2)))
    if "hole_scale" not in arrays:
        shape_id = np.asarray(arrays["shape_id"], dtype=np.int64)
        filled["hole_scale"] = np.asarray(SPEC_HOLE_SCALE, dtype=np.float64)[shape_id]
    return filled
