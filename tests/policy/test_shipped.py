"""The shipped policies (policies/NAME): resolved by name on every --policy and in load_policy."""

import json
import subprocess
import sys

import numpy as np
import pytest

from mjx_peg.errors import UsageError
from mjx_peg.policy import shipped
from mjx_peg.policy.export import load_policy, save_policy
from mjx_peg.skill.search import (
    SKILLS,
    NamedSkill,
    SkillConfig,
    constants_from_record,
    named_skill,
)


@pytest.fixture
def shelf(tmp_path, monkeypatch):
    """A policies/ folder with one policy, "mini" (trained with the search skill)."""
    folder = tmp_path / "policies"
    layers = [(0.01 * np.ones((8, 38)), np.zeros(38))]
    save_policy(folder / "mini", layers, np.zeros(8), np.ones(8), {"skill": "search"})
    (folder / "empty").mkdir()  # no manifest: not a policy
    monkeypatch.setattr(shipped, "SHIPPED_DIR", folder)
    return folder


# the `paper` shipped until 2026-12 (the 38 alone, the names layout)
PAPER_38 = str(shipped.SHIPPED_DIR.parent / "docs/design/data/learning/paper_search_38")
TRANSFER = (9, 38)  # inputs and outputs of the shipped transfer: the 38, the skill held


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
    assert policy.skill == policy.trained_skill == NamedSkill("search", SkillConfig(centre_gain=1))
    by_path = load_policy(shelf / "mini")
    obs = np.zeros((3, 8))
    np.testing.assert_array_equal(policy.vectors_for(obs), by_path.vectors_for(obs))


def test_the_shipped_policies_load_and_say_how_they_were_made():
    """The README's policies are shipped: the controllers `family`, `paper`, `quick` and
    `transfer`, each running by default the shipped skill (`spiral`, the skill it was trained
    with and its published numbers used; `family` with its yaw sweep following the declared yaw
    uncertainty), its manifest's and config's constants those of the skill (a constant added to
    the skill since they were written reads its default, off); its provenance names the commit
    and command that trained it."""
    names = shipped.shipped_names()
    assert names == ["family", "paper", "quick", "transfer"]
    for name in names:
        policy = load_policy(name)
        inputs, outputs = {"family": (9, 38), "paper": (9, 47), "quick": (9, 47),
                           "transfer": TRANSFER}[name]  # fmt: skip
        vectors = policy.vectors_for(np.zeros((2, inputs)))
        assert vectors.shape == (2, outputs) and np.all(np.isfinite(vectors))
        folder = shipped.SHIPPED_DIR / name
        manifest = json.loads((folder / "manifest.json").read_text())
        runs = SKILLS["spiral"].replace(yaw_scale="uncertainty" if name == "family" else "absolute")
        spiral = NamedSkill("spiral", runs)
        assert policy.skill == spiral
        recorded = named_skill(manifest["skill"]["name"], manifest["skill"]["constants"])
        assert recorded == spiral
        assert manifest["skill"]["constants"].items() <= spiral.record()["constants"].items()
        config = json.loads((folder / "config.json").read_text())
        assert policy.trained_skill.name == config["skill"] == "spiral"
        assert constants_from_record(config["skill_constants"]) == policy.trained_skill.config
        assert policy.trained_skill.config.yaw_scale == "absolute"
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


def _names_observation(specs, trained: tuple[str, ...]):
    """The observation the shipped policies were trained on, written out here (not imported):
    hole x, y, the yaw at the shape's symmetry, a one-hot of circle, square, triangle, the size;
    held to their training parts (`trained` shapes, all at 50 mm): a shape they never saw reads
    0, a policy of one shape sees it always, and every size is 50 mm."""
    order = np.array([0.0, 4.0, 3.0])[specs.shape_id]
    one_hot = np.eye(3)[specs.shape_id]
    for k, shape in enumerate(("circle", "square", "triangle")):
        one_hot[:, k] = (1.0 if len(trained) == 1 else one_hot[:, k]) if shape in trained else 0.0
    return np.concatenate(
        [
            (specs.hole_est_pos - np.array([0.4, 0.0])) / 0.3,
            np.stack([np.cos(order * specs.hole_est_yaw), np.sin(order * specs.hole_est_yaw)], -1),
            one_hot,
            np.zeros((len(specs), 1)),
        ],
        axis=-1,
    )


def _geometry_observation(specs, low, high):
    """The geometry layout written out here (not imported): hole x, y, the yaw at the shape's
    symmetry, then 1 / n, the peg's in- and circumradius ((r - 25 mm) / 10 mm), the radial
    clearance in mm and the hole's depth over 80 mm; the part's five held to [low, high]."""
    pose = _names_observation(specs, ("circle",))[:, :4]
    inverse = np.array([0.0, 1 / 4, 1 / 3])[specs.shape_id]
    r_in = np.array([0.5, 0.5, 0.5 / np.sqrt(3)])[specs.shape_id] * specs.size
    r_out = np.array([0.5, np.sqrt(0.5), 1 / np.sqrt(3)])[specs.shape_id] * specs.size
    clearance = (specs.hole_scale - 1.0) * r_in / 0.001
    part = np.stack([inverse, (r_in - 0.025) / 0.01, (r_out - 0.025) / 0.01, clearance,
                     np.ones(len(specs))], -1)  # fmt: skip
    return np.concatenate([pose, np.clip(part, low, high)], -1)


@pytest.mark.parametrize("name", ["paper", "quick", "transfer", PAPER_38])
def test_the_shipped_policies_act_as_their_network_on_their_training_parts(name):
    """Each reads its layout (the `paper` shipped until 2026-12, kept in docs/design/data, has a
    manifest that predates the layouts: names; the shipped ones the geometry) and gives, bit for
    bit, the numbers its network gives for the observation it was trained on, a part beyond its
    training parts held to the range they span; on the robot too."""
    from mjx_peg.policy import network
    from mjx_peg.robot.runtime import HoleEstimate, controller_vector
    from mjx_peg.world.task import TaskConfig, sample_trials

    policy = load_policy(name)
    layout = None if name == PAPER_38 else "geometry"
    assert policy.layout == (layout or "names")
    assert policy.manifest["observation"].get("layout") == layout
    assert policy.sizes_mm == (50.0,)
    config = TaskConfig(shapes=("circle", "square", "triangle"), sizes=(0.025, 0.05, 0.06))
    specs = sample_trials(config, 11, 24)
    recorded = policy.manifest["observation"]["part_range"]

    def expected(specs):
        if layout == "geometry":
            obs = _geometry_observation(specs, recorded["low"], recorded["high"])
        else:
            obs = _names_observation(specs, policy.shapes)
        action = network.mean_action(policy.layers, policy.obs_mean, policy.obs_std, obs)
        return np.asarray(network.controller_vector(action, policy.centre), np.float64)

    assert policy.controller_vectors(specs).tobytes() == expected(specs).tobytes()
    for i in range(0, len(specs), 5):  # the robot's batch of one
        robot = controller_vector(policy, HoleEstimate.of_trial(specs, i))
        assert robot.tobytes() == expected(specs.take([i]))[0].tobytes()
