"""longslam.study: the experiment grid, its runs, the results database and the report.

`config` (study files), `spec` (the runs), `prepare` (routes rendered once, ground truth),
`execute` (one run on a worker), `executors` (local processes, Ray), `database` (SQLite),
`runner` (the resumable loop), `report` and `plots` (tables and figures), `paper` (the paper's
own numbers).
"""
