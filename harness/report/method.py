""""Your method": what the report measured of each integrator, and the origin of every registered one.

For someone checking an integrator (a plug-in, or a built-in): its fitted orders (convergence.csv), its stability limit
and round-off floor (the dt ladders), whether its energy error stays bounded (measured on the stored series) and what it
costs against the best built-in integrator at a few accuracy targets (results.csv and ladder.csv).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from ..testing import energy_noise
from . import sections
from ..words import plural
from .markdown import markdown_table, number

# Accuracy targets (max attitude error, rad) of the cost comparison.
COST_TARGETS = (1e-3, 1e-6, 1e-9)
# Energy trend from a stored series: the max deviation over the second half of the run against that over the first.
# A bounded error (a symplectic method, an oscillating error) gives about 1; a secular drift that grows like t^p gives
# 2^p >= 2 for p >= 1. Below ENERGY_NOISE (relative), or round-off's share for the run's steps where that is more
# (harness.testing.energy_noise: it grows with the steps), the deviation says nothing about a trend.
SECULAR_GROWTH = 1.5
ENERGY_NOISE = 1e-13


def origin(cls) -> str:
    """'built in', or 'plug-in from DIST' (the installed distribution that holds the class's top-level module)."""
    module = getattr(cls, "__module__", "") or ""
    if module.split(".")[0] == "stereodyn":
        return "built in"
    from importlib.metadata import packages_distributions

    dists = packages_distributions().get(module.split(".")[0], [])
    return f"plug-in from {', '.join(sorted(set(dists)))}" if dists else f"plug-in (module {module})"


def integrator_rows() -> list[dict]:
    """Every integrator `stereodyn run --integrators` accepts: the registry's classes (each state space) with their
    metadata and origin, then each engine's own integrators (MuJoCo's) that the registry does not hold."""
    from .. import integrators as registry
    from ..engines import engine_names, get_engine

    rows = []
    for space in registry.state_spaces():
        for name in registry.names(space):
            cls = registry.get(name, space)
            rows.append({"name": name, "state_space": space, "order": cls.order, "stages": cls.stages,
                         "symplectic": cls.symplectic, "geometric": cls.geometric,
                         "energy_bounded": getattr(cls, "energy_bounded", False),
                         "symmetric": getattr(cls, "symmetric", False),
                         "casimir_preserving": getattr(cls, "casimir_preserving", False),
                         "default_sweep": registry.joins_default_sweep(cls), "origin": origin(cls),
                         "description": cls.description})
    from ..engines.catalog import origin as engine_origin
    from ..analysis.fitting import declared_order
    from ..engines.declared import in_default_sweep

    for engine in engine_names():
        try:
            adapter = get_engine(engine)
            names = adapter.integrators()
        except Exception:  # an engine that is not installed lists nothing
            continue
        # the engine's own integrators: all of them for an engine that steps its own model, those the registry does
        # not hold for one that runs the registry's (adapter.about.state_space); labelled with the engine, since names
        # repeat across engines (MuJoCo's euler is semi-implicit, the registry's explicit)
        registered = set(registry.names(adapter.about.state_space)) if adapter.about.state_space else set()
        for name in names:
            if name not in registered:
                rows.append({"name": name, "state_space": f"{engine} (engine)", "order": declared_order(engine, name),
                             "stages": "", "symplectic": "", "geometric": "", "energy_bounded": "",
                             "symmetric": "", "casimir_preserving": "",
                             "default_sweep": in_default_sweep(adapter, name),
                             "origin": f"{engine_origin(engine)} ({engine})",
                             "description": adapter.offer(name).unmodelled
                             or ("adaptive (error-controlled)" if adapter.offer(name).adaptive else "")})
    return rows


# `stereodyn integrators` fits this many columns unless --wide (issue 32: 330 columns wrapped in an 80-column terminal)
NARROW = 100
# The claims column of the narrow listing: one letter a declared property, '.' where it is not declared
CLAIM_LETTERS = (("symplectic", "s"), ("symmetric", "r"), ("geometric", "g"), ("energy_bounded", "e"),
                 ("casimir_preserving", "c"))


def listing(rows: list[dict], wide: bool = False) -> str:
    """The text of `stereodyn integrators`: a fixed-width table. Narrow (the default) fits NARROW columns: the
    declared properties as letters (a legend ends the table) and the description cut to the room left; wide has a
    column per property and the whole description."""
    if wide:
        columns = ("name", "state_space", "order", "stages", "symplectic", "geometric", "energy_bounded",
                   "symmetric", "casimir_preserving", "default_sweep", "origin", "description")
        cells = [list(columns)] + [[_text(row[c]) for c in columns] for row in rows]
    else:
        columns = ("name", "state_space", "order", "stages", "sweep", "claims", "origin", "description")
        cells = [list(columns)] + [[_text(row["name"]), _text(row["state_space"]), _text(row["order"]),
                                    _text(row["stages"]), _text(row["default_sweep"]), _claims(row),
                                    _short_origin(row["origin"]), _text(row["description"])] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(columns) - 1)]
    room = None if wide else NARROW - sum(w + 2 for w in widths)
    room = room if room is None or room >= 20 else 0  # a description cut to a few letters says nothing
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)) + "  " + _cut(r[-1], room) for r in cells]
    if not wide:
        lines += ["claims: " + ", ".join(f"{letter} {name}" for name, letter in CLAIM_LETTERS),
                  "('.': not declared) every column and the descriptions in full: stereodyn integrators --wide"]
    return "\n".join(line.rstrip() for line in lines)


def _short_origin(origin) -> str:
    """'built in' for every built-in (an engine's own says its engine in state_space); a plug-in's in full."""
    text = _text(origin)
    return "built in" if text.startswith("built in") else text


def _claims(row: dict) -> str:
    """The declared properties as letters ('srg..'); empty for an engine's own integrator (it declares none)."""
    if all(row[name] == "" for name, _ in CLAIM_LETTERS):
        return ""
    return "".join(letter if row[name] is True else "." for name, letter in CLAIM_LETTERS)


def _cut(text: str, room: int | None) -> str:
    return text if room is None or len(text) <= room else (text[:room - 1] + "…" if room > 1 else "")


def _text(value) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float) and math.isfinite(value) and value == int(value):
        return str(int(value))
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else str(value)


def energy_trend(series: dict[tuple, dict], integrator: str) -> tuple[str, float]:
    """('bounded' | 'secular' | 'round-off' | 'not measured', median growth) over the integrator's stored energy
    series: growth = max deviation over the second half / max over the first half."""
    growths = []
    for key, values in series.items():
        if key[3] != integrator or not key[4] or "energy" not in values:
            continue
        y = np.array([np.nan if v is None else v for v in values["energy"]], dtype=float)
        half = len(y) // 2
        if half < 4 or not np.isfinite(y).all():
            continue
        first, second = np.max(y[:half]), np.max(y[half:])
        t_end = values.get("t", [math.nan])[-1] or math.nan
        steps = t_end / float(key[4]) if math.isfinite(t_end) else 0.0
        if second <= max(ENERGY_NOISE, energy_noise(steps)):
            growths.append(1.0)
        elif first > 0:
            growths.append(second / first)
    if not growths:
        return "not measured", math.nan
    growth = float(np.median(growths))
    return ("bounded" if growth < SECULAR_GROWTH else "secular"), growth


def _costs(runs: pd.DataFrame) -> pd.DataFrame:
    ok = runs[(runs["status"] == "ok") & runs["dt"].notna() & np.isfinite(runs["attitude_err"])
              & np.isfinite(runs["wall_s"])]
    return ok.assign(cost=ok["wall_s"] / ok["t_end"] * 1e6)


def cost_ratios(runs: pd.DataFrame, integrator: str, builtin: set[str], targets=COST_TARGETS) -> dict[float, str]:
    """Per target: the median over cases of (the integrator's cheapest run reaching it) / (the cheapest run of any
    other built-in integrator reaching it), with the number of cases compared."""
    costs = _costs(runs)
    out = {}
    for target in targets:
        # cheapest cost reaching the target, case x integrator (NaN: none reaches it); one groupby, not a mask per
        # case (that was 3 s of the default report)
        cheapest = costs[costs["attitude_err"] <= target].groupby(["case", "integrator"], sort=False)["cost"].min() \
            .unstack("integrator")
        others = [c for c in cheapest.columns if c != integrator and c in builtin]
        if integrator in cheapest.columns and others:
            ratios = (cheapest[integrator] / cheapest[others].min(axis=1)).dropna()
        else:
            ratios = pd.Series(dtype=float)
        out[target] = f"{np.median(ratios):.2g}x ({plural(len(ratios), 'case')})" if len(ratios) else "-"
    return out


def own_label(engine: str, integrator: str) -> str:
    """An engine's own integrator is named with its engine ("euler (mujoco)": names repeat across engines and mean
    different methods); a registered integrator by its name."""
    from .. import integrators as registry
    from ..engines import get_engine

    try:
        space = get_engine(engine).about.state_space
    except Exception:  # an engine that cannot be loaded: its rows keep their names
        return integrator
    return integrator if space and integrator in registry.names(space) else f"{integrator} ({engine})"


def _labelled(table: pd.DataFrame | None) -> pd.DataFrame | None:
    """The table with each row's integrator replaced by own_label (engine, integrator)."""
    if table is None or table.empty or "engine" not in table:
        return table
    pairs = {pair: own_label(*pair) for pair in set(zip(table["engine"].astype(str), table["integrator"].astype(str)))}
    return table.assign(integrator=[pairs[pair] for pair in zip(table["engine"].astype(str),
                                                                 table["integrator"].astype(str))])


def method_lines(df: pd.DataFrame, out_dir: Path, series: dict[tuple, dict] | None = None) -> list[str]:
    """The report section "Each integrator (your method)": a subsection per integrator that ran (an engine's own
    named with its engine, own_label)."""
    from ..analysis import workprecision

    truth_rows = df["integrator"].astype(str) == "taylor"
    df = _labelled(df[~truth_rows])
    ran = list(dict.fromkeys(df.loc[df["status"] == "ok", "integrator"].astype(str))) if not df.empty else []
    if not ran:
        return []
    series = {(key[0], key[1], key[2], own_label(key[1], key[3]), *key[4:]): values
              for key, values in (series or {}).items()}
    try:
        catalogue = {f"{row['name']} ({row['state_space'].removesuffix(' (engine)')})"
                     if row["state_space"].endswith(" (engine)") else row["name"]: row for row in integrator_rows()}
    except Exception:  # the listing is context; the measurements stand without it
        catalogue = {}
    builtin = {name for name, row in catalogue.items() if str(row["origin"]).startswith("built in")}
    convergence = _labelled(workprecision.read_optional(Path(out_dir) / workprecision.CONVERGENCE_FILE,
                                                        ("formulation", "note", "source")))
    if convergence is not None:  # a table with no fitted value reads as text: the numbers as numbers
        numeric = ("order", "floor_dt", "floor_err", "stable_dt_max", "declared_order")
        convergence = convergence.assign(**{c: pd.to_numeric(convergence[c], errors="coerce")
                                            for c in numeric if c in convergence})
    ladder = _labelled(workprecision.read_optional(Path(out_dir) / workprecision.LADDER_FILE))
    runs = df if ladder is None or ladder.empty else pd.concat(
        [df, ladder[[c for c in ladder.columns if c in df.columns]]], ignore_index=True)
    lines = ["## Each integrator (your method)", "",
             "For each integrator that ran: the fitted order over the cases (convergence.csv, min and max), the "
             "largest stable dt and the round-off floor where a dt ladder ran, the energy trend measured on its stored "
             f"series (max deviation over the second half of a run / over the first, median over its runs; secular "
             f"when >= {SECULAR_GROWTH:g}) and its cost against the cheapest other built-in integrator reaching each "
             "accuracy target (median over cases of the cost ratio; below 1 is cheaper). `stereodyn integrators` "
             "lists every registered one.", ""]
    header = ["integrator", "origin", "declared", "fitted order (min / max, cases)", "stable dt max",
              "round-off floor", "energy trend"] + [f"cost ≤ {t:.0e}" for t in COST_TARGETS]
    rows = []
    for name in ran:
        row = catalogue.get(name, {})
        fitted = convergence[(convergence["integrator"] == name) & np.isfinite(convergence["order"])] \
            if convergence is not None else pd.DataFrame()
        declared = fitted["declared_order"].iloc[0] if len(fitted) else row.get("order", math.nan)
        orders = (f"{fitted['order'].min():.2f} / {fitted['order'].max():.2f} ({fitted['case'].nunique()})"
                  if len(fitted) else "-")
        laddered = convergence[(convergence["integrator"] == name) & (convergence["source"] == "ladder")] \
            if convergence is not None else pd.DataFrame()
        stable = number(laddered["stable_dt_max"].min(), ".3g") if len(laddered) else "-"
        floor = number(laddered["floor_err"].min()) if len(laddered) else "-"
        trend, growth = energy_trend(series or {}, name)
        trend = trend if math.isnan(growth) else f"{trend} ({growth:.2g}x)"
        costs = cost_ratios(runs, name, builtin)
        rows.append([name, row.get("origin", "?"), _text(declared), orders, stable, floor, trend,
                     *[costs[t] for t in COST_TARGETS]])
    return lines + markdown_table(header, rows) + [""]


@sections.register("each-integrator", 40)
def _each_integrator(context: sections.Context) -> list[str]:
    return method_lines(context.results, context.out_dir, context.series)
