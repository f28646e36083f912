"""The shipped policies (policies/NAME): resolved by name on every --policy and in load_policy."""

import json
import subprocess
import sys

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.policy import shipped
from mjx_peg.policy.export import load_policy, save_policy


@pytest.fixture
def shelf(tmp_path, monkeypatch):
    """A policies/ folder with one policy, "mini" (trained with the search skill)."""
    folder = tmp_path / "policies"
    layers = [(0.01 * np.ones((8, 38)), np.zeros(38))]
    save_policy(folder / "mini", layers, np.zeros(8), np.ones(8), {"skill": "search"})
    (folder / "empty").mkdir()  # no manifest: not a policy
    monkeypatch.setattr(shipped, "SHIPPED_DIR", folder)
    return folder


def test_names_resolve_and_paths_win(shelf, tmp_path, monkeypatch):
    assert shipped.shipped_names() == ["mini"]
    monkeypatch.chdir(tmp_path)
    assert shipped.resolve_policy("mini") == "policies/mini"  # below the working directory
    assert shipped.resolve_policy("baseline") == "baseline"
    (tmp_path / "mini").mkdir()  # a path that exists is taken as given
    assert shipped.resolve_policy("mini") == "mini"
    monkeypatch.chdir(shelf / "empty")
    assert shipped.resolve_policy("mini") == str(shelf / "mini")  # not below: absolute
    with pytest.raises(UsageError, match=r"no shipped policy of that name \(shipped: mini; or"):
        shipped.resolve_policy("nope")


def test_load_policy_by_name(shelf, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    policy = load_policy("mini")
    assert policy.skill == "search"
    by_path = load_policy(shelf / "mini")
    obs = np.zeros((3, 8))
    np.testing.assert_array_equal(policy.vectors_for(obs), by_path.vectors_for(obs))


def test_the_shipped_policies_load_and_say_how_they_were_made():
    """The README's policies are shipped; each loads, runs its own skill, and its provenance
    names the commit and command that trained it."""
    names = shipped.shipped_names()
    assert {"quick", "paper", "transfer"} <= set(names)
    for name in names:
        policy = load_policy(name)
        vectors = policy.vectors_for(np.zeros((2, 8)))
        assert vectors.shape == (2, 38) and np.all(np.isfinite(vectors))
        folder = shipped.SHIPPED_DIR / name
        assert policy.skill == json.loads((folder / "config.json").read_text())["skill"]
        provenance = json.loads((folder / "provenance.json").read_text())
        assert len(provenance["commit"]) == 40 and "train.py" in provenance["command"]


def test_an_unknown_name_is_one_line_and_exit_2(tmp_path):
    run = subprocess.run(
        [sys.executable, "eval.py", "--policy", "no-such-policy", "--out", str(tmp_path / "e")],
        capture_output=True,
        text=True,
        cwd=shipped.SHIPPED_DIR.parent,
    )
    assert run.returncode == 2
    assert len(run.stderr.strip().splitlines()) == 1
    assert "no shipped policy of that name" in run.stderr
