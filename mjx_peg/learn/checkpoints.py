"""Orbax checkpoints of one pytree: a numbered step directory each, the last `keep` kept.

    with Checkpoints(run / "checkpoints", keep=3) as ckpt:
        ckpt.save(step, state)              # the leaves, as host NumPy arrays
        state = ckpt.restore(template)      # the latest step, in the template's structure
        ckpt.latest_step()                  # None before the first save

A step holds the tree's leaves as a flat {position: array} dict, not the tree itself: some
leaves (Brax's UInt64 step count) turn themselves back into device arrays, which Orbax refuses
to write from several processes; NumPy leaves work with one process or many. Orbax writes a
step into a temporary directory and renames it when complete, so a killed save leaves the steps
before it. A step that does not read is one UsageError line naming it. Nothing is unpickled.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
from pathlib import Path

import jax
import numpy as np
import orbax.checkpoint as ocp

from mjx_peg import errors
from mjx_peg.errors import UsageError
from mjx_peg.learn import restore_noise

# tensorstore's status codes of a failed write (Orbax raises them as ValueError)
_IO_STATUS = ("RESOURCE_EXHAUSTED", "PERMISSION_DENIED", "DATA_LOSS", "UNAVAILABLE")


def io_failure(error: BaseException) -> tuple[int, str] | None:
    """(errno, text) if `error` is a failed read or write of a file (an OSError, or Orbax's
    ValueError carrying tensorstore's status and the OS error code), else None."""
    if isinstance(error, OSError):
        code = error.errno or errno.EIO
        return code, error.strerror or os.strerror(code)
    text = str(error)
    found = re.search(r"os_error_code='(\d+)'", text)
    if found is None and not text.startswith(_IO_STATUS):
        return None
    code = int(found.group(1)) if found else errno.EIO
    return code, os.strerror(code)


def has_steps(directory) -> bool:
    """Whether `directory` holds a finished step (without creating anything)."""
    directory = Path(directory)
    return directory.is_dir() and any(p.name.isdigit() for p in directory.iterdir())


class Checkpoints:
    """The checkpoints of one training state in `directory` (created when absent).

    `key_width` is the number of digits of a leaf's position in the saved dict; a restore
    needs the width the steps were saved with."""

    def __init__(self, directory, keep: int, key_width: int = 3):
        self.directory = Path(directory).absolute()
        self.key_width = key_width
        self._manager = ocp.CheckpointManager(
            self.directory,
            options=ocp.CheckpointManagerOptions(
                max_to_keep=keep, enable_async_checkpointing=False
            ),
        )

    def _flat(self, tree) -> dict[str, np.ndarray]:
        width = self.key_width
        return {f"{i:0{width}d}": np.asarray(leaf) for i, leaf in enumerate(jax.tree.leaves(tree))}

    def drop_partial(self) -> None:
        """Remove the steps a killed save left unfinished (Orbax ignores them, then warns when
        it saves that step again)."""
        for partial in self.directory.glob("*.orbax-checkpoint-tmp*"):
            shutil.rmtree(partial, ignore_errors=True)

    def latest_step(self) -> int | None:
        return self._manager.latest_step()

    def steps(self) -> list[int]:
        """The finished steps kept, in order."""
        return sorted(self._manager.all_steps())

    def save(self, step: int, tree) -> None:
        """Save `tree` as step `step` and wait until it is on disk. A save that fails on I/O (a
        full disk) leaves nothing of the step and raises OSError naming it (Orbax raises
        ValueError with tensorstore's status for some of these)."""
        restore_noise.expect_failed_reads(self.directory)
        try:
            with restore_noise.held_reports():
                self._manager.save(int(step), args=ocp.args.StandardSave(self._flat(tree)))
                self._manager.wait_until_finished()
        except (OSError, ValueError) as e:
            for partial in self.directory.glob(f"{int(step)}.orbax-checkpoint-tmp*"):
                shutil.rmtree(partial, ignore_errors=True)
            failure = io_failure(e)
            if failure is None:
                raise
            raise OSError(*failure, str(self.directory / str(int(step)))) from None

    def restore(self, template, step: int | None = None):
        """Step `step` (default: the latest) as a tree of `template`'s structure (NumPy leaves);
        UsageError naming the step if it cannot be read or does not fit the template."""
        step = self.latest_step() if step is None else step
        abstract = jax.tree.map(ocp.utils.to_shape_dtype_struct, self._flat(template))
        restore_noise.expect_failed_reads(self.directory)
        try:
            flat = self._manager.restore(step, args=ocp.args.StandardRestore(abstract))
            leaves = [np.asarray(flat[k]) for k in sorted(flat)]
            if len(leaves) != len(jax.tree.leaves(template)):
                raise UsageError(f"{len(leaves)} arrays, the state has another number")
            return jax.tree.unflatten(jax.tree.structure(template), leaves)
        except Exception as e:  # a corrupt or truncated checkpoint can fail anywhere inside Orbax
            text = errors.message(e).split(" [tensorstore_spec=")[0]
            text = text if len(text) <= 300 else text[:297] + "..."
            raise UsageError(
                f"checkpoint {self.directory / str(step)} is corrupt or truncated "
                f"({type(e).__name__}: {text})"
            ) from None

    def close(self) -> None:
        self._manager.close()

    def __enter__(self) -> Checkpoints:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
