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
