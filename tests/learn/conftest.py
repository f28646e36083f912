"""The learning tests share one tiny training run (3 iterations of 16 trials of at most 0.6 s)."""

from pathlib import Path

import pytest

from mjx_peg.learn.config import PRESETS
from mjx_peg.learn.trainer import train

ROOT = Path(__file__).resolve().parents[2]
# `python train.py` with TINY_ARGS: the quick preset (its skill, the spiral, and its movement)
TINY = PRESETS["quick"].replace(trials=48, num_envs=16, time_limit_s=0.6, seed=3)
TINY_ARGS = ["--trials", "48", "--num-envs", "16", "--time-limit", "0.6", "--seed", "3"]


@pytest.fixture(scope="session")
def tiny_config():
    """The tiny run's TrainConfig."""
    return TINY


@pytest.fixture(scope="session")
def tiny_args() -> list[str]:
    """train.py's flags of the tiny run (all but --out)."""
    return list(TINY_ARGS)


def pytest_collection_modifyitems(items):
    """The tests of the tiny run on one xdist worker (`--dist loadgroup`), which trains it once:
    spread over two, each worker trained it (8-12 s of the suite's CPU)."""
    for item in items:
        if "tiny_run" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.xdist_group("tiny_run"))


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """(run directory, summary) of the tiny run, trained once for the session (per worker)."""
    out = tmp_path_factory.mktemp("tiny")
    summary = train(TINY, out, progress=False)
    return out, summary


def run_train(args, **kwargs):
    """`python train.py ARGS` in the repository on JAX's CPU backend."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    return subprocess.run([sys.executable, "train.py", *args], cwd=ROOT, capture_output=True,
                          text=True, env=env, **kwargs)  # fmt: skip


@pytest.fixture
def train_py():
    """Runs `python train.py ARGS` (a subprocess.CompletedProcess with its output)."""
    return run_train


def read_tensorboard_scalars(folder: Path) -> dict[str, list[tuple[int, float]]]:
    """{tag: [(step, value), ...]} of the one TensorBoard event file in `folder`."""
    from tensorboardX.proto.event_pb2 import Event

    (events,) = folder.glob("events.out.tfevents.*")
    data, tags = events.read_bytes(), {}
    while data:  # TFRecord framing: length (8 bytes), its CRC (4), the record, its CRC (4)
        n = int.from_bytes(data[:8], "little")
        event = Event.FromString(data[12 : 12 + n])
        for value in event.summary.value:
            tags.setdefault(value.tag, []).append((event.step, value.simple_value))
        data = data[16 + n :]
    return tags


@pytest.fixture
def tensorboard_scalars():
    """Reads a folder's TensorBoard scalars: {tag: [(step, value), ...]}."""
    return read_tensorboard_scalars
