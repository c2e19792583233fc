"""The study report: the paper's two tables reproduced from the results database, beside the
paper's own numbers, the field's metrics, a row per run to drill into, and the figures; as Markdown
(`report.md`, images in `report_files/`) and as one self-contained HTML page (`report.html`:
images embedded, the trajectories and curves as plotly figures with plotly.js inline, so it works
offline).

Table 1: E_trans, E_rot (deg/m) and ATE (m), mean +- std over the n seeds, per method, route and
noise level; Table 1b: APE and RPE RMSE; Table 2: peak resident memory (MB, VmHWM of the run's own
process); Table 3: map quality; then every run with its metrics and links to its files and log.
The best value of each column is in bold (lower is better; for map quality, higher). The paper's
rows (RTAB-Map, Voxgraph) stand beside ours for the routes that are the paper's (paper-300m,
paper-1km).
"""

from longslam.study.report.figures import Figure, make_figures
from longslam.study.report.render import Report, build_report, render_html, render_markdown, write_report
from longslam.study.report.results import StudyResults, load_results
from longslam.study.report.tables import (
    Cell,
    Table,
    accuracy_table,
    format_mean_std,
    format_number,
    map_table,
    memory_table,
)

__all__ = [
    "Cell",
    "Figure",
    "Report",
    "StudyResults",
    "Table",
    "accuracy_table",
    "build_report",
    "format_mean_std",
    "format_number",
    "load_results",
    "make_figures",
    "map_table",
    "memory_table",
    "render_html",
    "render_markdown",
    "write_report",
]
