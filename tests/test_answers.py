"""One answer per case, engine and target (issue 32 item 3, harness.analysis.answers): "What to use", "Step-size
advice" and the Summary read one table, and on the committed default report they name the same integrator and
setting wherever more than one of them answers."""
import math
import re
from pathlib import Path

import pandas as pd

from stereodyn.harness.analysis import answers
from stereodyn.harness.analysis.answers import LISTED, SEARCHED
from stereodyn.harness.analysis.pareto import ANY, PARETO_COLUMNS
from stereodyn.harness.report.advice import advice_lines
from stereodyn.harness.report.build import SUMMARY_ACCURACY, summary_lines
from stereodyn.harness.report.what_to_use import SAME, what_to_use_lines
from stereodyn.harness.run.results import read_results

DEFAULT = Path(__file__).resolve().parent.parent / "reports" / "default"


def _pareto(rows):
    """pareto.csv rows: (scope, target, engine, integrator, dt, tolerance, err, cost)."""
    return pd.DataFrame([{"case": "c", "scope": scope, "target": target, "engine": engine, "formulation": "",
                          "integrator": integrator, "dt": dt, "tolerance": tol, "attitude_err": err,
                          "us_per_sim_s": cost, "us_per_sim_s_spread": 1.0, "rhs_per_sim_s": math.nan, "steps": 1,
                          "source": "sweep" if engine else "none reached it", "ties": "", "not_recommended": ""}
                         for scope, target, engine, integrator, dt, tol, err, cost in rows],
                        columns=list(PARETO_COLUMNS))


def _advice(rows):
    """advice.csv rows: (engine, integrator, target, dt, tolerance, error, cost)."""
    return pd.DataFrame([{"case": "c", "engine": engine, "formulation": "", "integrator": integrator,
                          "target": target, "dt": dt, "tolerance": tol, "error_checked": err, "us_per_sim_s": cost,
                          "fails_at": dt * 1.25, "note": ""}
                         for engine, integrator, target, dt, tol, err, cost in rows])


def test_searched_setting_replaces_its_family_listed_one_and_the_cheapest_engine_answers_any():
    nan = math.nan
    pareto = _pareto([
        # 1e-3: mujoco rk4 listed at dt 0.01 (100 µs/s); advice searched rk4 up to dt 0.05 (30 µs/s)
        ("any", 1e-3, "mujoco", "rk4", 0.01, nan, 1e-5, 100.0),
        ("mujoco", 1e-3, "mujoco", "rk4", 0.01, nan, 1e-5, 100.0),
        ("pinocchio", 1e-3, "pinocchio", "euler", 0.001, nan, 8e-4, 50.0),
        # 1e-6: advice searched rk4 (200 µs/s), but a listed euler run is cheaper still (150 µs/s)
        ("any", 1e-6, "mujoco", "euler", 1e-4, nan, 9e-7, 150.0),
        ("mujoco", 1e-6, "mujoco", "euler", 1e-4, nan, 9e-7, 150.0),
        ("pinocchio", 1e-6, "pinocchio", "rk4", 0.003, nan, 2e-8, 400.0),
        # 1e-9: nothing listed reaches it, advice did not search it
        ("any", 1e-9, "", "", nan, nan, nan, nan), ("mujoco", 1e-9, "", "", nan, nan, nan, nan),
        ("pinocchio", 1e-9, "", "", nan, nan, nan, nan)])
    advice = _advice([("mujoco", "rk4", 1e-3, 0.05, nan, 7e-4, 30.0), ("mujoco", "rk4", 1e-6, 0.008, nan, 8e-7, 200.0),
                      # a failed integrator's advice is no answer
                      ("pinocchio", "liar", 1e-3, 0.5, nan, 1e-3, 1.0)])
    table = answers.answers(pareto, advice, failed={("pinocchio", "", "liar")}).set_index(["scope", "target"])
    assert list(dict.fromkeys(table.index.get_level_values(0))) == ["mujoco", "pinocchio", ANY]
    cell = table.loc[("mujoco", 1e-3)]
    assert (cell.integrator, cell["dt"], cell.error, cell.source) == ("rk4", 0.05, 7e-4, SEARCHED)
    cell = table.loc[("mujoco", 1e-6)]   # the listed euler is cheaper than the searched rk4: it answers, says so
    assert (cell.integrator, cell["dt"], cell.error, cell.source) == ("euler", 1e-4, 9e-7, LISTED)
    cell = table.loc[("pinocchio", 1e-3)]
    assert (cell.integrator, cell.source) == ("euler", LISTED)
    # any: the cheapest engine's answer (mujoco's searched rk4 at 30 µs/s, not pareto's listed any at 100)
    cell = table.loc[(ANY, 1e-3)]
    assert (cell.engine, cell.integrator, cell["dt"], cell.source) == ("mujoco", "rk4", 0.05, SEARCHED)
    assert table.loc[(ANY, 1e-6)].engine == "mujoco" and table.loc[(ANY, 1e-6)].integrator == "euler"
    none = table.loc[(ANY, 1e-9)]
    assert none.engine == "" and none.why_none == "none reached it"
    # the page: What to use shows the searched answer, the advice row that gave it is marked
    page = "\n".join(what_to_use_lines(answers.answers(pareto, advice, {("pinocchio", "", "liar")})))
    # (1e-9 is not among the targets shown)
    assert "| c | rk4 dt=0.05: 0.0007 rad, 30 µs/s (searched) | euler dt=0.0001: 9e-07 rad, 150 µs/s (listed, " \
           "not searched) |\n" in page


def _method(text: str) -> tuple[str, str]:
    """(method, setting) of a What to use cell or Summary answer: 'rk4 dt=0.05: ...' -> ('rk4', 'dt=0.05')."""
    found = re.match(r"(.+?) (dt=\S+|tol=\S+|default tol)(?::| \()", text)
    assert found, text
    return found.group(1), found.group(2)


def _what_to_use(lines: list[str]) -> dict:
    """{(case, scope, target): (method, setting)} from What to use's tables ('=' resolved to the cell on its left)."""
    out, scope, header = {}, None, None
    for line in lines:
        if line.startswith("### "):
            scope = ANY if line == "### any engine" else line[4:]
        elif line.startswith("| case |"):
            header = [float(h.strip("≤ ")) for h in line.strip("|").split("|")[1:]]
        elif line.startswith("| ") and scope and header:
            cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
            last = None
            for target, text in zip(header, cells[1:]):
                last = last if text == SAME else None if text == "-" else _method(text)
                if last is not None:
                    out[(cells[0], scope, target)] = last
    return out


def _advice_marks(lines: list[str]) -> dict:
    """{(case, engine, target): (method, setting)} of the advice rows marked as the engine's answer."""
    out, engine = {}, None
    for line in lines:
        if line.startswith("### "):
            engine = line[4:].split(":")[0]
        elif line.startswith("| ") and "**answer**" in line:
            case, method, target, advised = [c.strip() for c in line.strip("|").split("|")][:4]
            out[(case, engine, float(target))] = (method, advised.replace(" = ", "="))
    return out


def test_the_committed_report_gives_one_answer_per_case_engine_and_target():
    """On reports/default's tables: where What to use, Step-size advice and the Summary answer the same case, engine
    and target, they name the same integrator and dt or tolerance. Break-checks: What to use from pareto.csv alone
    (answers(pareto, None), as before issue 32) contradicts the advice on 13 of the 16 shared cells (heavy-asymmetric's
    MuJoCo rk4 at 1e-6: dt 0.01466 listed against 0.02036 searched); the Summary from results.csv alone
    (summary_lines(results)) names reference euler_zxz taylor on free-asymmetric, What to use quaternion taylor."""
    table = answers.read(DEFAULT)
    shown = _what_to_use(what_to_use_lines(table))
    advice = pd.read_csv(DEFAULT / "advice.csv", keep_default_na=False, na_values=[""],
                         dtype={"formulation": str, "note": str}).fillna({"formulation": "", "note": ""})
    marks = _advice_marks(advice_lines(advice, table))
    shared = [k for k in marks if (k[0], k[1], k[2]) in shown]
    # the default run's advice: 2 cases x 2 targets (1e-3, 1e-6, both shown) x 4 engines = 16 (12 without Drake)
    assert len(shared) >= 12, (len(shared), marks)
    for case, engine, target in shared:
        method, setting = marks[(case, engine, target)]
        assert shown[(case, engine, target)] == (method, setting), (case, engine, target)
    # the Summary's answer at 1e-6 is What to use's `any` answer, and its engine's own
    results = read_results(DEFAULT / "results.csv")
    summary = summary_lines(results, answer_table=table)
    compared = 0
    for line in summary[2:]:
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")] if line.startswith("| ") else []
        if len(cells) < 4 or cells[3] in ("-", ""):
            continue
        engine, method = cells[3].split(" ", 1)
        name, setting = _method(method)
        name = re.sub(r"(\S+) \((.+)\)$", r"\2 \1", name)  # 'taylor (quaternion)' as What to use says it
        assert shown[(cells[0], ANY, SUMMARY_ACCURACY)] == (f"{engine} {name}", setting), cells
        assert shown[(cells[0], engine, SUMMARY_ACCURACY)] == (name, setting), cells
        compared += 1
    assert compared == results["case"].nunique()


def test_the_committed_answers_csv_is_what_the_committed_report_shows():
    """reports/default/answers.csv (issue 47): for every row at a target What to use shows, report.md's What to use
    names the same integrator and dt or tolerance (the report is rendered from the file)."""
    from stereodyn.harness.report.what_to_use import cell, shown as is_shown

    table = pd.read_csv(DEFAULT / answers.ANSWERS_FILE, keep_default_na=False, na_values=[""],
                        dtype={c: str for c in ("engine", "formulation", "integrator", "source", "why_none")})
    table = table.fillna({c: "" for c in ("engine", "formulation", "integrator", "source", "why_none")})
    section = (DEFAULT / "report.md").read_text(encoding="utf-8").split("## What to use")[1].split("\n## ")[0]
    on_page = _what_to_use(["## What to use", *section.splitlines()])
    checked = 0
    for _, row in table.iterrows():
        if not is_shown(row["target"]) or not row["engine"]:
            continue
        key = (row["case"], row["scope"], float(row["target"]))
        assert on_page.get(key) == _method(cell(row, row["scope"] != ANY)), key
        checked += 1
    assert checked >= 26  # at least one answered target per case of the default run


def test_a_changed_answer_is_a_line_of_the_pull_request_summary(tmp_path):
    """compare --format pr (issue 47): the answers of answers.csv that differ between A and B, one line; B is then
    not identical to A (issue 46 F8), and the headline counts them."""
    from stereodyn.harness.report.compare import pr_lines

    answer_changes = answers.folder_changes

    nan = math.nan
    rows = [("any", 1e-3, "mujoco", "rk4", 0.01, nan, 1e-5, 100.0), ("mujoco", 1e-3, "mujoco", "rk4", 0.01, nan, 1e-5,
                                                                      100.0)]
    a, b = tmp_path / "a", tmp_path / "b"
    for folder, advice in ((a, None), (b, _advice([("mujoco", "rk4", 1e-3, 0.05, nan, 7e-4, 30.0)]))):
        folder.mkdir()
        answers.answers(_pareto(rows), advice).to_csv(folder / answers.ANSWERS_FILE, index=False)

    def summary(x, y):  # the same rows, orders, verdicts and environment: only the answers can differ
        return pr_lines(x, y, {}, {}, pd.DataFrame(), [], [], True, answer_changes(x, y))

    assert len(summary(a, a)) == 1 and "is identical to" in summary(a, a)[0]  # the same answers: nothing said
    lines = summary(a, b)
    assert "is identical" not in "\n".join(lines) and "; 2 answers changed (What to use)." in lines[0], lines
    assert lines[-3] == ("What to use (answers.csv): 2 answers changed: c mujoco 1e-03: mujoco rk4 dt=0.01 -> "
                         "mujoco rk4 dt=0.05; c any 1e-03: mujoco rk4 dt=0.01 -> mujoco rk4 dt=0.05.")
    assert lines[-1] == "Every row: compare.md and compare.csv beside this summary." and lines[-2] == ""
    assert answer_changes(a, tmp_path / "base.json") == []  # a baseline file holds no answers
    # a case name with markup and a newline (issue 46's second attack: the line split, its markup rendered)
    for folder in (a, b):
        table = pd.read_csv(folder / answers.ANSWERS_FILE, keep_default_na=True)
        table.assign(case="a|b*c`x`\n<b>").to_csv(folder / answers.ANSWERS_FILE, index=False)
    line = summary(a, b)[-3]
    assert "\n" not in line and line.split(": ", 2)[2].startswith(r"a\|b\*c\`x\`\\n\<b\> mujoco 1e-03: "), line
