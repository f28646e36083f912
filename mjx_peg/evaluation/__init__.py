"""The evaluation grid (paper section 6): success rate and time to complete per error range.

config.py       EvalConfig, the paper's grids, the trials of a range
eval_dir.py     the output directory: config.json, ranges/NNNNN.npz, resume
runner.py       a policy's controller over every range not yet saved
grid_table.py   one row per range, grid.csv
stats.py        quarters, Mann-Whitney U tests, McNemar's test
paper_tables.py the paper's Tables 4-5
summary.py      summary.md: the quarters beside the paper's, the tests
plots.py        heatmaps (Figs. 6-7), the quarters beside the paper's
report.py       grid.csv, heatmaps and summary.md of a finished evaluation
taxonomy.py     where failed trials ended
demo.py         one trial watched: its forces and frames
eval_cli.py     python eval.py; demo_cli.py, baseline_cli.py: the other commands
"""
