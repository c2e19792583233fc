"""The report page's interactive figures (plotly): trajectories over the floor plan with a seed
selector, and error and memory against distance travelled, one line per run. report.html holds
plotly.js once, inline, so the page works offline; report.md keeps the static PNGs."""

from __future__ import annotations

from typing import Any

import numpy as np
import plotly.graph_objects as go
import plotly.io as pio
from plotly.subplots import make_subplots

from longslam.core.gridmap import GridMap
from longslam.viz.plots import GROUND_TRUTH, grid_image, place_labels

MAX_POINTS = 1500  # per line: a 1 km route's 10 Hz trajectory thinned, enough for the eye
PLAN_PIXELS = 500  # the floor plan's width in heatmap cells
# The colours of matplotlib's default cycle, so a method looks the same in the PNG and the page.
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
CONFIG = {"displaylogo": False, "responsive": True}


def plotly_js() -> str:
    """plotly.js itself (minified), to inline once in a page."""
    from plotly.offline import get_plotlyjs

    return get_plotlyjs()


def figure_div(fig: go.Figure, div_id: str) -> str:
    """A figure as a <div> and the script that draws it, without plotly.js (see `plotly_js`)."""
    return pio.to_html(fig, full_html=False, include_plotlyjs=False, div_id=div_id, config=CONFIG)


def _thin(xy: np.ndarray, most: int = MAX_POINTS) -> np.ndarray:
    xy = np.asarray(xy, dtype=np.float64)
    if len(xy) <= most:
        return xy
    return xy[np.unique(np.linspace(0, len(xy) - 1, most).round().astype(int))]


def _line(xy: np.ndarray, **style: Any) -> go.Scatter:
    """An (N, 2) array of points drawn as one line; `style` is the rest of the trace's properties."""
    return go.Scatter(x=xy[:, 0], y=xy[:, 1], mode="lines", **style)


def _plan_trace(grid: GridMap, view: tuple[float, float, float, float]) -> go.Heatmap:
    """The floor plan as a grey heatmap (white free, grey unknown, black walls) over `view`."""
    xmin, xmax, ymin, ymax = view
    block = max(1, round((xmax - xmin) / grid.resolution / PLAN_PIXELS))
    image, (x0, x1, y0, y1) = grid_image(grid, block)
    size = grid.resolution * block
    xs = x0 + size * (np.arange(image.shape[1]) + 0.5)
    ys = y0 + size * (np.arange(image.shape[0]) + 0.5)
    cols = (xs >= xmin - size) & (xs <= xmax + size)
    rows = (ys >= ymin - size) & (ys <= ymax + size)
    # Small integers (0 wall, 1 unknown, 2 free), which plotly sends as one byte each.
    levels = np.where(image == 0.0, 0, np.where(image == 1.0, 2, 1)).astype(np.uint8)
    return go.Heatmap(
        z=levels[np.ix_(rows, cols)],
        x=xs[cols],
        y=ys[rows],
        zmin=0,
        zmax=2,
        showscale=False,
        colorscale=[[0.0, "black"], [0.5, "#bfbfbf"], [1.0, "white"]],
        hoverinfo="skip",
        name="floor plan",
    )


def trajectories_figure(
    grid: GridMap,
    view: tuple[float, float, float, float],
    truth_xy: np.ndarray,
    estimates: dict[str, dict[int, np.ndarray]],
    ates: dict[tuple[str, int], float],
    waypoints: np.ndarray | None = None,
    title: str = "",
) -> go.Figure:
    """Every seed's estimate of every method over the floor plan; a menu shows all seeds or one.
    `estimates[method][seed]` is an (N, 2) xy path; `ates[(method, seed)]` its ATE (m)."""
    fig = go.Figure()
    fig.add_trace(_plan_trace(grid, view))
    truth = _thin(truth_xy)
    fig.add_trace(_line(truth, name=GROUND_TRUTH, line={"color": "black", "dash": "dash", "width": 2}))
    seeds = sorted({seed for runs in estimates.values() for seed in runs})
    trace_seeds: list[int] = []
    for k, (method, runs) in enumerate(estimates.items()):
        colour = COLOURS[k % len(COLOURS)]
        # As in the PNG (viz.plots.method_styles): the first method widest, each later one
        # narrower and over it, so a method that follows another closely still shows.
        width = 1.5 + 1.2 * (len(estimates) - 1 - k)
        for i, seed in enumerate(sorted(runs)):
            xy = _thin(runs[seed])
            ate = ates.get((method, seed))
            name = f"{method}, seed {seed}" + (f" (ATE {ate:.3f} m)" if ate is not None else "")
            fig.add_trace(
                _line(
                    xy,
                    name=name,
                    legendgroup=method,
                    legendgrouptitle={"text": method} if i == 0 else None,
                    line={"color": colour, "width": width},
                    hovertemplate=f"{method}, seed {seed}<br>x %{{x:.2f}} m<br>y %{{y:.2f}} m<extra></extra>",
                )
            )
            trace_seeds.append(seed)
    # The places and the start over the lines.
    on_top = 1
    if waypoints is not None and len(waypoints):
        places = place_labels(waypoints)
        fig.add_trace(
            go.Scatter(
                x=[p[0][0] for p in places],
                y=[p[0][1] for p in places],
                mode="markers+text",
                text=[p[1] for p in places],
                textposition="top right",
                name="waypoints",
                marker={"color": "#d62728", "size": 7},
                textfont={"color": "#d62728"},
            )
        )
        on_top += 1
    fig.add_trace(
        go.Scatter(
            x=[truth[0, 0]],
            y=[truth[0, 1]],
            mode="markers",
            name="start",
            marker={"color": "#2ca02c", "size": 12, "line": {"color": "black", "width": 1}},
        )
    )
    below = 2  # the floor plan and the ground truth
    buttons = [
        {"label": "all seeds", "method": "update", "args": [{"visible": [True] * (below + len(trace_seeds) + on_top)}]}
    ]
    for seed in seeds:
        visible = [True] * below + [s == seed for s in trace_seeds] + [True] * on_top
        buttons.append({"label": f"seed {seed}", "method": "update", "args": [{"visible": visible}]})
    xmin, xmax, ymin, ymax = view
    height = int(min(900, max(380, 760 * (ymax - ymin) / max(xmax - xmin, 1e-6) + 120)))
    fig.update_layout(
        title={"text": title, "font": {"size": 14}, "x": 0.0, "xanchor": "left"},
        height=height,
        margin={"l": 60, "r": 20, "t": 70, "b": 50},
        xaxis={"title": {"text": "x [m]"}, "range": [xmin, xmax], "constrain": "domain"},
        yaxis={"title": {"text": "y [m]"}, "range": [ymin, ymax], "scaleanchor": "x", "scaleratio": 1},
        legend={"groupclick": "toggleitem", "font": {"size": 11}},
        plot_bgcolor="white",
        # The seed menu sits over the legend, clear of the title.
        updatemenus=[
            {
                "buttons": buttons,
                "direction": "down",
                "x": 1.02,
                "xanchor": "left",
                "y": 1.0,
                "yanchor": "bottom",
                "showactive": True,
            }
        ]
        if len(seeds) > 1
        else [],
    )
    return fig


def curves_figure(
    panels: dict[str, dict[str, dict[int, np.ndarray]]],
    ylabel: str,
    title: str = "",
) -> go.Figure:
    """One panel per key (a noise level), one line per run: `panels[panel][method][seed]` is an
    (M, 2) array of (distance travelled [m], value)."""
    names = list(panels)
    fig = make_subplots(
        rows=1,
        cols=len(names),
        shared_yaxes=True,
        subplot_titles=names,
        horizontal_spacing=0.04 if len(names) > 1 else 0.1,
    )
    methods = list(dict.fromkeys(m for panel in panels.values() for m in panel))
    for c, name in enumerate(names, start=1):
        for method, runs in panels[name].items():
            colour = COLOURS[methods.index(method) % len(COLOURS)]
            for seed in sorted(runs):
                curve = _thin(runs[seed])
                fig.add_trace(
                    _line(
                        curve,
                        name=method,
                        legendgroup=method,
                        showlegend=c == 1 and seed == min(runs),
                        line={"color": colour, "width": 1.2},
                        opacity=0.8,
                        hovertemplate=f"{method}, seed {seed}<br>%{{x:.1f}} m travelled"
                        f"<br>%{{y:.3g}}<extra>{name}</extra>",
                    ),
                    row=1,
                    col=c,
                )
        fig.update_xaxes(title_text="distance travelled [m]", row=1, col=c)
    fig.update_yaxes(title_text=ylabel, row=1, col=1)
    fig.update_layout(
        title={"text": title, "font": {"size": 14}},
        height=380,
        margin={"l": 60, "r": 20, "t": 70, "b": 50},
        plot_bgcolor="white",
    )
    fig.update_xaxes(gridcolor="#ddd")
    fig.update_yaxes(gridcolor="#ddd")
    return fig
