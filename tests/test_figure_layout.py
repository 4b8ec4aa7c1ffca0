"""The report's figures as drawn (issue 32 item 4), without a browser: nothing clipped (every text and legend inside
the figure), every log axis labelled even within one decade, exponents as large as the digits, colours distinct
within a figure's legends, legend markers only where the lines have them, time tick labels on every invariants
panel, and the width available used. The figures are caught as matplotlib Figures (figures.png patched) from small
made-up tables, so this needs no sweep."""
import io
import math

import numpy as np
import pandas as pd
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_hex
from matplotlib.text import Text

from stereodyn.harness.report import figures

MIN_TEXT_PX = 10.0


@pytest.fixture
def drawn(monkeypatch):
    """figures.png records each Figure it is given (then encodes it as usual)."""
    caught = []
    original = figures.png

    def keep(figure):
        caught.append(figure)
        return original(figure)

    monkeypatch.setattr(figures, "png", keep)
    return caught


def _rows(case, engine, integrators, costs, formulation=""):
    """A case's ok runs: per integrator three dt, errors falling, costs within [costs[0], costs[1]] µs/s."""
    rows = []
    for k, integrator in enumerate(integrators):
        for j, dt in enumerate((0.01, 0.005, 0.0025)):
            cost = costs[0] * (costs[1] / costs[0]) ** ((j + k / len(integrators)) / 3)
            rows.append({"case": case, "engine": engine, "formulation": formulation, "integrator": integrator,
                         "dt": dt, "tolerance": math.nan, "status": "ok", "attitude_err": 1e-3 * (dt / 0.01) ** 4
                         / (k + 1), "wall_s": cost * 1e-6, "t_end": 1.0})
    return rows


def _outside(figure) -> list[str]:
    """The visible texts and legends that reach outside the figure (1 px of anti-aliasing allowed)."""
    renderer = FigureCanvasAgg(figure).get_renderer() if not hasattr(figure.canvas, "get_renderer") \
        else figure.canvas.get_renderer()
    width, height = figure.bbox.width, figure.bbox.height
    out = []
    # a tick's label is drawn only where its tick lies in the view (the others keep stale positions)
    ticks = [tick for axes in figure.axes for axis in (axes.xaxis, axes.yaxis)
             for tick in axis.get_major_ticks() + axis.get_minor_ticks()]
    tick_texts = {id(text) for tick in ticks for text in (tick.label1, tick.label2)}
    items = [t for t in figure.findobj(Text) if t.get_visible() and t.get_text().strip()
             and (t.axes is None or t.axes.get_visible()) and id(t) not in tick_texts]
    items += [text for axes in figure.axes if axes.get_visible() for axis in (axes.xaxis, axes.yaxis)
              for text in _drawn_labels(axis)]
    items += [legend for axes in figure.axes for legend in [axes.get_legend()] if legend] + figure.legends
    for item in items:
        box = item.get_window_extent(renderer)
        if box.x0 < -1 or box.y0 < -1 or box.x1 > width + 1 or box.y1 > height + 1:
            out.append(f"{getattr(item, 'get_text', lambda: type(item).__name__)()!r} at {box.bounds}")
    return out


def _overlapping(figure) -> list[str]:
    """A panel's legend that covers another panel's tick labels (the legends stand right of their panels)."""
    renderer = FigureCanvasAgg(figure).get_renderer()
    out = []
    for axes in figure.axes:
        legend = axes.get_legend()
        if legend is None:
            continue
        box = legend.get_window_extent(renderer)
        for other in figure.axes:
            if other is axes or not other.get_visible():
                continue
            for text in _drawn_labels(other.xaxis) + _drawn_labels(other.yaxis):
                if box.overlaps(text.get_window_extent(renderer)):
                    out.append(f"{axes.get_title()}'s legend over {other.get_title()}'s {text.get_text()!r}")
    return out


def _drawn_labels(axis) -> list:
    """The tick label Texts an axis draws (major and minor, inside its view)."""
    low, high = sorted(axis.get_view_interval())
    span = 1e-9 * (high - low)
    return [tick.label1 for tick in axis.get_major_ticks() + axis.get_minor_ticks()
            if tick.label1.get_visible() and tick.label1.get_text() and low - span <= tick.get_loc() <= high + span]


def _labelled(axis) -> list[str]:
    return [text.get_text() for text in _drawn_labels(axis)]


def _check(figure, markers: bool) -> None:
    FigureCanvasAgg(figure).draw()
    assert not _outside(figure), _outside(figure)
    assert not _overlapping(figure), _overlapping(figure)
    assert figure.get_figwidth() * figures.DPI <= figures.MAX_WIDTH_PX + 0.5  # shown at its own size
    assert figures.smallest_font(figure) * figures.DPI / 72.0 >= MIN_TEXT_PX
    for axes in figure.axes:
        if not axes.get_visible():
            continue
        for axis in (axes.xaxis, axes.yaxis):
            if axis is axes.yaxis and not axis.get_major_ticks()[0].label1.get_visible():
                continue  # an inner panel of a row that shares its y range (the first panel labels it)
            assert len(_labelled(axis)) >= 2, (axes.get_title(), axis.axis_name, _labelled(axis))
    for legend in [a.get_legend() for a in figure.axes if a.get_legend()] + figure.legends:
        lines = [h for h in legend.legend_handles if h.get_linestyle() not in ("None", "")]
        coloured = [to_hex(h.get_color()) for h, t in zip(legend.legend_handles, legend.get_texts())
                    if not t.get_text().startswith(("engine ", "error = tol", "truth"))]
        assert len(set(coloured)) == len(coloured), [t.get_text() for t in legend.get_texts()]
        assert lines
        if not markers:
            assert all(h.get_marker() in ("None", "", None) for h in legend.legend_handles), "markers in legend"


def test_a_single_panel_with_a_long_legend_label_and_a_one_decade_cost_axis(drawn):
    """Drake's names (runge_kutta3_adaptive: the legend cut to "runge_kutta3_ada") and MuJoCo's would share colours by
    their hash (euler and discrete, rk4 and runge_kutta2); a one-decade cost axis had no tick label; the single
    panel's title was clipped at both ends. Break-checks: legend_width() returning 1.5 (the old fixed width) clips the
    legend; integrator_style() in place of figure_styles() repeats a colour; log_ticks without its minor labels leaves
    the cost axis unlabelled; the title unwrapped reaches outside."""
    case = "a-case-with-a-long-name-as-users-write-them-in-their-own-suites-of-bodies"
    rows = pd.DataFrame(_rows(case, "drake",
                              ["runge_kutta3_adaptive", "runge_kutta2", "discrete", "rk4", "euler"], (200.0, 900.0),
                              "quaternion_free"))
    assert figures.work_precision(rows, case) is not None
    figure = drawn[-1]
    _check(figure, markers=True)
    # the width available: a single panel is not drawn at half the page
    assert figure.get_figwidth() * figures.DPI >= 0.55 * figures.MAX_WIDTH_PX


def test_the_tolerance_figure(drawn):
    """Three panels side by side (the reference's formulations), as a report's free-asymmetric has. Break-check:
    panels floored at the old 3.6 in each drew it 1435 px wide here (1377 in a report), over MAX_WIDTH_PX; the old gap
    between panels (legend + 0.55 in) put a legend over the next panel's tick labels (0.0001, 0.001)."""
    methods = [("reference", "quaternion", "scipy_rk45"), ("reference", "quaternion", "taylor"),
               ("reference", "gibbs", "scipy_rk45"), ("reference", "euler_zxz", "scipy_rk45")]
    points = pd.DataFrame([{"case": "c", "engine": engine, "formulation": formulation, "integrator": integrator,
                            "tolerance": tol, "status": "ok", "state_err": tol * 3.0}
                           for engine, formulation, integrator in methods for tol in (1e-3, 1e-5, 1e-7, 1e-9)])
    assert figures.tolerance(points, "c") is not None
    _check(drawn[-1], markers=True)


def test_invariants_every_panel_has_time_labels_and_no_legend_marker(drawn):
    """Break-checks: without labelbottom=True only the lowest row has time labels; the old legend drew markers the
    lines do not have."""
    rows, series = [], {}
    t = np.linspace(0.0, 2.0, 50)
    for engine, integrators in (("mujoco", ["euler", "rk4"]), ("drake", ["discrete", "runge_kutta2"])):
        for integrator in integrators:
            rows.append({"case": "c", "engine": engine, "formulation": "", "integrator": integrator, "dt": 0.01})
            series[("c", engine, "", integrator, figures.dt_key(0.01))] = {
                "t": list(t), "energy": list(1e-9 + 1e-6 * t), "attitude_err": list(1e-8 + 1e-4 * t)}
    rows.append({"case": "c", "engine": "reference", "formulation": "quaternion", "integrator": "taylor",
                 "dt": math.nan})
    series[("c", "reference", "quaternion", "taylor", "")] = {"t": list(t), "energy": list(1e-16 + 0 * t),
                                                              "attitude_err": list(1e-15 + 1e-15 * t)}
    assert figures.invariants(pd.DataFrame(rows), series, "c") is not None
    figure = drawn[-1]
    _check(figure, markers=False)
    shown = [a for a in figure.axes if a.get_visible()]
    assert len(shown) == 4  # two quantities x two engines
    assert all(len(_labelled(a.xaxis)) >= 2 for a in shown)
    rows = sorted({round(a.get_position().y0, 6) for a in shown})
    for y0 in rows:  # each row's first panel labels the row's shared y range
        first = min((a for a in shown if round(a.get_position().y0, 6) == y0), key=lambda a: a.get_position().x0)
        assert len(_labelled(first.yaxis)) >= 2, first.get_ylabel()


def test_smallest_font_counts_an_exponent_at_its_drawn_size():
    """matplotlib's log ticks (10^-13 in mathtext) draw the exponent at 0.7 of the label: 8 pt labels had 5.6 pt
    exponents (issue 32: about 5 px). smallest_font says so, and the report's own log axes draw none."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(3, 2))
    axes = figure.subplots()
    axes.loglog([1e-13, 1e-3], [1, 10])
    axes.tick_params(labelsize=8)
    FigureCanvasAgg(figure).draw()
    assert figures.smallest_font(figure) == pytest.approx(8 * figures.SUPERSCRIPT_SHRINK)
    figures.log_ticks(axes.xaxis)
    figures.log_ticks(axes.yaxis)
    figure.canvas.draw()  # the Agg canvas attached above
    assert figures.smallest_font(figure) == pytest.approx(8)
    assert "1e-13" in [t.get_text() for t in axes.get_xticklabels()]


def _matplotlib_png(figure) -> bytes:
    """figures.png as it was before drawing to raw pixels: matplotlib's own PNG, decoded again for the palette."""
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    buffer, small, info = io.BytesIO(), io.BytesIO(), PngInfo()
    figure.savefig(buffer, format="png", dpi=figures.DPI)
    info.add_text(figures.FONT_KEY, f"{figures.smallest_font(figure):g}")
    quantized = Image.open(buffer).convert("RGB").quantize(colors=figures.PALETTE, method=Image.Quantize.FASTOCTREE)
    quantized.save(small, format="png", optimize=True, dpi=(figures.DPI, figures.DPI), pnginfo=info)
    return small.getvalue()


def _each_kind():
    """A work-precision, a tolerance and an invariants figure (one of its quantities without a line anywhere: a linear
    y axis), as (name, draw) with draw() -> PNG bytes."""
    t = np.linspace(0.0, 2.0, 50)
    rows, series = [], {}
    for integrator in ("euler", "rk4"):
        rows.append({"case": "c", "engine": "mujoco", "formulation": "", "integrator": integrator, "dt": 0.01})
        series[("c", "mujoco", "", integrator, figures.dt_key(0.01))] = {
            "t": list(t), "energy": list(0.0 * t), "attitude_err": list(1e-8 + 1e-4 * t)}
    points = pd.DataFrame([{"case": "c", "engine": "reference", "formulation": "quaternion", "integrator": "scipy_rk45",
                            "tolerance": tol, "status": "ok", "state_err": tol * 3.0} for tol in (1e-3, 1e-6, 1e-9)])
    work = pd.DataFrame(_rows("c", "mujoco", ["euler", "rk4"], (2.0, 90.0)) + _rows("c", "drake", ["discrete"],
                                                                                    (200.0, 900.0)))
    return [("work-precision", lambda: figures.work_precision(work, "c")),
            ("tolerance", lambda: figures.tolerance(points, "c")),
            ("invariants", lambda: figures.invariants(pd.DataFrame(rows), series, "c"))]


@pytest.mark.parametrize("name, draw", _each_kind(), ids=[name for name, _ in _each_kind()])
def test_the_fast_drawing_draws_matplotlibs_own_pixels(name, draw, monkeypatch):
    """figures.png draws to raw pixels and the panel titles sit at TITLE_Y without matplotlib's automatic placement
    (together 20 % of drawing the default report's figures): the PNG is byte for byte the one matplotlib's own PNG and
    automatic placement give, in this process. Break-checks: TITLE_Y = 1.02 fails each kind; the raw pixels read
    with width and height swapped fail each."""
    fast = draw()
    monkeypatch.setattr(figures, "TITLE_Y", None)  # matplotlib's automatic placement
    monkeypatch.setattr(figures, "png", _matplotlib_png)
    assert fast == draw()
