"""policy/export.py: a saved policy loads as it was saved and acts as its network computes; the
manifest says how actions become numbers, which skill runs it, which observation layout it
reads (older manifests the names layout) and which parts it trained on (a part beyond them reads
with its features held to their range); a damaged policy is one line naming its run."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from mjx_peg.learn.config import TrainConfig
from mjx_peg.policy import network, observation
from mjx_peg.policy.export import (
    MANIFEST_FILE,
    POLICY_FILE,
    PolicyError,
    choose_skill,
    load_policy,
    policy_skill,
    save_policy,
)
from mjx_peg.skill.baseline import baseline_params
from mjx_peg.skill.params import PARAM_NAMES, controller_from_action, vector_from_controller
from mjx_peg.skill.search import SKILLS, NamedSkill, named_skill
from mjx_peg.world.constants import SHAPES
from mjx_peg.world.task import TaskConfig, sample_trials

SPECS = sample_trials(TaskConfig(shapes=("circle", "square"), linear_error=0.002), 3, 3)


def _layers(width: int = 8, seed: int = 0, hidden: int = 16):
    """A network of `width` observation numbers, one hidden layer, 38 outputs."""
    rng = np.random.default_rng(seed)
    return [(rng.normal(size=(width, hidden)), rng.normal(size=hidden)),
            (0.3 * rng.normal(size=(hidden, 38)), 0.1 * rng.normal(size=38))]  # fmt: skip


def test_a_saved_policy_loads_as_it_was_saved_and_acts_as_its_network(tmp_path):
    """float32 arrays, the manifest's layer shapes and parameter names; the loaded policy's
    action is the network's mean on the float32 weights, its vectors the sigmoid map of it."""
    layers, mean, std = _layers(), np.linspace(-1, 1, 8), np.linspace(0.5, 2, 8)
    path = save_policy(tmp_path, layers, mean, std, {"note": "a test"})
    assert path == tmp_path / POLICY_FILE and (tmp_path / MANIFEST_FILE).is_file()
    policy = load_policy(tmp_path)
    for (kernel, bias), (k, b) in zip(policy.layers, layers, strict=True):
        assert kernel.dtype == bias.dtype == np.float32
        np.testing.assert_array_equal(kernel, np.float32(k))
        np.testing.assert_array_equal(bias, np.float32(b))
    np.testing.assert_array_equal(policy.obs_std, np.float32(std))
    assert policy.manifest["network"]["layers"] == [[8, 16], [16, 38]]
    assert policy.manifest["action"]["param_names"] == list(PARAM_NAMES)
    assert policy.manifest["config"] == {"note": "a test"} and policy.centre is None
    obs = np.random.default_rng(1).normal(size=(5, 8))
    expected = network.mean_action(policy.layers, policy.obs_mean, policy.obs_std, obs)
    np.testing.assert_array_equal(policy.act(obs), expected)
    np.testing.assert_array_equal(
        policy.vectors_for(obs), vector_from_controller(controller_from_action(expected))
    )
    assert load_policy(path).manifest == policy.manifest  # policy.npz names its run too


def test_the_manifest_says_how_actions_become_numbers(tmp_path):
    """A centred-map policy decodes around its recorded centre; a manifest written before the
    centred map (no "map") decodes with the sigmoid map, as it was trained; an unknown map or a
    centre on a range's edge is one PolicyError."""
    rng = np.random.default_rng(1)
    layers = [(rng.normal(size=(8, 16)), rng.normal(size=16)), (np.zeros((16, 38)), np.zeros(38))]
    specs = SPECS
    save_policy(tmp_path / "c", layers, np.zeros(8), np.ones(8), {}, centre=baseline_params())
    vectors = load_policy(tmp_path / "c").controller_vectors(specs)
    np.testing.assert_allclose(vectors, np.broadcast_to(baseline_params(), (3, 38)), rtol=1e-6)
    save_policy(tmp_path / "s", layers, np.zeros(8), np.ones(8), {})
    manifest_path = tmp_path / "s" / "manifest.json"
    manifest = json.loads(manifest_path.read_text())
    assert manifest["action"]["ranges"].pop("map") == "sigmoid"
    manifest_path.write_text(json.dumps(manifest))
    sigmoid_zero = vector_from_controller(controller_from_action(np.zeros(38)))
    np.testing.assert_array_equal(
        load_policy(tmp_path / "s").controller_vectors(specs),
        np.broadcast_to(sigmoid_zero, (3, 38)),
    )
    good = (tmp_path / "c" / "manifest.json").read_text()
    for change, message in ((("map", "linear"), "unknown action map"),
                            (("centre", [1000.0] * 38), "not strictly inside")):  # fmt: skip
        bad = json.loads(good)
        bad["action"]["ranges"][change[0]] = change[1]
        (tmp_path / "c" / "manifest.json").write_text(json.dumps(bad))
        with pytest.raises(PolicyError, match=message):
            load_policy(tmp_path / "c")


def test_the_skill_to_run_it_with(tmp_path):
    """By default the skill its config trained with, every constant; `skill=` another; the
    baseline runs the paper's skill; a --skill given wins over the policy's."""
    save_policy(tmp_path / "a", _layers(), np.zeros(8), np.ones(8), {"skill": "spiral"})
    save_policy(tmp_path / "b", _layers(), np.zeros(8), np.ones(8), {"skill": "spiral"},
                skill=NamedSkill("paper", SKILLS["paper"]))  # fmt: skip
    a, b = load_policy(tmp_path / "a"), load_policy(tmp_path / "b")
    spiral, paper = NamedSkill("spiral", SKILLS["spiral"]), NamedSkill("paper", SKILLS["paper"])
    assert a.skill == a.trained_skill == spiral == policy_skill(tmp_path / "a")
    assert b.skill == paper and b.trained_skill == spiral
    assert policy_skill("baseline") == paper and policy_skill(b) == paper
    assert choose_skill("spiral", b) == named_skill("spiral") and choose_skill(None, b) == paper


def test_a_manifest_whose_skill_does_not_read_is_one_policy_error(tmp_path):
    save_policy(tmp_path, _layers(), np.zeros(8), np.ones(8), {"skill": "search"})
    path = tmp_path / MANIFEST_FILE
    good = json.loads(path.read_text())
    for skill, message in (({"name": "wiggle", "constants": None}, "unknown skill 'wiggle'"),
                           ({"name": "spiral", "constants": {"spiral_speed": -1}}, "spiral_speed"),
                           ({"constants": None}, "'name'")):  # fmt: skip
        path.write_text(json.dumps({**good, "skill": skill}))
        with pytest.raises(PolicyError, match="its skill is not readable") as error:
            load_policy(tmp_path)
        assert message in str(error.value) and len(str(error.value).splitlines()) == 1


def _rewrite_manifest(change):
    def damage(run_dir):
        path = run_dir / MANIFEST_FILE
        manifest = json.loads(path.read_text())
        change(manifest)
        path.write_text(json.dumps(manifest))

    return damage


def _rewrite_arrays(change):
    def damage(run_dir):
        path = run_dir / POLICY_FILE
        with np.load(path, allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
        change(arrays)
        np.savez(path, **arrays)

    return damage


def _truncate(run_dir):
    path = run_dir / POLICY_FILE
    path.write_bytes(path.read_bytes()[:300])


def _not_json(run_dir):
    (run_dir / MANIFEST_FILE).write_text('{"schema": "mjx-peg-policy", ')


def _without(name):
    def damage(run_dir):
        (run_dir / name).unlink()

    return damage


@pytest.mark.parametrize(
    "damage",
    [
        _without(POLICY_FILE),
        _without(MANIFEST_FILE),
        _not_json,
        _truncate,
        _rewrite_manifest(lambda m: m.update(schema="another")),
        _rewrite_manifest(lambda m: m.update(schema_version=2)),
        _rewrite_manifest(lambda m: m["network"].update(activation="relu")),
        _rewrite_manifest(lambda m: m["network"]["layers"].pop()),  # outputs 16, not 38
        _rewrite_manifest(lambda m: m["observation"]["names"].reverse()),
        _rewrite_arrays(lambda a: a.pop("layer1_bias")),
        _rewrite_arrays(lambda a: a.update(layer0_kernel=a["layer0_kernel"][:, :15])),
        _rewrite_arrays(lambda a: a["layer1_kernel"].__setitem__((0, 0), np.nan)),
        _rewrite_arrays(lambda a: a["obs_std"].__setitem__(3, 0.0)),
    ],
)
def test_a_damaged_policy_is_one_line_naming_its_run(tmp_path, damage):
    save_policy(tmp_path, _layers(), np.zeros(8), np.ones(8), {})
    load_policy(tmp_path)  # whole, it loads
    damage(tmp_path)
    with pytest.raises(PolicyError) as error:
        load_policy(tmp_path)
    text = str(error.value)
    assert len(text.splitlines()) == 1 and str(tmp_path) in text, text


def test_a_path_that_is_no_policy_is_one_line(tmp_path):
    with pytest.raises(PolicyError, match="is not a directory"):
        load_policy(tmp_path / "nowhere")
    with pytest.raises(PolicyError, match="holds no policy.npz: not a run directory"):
        load_policy(tmp_path)


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


def _ranged(tmp_path, layout="geometry"):
    """A policy of `layout` trained (so its manifest says) on the 50 mm circle and square."""
    config = TrainConfig(shapes=("circle", "square"), size_mm=(50.0,), observation=layout)
    width = len(observation.LAYOUTS[layout])
    save_policy(tmp_path, _layers(width), np.zeros(width), np.ones(width), config.to_json(),
                part_range=config.part_range())  # fmt: skip
    return load_policy(tmp_path)


@pytest.mark.parametrize("layout", sorted(observation.LAYOUTS))
def test_a_part_beyond_the_training_parts_reads_as_the_trained_part_of_its_shape(tmp_path, layout):
    """A 10 mm circle gets the 50 mm circle's numbers at the same estimated hole, a trained part
    its network's; the hole's pose is never clipped; the bare network tells the two apart."""
    policy = _ranged(tmp_path, layout)
    pos, yaw = np.array([[0.45, -0.1], [0.3, 0.2]]), np.array([0.2, -0.4])
    shape, fit = np.full(2, SHAPES.index("circle")), np.full(2, 1.03)

    def numbers(size, of=policy):
        return of.vectors_for(policy.observe(shape, np.full(2, size), fit, pos, yaw))

    np.testing.assert_array_equal(numbers(0.01), numbers(0.05))
    bare = dataclasses.replace(policy, part_range=None)
    square = policy.observe(np.full(2, SHAPES.index("square")), np.full(2, 0.05),
                            np.full(2, 1.08), pos, yaw)  # fmt: skip
    np.testing.assert_array_equal(policy.act(square), bare.act(square))  # trained: its network
    assert np.abs(numbers(0.01, bare) - numbers(0.05, bare)).max() > 1e-3
    obs = policy.observe(shape, np.full(2, 0.05), fit, pos, yaw)
    moved = policy.observe(shape, np.full(2, 0.05), fit, pos + 0.05, yaw)
    assert np.abs(policy.act(moved) - policy.act(obs)).max() > 1e-3  # the pose reaches it


@pytest.mark.parametrize(
    "record, message",
    [
        ([0.0, 1.0], "is not {low"),
        ({"low": [0.0] * 4, "high": [1.0] * 5}, "needs 5 numbers"),
        ({"low": [0.0] * 5, "high": [1.0, 1.0, -1.0, 1.0, 1.0]}, "empty interval"),
        ({"low": [0.0] * 5, "high": [1.0, "nan", 1.0, 1.0, 1.0]}, "non-finite"),
    ],
)
def test_a_malformed_part_range_is_one_policy_error(tmp_path, record, message):
    _ranged(tmp_path)
    path = tmp_path / "manifest.json"
    manifest = json.loads(path.read_text())
    manifest["observation"]["part_range"] = record
    path.write_text(json.dumps(manifest))
    with pytest.raises(PolicyError, match=message) as error:
        load_policy(tmp_path)
    assert len(str(error.value).splitlines()) == 1
