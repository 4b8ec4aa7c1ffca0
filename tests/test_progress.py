"""The progress bar: drawn on a terminal with an ETA, silent otherwise."""
import io

from stereodyn.harness import cli
from stereodyn.harness.run.sweep import SweepOptions, run_sweep
from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.harness.run.progress import ProgressBar


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_the_bar_counts_runs_and_shows_an_eta():
    screen = Terminal()
    bar = ProgressBar(screen, width=120)
    bar.phase("truth lagrange-top")
    bar.start(total=4, total_cost=10.0, resumed=2)
    bar.advance("lagrange-top mujoco rk4 dt=0.01", 5.0, "ok")
    assert "1/4 (2 resumed)" in bar.line("") and "50%" in bar.line("") and "ETA 0:" in bar.line("")
    for _ in range(3):
        bar.advance("run", 5.0 / 3, "ok")
    bar.close()
    text = screen.getvalue()
    frames = text.split("\r")[1:]
    assert frames[0].startswith("truth lagrange-top")
    assert frames[-1].rstrip().endswith("run: ok") and "4/4" in frames[-1] and "100%" in frames[-1]
    assert all(len(frame.rstrip("\n")) == 119 for frame in frames)  # each frame overwrites the whole line
    assert text.endswith("\n")


def test_silent_when_not_a_terminal_or_disabled():
    for bar, stream in ((ProgressBar(s := io.StringIO()), s), (ProgressBar(t := Terminal(), enabled=False), t)):
        bar.phase("truth")
        bar.start(2, 2.0)
        bar.advance("run", 1.0, "ok")
        bar.close()
        assert stream.getvalue() == ""


def test_a_sweep_drives_the_bar(tmp_path):
    screen = Terminal()
    case = with_overrides(find_case("free-asymmetric"), t_end=0.2, dt=[1e-2, 5e-3])
    run_sweep([case], SweepOptions(["mujoco"], tmp_path, ["euler", "rk4"], jobs=1),
              progress=ProgressBar(screen, width=100))
    final = screen.getvalue().split("\r")[-1]
    assert "4/4" in final and "100%" in final and screen.getvalue().endswith("\n")


def test_run_prints_one_line_per_phase_when_stderr_is_not_a_terminal(tmp_path, capsys):
    assert cli.main(["run", "free-asymmetric", "--engines", "mujoco", "--integrators", "euler", "--t-end", "0.2",
                     "--jobs", "1", "--out", str(tmp_path)]) == 0
    assert capsys.readouterr().err.splitlines() == [
        "stereodyn: truths of 1 cases, then 3 runs on 1 workers", "stereodyn: timing 3 runs, one at a time, in rounds",
        "stereodyn: report: report.md, report.html"]  # STEREODYN_FIGURES=0 (tests/conftest.py)
    assert cli.main(["run", "free-asymmetric", "--engines", "mujoco", "--integrators", "euler", "--t-end", "0.2",
                     "--jobs", "1", "--out", str(tmp_path / "quiet"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_a_phase_is_one_plain_line_off_a_terminal_and_one_line_on_it():
    log = io.StringIO()
    bar = ProgressBar(log)
    bar.phase("truth lagrange-top")  # a step inside a phase: nothing in a log
    bar.stage("timing 3 runs")
    bar.start(1, 1.0)
    bar.advance("run", 1.0, "ok")
    bar.close()
    assert log.getvalue() == "stereodyn: timing 3 runs\n"
    screen = Terminal()
    bar = ProgressBar(screen, width=60)
    bar.start(1, 1.0)
    bar.advance("run", 1.0, "ok")
    bar.stage("report")  # the bar's line is kept, the phase gets its own
    lines = screen.getvalue().split("\n")
    assert lines[-2:] == ["stereodyn: report", ""] and lines[-3].rstrip().endswith("run: ok")
    for quiet in (ProgressBar(s := io.StringIO(), enabled=False), ProgressBar(t := Terminal(), enabled=False)):
        quiet.stage("report")
    assert s.getvalue() == t.getvalue() == ""
