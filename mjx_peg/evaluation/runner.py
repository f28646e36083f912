"""Running an evaluation: a policy's controller on every range of a grid, resumable.

All trials of a chunk of ranges go through the engine's trial queue in one `run_trials` call, so
cost follows the simulated time actually used (the paper's 60 s limit per trial, a failure that
has settled ending early unless the config says otherwise); each range is saved as soon as its
chunk ends (`eval_dir.save_range`), and a rerun runs only the ranges not yet saved.

    python eval.py --policy runs/quick --grid paper-small --out eval/quick
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mjx_peg.engines import run_trials
from mjx_peg.evaluation.config import EvalConfig, range_specs
from mjx_peg.evaluation.eval_dir import range_path, save_range
from mjx_peg.policy.export import POLICY_FILE, load_policy
from mjx_peg.policy.shipped import resolve_policy
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.world.task import TrialSpec

# Trials per run_trials call: results are saved this often. A call ends by draining its slots
# (its last trials run beside empty slots), so a chunk is many times the engine's slots
# (docs/design/evaluation_chunks.md).
DEFAULT_CHUNK_TRIALS = 10_000

Controller = Callable[[TrialSpec], np.ndarray]  # trials -> (B, 38) controller numbers


def load_controller(policy: str) -> tuple[str, Controller]:
    """(label, controller) of a policy: "baseline" (the hand-tuned numbers) or a run directory,
    policy.npz or shipped policy's name, labelled 'sha256:<digest of policy.npz>'; UsageError
    naming the file if it does not load (PolicyError)."""
    if policy == "baseline":
        vector = baseline_params()
        return "baseline", lambda specs: np.tile(vector, (len(specs), 1))
    policy = resolve_policy(policy)  # a shipped policy's name: its directory
    loaded = load_policy(policy)
    path = Path(policy)
    npz = path if path.name == POLICY_FILE else path / POLICY_FILE
    digest = hashlib.sha256(npz.read_bytes()).hexdigest()
    return f"sha256:{digest}", loaded.controller_vectors


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
                save_range(out, i, result, slice(start, start + len(s)), s.shape_id)
                start += len(s)
            ran += len(result)
    return ran
