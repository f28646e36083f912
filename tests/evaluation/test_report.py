"""evaluation/report.py: the outputs of a finished evaluation describe it and its trials."""

from mjx_peg.evaluation import eval_dir
from mjx_peg.evaluation.config import EvalConfig
from mjx_peg.evaluation.report import write_outputs
from mjx_peg.evaluation.runner import load_controller, run_evaluation


def test_the_report_of_a_finished_evaluation(tmp_path):
    config = EvalConfig(policy="baseline", grid="custom", linear_mm=(1.0,), angular_deg=(1.0, 2.0),
                        trials=3, shapes=("square", "circle"), size_mm=50.0, time_limit_s=0.3,
                        seed=4)  # fmt: skip
    out = eval_dir.prepare_out_dir(tmp_path / "eval", config)
    _, controller = load_controller("baseline")
    assert run_evaluation(config, out, controller, {"threads": 1}, show_progress=False) == 6
    grid = write_outputs(out, config, "baseline", "nominal")
    for name in ("grid.csv", "summary.md", "success_heatmap.png", "time_heatmap.png",
                 "paper_comparison.png"):  # fmt: skip
        assert (out / name).stat().st_size > 0, name
    assert list(grid.trials) == [3, 3] and (out / "grid.csv").read_text() == grid.csv_text()
    summary = (out / "summary.md").read_text()
    assert "- policy: baseline" in summary
    assert "- grid: custom, 1 linear x 2 angular = 2 ranges" in summary
    assert "- shapes: square, circle (trials split evenly); size S = 50 mm" in summary
    assert "- skill: paper (" in summary and "- seed 4; engine mujoco" in summary
    # 0.3 s: no trial reaches the hole; every one is in the failure taxonomy
    assert (
        "all trials: 0 / 6 succeeded (0.00 %); per shape: square 0.0 % of 4, circle 0.0 % of 2"
        in summary
    )
    assert "## Failures" in summary
