"""A training run directory: its files, its Orbax checkpoints, and the rules for reusing it.

    RUN_DIR/config.json          the resolved TrainConfig (a resumed run must match it)
    RUN_DIR/metrics.csv          one row per iteration (trials seen, mean return, success, ...)
    RUN_DIR/trials.csv           one row per trial (return, success, time): the learning curve
    RUN_DIR/checkpoints/         Orbax checkpoints of the whole TrainingState, the last few kept
    RUN_DIR/policy.npz, manifest.json, training_curve.png   written when the run finishes

The CSV files are appended as training goes; on resume they are cut back to the checkpoint's
trial count, so a killed run's curve continues without gaps or duplicates.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import orbax.checkpoint as ocp

from mjx_peg import cli
from mjx_peg.errors import UsageError
from mjx_peg.learn.config import TrainConfig
from mjx_peg.policy.export import MANIFEST_FILE, POLICY_FILE

METRICS_COLUMNS = (
    "iteration",
    "trials",
    "mean_return",
    "success_rate",
    "time_to_complete_s",
    "unstable_rate",
    "settled_rate",
    "protective_stop_rate",
    "peak_force_median_n",
    "chatter_median_n",
    "wall_s",
    "trials_per_s",
    "policy_loss",
    "value_loss",
    "entropy_loss",
    "kl",
    "policy_std",
)
TRIALS_COLUMNS = ("trial", "return", "success", "time_s")
# metrics.csv columns added after runs were made, each after another: (name, after)
_ADDED_METRICS = (
    ("settled_rate", "unstable_rate"),
    ("protective_stop_rate", "settled_rate"),
    ("peak_force_median_n", "protective_stop_rate"),
    ("chatter_median_n", "peak_force_median_n"),
)
KEEP_CHECKPOINTS = 3


class RunDir:
    """Paths and bookkeeping of one run directory."""

    def __init__(self, path):
        self.path = Path(path)
        self.config_path = self.path / "config.json"
        self.metrics_path = self.path / "metrics.csv"
        self.trials_path = self.path / "trials.csv"
        self.checkpoint_dir = self.path / "checkpoints"
        self.policy_path = self.path / POLICY_FILE
        self.manifest_path = self.path / MANIFEST_FILE
        self.curve_path = self.path / "training_curve.png"

    def is_finished(self) -> bool:
        try:
            return bool(json.loads(self.manifest_path.read_text()).get("finished"))
        except (OSError, ValueError):
            return False

    def read_config(self) -> TrainConfig:
        try:
            return TrainConfig.from_json(json.loads(self.config_path.read_text()))
        except (OSError, ValueError, TypeError) as e:
            raise UsageError(
                f"{self.path} is not a training run ({self.config_path.name}: {e})"
            ) from None

    def plan(self, config: TrainConfig, force: bool, init_from=None) -> str:
        """What `prepare` will do, decided without touching anything: "new" (an empty or absent
        directory), "resume" (an unfinished run of this config) or "replace" (--force on a run:
        it is moved aside); ValueError (one line) for everything else."""
        if init_from is not None:
            cli.check_apart(self.path, {"--init-from": init_from})
        if self.path.exists() and not self.path.is_dir():
            raise UsageError(f"--out {self.path} exists and is not a directory")
        if not self.path.is_dir() or not any(self.path.iterdir()):
            return "new"
        if not self.config_path.is_file():
            raise UsageError(
                f"--out {self.path} is not empty and holds no training run; choose another "
                "directory (--force replaces only a training run)"
            )
        previous = self.read_config()  # a config.json that is not a run's: ValueError
        if force:
            return "replace"
        if self.is_finished():
            raise UsageError(
                f"--out {self.path} holds a finished run; pass --force to move it aside and "
                "start over"
            )
        if previous != config:
            changed = sorted(
                k for k, v in config.to_json().items() if previous.to_json().get(k) != v
            )
            raise UsageError(
                f"--out {self.path} holds an unfinished run with a different config "
                f"({', '.join(changed)} differ); rerun it with the same options, or pass "
                "--force to move it aside and start over"
            )
        return "resume"

    def prepare(self, config: TrainConfig, plan: str) -> Path | None:
        """Carry out `plan` (from `plan()`): move a replaced run aside, create the directory,
        (re)write config.json atomically (which proves the directory writable); returns where
        a replaced run went."""
        moved = None
        if plan == "replace":
            moved = cli.move_aside(self.path)
        if plan != "resume":
            cli.prepare_dir(self.path)
        cli.write_atomic(self.config_path, config.dumps())
        return moved

    def checkpoints(self) -> ocp.CheckpointManager:
        return ocp.CheckpointManager(
            self.checkpoint_dir.absolute(),
            options=ocp.CheckpointManagerOptions(
                max_to_keep=KEEP_CHECKPOINTS, enable_async_checkpointing=False
            ),
        )

    def start_tables(self) -> None:
        tables = ((self.metrics_path, METRICS_COLUMNS), (self.trials_path, TRIALS_COLUMNS))
        for path, columns in tables:
            with open(path, "w", newline="") as f:
                csv.writer(f).writerow(columns)

    def truncate_tables(self, trials: int) -> None:
        """Drop rows written after the checkpoint that holds `trials` trials."""
        if not (self.metrics_path.is_file() and self.trials_path.is_file()):
            self.start_tables()
            return
        for path, column in ((self.metrics_path, "trials"), (self.trials_path, "trial")):
            try:
                with open(path, newline="") as f:
                    rows = list(csv.reader(f))
                header, body = rows[0], rows[1:]
                if path == self.metrics_path:  # an older run: columns added since, left empty
                    for name, after in _ADDED_METRICS:
                        if name not in header:
                            at = header.index(after) + 1
                            header.insert(at, name)
                            body = [r[:at] + [""] + r[at:] for r in body]
                i = header.index(column)
                limit = trials if column == "trials" else trials - 1
                kept = [r for r in body if len(r) == len(header) and int(r[i]) <= limit]
            except (IndexError, ValueError, csv.Error, UnicodeDecodeError) as e:
                raise UsageError(
                    f"{path} is corrupt ({type(e).__name__}: {cli.message(e)}); move the run "
                    "aside (--force) to start over"
                ) from None
            tmp = path.with_suffix(".tmp")
            with open(tmp, "w", newline="") as f:
                csv.writer(f).writerows([header] + kept)
            os.replace(tmp, path)

    def append(self, metrics_row: list, trial_rows: list[list]) -> None:
        with open(self.trials_path, "a", newline="") as f:
            csv.writer(f).writerows(trial_rows)
        with open(self.metrics_path, "a", newline="") as f:
            csv.writer(f).writerow(metrics_row)
