"""The report's figures as PNG bytes: work–precision and invariants against time, one of each per case.

Drawn on bare matplotlib Figures (the Agg renderer, no pyplot): no global state, no display needed.
"""
from __future__ import annotations

import io
import math

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

DPI = 80
PALETTE = 64  # colours of a figure's PNG: plenty for lines on white, and no visible banding
# Invariant plot rows: series name -> axis label. Only quantities some run of the case recorded are drawn.
LEGEND_COLUMN_IN = 2.7  # width of a legend column, inches: fits "reference rk4 (gibbs_hamiltonian)" at 8 pt
QUANTITIES = {"energy": "energy |E−E₀|/scale", "momentum": "momentum drift", "attitude_err": "attitude error (rad)"}


def linestyle(engine: str) -> str:
    """The engine's line style (Engine.linestyle); an engine no longer registered gets the base class's."""
    from stereodyn.harness.engines import Engine, EngineError, get_engine

    try:
        return get_engine(engine).linestyle
    except (KeyError, EngineError):
        return Engine.linestyle


def dt_key(dt) -> str:
    """A dt as it appears in results.csv ("" for adaptive runs): the key that matches rows with stored series."""
    return "" if dt is None or (isinstance(dt, float) and math.isnan(dt)) else f"{float(dt):.10g}"


def run_label(row) -> str:
    formulation = row.get("formulation", "") if hasattr(row, "get") else ""
    formulation = "" if not isinstance(formulation, str) else formulation
    return f"{row['engine']} {row['integrator']}" + (f" ({formulation})" if formulation else "")


def _colours(group: pd.DataFrame) -> dict[str, tuple]:
    from matplotlib import colormaps

    labels = list(dict.fromkeys(run_label(row) for _, row in group.iterrows()))
    palette = colormaps["tab10" if len(labels) <= 10 else "tab20"]
    return {label: palette(i % palette.N) for i, label in enumerate(labels)}


def _png(figure: Figure) -> bytes:
    """The figure as a palette PNG: a quarter of the bytes of full colour, which matters in a self-contained page."""
    from PIL import Image

    buffer = io.BytesIO()
    # Fixed margins (subplots_adjust) rather than bbox_inches="tight" or tight_layout: each of those lays out all the
    # text once more, which doubles the time of a report.
    figure.savefig(buffer, format="png", dpi=DPI)
    small = io.BytesIO()
    Image.open(buffer).convert("RGB").quantize(colors=PALETTE).save(small, format="png", optimize=True)
    return small.getvalue()


def work_precision(group: pd.DataFrame, case: str) -> bytes | None:
    """Attitude error against cost (µs of stepping per simulated second), one line per engine × integrator over dt.

    None when no run of the case has both a finite error and a timing.
    """
    rows = group[(group["status"] == "ok") & np.isfinite(group["attitude_err"]) & np.isfinite(group["wall_s"])
                 & (group["attitude_err"] > 0)]
    if rows.empty:
        return None
    colours = _colours(group)
    figure = Figure(figsize=(9.0, 4.4))
    figure.subplots_adjust(left=0.09, right=0.70, bottom=0.12, top=0.92)
    axes = figure.subplots()
    for label, runs in rows.groupby(rows.apply(run_label, axis=1), sort=False):
        cost = runs["wall_s"] / runs["t_end"] * 1e6
        order = np.argsort(cost.to_numpy())
        engine = runs["engine"].iloc[0]
        axes.plot(cost.to_numpy()[order], runs["attitude_err"].to_numpy()[order], marker="o", markersize=4,
                  linestyle=linestyle(engine), color=colours[label], label=label)
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.xaxis.set_minor_formatter(NullFormatter())  # labelled minor ticks overlap on a short decade range
    axes.set_xlabel("µs of stepping per simulated second")
    axes.set_ylabel("max attitude error (rad)")
    axes.set_title(f"{case}: work–precision (points: dt)")
    axes.grid(True, which="major", alpha=0.3)
    axes.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    return _png(figure)


def invariants(group: pd.DataFrame, series: dict[tuple, dict], case: str) -> bytes | None:
    """Relative energy and momentum deviation and attitude error against time: a column per dt, a row per quantity.

    series: (case, engine, formulation, integrator, dt_key) -> {"t": [...], quantity: [...]}. Adaptive runs (the
    truth) are drawn in every column. None when no run of the case has a stored series.
    """
    found = [(row, series.get((case, row["engine"], row["formulation"], row["integrator"], dt_key(row["dt"]))))
             for _, row in group.iterrows()]
    found = [(row, s) for row, s in found if s]
    if not found:
        return None
    quantities = [q for q in QUANTITIES if any(q in s for _, s in found)]
    dts = sorted({float(row["dt"]) for row, _ in found if dt_key(row["dt"])}, reverse=True) or [math.nan]
    colours = _colours(group)
    labels = list(dict.fromkeys(run_label(row) for row, _ in found))
    width = min(16.0, max(3.6 * len(dts) + 1.0, 2 * LEGEND_COLUMN_IN))
    columns = max(1, min(len(labels), int(width // LEGEND_COLUMN_IN)))
    legend_rows = math.ceil(len(labels) / columns)
    height = 2.4 * len(quantities) + 1.1 + 0.2 * legend_rows
    figure = Figure(figsize=(width, height))
    figure.subplots_adjust(left=0.75 / width, right=1 - 0.2 / width, bottom=(0.75 + 0.2 * legend_rows) / height,
                           top=1 - 0.65 / height, wspace=0.08, hspace=0.12)
    grid = figure.subplots(len(quantities), len(dts), squeeze=False, sharex=True, sharey="row")
    for column, dt in enumerate(dts):
        for row, values in found:
            adaptive = not dt_key(row["dt"])
            if not adaptive and float(row["dt"]) != dt:
                continue
            label = run_label(row)
            t = np.asarray(values["t"], dtype=float)
            for line, quantity in enumerate(quantities):
                if quantity not in values:
                    continue
                y = np.array([np.nan if v is None else v for v in values[quantity]], dtype=float)
                y[~(y > 0)] = np.nan  # a log axis has no place for the exact zero at t = 0
                if np.isfinite(y).any():
                    grid[line, column].plot(t, y, linestyle=linestyle(row["engine"]),
                                            color="black" if adaptive else colours[label], linewidth=1.0,
                                            label=label)
        grid[0, column].set_title(f"dt = {dt:g} s" if math.isfinite(dt) else "adaptive")
        grid[-1, column].set_xlabel("t (s)")
    for line, quantity in enumerate(quantities):
        grid[line, 0].set_ylabel(QUANTITIES[quantity], fontsize=8)
        for axes in grid[line]:
            if axes.has_data():
                axes.set_yscale("log")
            axes.grid(True, alpha=0.3)
    handles = {}
    for axes in grid.flat:
        for handle, label in zip(*axes.get_legend_handles_labels()):
            handles.setdefault(label, handle)
    figure.legend(handles.values(), handles.keys(), fontsize=8, loc="lower center", ncol=columns,
                  frameon=False)
    figure.suptitle(f"{case}: invariants and attitude error against time (max over buckets of samples)")
    return _png(figure)
