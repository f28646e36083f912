"""mjx_peg/file_versions.py: a file that an earlier version wrote reads with the meaning it had."""

import numpy as np

from mjx_peg import file_versions


def test_an_evaluation_config_gets_the_fields_it_predates():
    old = {"policy": "baseline", "grid": "paper-small", "seed": 3}
    assert file_versions.eval_config(old) == {
        **old, "full_time_limit": True, "contact_model": 1, "grasp_model": "flange",
        "skill": "paper", "skill_constants": None,  # None: the named skill's constants
    }  # fmt: skip
    new = {**old, "full_time_limit": False, "contact_model": 2, "grasp_model": "board"}
    assert file_versions.eval_config({**new, "skill": "spiral"})["skill"] == "spiral"
    assert file_versions.eval_config(new)["full_time_limit"] is False


def test_a_training_config_keeps_the_former_defaults():
    assert file_versions.train_config({"seed": 1}) == {
        "seed": 1, "action_map": "sigmoid", "grasp_model": "flange", "skill": "paper",
        "skill_constants": None, "linear_mm": 4.0, "angular_deg": 6.0, "trials": 12288,
        "learn_search": False, "learning_rate": 1e-3, "normalized_actions": False,
        "kl_target": 0.0, "obs_statistics": "running",
        "observation": "names",
    }  # fmt: skip
    assert file_versions.train_config({"trials": 3584})["trials"] == 3584


def test_old_range_results_and_specs_get_their_missing_arrays():
    arrays = file_versions.range_results({"success": np.array([True, False, True])})
    np.testing.assert_array_equal(arrays["settled"], [False, False, False])
    kept = file_versions.range_results({"success": np.ones(2, bool), "settled": np.ones(2, bool)})
    assert kept["settled"].all()
    specs = file_versions.spec_arrays({"shape_id": np.array([0, 1, 2, 0], np.int32)})
    assert specs["board_height"].shape == (4,) and specs["board_tilt"].shape == (4, 2)
    assert not specs["board_height"].any() and not specs["board_tilt"].any()
    np.testing.assert_array_equal(specs["hole_scale"], [1.03, 1.08, 1.08, 1.03])  # the paper's
    both = {"shape_id": np.zeros(1, np.int32), "board_height": np.ones(1), "hole_scale": [1.02]}
    assert file_versions.spec_arrays(both)["hole_scale"] == [1.02]


def test_a_manifest_runs_the_skill_it_names_else_the_one_it_trained_with():
    named = {"name": "spiral", "constants": {"centre_gain": 1.0}}
    assert file_versions.manifest_skill({"skill": named, "config": {"skill": "paper"}}) == named
    trained = {"config": {"skill": "search", "skill_constants": None}}
    assert file_versions.manifest_skill(trained) == {"name": "search", "constants": None}
