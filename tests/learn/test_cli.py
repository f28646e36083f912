"""learn/cli.py (`python train.py`): flags into a TrainConfig; bad input is one line."""

import json

import pytest

from mjx_peg.learn.curves import read_table


def test_full_time_limit_flag(tiny_args, tiny_config):
    from mjx_peg.learn import cli

    args = cli.parser().parse_args([*tiny_args, "--full-time-limit"])
    config = cli.resolve_config(args)
    assert config.full_time_limit and not config.trial().end_settled
    assert tiny_config.trial().end_settled  # the default: settled failures end early


def test_error_range_flags_set_the_training_trials_errors(tiny_args):
    """--linear-mm and --angular-deg set the training trials' error ranges (the family's linear
    errors scaled with each part); out of range is argparse's one line."""
    from mjx_peg.learn import cli

    config = cli.resolve_config(cli.parser().parse_args(
        [*tiny_args, "--linear-mm", "10", "--angular-deg", "15"]))  # fmt: skip
    task = config.task()
    assert (config.linear_mm, config.angular_deg) == (10.0, 15.0)
    assert task.linear_error == pytest.approx(0.010)
    assert task.angular_error == pytest.approx(0.2617993877991494)
    family = cli.resolve_config(cli.parser().parse_args(
        ["--preset", "family", "--linear-mm", "10"]))  # fmt: skip
    assert family.linear_mm == 10.0 and family.linear_per_size and family.angular_deg == 12.0
    with pytest.raises(SystemExit):
        cli.parser().parse_args([*tiny_args, "--angular-deg", "90"])


def test_cli_bad_input_is_one_line(tmp_path, tiny_run, tiny_args, train_py):
    reference, _ = tiny_run
    broken = tmp_path / "broken"
    broken.mkdir()
    for name in ("config.json", "manifest.json"):
        (broken / name).write_bytes((reference / name).read_bytes())
    (broken / "policy.npz").write_bytes((reference / "policy.npz").read_bytes()[:100])
    cases = [
        ["--preset", "nope"],
        ["--trials", "-5"],
        ["--preset", "transfer", "--init-from", str(tmp_path)],
        ["--preset", "transfer", "--init-from", str(broken)],
        ["--preset", "transfer", "--init-from", "baseline"],
        ["--out", str(reference), *tiny_args],  # a finished run, no --force
    ]
    for args in cases:
        done = train_py(args)
        assert done.returncode == 2, (args, done.stderr)
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("train.py: error:"), (args, done.stderr)
    assert "--force" in done.stderr  # the finished run's line names the way to replace it


def test_a_rerun_whose_skill_constants_changed_is_refused(tiny_run, tiny_args, monkeypatch, capsys):
    """The skill's constants are part of a run's config: after one constant of the preset's
    skill changed, the same command refuses in one line naming --out and the constant."""
    from mjx_peg.learn import cli
    from mjx_peg.learn.config import PRESETS

    out, _ = tiny_run
    before = (out / "config.json").read_bytes()
    changed = PRESETS["quick"].skill_constants.replace(spiral_speed=0.04)
    monkeypatch.setitem(PRESETS, "quick", PRESETS["quick"].replace(skill_constants=changed))
    assert cli.main([*tiny_args, "--no-progress", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"--out {out}" in err
    assert "skill_constants.spiral_speed: 0.03 there, 0.04 now" in err
    assert (out / "config.json").read_bytes() == before


@pytest.mark.slow
def test_a_set_of_seeds_trains_each_and_summarizes_their_spread(tmp_path, train_py, capsys):
    """`python train.py --seeds 3,4` trains each seed and writes their spread; the same command
    again skips both (and a repeated seed is one line), run in this process."""
    from mjx_peg.learn import cli

    args = ["--trials", "16", "--num-envs", "8", "--time-limit", "0.3", "--no-progress",
            "--processes", "1"]  # fmt: skip
    done = train_py(["--seeds", "3,4", "--out", str(tmp_path / "set"), *args])
    assert done.returncode == 0, done.stderr
    for seed in (3, 4):
        config = json.loads((tmp_path / "set" / f"seed-{seed}" / "config.json").read_text())
        assert config["seed"] == seed
    rows = read_table(tmp_path / "set" / "seeds.csv")
    assert rows["trials"] == [8.0, 16.0] and rows["success_rate_seeds"] == [2.0, 2.0]
    assert (tmp_path / "set" / "seeds.png").stat().st_size > 10_000
    assert "2 seeds (3, 4)" in done.stdout
    assert cli.main(["--seeds", "3,4", "--out", str(tmp_path / "set"), *args]) == 0
    assert capsys.readouterr().err.count("is finished: skipped") == 2
    assert cli.main(["--seeds", "3,3", "--out", str(tmp_path / "x"), *args]) == 2
    message = "train.py: error: --seeds must name distinct seeds, got '3,3'\n"
    assert capsys.readouterr().err == message


def test_init_from_takes_its_runs_observation_layout(paper_38):
    """--init-from a run trained on the names layout (the `paper` shipped until 2026-12, kept in
    docs/design/data) reads that layout; asking for another is one line; a new run reads the
    geometry layout unless told."""
    import pytest

    from mjx_peg.errors import UsageError
    from mjx_peg.learn import cli

    def resolve(*argv):
        return cli.resolve_config(cli.parser().parse_args(list(argv)))

    names = str(paper_38)
    assert resolve("--preset", "transfer", "--init-from", names).observation == "names"
    assert resolve("--preset", "transfer", "--init-from", "paper").observation == "geometry"
    assert resolve().observation == "geometry"
    assert resolve("--observation", "names").observation == "names"
    with pytest.raises(UsageError, match="--observation geometry: .* trained on the names layout"):
        resolve("--preset", "transfer", "--init-from", names, "--observation", "geometry")


def test_parts_names_the_suites_parts_and_scales_their_errors():
    """--parts trains on named parts of the suite (e.g. a held-out one for transfer), their
    linear errors x S / 50 mm; an unknown name is one line naming the suite's parts."""
    import pytest

    from mjx_peg.learn import cli

    def resolve(*argv):
        return cli.resolve_config(cli.parser().parse_args(list(argv)))

    config = resolve("--preset", "transfer", "--init-from", "paper", "--parts", "triangle-60-tight")
    assert config.parts == (("triangle", 60.0, 1.02),) and config.linear_per_size
    assert config.shapes == ("triangle",) and config.size_mm == (60.0,)
    assert resolve("--preset", "family").linear_per_size and not resolve().linear_per_size
    with pytest.raises(SystemExit):
        resolve("--parts", "triangle-61")


def test_the_family_preset_holds_the_skill_and_either_flag_sets_what_is_learned(capsys):
    """family and transfer learn the 38 alone; --learn-skill / --fixed-skill override any
    preset; both at once are refused."""
    import pytest

    from mjx_peg.learn import cli

    def learns_skill(*argv):
        return cli.resolve_config(cli.parser().parse_args(list(argv))).learn_search

    assert not learns_skill("--preset", "family") and learns_skill("--preset", "paper")
    assert not learns_skill("--preset", "transfer", "--init-from", "paper")
    assert learns_skill("--preset", "family", "--learn-skill")
    assert not learns_skill("--preset", "paper", "--fixed-skill")
    with pytest.raises(SystemExit):
        learns_skill("--fixed-skill", "--learn-skill")
    assert "not allowed with argument" in capsys.readouterr().err


def test_kl_target_and_std_decay_reach_the_config_and_refuse_bad_values(capsys):
    import pytest

    from mjx_peg.learn import cli

    args = cli.parser().parse_args(["--preset", "paper", "--prior", "none", "--kl-target",
                                    "0.03", "--std-decay", "0.25"])  # fmt: skip
    config = cli.resolve_config(args)
    assert (config.kl_target, config.std_decay, config.prior) == (0.03, 0.25, "none")
    default = cli.resolve_config(cli.parser().parse_args([]))
    assert (default.kl_target, default.std_decay) == (0.01, 1.0)
    for flag, value in (("--kl-target", "0"), ("--std-decay", "1.5")):
        with pytest.raises(SystemExit):
            cli.parser().parse_args([flag, value])
        assert f"{flag} must be a number in (0, 1], got {value}" in capsys.readouterr().err


def test_a_generic_start_takes_the_larger_step_and_the_press_of_its_own_unless_told_otherwise():
    """--prior none: the update held to a KL of 0.03 and, where the skill spirals, the spiral's
    press a compliance of its own (GENERIC_PRESS_REF); what the command line sets itself wins,
    so the former generic start stays one command away."""
    from mjx_peg.learn import cli
    from mjx_peg.learn.config import GENERIC_PRESS_REF

    def resolve(*argv):
        return cli.resolve_config(cli.parser().parse_args(["--preset", "paper", *argv]))

    generic = resolve("--prior", "none")
    press = generic.skill_constants.spiral_axial_ref
    assert (generic.kl_target, press) == (0.03, GENERIC_PRESS_REF)
    former = resolve("--prior", "none", "--kl-target", "0.01", "--skill-constant",
                     "spiral_axial_ref=0")  # fmt: skip
    assert (former.kl_target, former.skill_constants.spiral_axial_ref) == (0.01, 0.0)
    assert resolve("--prior", "none", "--skill", "paper").skill_constants.spiral_axial_ref == 0.0
    for hand_tuned in (resolve(), resolve("--prior", "baseline")):
        assert (hand_tuned.kl_target, hand_tuned.skill_constants.spiral_axial_ref) == (0.01, 0.0)


def test_skill_constant_sets_one_of_the_skills_constants_and_refuses_others(capsys):
    """--skill-constant NAME=VALUE (repeatable) changes that constant of the preset's skill and
    no other; an unknown name or a value that is not a number is one line; a value the skill
    refuses is the skill's own UsageError."""
    from mjx_peg.errors import UsageError
    from mjx_peg.learn import cli
    from mjx_peg.skill.search import SKILLS

    args = cli.parser().parse_args(["--skill-constant", "spiral_axial_ref=0.001",
                                    "--skill-constant", "spiral_pitch=0.005"])  # fmt: skip
    config = cli.resolve_config(args)
    assert config.skill_constants == SKILLS["spiral"].replace(spiral_axial_ref=0.001,
                                                              spiral_pitch=0.005)  # fmt: skip
    refused = (("bogus=1", "NAME a constant of the skill"),
               ("spiral_pitch", "NAME a constant of the skill"),
               ("spiral_pitch=wide", "spiral_pitch must be a number, got 'wide'"))  # fmt: skip
    for text, message in refused:
        with pytest.raises(SystemExit):
            cli.parser().parse_args(["--skill-constant", text])
        assert message in capsys.readouterr().err
    with pytest.raises(UsageError, match="spiral_axial_ref must be in"):
        cli.resolve_config(cli.parser().parse_args(["--skill-constant", "spiral_axial_ref=1"]))
