"""longslam.study: the experiment grid, its runs, the results database and the report.

`config` (study files), `spec` (the runs), `prepare` (routes rendered once, ground truth),
`execute` (one run on a worker), `run_scores` (what it keeps of a run's quality), `record` (a
run's record and its database columns), `executors` (local processes, Ray), `database` (SQLite),
`runner` (the resumable loop), `report` (tables, figures and the page), `paper` (the paper's
own numbers).
"""
