"""learn/cli.py (`python train.py`): flags into a TrainConfig; bad input is one line."""


def test_full_time_limit_flag(tiny_args, tiny_config):
    from mjx_peg.learn import cli

    args = cli.parser().parse_args([*tiny_args, "--full-time-limit"])
    config = cli.resolve_config(args)
    assert config.full_time_limit and not config.trial().end_settled
    assert tiny_config.trial().end_settled  # the default: settled failures end early


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
    assert "--force" in train_py(["--out", str(reference), *tiny_args]).stderr


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
