"""Reading files that earlier versions wrote: the value each field had before it existed.

One place for every such rule, so that a reader of an old run, evaluation, policy or spec file
finds here what it meant:

- evaluations (config.json) from before early ending ran every failure to the time limit; those
  from before credible contact (the F/T pipeline, the protective stop, the compliance damping)
  ran another physics (contact_model 1) and recorded no contact metrics; all of them, and every
  one from before the board error model, put the grasp errors on the peg in the flange;
- per-range results from before early ending have no `settled` (no trial had settled);
- training runs (config.json) from before the centred action map used the sigmoid map, from
  before the board error model the flange one, from before the skills the paper's skill; exported
  manifests without a "map" likewise; a config that leaves out the error ranges or the budget
  meant TrainConfig's defaults before they became the `quick` preset's (+-4 mm / +-6 deg, 12,288
  trials);
- trial specs from before the board error model have a flat board at its nominal height.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

EVAL_CONFIG = {
    "full_time_limit": True,
    "contact_model": 1,
    "grasp_model": "flange",
    "skill": "paper",
}
TRAIN_CONFIG = {
    "action_map": "sigmoid",
    "grasp_model": "flange",
    "skill": "paper",
    "linear_mm": 4.0,
    "angular_deg": 6.0,
    "trials": 12288,
}
MANIFEST_ACTION_MAP = "sigmoid"


def eval_config(saved: Mapping) -> dict:
    """An evaluation's saved config with the fields it predates filled in."""
    return {**EVAL_CONFIG, **saved}


def train_config(saved: Mapping) -> dict:
    """A training run's saved config with the fields it predates filled in."""
    return {**TRAIN_CONFIG, **saved}


def range_results(arrays: dict) -> dict:
    """One evaluation range's saved results (NumPy arrays) with `settled` if it predates it."""
    if "success" in arrays and "settled" not in arrays:
        arrays["settled"] = np.zeros(np.shape(arrays["success"]), bool)
    return arrays


def spec_arrays(arrays: Mapping):
    """TrialSpec arrays with the board's height and tilt (zero) if they predate them."""
    if "board_height" in arrays or "shape_id" not in arrays:
        return arrays
    n = np.shape(arrays["shape_id"])[0]
    return {**arrays, "board_height": np.zeros(n), "board_tilt": np.zeros((n, 2))}
