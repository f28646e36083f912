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
import io
from pathlib import Path

from mjx_peg import errors, inputs, outdir
from mjx_peg.errors import UsageError
from mjx_peg.learn.checkpoints import Checkpoints
from mjx_peg.learn.config import TrainConfig
from mjx_peg.outdir import OutDir
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
    "learning_rate",
)
TRIALS_COLUMNS = ("trial", "return", "success", "time_s")
# eval.csv: the policy's mean on the held-out trials (TrainConfig.eval_every)
EVAL_COLUMNS = ("iteration", "trials", "success_rate", "mean_return", "time_to_complete_s",
                "protective_stop_rate")  # fmt: skip
# metrics.csv columns added after runs were made, each after another: (name, after)
_ADDED_METRICS = (
    ("settled_rate", "unstable_rate"),
    ("protective_stop_rate", "settled_rate"),
    ("peak_force_median_n", "protective_stop_rate"),
    ("chatter_median_n", "peak_force_median_n"),
    ("learning_rate", "policy_std"),
)
KEEP_CHECKPOINTS = 3


def _recorded(doc: dict) -> dict:
    """The config a run's config.json records, with the defaults of fields added since."""
    return TrainConfig.from_json(doc).to_json()


MAX_TABLE_BYTES = 2**31  # metrics.csv, trials.csv or eval.csv (10,000,000 trials: ~300 MB)


def _parses(row: list[str], width: int, index: int) -> bool:
    """Whether a table row is whole: `width` fields, an integer at `index`."""
    return len(row) == width and row[index].strip().isdigit()


def _start_table(path: Path, columns) -> None:
    """Write a table's header, whole or not at all (a full disk leaves no empty table)."""
    text = io.StringIO(newline="")
    csv.writer(text).writerow(columns)
    outdir.write_atomic(path, text.getvalue())


def _append_rows(path: Path, rows: list[list]) -> None:
    """Append rows to a table; a full disk's error names the table."""
    try:
        with open(path, "a", newline="") as f:
            csv.writer(f).writerows(rows)
    except OSError as e:
        raise OSError(e.errno, e.strerror, str(path)) from None


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
        self.eval_path = self.path / "eval.csv"
        self.tensorboard_dir = self.path / "tensorboard"
        self.out = OutDir(self.path, self.config_path.name, "training run", read=_recorded)

    def is_finished(self) -> bool:
        if not self.manifest_path.exists():
            return False
        manifest = inputs.read_json(self.manifest_path, "a policy manifest")
        return isinstance(manifest, dict) and manifest.get("finished") is True

    def read_config(self) -> TrainConfig:
        if not self.config_path.exists():
            raise UsageError(f"{self.path} is not a training run (it holds no config.json)")
        doc = inputs.read_json(self.config_path, "a training run's config")
        try:
            if not isinstance(doc, dict):
                raise TypeError("not an object")
            return TrainConfig.from_json(doc)
        except (ValueError, TypeError, AttributeError) as e:
            raise UsageError(
                f"{self.path} is not a training run ({self.config_path.name}: "
                f"{errors.message(e)[:100]})"
            ) from None

    def plan(self, config: TrainConfig, force: bool, init_from=None) -> str:
        """What `prepare` will do, decided without touching anything: "new" (an empty or absent
        directory), "resume" (an unfinished run of this config) or "replace" (--force on a run:
        it is moved aside); UsageError (one line) for everything else."""
        if init_from is not None:
            outdir.check_apart(self.path, {"--init-from": init_from})
        plan = self.out.plan(config.to_json(), force)
        if plan == "resume" and self.is_finished():
            raise UsageError(
                f"--out {self.path} holds a finished run; pass --force to move it aside and "
                "start over"
            )
        return plan

    def prepare(self, config: TrainConfig, plan: str, note=None) -> Path | None:
        """Carry out `plan` (from `plan()`): move a replaced run aside (`note` is told where),
        create the directory, (re)write config.json; returns where a replaced run went."""
        return self.out.prepare(plan, config.dumps(), note)

    def checkpoints(self) -> Checkpoints:
        return Checkpoints(self.checkpoint_dir, keep=KEEP_CHECKPOINTS)

    def start_tables(self) -> None:
        for path, columns in self._columns().items():
            _start_table(path, columns)

    def truncate_tables(self, trials: int) -> None:
        """Drop rows written after the checkpoint that holds `trials` trials."""
        columns = self._columns()
        for path in columns:
            if path.exists() or path.is_symlink():
                inputs.regular_file(path)  # a FIFO or folder there: one line, never replaced
        if not (self.metrics_path.is_file() and self.trials_path.is_file()):
            self.start_tables()
            return
        if not self.eval_path.is_file():  # a run from before the held-out evaluation
            _start_table(self.eval_path, EVAL_COLUMNS)
        tables = ((self.metrics_path, "trials"), (self.trials_path, "trial"),
                  (self.eval_path, "trials"))  # fmt: skip
        for path, column in tables:
            try:
                rows = list(csv.reader(io.StringIO(inputs.read_text(path, MAX_TABLE_BYTES))))
                if not rows:  # an empty table (a full disk before its header): start it again
                    rows = [list(columns[path])]
                header, body = rows[0], rows[1:]
                if path == self.metrics_path:  # an older run: columns added since, left empty
                    for name, after in _ADDED_METRICS:
                        if name not in header:
                            at = header.index(after) + 1
                            header.insert(at, name)
                            body = [r[:at] + [""] + r[at:] for r in body]
                i = header.index(column)
                limit = trials if column == "trials" else trials - 1
                if body and not _parses(body[-1], len(header), i):  # a failed append's row
                    body = body[:-1]
                kept = [r for r in body if len(r) == len(header) and int(r[i]) <= limit]
            except (IndexError, ValueError, csv.Error, UnicodeDecodeError) as e:
                raise UsageError(
                    f"{path} is corrupt ({type(e).__name__}: {errors.message(e)}); move the run "
                    "aside (--force) to start over"
                ) from None
            text = io.StringIO(newline="")
            csv.writer(text).writerows([header] + kept)
            outdir.write_atomic(path, text.getvalue())

    def append(self, metrics_row: list, trial_rows: list[list]) -> None:
        """Append an iteration's rows (a resume cuts off rows a failed append left behind)."""
        _append_rows(self.trials_path, trial_rows)
        _append_rows(self.metrics_path, [metrics_row])

    def append_eval(self, row: list) -> None:
        """Append a held-out evaluation's row."""
        _append_rows(self.eval_path, [row])

    def _columns(self) -> dict[Path, tuple[str, ...]]:
        """Each table of the run and its columns."""
        return {self.metrics_path: METRICS_COLUMNS, self.trials_path: TRIALS_COLUMNS,
                self.eval_path: EVAL_COLUMNS}  # fmt: skip
