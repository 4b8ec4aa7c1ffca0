"""`stereodyn history` (issue 31 item 4): result folders lined up in order, each metric, status and fitted order of
each row followed over them, and a step flagged on exactly the series that stepped, where it stepped. The folders are
written by hand (a results table of a few rows, runs.json, convergence.csv): no run is needed."""
import json
import shutil

import pandas as pd
import pytest

from stereodyn.harness import cli
from stereodyn.harness.analysis import history

ROWS = [  # case, engine, formulation, integrator, dt, energy_drift, attitude_err
    ("free-asymmetric", "mujoco", "", "rk4", 0.01, 3.1e-9, 2.0e-7),
    ("free-asymmetric", "mujoco", "", "rk4", 0.003, 2.5e-11, 1.7e-9),
    ("free-asymmetric", "mujoco", "", "euler", 0.01, 4.0e-3, 5.0e-2),
    ("lagrange-top", "reference", "quaternion", "rk4", 0.01, 1.0e-9, 3.0e-7),
]
DATES = ("2026-11-01T10:00:00+00:00", "2026-11-02T10:00:00+00:00", "2026-11-03T10:00:00+00:00",
         "2026-11-04T10:00:00+00:00")


def folder(path, date, mujoco="4.0.0", scale=None, order=4.0, status=None):
    """A finished result folder: results.csv (ROWS; `scale` multiplies one row's one metric: (row, metric, factor)),
    runs.json (the environment with `date` and `mujoco`), convergence.csv (mujoco rk4's fitted order)."""
    path.mkdir(parents=True)
    rows = []
    for index, (case, engine, formulation, integrator, dt, energy, attitude) in enumerate(ROWS):
        row = dict(case=case, engine=engine, formulation=formulation, integrator=integrator, precision="float64",
                   dt=dt, t_end=2.0, steps=round(2.0 / dt), status="ok", message="", energy_drift=energy,
                   attitude_err=attitude, us_per_step=1.0 + 0.3 * index)
        if scale and scale[0] == index:
            row[scale[1]] *= scale[2]
        if status and status[0] == index:
            row["status"] = status[1]
        rows.append(row)
    pd.DataFrame(rows).to_csv(path / "results.csv", index=False)
    env = {"python": "3.11.7", "mujoco": mujoco, "date": date, "git commit": "0" * 40}
    (path / "runs.json").write_text(json.dumps({"format": 1, "environment": env, "code": {}, "runs": [],
                                                "complete": True}))
    pd.DataFrame([dict(case="free-asymmetric", engine="mujoco", formulation="", integrator="rk4",
                       precision="float64", order=order, declared_order=4.0, points=2, source="dt_list", note="")]) \
        .to_csv(path / "convergence.csv", index=False)
    return path


def test_a_step_in_the_third_run_is_flagged_on_exactly_that_row_and_metric(tmp_path, capsys):
    """Four runs; from the third on, mujoco rk4 dt=0.003's attitude_err is 3x worse (a step that stays). The folders
    are given out of order: --by date puts them in order. Exactly one step is flagged: that row, that metric, the
    third run, worse, 3x; history.csv holds every series (4 rows x (status + 2 metrics) + 1 order, 4 points each)."""
    dirs = [folder(tmp_path / name, date, scale=(1, "attitude_err", 3.0) if i >= 2 else None)
            for i, (name, date) in enumerate(zip("abcd", DATES))]
    out = tmp_path / "out"
    assert cli.main(["history", *map(str, [dirs[2], dirs[0], dirs[3], dirs[1]]), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "4 runs in order (date): a, b, c, d" in printed and "1 steps flagged, 1 worse" in printed
    steps = pd.read_csv(out / "history_steps.csv", keep_default_na=False, dtype={"dt": str})
    assert len(steps) == 1, steps
    step = steps.iloc[0]
    assert (step["case"], step["engine"], step["integrator"], step["dt"], step["quantity"], step["point"],
            step["label"], step["direction"], step["change"]) == (
        "free-asymmetric", "mujoco", "rk4", "0.003", "attitude_err", 3, "c", "worse", "3x")
    assert step["after"] == pytest.approx(3 * step["before"], rel=1e-9)
    table = pd.read_csv(out / "history.csv", keep_default_na=False)
    assert len(table) == (4 * 3 + 1) * 4
    assert (table["step"] != "").sum() == 1
    points = pd.read_csv(out / "history_points.csv", keep_default_na=False)
    assert points["label"].tolist() == list("abcd") and points["worse"].tolist() == [0, 0, 1, 0]
    page = (out / "history.html").read_text().replace("<wbr>", "")  # names may break after underscores
    assert "attitude_err" in page and "figures/history-steps.png" in page
    assert (out / "figures" / "history-steps.png").stat().st_size > 1000


def test_unchanged_runs_and_round_off_flag_nothing(tmp_path):
    """Runs that differ by round-off (a few parts in 1e6) and in timing flag no step."""
    dirs = [folder(tmp_path / name, date, scale=(i % 4, "energy_drift", 1 + 3e-6 * i))
            for i, (name, date) in enumerate(zip("abcd", DATES))]
    assert cli.main(["history", *map(str, dirs), "--out", str(tmp_path / "out")]) == 0
    assert pd.read_csv(tmp_path / "out" / "history_steps.csv").empty
    assert "No series stepped" in (tmp_path / "out" / "history.md").read_text()


def test_orders_and_statuses_step_and_are_signed(tmp_path):
    """Ordered by the recorded mujoco version (3.3.7, 4.0.0, 4.1.0, not as given nor by date): rk4's fitted order 2.0
    under 3.3.7 and 4.07 under 4.0.0 is a step, better (nearer the declared 4); euler's row diverged under 3.3.7 and
    runs ok under 4.0.0 (better), then fails under 4.1.0 (worse)."""
    a = folder(tmp_path / "new", DATES[0], mujoco="4.0.0", order=4.07)
    b = folder(tmp_path / "old", DATES[1], mujoco="3.3.7", order=2.0, status=(2, "diverged"))
    c = folder(tmp_path / "newer", DATES[2], mujoco="4.1.0", order=4.07, status=(2, "failed"))
    out = tmp_path / "out"
    assert cli.main(["history", str(a), str(b), str(c), "--by", "mujoco", "--out", str(out)]) == 0
    steps = pd.read_csv(out / "history_steps.csv", keep_default_na=False)
    got = sorted((s["quantity"], s["integrator"], s["label"], s["direction"], s["change"])
                 for _, s in steps.iterrows())
    assert got == [("order", "rk4", "new", "better", "+2.07"),
                   ("status", "euler", "new", "better", "diverged -> ok"),
                   ("status", "euler", "newer", "worse", "ok -> failed")]
    assert "mujoco" in pd.read_csv(out / "history_points.csv").columns  # the varying version, per run


def test_baselines_line_up_with_folders(tmp_path):
    """A baseline file is a point like a folder, its rows and its fitted orders (rk4's 4.0 in the baseline, 2.0 in
    the folder after it)."""
    a = folder(tmp_path / "a", DATES[0])
    b = folder(tmp_path / "b", DATES[1], scale=(0, "energy_drift", 100.0), order=2.0)
    assert cli.main(["baseline", str(a), "--out", str(tmp_path / "a.json")]) == 0
    out = tmp_path / "out"
    assert cli.main(["history", str(tmp_path / "a.json"), str(b), "--by", "given", "--out", str(out)]) == 0
    steps = pd.read_csv(out / "history_steps.csv", keep_default_na=False)
    assert sorted(steps[["quantity", "label", "change"]].values.tolist()) == [["energy_drift", "b", "100x"],
                                                                              ["order", "b", "-2.00"]]


@pytest.mark.parametrize("argv, words", [
    (["--by", "pin"], "--by pin: "),
    (["--step-factor", "1"], "--step-factor: must be a finite number > 1"),
    (["--order-step", "nan"], "--order-step: must be a finite number > 0"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, words):
    dirs = [folder(tmp_path / n, d) for n, d in zip("ab", DATES)]
    assert cli.main(["history", *map(str, dirs), "--out", str(tmp_path / "out"), *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err, err


def test_one_folder_is_not_a_history(tmp_path, capsys):
    assert cli.main(["history", str(folder(tmp_path / "a", DATES[0])), "--out", str(tmp_path / "o")]) == 2
    assert "at least two" in capsys.readouterr().err


def test_segments_find_a_step_and_ignore_noise():
    """The L1 piecewise-constant fit: one step of 1 in log10 at index 3; noise below the threshold is no step; a
    single outlier of 10x is two steps (there and back), as asv flags it."""
    assert history.segments([0, 0.01, -0.01, 1, 1.01, 0.99], 0.04) == [3]
    assert history.segments([0, 0.01, -0.01, 0.02, 0.0], 0.04) == []
    assert history.segments([0, 0, 1, 0, 0], 0.04) == [2, 3]
    assert history.segments([5.0], 0.04) == []


def test_the_section_is_absent_from_a_report_without_history(tmp_path):
    """The History section is registered with the others and shows only where a folder holds history tables."""
    from stereodyn.harness.report import history as page, sections

    assert "history" in [s.name for s in sections.registered()]
    context = sections.Context(tmp_path, pd.DataFrame(), {}, None, {}, {})
    assert page.history_lines(context) == []
    shutil.rmtree(tmp_path)


def test_the_page_is_readable_at_100_percent(tmp_path):
    """The history page as Chromium lays it out in a 1400 px window (tests/test_figures_readable.py's measure): its
    figure's smallest text is >= 10 px, drawn at >= 96 dpi; a table's text is the page's (0.85 em of 16 px)."""
    import io

    from PIL import Image

    from stereodyn.harness.report import figures
    from test_figures_readable import CHROMIUM, MIN_DPI, MIN_TEXT_PX, displayed_widths, png_of

    if CHROMIUM is None:
        pytest.skip("chromium not installed (apt-get install -y chromium)")
    dirs = [folder(tmp_path / name, date, scale=(1, "attitude_err", 3.0) if i >= 2 else None)
            for i, (name, date) in enumerate(zip("abcd", DATES))]
    out = tmp_path / "out"
    assert cli.main(["history", *map(str, dirs), "--out", str(out)]) == 0
    measured = displayed_widths(out / "history.html", tmp_path)
    assert len(measured) == 1, measured
    src, shown, natural = measured[0]
    image = Image.open(io.BytesIO(png_of(out / "history.html", src)))
    dpi, font = image.info["dpi"][0], float(image.info[figures.FONT_KEY])
    assert round(dpi) >= MIN_DPI and font * dpi / 72.0 * shown / natural >= MIN_TEXT_PX, (dpi, font, shown, natural)


def test_by_commit_follows_the_repository_history(tmp_path, capsys):
    """--by commit: the runs in the order of their recorded commits in --repo's history (not by date, nor as given);
    a commit the repository lacks is one line, exit 2."""
    import subprocess

    repo = tmp_path / "repo"
    repo.mkdir()
    git = lambda *a: subprocess.run(["git", "-C", str(repo), *a], check=True, capture_output=True,  # noqa: E731
                                    text=True).stdout.strip()
    git("init", "-q")
    shas = []
    for n in range(3):
        git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "--allow-empty", "-m", f"c{n}")
        shas.append(git("rev-parse", "HEAD"))
    dirs = []
    for name, sha, date in (("x", shas[2], DATES[0]), ("y", shas[0], DATES[1]), ("z", shas[1], DATES[2])):
        dirs.append(folder(tmp_path / name, date))
        manifest = json.loads((dirs[-1] / "runs.json").read_text())
        manifest["environment"]["git commit"] = sha
        (dirs[-1] / "runs.json").write_text(json.dumps(manifest))
    out = tmp_path / "out"
    assert cli.main(["history", *map(str, dirs), "--by", "commit", "--repo", str(repo), "--out", str(out)]) == 0
    assert "3 runs in order (commit): y, z, x" in capsys.readouterr().out
    manifest["environment"]["git commit"] = "f" * 40
    (dirs[-1] / "runs.json").write_text(json.dumps(manifest))
    assert cli.main(["history", *map(str, dirs), "--by", "commit", "--repo", str(repo), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--by commit: {dirs[-1]}: git commit 'ffffffff" in err, err


def test_a_series_without_numbers_and_a_row_that_appears(tmp_path):
    """A metric a row has at no run (empty in every results.csv) flags nothing; a row only in the later run is a
    change (the gate does not check a new row), one gone from it is worse (the gate's "missing")."""
    a = folder(tmp_path / "a", DATES[0], scale=(3, "attitude_err", float("nan")))
    b = folder(tmp_path / "b", DATES[1], scale=(3, "attitude_err", float("nan")))
    rows = pd.read_csv(a / "results.csv")
    rows.iloc[[0, 1, 3]].to_csv(a / "results.csv", index=False)  # euler dt=0.01 appears in b
    rows = pd.read_csv(b / "results.csv")
    rows.iloc[[0, 2, 3]].to_csv(b / "results.csv", index=False)  # rk4 dt=0.003 gone from b
    out = tmp_path / "out"
    assert cli.main(["history", str(a), str(b), "--out", str(out)]) == 0
    steps = pd.read_csv(out / "history_steps.csv", keep_default_na=False, dtype={"dt": str})
    assert sorted(zip(steps["integrator"], steps["dt"], steps["quantity"], steps["change"], steps["direction"])) == [
        ("euler", "0.01", "status", "- -> ok", "changed"), ("rk4", "0.003", "status", "ok -> -", "worse")]


def test_a_run_label_with_newlines_and_markup_stays_one_cell_as_itself(tmp_path, capsys):
    """Issue 46's fifth attack, finding 5: a folder named `evil|*`<b>\\n# H\\x1b[31m` broke history.md's tables (the
    newline ended the row, `# H` became a heading), wrote its ESC into the page and printed it raw; compare's pull-
    request summary escaped the same name. The page escapes it as that summary does (markdown.md_text), a table
    cell is one line, the terminal prints the escapes. Break-checked: without md_text in history's two tables the
    markup is raw."""
    evil = "evil|*`<b>\n# H\x1b[31m"
    first = folder(tmp_path / "a", DATES[0])
    second = folder(tmp_path / evil, DATES[1], scale=(1, "attitude_err", 3.0))
    out = tmp_path / "out"
    assert cli.main(["history", str(first), str(second), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    page = (out / "history.md").read_text()
    assert "\x1b" not in page and "\x1b" not in printed and "\n# H" not in page
    assert r"evil\|\*\`\<b\>\\n\# H\\x1b\[31m" in page, page  # each markup escaped, as compare's summary
    assert "evil|*`<b>\\n# H\\x1b[31m" in printed, printed
    rows = [line for line in page.splitlines() if line.startswith("|")]
    assert all(line.endswith("|") for line in rows), rows  # no row cut by a newline
    # The browser shows the name as itself (the sixth attack saw \&lt;b\&gt;: the escapes' backslashes on the page).
    # Break-checked: without html._inline's backslash escapes the backslashes show.
    html_page = (out / "history.html").read_text()
    assert "evil|*`&lt;b&gt;\\n# H\\x1b[31m" in html_page and "<b>" not in html_page, html_page


def test_a_run_label_with_a_carriage_return_gives_a_history_that_reads_back(tmp_path):
    """Issue 46's sixth attack, finding 5: a folder name with a CR was written raw into history_points.csv, which the
    command then refused on reading it back ("row 2: 2 fields"), exit 2 and no history.md. Labels and paths are one
    line (words.one_line). Break-checked: without one_line on the label the command exits 2."""
    first = folder(tmp_path / "a", DATES[0])
    second = folder(tmp_path / "h-cr\rX", DATES[1])
    out = tmp_path / "out"
    assert cli.main(["history", str(first), str(second), "--out", str(out)]) == 0
    points = pd.read_csv(out / "history_points.csv", keep_default_na=False)
    assert points["label"].tolist() == ["a", "h-cr\\rX"] and (out / "history.md").is_file()


def test_by_date_orders_by_the_moment_and_refuses_what_is_no_date():
    """Issue 46's thirteenth attack, F10: --by date sorted runs.json's dates as text: "not a date", {"a": 1} and
    null after 2026-12-06, 12 before it, exit 0; two dates with other UTC offsets in the wrong order. A date is
    read as ISO 8601 (no offset: UTC) and ordered by its moment; anything else is one line naming the folder.
    Break-checked: with the text sort the offsets' order is wrong and the bad dates pass."""
    import pandas as pd

    from stereodyn.harness.analysis.history import Point, order

    def point(label, date):
        return Point(label, f"/runs/{label}", pd.DataFrame(), pd.DataFrame(), {"date": date})

    # 10:00 at +05:00 is 05:00 UTC: before 06:00 UTC, though after it as text
    east, west, naive = point("east", "2026-12-06T10:00:00+05:00"), point("west", "2026-12-06T06:00:00+00:00"), \
        point("naive", "2026-12-06T05:30:00")
    assert [p.label for p in order([west, east, naive], "date")] == ["east", "naive", "west"]
    for bad in ("not a date", 12, {"a": 1}, None, "2026-13-01"):
        with pytest.raises(ValueError, match=r"^/runs/bad: date .* recorded in its environment \(runs.json\) is no "
                                             r"ISO 8601 date and time, so --by date cannot place it$"):
            order([west, point("bad", bad)], "date")
