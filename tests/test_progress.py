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
        "stereodyn: truths of 1 case and 3 runs on 1 worker",
        "stereodyn: timing 3 runs timed once: again, best of 3, here, one at a time, those whose time decides an answer",
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


class FakeClock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


def test_off_a_terminal_a_heartbeat_line_comes_at_least_every_30_s():
    """Issue 32: with stderr redirected, progress lines at most 30 s apart over a run of more than 2 minutes, with the
    phase, the count done of the total, the elapsed time and the ETA. A fake clock, the heartbeat called as the
    thread calls it (every HEARTBEAT_POLL_S)."""
    from stereodyn.harness.run import progress

    log, clock = io.StringIO(), FakeClock()
    bar = ProgressBar(log, clock=clock, heartbeat=False)
    written: list[float] = []
    stamp = lambda: written.extend([clock.now] * (log.getvalue().count("\n") - len(written)))  # noqa: E731
    bar.stage("truths of 2 cases, then 10 runs on 2 workers")
    stamp()
    bar.start(10, 10.0)
    while clock.now < 1000.0 + 150.0:  # 2.5 min: 10 runs of 12 s, then a phase without counts
        clock.now += progress.HEARTBEAT_POLL_S
        if bar.total and bar.done < 10 and clock.now - 1000.0 >= 12.0 * (bar.done + 1):
            bar.advance("run", 1.0, "ok")
        if bar.done == 10 and bar.phase_name.startswith("truths"):
            bar.stage("work–precision: default dt and tolerance ladders")
        bar.heartbeat()
        stamp()
    lines = log.getvalue().splitlines()
    gaps = [b - a for a, b in zip([1000.0, *written], [*written, clock.now])]
    assert max(gaps) <= 30.0, gaps
    beats = [line for line in lines if line.startswith("stereodyn: ... ")]
    assert len(beats) >= 4, lines
    assert "truths of 2 cases" in beats[0] and "/10 runs, ETA " in beats[0] and "in all" in beats[0], beats[0]
    assert any(line.startswith("stereodyn: ... work–precision") and "runs" not in line.split(";")[0]
               for line in beats), beats  # a phase that counts nothing says so by saying no count


def test_the_heartbeat_thread_writes_and_stops(monkeypatch):
    import time

    from stereodyn.harness.run import progress

    monkeypatch.setattr(progress, "HEARTBEAT_S", 0.05)
    monkeypatch.setattr(progress, "HEARTBEAT_POLL_S", 0.01)
    log = io.StringIO()
    bar = ProgressBar(log)
    bar.stage("timing")
    time.sleep(0.5)
    assert bar.finish() >= 0.5
    written = log.getvalue()
    assert written.count("stereodyn: ... timing") >= 2, written
    time.sleep(0.2)
    assert log.getvalue() == written  # finished: no more lines
    assert ProgressBar(io.StringIO(), enabled=False)._thread is None  # --quiet: no thread at all


def test_the_bar_ends_at_100_percent_when_an_engine_declares_a_start_up(tmp_path, monkeypatch):
    """The bar's total counts each engine's start-up once per worker that pays it (pool.startup_cost); the runs that
    paid it count it when they finish (pool.startup_charges). Before, no run counted it: the quick suite's bar (every
    extra) stalled at the runs' share and showed 'ETA 1:00:01' a minute before its sweep ended."""
    from stereodyn.harness.run import pool

    from stereodyn.harness.run import progress

    monkeypatch.setattr(pool, "startup_s", lambda engine: 100.0)  # 100 s against runs of ~0.01 s
    monkeypatch.setattr(progress, "REFRESH_S", 0.0)  # a frame after every run
    screen = Terminal()
    case = with_overrides(find_case("free-asymmetric"), t_end=0.2, dt=[1e-2, 5e-3])
    run_sweep([case], SweepOptions(["mujoco"], tmp_path, ["euler", "rk4"], jobs=1),
              progress=ProgressBar(screen, width=100))
    frames = screen.getvalue().split("\r")
    assert "4/4" in frames[-1] and "100%" in frames[-1], frames[-1]
    first = next(frame for frame in frames if "1/4" in frame)  # the first run paid the start-up: most of the total
    assert int(first.split("%")[0].split()[-1]) >= 90, first


def test_start_up_charges_add_up_to_the_start_up_cost(monkeypatch):
    from types import SimpleNamespace
    from stereodyn.harness.run import pool

    monkeypatch.setattr(pool, "startup_s", lambda engine: {"a": 10.0, "b": 3.0}[engine])
    specs = [SimpleNamespace(engine="a")] * 3 + [SimpleNamespace(engine="b")]
    charge = pool.startup_charges(specs, jobs=2)
    charged = [charge(spec.engine) for spec in specs]
    assert charged == [10.0, 10.0, 0.0, 3.0]  # a: paid by both workers; b: one run, one worker
    assert sum(charged) == pool.startup_cost(specs, jobs=2) == 23.0
