"""evaluation/summary.py: summary.md's quarters beside the paper's, and its tests."""

from mjx_peg.evaluation.summary import summary_markdown


def test_summary_puts_the_quarters_beside_the_papers(synthetic_grid):
    grid = synthetic_grid
    text = summary_markdown(grid, ["policy: test"], "nominal", grid, "other", "less")
    assert "- policy: test" in text
    assert "97.00 (96.96)" in text  # Q1 mean success beside the paper's
    assert "89.25 (87.83)" in text
    # Q1 vs Q4 success: U = 15 of 16, exact p = 2 / 70 (test_stats.py); the paper: Q1 better
    assert "| Q1 vs Q4 | success | 15.0 | 0.0286 | 0.986 | Q1 better | Q1 better |" in text
    assert "## Against other" in text and "its tests against nominal performance" in text
    # The grid against itself: U = 8 of 16, every value tied twice, so the normal approximation:
    # sigma^2 = 16 / 12 (9 - 4 * 6 / 56), p = Phi((8 + 0.5 - 8) / sigma) = 0.559; the paper
    # states no such test for its nominal condition.
    same = "| Q1 | success | this less | 4 / 4 | 97.00 | 97.00 | 8.0 | 0.559 | n.s. | - |"
    assert same in text


def test_summary_without_a_paper_condition_says_so(synthetic_grid):
    text = summary_markdown(synthetic_grid, [], None)
    assert "No paper condition matches this evaluation: no reference numbers." in text
    assert "(96.96)" not in text and "## Against" not in text
    triangle = summary_markdown(synthetic_grid, [], "triangle")
    assert "The paper reports no times for Section 6.4" in triangle
