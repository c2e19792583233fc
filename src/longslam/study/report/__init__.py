"""The study report: the paper's two tables reproduced from the results database, beside the
paper's own numbers, and the figures; as Markdown (`report.md`, images in `report_files/`) and
as one self-contained HTML page (`report.html`, images embedded).

Table 1: E_trans, E_rot (deg/m) and ATE (m), mean +- std over the seeds, per method, route and
noise level. Table 2: peak resident memory (GB) of the process that ran the method. The best
value of each column is in bold (lower is better; for map quality, higher). The paper's rows
(RTAB-Map, Voxgraph) stand beside ours for the routes that are the paper's (paper-300m, paper-1km).
"""

from longslam.study.report.figures import Figure, make_figures
from longslam.study.report.render import Report, build_report, render_html, render_markdown, write_report
from longslam.study.report.results import StudyResults, load_results
from longslam.study.report.tables import Cell, Table, accuracy_table, format_mean_std, format_number, map_table, memory_table

__all__ = [
    "Cell", "Figure", "Report", "StudyResults", "Table", "accuracy_table", "build_report", "format_mean_std",
    "format_number", "load_results", "make_figures", "map_table", "memory_table", "render_html", "render_markdown",
    "write_report",
]
