"""The table of an evaluation grid: one row per error range, and grid.csv.

Per range: the trials, the successes and the success rate (%), the mean, min and max time to
complete over the successful trials (s; NaN without a success), and the contact metrics: failures
ended early as settled, protective stops, the median peak sensed force (N) and the share of the
trials longer than 1.2 s whose chatter (mean |dF| of the axial force over a trial's last second)
is under 5 N (%).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from pathlib import Path

import numpy as np

from mjx_peg import inputs
from mjx_peg.engines.trial import chatter_counted, smooth_pct
from mjx_peg.errors import UsageError, message
from mjx_peg.evaluation.stats import quarter_labels

MAX_GRID_CSV_BYTES = 64 * 2**20  # a grid.csv of 10,000 ranges is ~1.5 MB
_TIME_COLUMNS = ("time_mean_s", "time_min_s", "time_max_s")
# How failures ended and the contact metrics (TrialResult): failures ended early as settled,
# protective stops, the median peak sensed force (N), the share of the trials longer than 1.2 s
# whose chatter is under 5 N (%). grid.csv files from before them lack these columns.
_CONTACT_COLUMNS = ("settled", "protective_stops", "peak_force_median_n", "chatter_under_5n_pct")
GRID_COLUMNS = (
    "range",
    "linear_mm",
    "angular_deg",
    "quarter",
    "trials",
    "successes",
    "success_rate_pct",
    *_TIME_COLUMNS,
    *_CONTACT_COLUMNS,
)


@dataclasses.dataclass(frozen=True)
class GridTable:
    """Per-range results of an evaluation grid, R rows (NumPy arrays)."""

    linear_mm: np.ndarray  # (R,) +- linear error range (mm)
    angular_deg: np.ndarray  # (R,) +- angular error range (deg)
    trials: np.ndarray  # (R,) int
    successes: np.ndarray  # (R,) int
    time_mean_s: np.ndarray  # (R,) mean time to complete over successful trials (NaN if none)
    time_min_s: np.ndarray  # (R,)
    time_max_s: np.ndarray  # (R,)
    settled: np.ndarray | None = None  # (R,) int: failures ended early, settled
    protective_stops: np.ndarray | None = None  # (R,) int
    peak_force_median_n: np.ndarray | None = None  # (R,) median peak sensed force (N)
    chatter_under_5n_pct: np.ndarray | None = None  # (R,) % of trials > 1.2 s with chatter < 5 N

    @property
    def success_pct(self) -> np.ndarray:
        """(R,) success rate (%)."""
        return 100.0 * self.successes / np.maximum(self.trials, 1)

    @property
    def quarter(self) -> np.ndarray:
        return quarter_labels(self.linear_mm, self.angular_deg)

    def values(self, metric: str) -> np.ndarray:
        """(R,) per-range success rate (%) or mean time to complete (s)."""
        return self.success_pct if metric == "success" else self.time_mean_s

    def __len__(self) -> int:
        return int(self.trials.shape[0])

    def csv_text(self) -> str:
        """grid.csv: one row per range (mm, deg, %, s; 'nan' for no time)."""

        def fmt(value: float, digits: int = 4) -> str:
            return f"{value:.{digits}f}" if math.isfinite(value) else "nan"

        quarter, pct = self.quarter, self.success_pct
        nan = np.full(len(self), math.nan)
        contact = [nan if (v := getattr(self, c)) is None else v for c in _CONTACT_COLUMNS]
        digits = (0, 0, 2, 2)  # counts, N, %
        lines = [",".join(GRID_COLUMNS)]
        for i in range(len(self)):
            lines.append(
                f"{i},{self.linear_mm[i]:.6g},{self.angular_deg[i]:.6g},{quarter[i]},"
                f"{self.trials[i]},{self.successes[i]},{pct[i]:.2f},{fmt(self.time_mean_s[i])},"
                f"{fmt(self.time_min_s[i])},{fmt(self.time_max_s[i])},"
                + ",".join(fmt(float(c[i]), d) for c, d in zip(contact, digits, strict=True))
            )
        return "\n".join(lines) + "\n"

    @classmethod
    def from_csv(cls, path) -> GridTable:
        """The table in a grid.csv written by csv_text; ValueError (one line) if unreadable."""
        if not Path(path).exists():
            raise UsageError(f"{path} is missing: not a finished evaluation")
        text = inputs.read_text(path, MAX_GRID_CSV_BYTES)  # a regular file: a FIFO never blocks
        try:
            rows = list(csv.DictReader(io.StringIO(text, newline="")))
            if not rows:
                raise UsageError("no rows")
            col = {c: [r[c] for r in rows] for c in GRID_COLUMNS if c in rows[0]}
            contact = {c: np.array(col[c], dtype=float) for c in _CONTACT_COLUMNS if c in col}
            table = cls(
                **contact,
                **{c: np.array(col[c], dtype=float) for c in ("linear_mm", "angular_deg")},
                **{c: np.array(col[c], dtype=np.int64) for c in ("trials", "successes")},
                **{c: np.array(col[c], dtype=float) for c in _TIME_COLUMNS},
            )
            ranges = np.concatenate([table.linear_mm, table.angular_deg])
            if not (np.all(np.isfinite(ranges)) and np.all(ranges >= 0)):
                raise ValueError("an error range is not a number >= 0")
            if not (np.all(table.trials >= 1) and np.all(table.successes >= 0)):
                raise ValueError("a count of trials or successes is not a count")
            if np.any(table.successes > table.trials):
                raise ValueError("a range has more successes than trials")
            return table
        except (KeyError, TypeError, ValueError, OverflowError, csv.Error) as exc:
            shown = message(exc)[:100]
            raise UsageError(f"{path} is not an evaluation grid.csv ({shown})") from None

    @classmethod
    def from_ranges(cls, ranges, results) -> GridTable:
        """The table of a grid from its per-range trial results.

        ranges: (R,) (linear mm, angular deg); results: R dicts of per-trial arrays
        (`eval_dir.RESULT_FIELDS`), the contact fields absent in ranges saved before them."""
        lin, ang = np.array(ranges, dtype=float).reshape(-1, 2).T
        rows = {k: [] for k in ("trials", "successes", "mean", "min", "max", "settled", "stops",
                                "peak", "smooth")}  # fmt: skip
        for arrays in results:
            times = arrays["time_s"][arrays["success"]]
            rows["trials"].append(arrays["success"].size)
            rows["successes"].append(int(arrays["success"].sum()))
            for stat, fn in (("mean", np.mean), ("min", np.min), ("max", np.max)):
                rows[stat].append(float(fn(times)) if times.size else math.nan)
            rows["settled"].append(int(arrays["settled"].sum()))
            contact = "chatter" in arrays and "protective_stop" in arrays
            rows["stops"].append(int(arrays["protective_stop"].sum()) if contact else math.nan)
            rows["peak"].append(float(np.median(arrays["peak_force"])) if contact else math.nan)
            long = arrays["chatter"][chatter_counted(arrays["time_s"])] if contact else np.zeros(0)
            rows["smooth"].append(smooth_pct(long))
        return cls(
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
