"""The policy export: a manifest records its observation layout, and a loaded policy computes
the observation that layout needs; older manifests are the names layout."""

import json

import numpy as np
import pytest

from mjx_peg.policy import network, observation
from mjx_peg.policy.export import PolicyError, load_policy, save_policy
from mjx_peg.world.constants import SHAPES
from mjx_peg.world.task import TaskConfig, sample_trials


def _layers(width: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    return [(0.3 * rng.normal(size=(width, 16)), rng.normal(size=16)),
            (0.1 * rng.normal(size=(16, 38)), np.zeros(38))]  # fmt: skip


@pytest.mark.parametrize("layout", sorted(observation.LAYOUTS))
def test_a_policy_reads_the_layout_it_was_trained_with(tmp_path, layout):
    width = len(observation.LAYOUTS[layout])
    save_policy(tmp_path, _layers(width), np.full(width, 0.1), np.full(width, 2.0),
                {"observation": layout})  # fmt: skip
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["observation"]["layout"] == layout
    assert manifest["observation"]["names"] == list(observation.LAYOUTS[layout])
    policy = load_policy(tmp_path)
    assert policy.layout == layout
    specs = sample_trials(TaskConfig(shapes=SHAPES, hole_scale="tight"), 2, 20)
    obs = observation.observe_specs(specs, layout)
    expected = network.controller_vector(
        network.mean_action(policy.layers, policy.obs_mean, policy.obs_std, obs), policy.centre
    )
    np.testing.assert_array_equal(policy.controller_vectors(specs), expected)
    part = (specs.shape_id, specs.size, specs.hole_scale, specs.hole_est_pos, specs.hole_est_yaw)
    np.testing.assert_array_equal(policy.observe(*part), obs)
    other = "names" if layout == "geometry" else "geometry"
    wrong = observation.observe_specs(specs, other)
    with pytest.raises(ValueError, match=f"reads {width} observation numbers \\(its {layout}"):
        policy.vectors_for(wrong)


def test_a_training_config_names_the_layout_and_older_ones_were_names(tmp_path):
    save_policy(tmp_path / "new", _layers(9), np.zeros(9), np.ones(9), {"observation": "geometry"})
    save_policy(tmp_path / "old", _layers(8), np.zeros(8), np.ones(8), {})
    assert load_policy(tmp_path / "new").layout == "geometry"
    assert load_policy(tmp_path / "old").layout == "names"
    path = tmp_path / "old" / "manifest.json"
    manifest = json.loads(path.read_text())
    del manifest["observation"]["layout"]  # a manifest written before the layouts
    path.write_text(json.dumps(manifest))
    assert load_policy(tmp_path / "old").layout == "names"


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda m: m["observation"].update(layout="pixels"), "unknown observation layout"),
        (lambda m: m["observation"].update(layout="geometry"), "is not the geometry layout's"),
        (lambda m: m["observation"]["names"].pop(), "is not the names layout's"),
    ],
)
def test_a_manifest_whose_observation_does_not_fit_is_one_policy_error(tmp_path, change, message):
    save_policy(tmp_path, _layers(8), np.zeros(8), np.ones(8), {"observation": "names"})
    path = tmp_path / "manifest.json"
    manifest = json.loads(path.read_text())
    change(manifest)
    path.write_text(json.dumps(manifest))
    with pytest.raises(PolicyError, match=message) as error:
        load_policy(tmp_path)
    assert len(str(error.value).splitlines()) == 1
