"""The report's figures as PNG bytes: work–precision and invariants against time, one of each per case.

Drawn on bare matplotlib Figures (the Agg renderer, no pyplot): no global state, no display needed.
"""
from __future__ import annotations

import io
import math
import textwrap

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from ...reference.integrals import INTEGRALS

# Readable at 100% (issue 21 item 5): a figure is drawn at DPI and never wider than MAX_WIDTH_PX, the width report.html
# gives a figure in a 1400 px wide window, so the browser shows it at its own size; its smallest text, MIN_FONT_PT, is
# then MIN_FONT_PT * DPI / 72 = 10.7 px. Panels that do not fit side by side in MAX_WIDTH_PX wrap to the next row (tests/test_figures_readable.py
# measures every figure of a report in Chromium). At 1400 px Chromium gives a case's figure 1337 px (1385 px of body
# less its padding, the <details> border and indent).
DPI = 96
MAX_WIDTH_PX = 1300
MAX_WIDTH_IN = MAX_WIDTH_PX / DPI
MIN_FONT_PT = 8       # tick labels, legends
LABEL_FONT_PT = 9     # axis labels
TITLE_FONT_PT = 10    # panel titles
SUPTITLE_FONT_PT = 11
# Colours of a figure's PNG: the integrators' colours, black, grey and their anti-aliasing. Median cut to 32 colours
# moved rk4's blue 83 (of 255) towards grey and merged orange into red (issue 32: legends that reuse colours); a fast
# octree to 64 keeps each within 2 at the same bytes (measured on a six-integrator figure: 10.2 kB against 10.2 kB).
PALETTE = 64
# A panel's title at the top of its axes, where matplotlib's automatic placement puts it in these figures (x tick labels
# at the bottom; y axes log, or linear 0-1 where no line was drawn: no offset text to avoid), without laying out every
# tick label once more to find out: 8 % of drawing the default report's figures; the same pixels.
TITLE_Y = 1.0
# Invariant plot rows: series name -> axis label. Only quantities some run of the case recorded are drawn.
# (The registry's integrals with a label, reference.integrals, then the attitude error.)
QUANTITIES = {**{name: i.label for name, i in INTEGRALS.items() if i.label is not None},
              "attitude_err": "attitude error (rad)"}


def linestyle(engine: str) -> str:
    """The engine's line style (About.linestyle); an engine no longer registered gets the base class's."""
    from ..engines import Engine, EngineError, get_engine

    try:
        return get_engine(engine).about.linestyle
    except (KeyError, EngineError):
        return Engine.about.linestyle


def dt_key(dt) -> str:
    """A dt as it appears in results.csv ("" for adaptive runs): the key that matches rows with stored series."""
    return "" if dt is None or (isinstance(dt, float) and math.isnan(dt)) else f"{float(dt):.10g}"


def run_label(row) -> str:
    formulation = row.get("formulation", "") if hasattr(row, "get") else ""
    formulation = "" if not isinstance(formulation, str) else formulation
    return f"{row['engine']} {row['integrator']}" + (f" ({formulation})" if formulation else "")


# At most this many series (lines) in one panel: more cannot be told apart (issue 15).
MAX_SERIES = 8
# Colour and marker by integrator, the same in every figure; an integrator outside the list gets the next free pair.
INTEGRATOR_STYLES = ("rk4", "euler", "symplectic_euler", "implicit", "implicitfast", "rk4_naive", "taylor", "rk3",
                     "rkmk4", "cg4", "midpoint", "heun", "scipy_rk45", "scipy_dop853", "scipy_radau", "scipy_bdf",
                     "scipy_lsoda")
_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#000000", "#e377c2", "#17becf",
            "#bcbd22", "#7f7f7f", "#aec7e8", "#393b79", "#e6550d", "#31a354", "#843c39", "#7b4173")
_MARKERS = ("o", "s", "^", "v", "D", "P", "*", "X", "<", ">", "h", "p", "d", "H", "8", "x", "+")


def integrator_style(integrator: str) -> tuple[str, str]:
    """(colour, marker) of an integrator: fixed for the built-in ones, from a hash of the name for the others."""
    return _style(_style_index(integrator))


def _style_index(integrator: str) -> int:
    if integrator in INTEGRATOR_STYLES:
        return INTEGRATOR_STYLES.index(integrator)
    return sum(map(ord, integrator)) % len(_COLOURS)


def _style(i: int) -> tuple[str, str]:
    return _COLOURS[i % len(_COLOURS)], _MARKERS[i % len(_MARKERS)]


def figure_styles(integrators) -> dict[str, tuple[str, str]]:
    """(colour, marker) per integrator of one figure, distinct within it: each its integrator_style unless an
    integrator before it took that colour (two names hashed alike: Drake's and MuJoCo's), then the next free one."""
    taken: set[int] = set()
    styles = {}
    for name in dict.fromkeys(integrators):
        i = _style_index(name)
        while i % len(_COLOURS) in taken and len(taken) < len(_COLOURS):
            i += 1
        taken.add(i % len(_COLOURS))
        styles[name] = _style(i)
    return styles


def _formulation(row) -> str:
    value = row.get("formulation", "") if hasattr(row, "get") else ""
    return value if isinstance(value, str) else ""


def facets(rows: pd.DataFrame, key=None, limit: int = MAX_SERIES) -> list[tuple[str, pd.DataFrame]]:
    """Panels of at most MAX_SERIES series: one per engine and formulation (so colour, marker and line style name a
    series), a panel with more split into chunks. key(row) names a row's series (default run_label)."""
    key = key or run_label
    panels = []
    names = rows.apply(key, axis=1) if len(rows) else pd.Series([], dtype=str)
    for (engine, formulation), group in rows.groupby([rows["engine"], rows.apply(_formulation, axis=1)], sort=False):
        labels = list(dict.fromkeys(names[group.index]))
        title = f"{engine} {formulation}".strip()
        for start in range(0, len(labels), limit):
            chosen = set(labels[start:start + limit])
            suffix = f" ({start // limit + 1})" if len(labels) > limit else ""
            panels.append((title + suffix, group[names[group.index].isin(chosen)]))
    return panels


# A panel's width at least and at most (in): a single panel is not stretched across the page into a strip.
PANEL_MIN_IN, PANEL_MAX_IN = 3.2, 6.0
SUPERSCRIPT_SHRINK = 0.7  # mathtext's superscript size (matplotlib's SHRINK_FACTOR): 8 pt ticks had 5.6 pt exponents


def legend_width(labels, fontsize: float = MIN_FONT_PT) -> float:
    """The width (in) a legend of these labels needs beside its line sample (a character ~0.6 em wide at most in
    DejaVu Sans, the sample and padding ~0.45 in)."""
    longest = max((len(str(label)) for label in labels), default=0)
    return 0.45 + 0.6 * fontsize / 72.0 * longest


def _panel_grid(count: int, height_in: float, legend_in: float, title: str):
    """A figure with `count` panels, as many a row as fit in MAX_WIDTH_IN (at most 3), each with room for its legend
    on its right, the panels widened to use the width available (at most PANEL_MAX_IN each); its title wrapped to
    its width."""
    columns = max(1, min(3, count, int(MAX_WIDTH_IN // (PANEL_MIN_IN + legend_in))))
    width_in = max(PANEL_MIN_IN, min(PANEL_MAX_IN, MAX_WIDTH_IN / columns - legend_in))
    height_in = max(height_in, 0.62 * width_in)
    rows = math.ceil(count / columns)
    width = columns * (width_in + legend_in)
    wrapped = _wrapped(title, width)
    extra_top = 0.25 + 0.2 * wrapped.count("\n")
    height = rows * height_in + 0.5 + extra_top
    figure = Figure(figsize=(width, height))
    figure.suptitle(wrapped, fontsize=SUPTITLE_FONT_PT)
    # between two panels: the left one's legend, then the right one's plain-text y tick labels (0.0001: ~0.5 in)
    figure.subplots_adjust(left=0.85 / width, right=1 - legend_in / width, bottom=0.55 / height,
                           top=1 - (0.45 + extra_top) / height, wspace=(legend_in + 0.85) / width_in,
                           hspace=0.55)
    grid = figure.subplots(rows, columns, squeeze=False)
    for axes in grid.flat[count:]:
        axes.set_visible(False)
    return figure, grid


def png(figure: Figure) -> bytes:
    """The figure as a palette PNG: a quarter of the bytes of full colour, which matters in a self-contained page."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    canvas = FigureCanvasAgg(figure)
    buffer = io.BytesIO()
    # Fixed margins (subplots_adjust) rather than bbox_inches="tight" or tight_layout: each of those lays out all the
    # text once more, which doubles the time of a report. The raw pixels, not a PNG: the PNG was only decoded again
    # for the palette (its encoding and decoding were 12 % of drawing the default report's figures; same pixels).
    figure.savefig(buffer, format="rgba", dpi=DPI)
    pixels = Image.frombuffer("RGBA", (canvas.renderer.width, canvas.renderer.height), buffer.getbuffer(), "raw",
                              "RGBA", 0, 1)
    small = io.BytesIO()
    # the resolution and the smallest text drawn travel with the PNG (pHYs, tEXt), so a reader of the page can tell
    # how large the text is where the page shows the figure (tests/test_figures_readable.py)
    info = PngInfo()
    info.add_text(FONT_KEY, f"{smallest_font(figure):g}")
    quantized = pixels.convert("RGB").quantize(colors=PALETTE, method=Image.Quantize.FASTOCTREE)
    quantized.save(small, format="png", optimize=True, dpi=(DPI, DPI), pnginfo=info)
    return small.getvalue()


FONT_KEY = "stereodyn:smallest-font-pt"  # the PNG text chunk that holds smallest_font


def smallest_font(figure: Figure) -> float:
    """The smallest font size (pt) of the figure's visible, non-empty text (tick labels, legends, titles)."""
    from matplotlib.text import Text

    sizes = [t.get_fontsize() * (SUPERSCRIPT_SHRINK if _superscript(t.get_text()) else 1.0)
             for t in figure.findobj(Text) if t.get_visible() and t.get_text().strip()
             and (t.axes is None or t.axes.get_visible())]
    return min(sizes) if sizes else math.nan


def _superscript(text: str) -> bool:
    """Whether a text draws an exponent smaller than itself (mathtext: $10^{-13}$)."""
    return text.count("$") >= 2 and ("^" in text or "_" in text.split("$")[1])


def work_precision(group: pd.DataFrame, case: str) -> bytes | None:
    """Attitude error against cost (µs of stepping per simulated second): a panel per engine (facets), a line per
    integrator through its points sorted by dt (colour and marker by integrator, line style by engine).

    None when no run of the case has both a finite error and a timing.
    """
    rows = group[(group["status"] == "ok") & np.isfinite(group["attitude_err"]) & np.isfinite(group["wall_s"])
                 & (group["attitude_err"] > 0)]
    if rows.empty:
        return None
    panels = facets(rows)
    styles = figure_styles(rows["integrator"])
    title = f"{case}: work–precision (points along dt or tolerance, largest first)"
    figure, grid = _panel_grid(len(panels), 2.9, legend_width(rows["integrator"]), title)
    for axes, (title_, panel) in zip(grid.flat, panels):
        for label, runs in panel.groupby(panel.apply(run_label, axis=1), sort=False):
            # along dt, an adaptive method's along its tolerance (tolerance ladders): no zig-zag
            keys = [k for k in ("dt", "tolerance") if k in runs]
            runs = runs.sort_values(keys, ascending=False, na_position="last", kind="stable")
            colour, marker = styles[runs["integrator"].iloc[0]]
            engine = runs["engine"].iloc[0]
            short = str(runs["integrator"].iloc[0])  # the panel's title names the engine and formulation
            axes.plot((runs["wall_s"] / runs["t_end"] * 1e6).to_numpy(), runs["attitude_err"].to_numpy(),
                      marker=marker, markersize=4, linestyle=linestyle(engine), color=colour,
                      linewidth=1.0, label=short)
        _log_log(axes, title_)
    _axis_labels(grid, "µs per simulated s", "max attitude error (rad)")
    return png(figure)


def _wrapped(title: str, width_in: float) -> str:
    """A figure title broken into lines that fit its width (a character ~0.55 em at SUPTITLE_FONT_PT)."""
    return textwrap.fill(title, max(20, int(width_in * 72.0 / (0.55 * SUPTITLE_FONT_PT))))


def _log_log(axes, title: str) -> None:
    """A work–precision-style panel: log-log, light grid, its legend outside on the right."""
    axes.set_xscale("log")
    axes.set_yscale("log")
    log_ticks(axes.xaxis)
    log_ticks(axes.yaxis)
    axes.set_title(title, fontsize=TITLE_FONT_PT, y=TITLE_Y)
    axes.tick_params(labelsize=MIN_FONT_PT)
    axes.grid(True, which="major", alpha=0.3)
    axes.legend(fontsize=MIN_FONT_PT, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)


def _tick(x: float, _position=None) -> str:
    """A log axis's tick label in plain text (1e-13, 0.01, 100): its exponent as large as its digits; matplotlib's
    10^-13 draws the exponent at SUPERSCRIPT_SHRINK of the tick size."""
    return f"{x:g}".replace("e-0", "e-").replace("e+0", "e").replace("e+", "e")


def log_ticks(axis) -> None:
    """Plain-text labels on a log axis; where the data span less than two labelled decades (a cost within one
    decade), the minor ticks at 2 and 5 are labelled too, so that the axis always carries numbers."""
    axis.set_major_formatter(FuncFormatter(_tick))
    axis.set_minor_formatter(NullFormatter())  # labelled minor ticks overlap on a long range
    axes = axis.axes
    low, high = (axes.get_xlim() if axis is axes.xaxis else axes.get_ylim())
    low, high = min(low, high), max(low, high)
    if low > 0 and math.floor(math.log10(high)) - math.ceil(math.log10(low)) < 1:
        axis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
        axis.set_minor_formatter(FuncFormatter(_tick))


def _axis_labels(grid, xlabel: str, ylabel: str) -> None:
    for column in grid.T:  # the lowest panel drawn in each column (a wrapped last row may leave some empty)
        shown = [axes for axes in column if axes.get_visible()]
        if shown:
            shown[-1].set_xlabel(xlabel, fontsize=LABEL_FONT_PT)
    for axes in grid[:, 0]:
        axes.set_ylabel(ylabel, fontsize=LABEL_FONT_PT)


def tolerance(points: pd.DataFrame, case: str) -> bytes | None:
    """The error achieved (state error: max of attitude_err, omega_err, casimir_drift) against the tolerance
    requested, a line per adaptive method (tolerance.csv's points of the case), with the diagonal error = tolerance:
    a panel per engine and formulation (facets). None when no point of the case has a finite error."""
    rows = points[(points["case"] == case) & (points["status"] == "ok")
                  & np.isfinite(points["state_err"].astype(float)) & (points["state_err"].astype(float) > 0)]
    if rows.empty:
        return None
    panels = facets(rows)
    styles = figure_styles(rows["integrator"])
    title = f"{case}: error reached against tolerance requested"
    figure, grid = _panel_grid(len(panels), 2.9, legend_width([*rows["integrator"], "error = tol"]),
                               title)
    for axes, (title_, panel) in zip(grid.flat, panels):
        for label, runs in panel.groupby(panel.apply(run_label, axis=1), sort=False):
            runs = runs.sort_values("tolerance", ascending=False, kind="stable")
            colour, marker = styles[runs["integrator"].iloc[0]]
            axes.plot(runs["tolerance"].to_numpy(float), runs["state_err"].to_numpy(float), marker=marker,
                      markersize=4, linestyle=linestyle(runs["engine"].iloc[0]), color=colour, linewidth=1.0,
                      label=str(runs["integrator"].iloc[0]))
        low, high = float(panel["tolerance"].min()), float(panel["tolerance"].max())
        axes.plot([low, high], [low, high], color="grey", linestyle="--", linewidth=0.8, label="error = tol")
        _log_log(axes, title_)
    _axis_labels(grid, "tolerance requested", "max state error")
    return png(figure)


def _legend(frame: pd.DataFrame, styles: dict[str, tuple[str, str]]) -> tuple[list, list[str]]:
    """Proxy handles: a colour per integrator (styles: figure_styles; no marker: the lines have none), a line style
    per engine, black for the truth."""
    from matplotlib.lines import Line2D

    handles, labels = [], []
    for integrator in dict.fromkeys(frame.loc[frame["dt"].notna(), "integrator"]):
        colour, _ = styles[integrator]
        handles.append(Line2D([], [], color=colour))
        labels.append(integrator)
    for engine in dict.fromkeys(frame["engine"]):
        handles.append(Line2D([], [], color="grey", linestyle=linestyle(engine)))
        labels.append(f"engine {engine}")
    if frame["dt"].isna().any():
        handles.append(Line2D([], [], color="black"))
        labels.append("truth (adaptive)")
    return handles, labels


def _truth_for(adaptive: pd.DataFrame, panel: pd.DataFrame) -> pd.DataFrame:
    """The one adaptive run drawn in a panel: the panel's own formulation's when it has one, else the truth
    (reference quaternion taylor), else the first."""
    if adaptive.empty:
        return adaptive
    formulations = adaptive.apply(_formulation, axis=1)
    wanted = set(panel.apply(_formulation, axis=1)) if len(panel) else set()
    for choice in (formulations.isin(wanted - {""}), formulations == "quaternion"):
        if choice.any():
            return adaptive[choice.to_numpy()].head(1)
    return adaptive.head(1)


def figure_quantities(series: list[dict]) -> list[str]:
    """The rows of an invariants figure: each quantity of QUANTITIES that some shown series recorded (a special
    integral only where the case meets its conditions, harness.scenes.series)."""
    return [q for q in QUANTITIES if any(q in s and any(v is not None for v in s[q]) for s in series)]


def _series_dt(found: list) -> float:
    """The dt whose runs the invariants figure shows: the middle of the fixed-step dt values (NaN: adaptive only)."""
    dts = sorted({float(row["dt"]) for row, _ in found if dt_key(row["dt"])}, reverse=True)
    return dts[len(dts) // 2] if dts else math.nan


def _shown(group: pd.DataFrame, series: dict[tuple, dict], case: str) -> tuple[float, list]:
    """(dt, [(row, series)]): the runs the invariants figure draws, at its dt, and the adaptive ones."""
    found = [(row, series.get((case, row["engine"], row["formulation"], row["integrator"], dt_key(row["dt"]))))
             for _, row in group.iterrows()]
    found = [(row, s) for row, s in found if s]
    if not found:
        return math.nan, []
    dt = _series_dt(found)
    return dt, [(row, s) for row, s in found if not dt_key(row["dt"]) or float(row["dt"]) == dt]


def invariant_rows(group: pd.DataFrame, series: dict[tuple, dict], case: str) -> list[str]:
    """The axis labels of the invariants figure's rows, top to bottom (for its caption)."""
    return [QUANTITIES[q] for q in figure_quantities([s for _, s in _shown(group, series, case)[1]])]


INVARIANT_COLUMN_IN, INVARIANT_LEGEND_IN = 2.7, 2.3  # an invariants panel's width, and the legend's on the right


def _share_y(panels: list, inner: list[list]) -> None:
    """One log y range over the panels of a quantity (those without a line too), tick labels only on the first panel
    of each row (inner: the others)."""
    with_data = [axes for axes in panels if axes.has_data()]
    for row in inner:
        for axes in row:
            axes.tick_params(labelleft=False)
    if not with_data:
        return
    for axes in with_data:
        axes.set_yscale("log")
    low = min(axes.get_ylim()[0] for axes in with_data)
    high = max(axes.get_ylim()[1] for axes in with_data)
    for axes in panels:
        axes.set_yscale("log")
        axes.set_ylim(low, high)


def invariants(group: pd.DataFrame, series: dict[tuple, dict], case: str) -> bytes | None:
    """Deviation of each conserved quantity the case has (energy, momentum, and its special integral: Lagrange,
    Kovalevskaya, Goryachev–Chaplygin, Hess, self-excited) and the attitude error against time: a row per quantity, a
    column per engine (facets), the fixed-step runs at the middle dt and the adaptive truth (black).

    series: (case, engine, formulation, integrator, dt_key) -> {"t": [...], quantity: [...]}. None when no run of
    the case has a stored series.
    """
    dt, shown = _shown(group, series, case)
    quantities = figure_quantities([s for _, s in shown])
    if not quantities:
        return None
    frame = pd.DataFrame([row for row, _ in shown])
    frame["_index"] = range(len(shown))
    adaptive = frame[frame["dt"].isna()]
    # the truth is drawn in every panel: one series fewer for the runs
    fixed = frame[frame["dt"].notna()]
    panels = facets(fixed, limit=MAX_SERIES - 1) if len(fixed) else [("adaptive", adaptive)]
    # columns of INVARIANT_COLUMN_IN beside a legend of INVARIANT_LEGEND_IN, as many as fit in MAX_WIDTH_IN; more
    # panels wrap into further blocks of rows below (a block: a row per quantity)
    styles = figure_styles(fixed["integrator"]) if len(fixed) else {}
    legend_in = max(INVARIANT_LEGEND_IN, legend_width([*styles, *(f"engine {e}" for e in frame["engine"]),
                                                       "truth (adaptive)"]))
    columns = max(1, min(len(panels), int((MAX_WIDTH_IN - legend_in - 0.9) // INVARIANT_COLUMN_IN)))
    blocks = math.ceil(len(panels) / columns)
    rows = blocks * len(quantities)
    # the columns widened to use the width available (a panel at most PANEL_MAX_IN)
    column_in = max(INVARIANT_COLUMN_IN, min(PANEL_MAX_IN, (MAX_WIDTH_IN - legend_in - 0.9) / columns))
    width = columns * column_in + legend_in + 0.9
    heading = _wrapped(f"{case}: invariants and attitude error against time ({when(dt)}; black: the adaptive truth)",
                       width)
    top_in = 0.45 + 0.2 * (heading.count("\n") + 1)
    # every panel row has its own time tick labels: a row more of text under each
    height = 1.6 * rows + 0.45 * (blocks - 1) + 0.55 + top_in
    figure = Figure(figsize=(width, height))
    figure.subplots_adjust(left=0.9 / width, right=1 - legend_in / width, bottom=0.55 / height,
                           top=1 - top_in / height, wspace=0.12, hspace=0.35 if blocks == 1 else 0.5)
    grid = figure.subplots(rows, columns, squeeze=False, sharex=True)
    for index in range(len(panels), blocks * columns):  # the last block's empty places
        for line in range(len(quantities)):
            grid[(blocks - 1) * len(quantities) + line, index % columns].set_visible(False)
    for position, (title, panel) in enumerate(panels):
        block, column = divmod(position, columns)
        top = block * len(quantities)
        members = pd.concat([panel, _truth_for(adaptive, panel)]).drop_duplicates("_index")
        for _, row in members.iterrows():
            values = shown[int(row["_index"])][1]
            is_truth = not dt_key(row["dt"])
            colour = "black" if is_truth else styles[row["integrator"]][0]
            t = np.asarray(values["t"], dtype=float)
            for line, quantity in enumerate(quantities):
                if quantity not in values:
                    continue
                y = np.array([np.nan if v is None else v for v in values[quantity]], dtype=float)
                y[~(y > 0)] = np.nan  # a log axis has no place for the exact zero at t = 0
                if np.isfinite(y).any():
                    grid[top + line, column].plot(t, y, linestyle=linestyle(row["engine"]),
                                                  color=colour, linewidth=1.0)
        grid[top, column].set_title(title, fontsize=TITLE_FONT_PT, y=TITLE_Y)
        grid[top + len(quantities) - 1, column].set_xlabel("t (s)", fontsize=LABEL_FONT_PT)
    for line, quantity in enumerate(quantities):  # one log y range per quantity, across the blocks
        panels_of = [grid[block * len(quantities) + line] for block in range(blocks)]
        drawn = [axes for row in panels_of for axes in row if axes.get_visible()]
        for row in panels_of:
            row[0].set_ylabel(QUANTITIES[quantity], fontsize=LABEL_FONT_PT)
        for axes in drawn:
            axes.grid(True, alpha=0.3)
            axes.tick_params(labelsize=MIN_FONT_PT, labelbottom=True)  # sharex hid all but the lowest row's
        _share_y(drawn, [row[1:] for row in panels_of])
        for axes in drawn:
            if axes.get_yscale() == "log":
                log_ticks(axes.yaxis)
    figure.legend(*_legend(frame, styles), fontsize=MIN_FONT_PT, frameon=False, loc="upper left",
                  bbox_to_anchor=(1 - (legend_in - 0.1) / width, 1 - top_in / height))
    figure.suptitle(heading, fontsize=SUPTITLE_FONT_PT)
    return png(figure)


def when(dt: float) -> str:
    return f"dt = {dt:g} s" if math.isfinite(dt) else "adaptive"
