"""Issue 49: no serial phase in `stereodyn run`. The truths are pool tasks, a case's runs waiting only for their own
case's truth; the runs whose time decides an answer are timed on the workers, as many at once as workers, each on a
core of its own; the parent computes and times nothing."""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

from stereodyn.harness.run import pool as run_pool
from stereodyn.harness.scenes.cases import find_case, with_overrides


class ThreadPool:
    """The pool's interface where run_local uses it (submit(fn, *args, affinity=...) -> Future), on threads, recording
    what was submitted."""

    def __init__(self, workers: int = 2):
        self.executor = ThreadPoolExecutor(workers)
        self.submitted: list[str] = []
        self.jobs = workers

    def submit(self, fn, *args, affinity=None):
        self.submitted.append(fn.__name__)
        return self.executor.submit(fn, *args)


def test_a_cases_runs_wait_only_for_their_own_truth(monkeypatch):
    """Two cases: the slow one's truth is held until the other's runs are all finished. They finish (the parent
    computed every truth before the first run: those runs would wait); then the held truth's runs finish too. Every
    truth is a pool task, none computed in the parent. Break-checked: submitting the runs only once every truth is
    back (a wait for all truths first) times out here on the held event."""
    fast = with_overrides(find_case("free-asymmetric"), t_end=0.1, dt=[0.01])
    slow = with_overrides(find_case("lagrange-top"), t_end=0.1, dt=[0.01])
    held, parent = threading.Event(), threading.get_ident()
    in_parent = []

    def case_truth(case, certify, budget_s):
        in_parent.append(threading.get_ident() == parent)
        if case is slow:
            assert held.wait(30), "the slow case's truth was never released"
        return f"truth of {case.name}"

    monkeypatch.setattr(run_pool, "case_truth", case_truth)
    monkeypatch.setattr(run_pool, "sweep_run", lambda spec, truth, budgets=None: {"truth": truth})
    monkeypatch.setattr(run_pool, "affinity", lambda spec: None)
    specs = [SimpleNamespace(case=case, engine="mujoco", integrator=name, dt=0.01, label=f"{case.name} {name}")
             for case in (slow, fast) for name in ("euler", "rk4")]
    finished = []

    def done(spec, row):
        finished.append((spec.case.name, row["truth"]))
        if sum(name == fast.name for name, _ in finished) == 2:
            held.set()  # the fast case's runs are done while the slow truth is still being computed

    pool = ThreadPool()
    try:
        run_pool.run_local(specs, pool, done, certify=False)
    finally:
        pool.executor.shutdown()
    assert finished[:2] == [(fast.name, f"truth of {fast.name}")] * 2
    assert sorted(finished[2:]) == [(slow.name, f"truth of {slow.name}")] * 2
    assert in_parent == [False, False] and pool.submitted.count("case_truth") == 2


def test_a_failed_truth_fails_its_cases_runs_only(monkeypatch):
    """A truth that raises on the pool fails its own case's runs (the message says so); the other case runs."""
    good = with_overrides(find_case("free-asymmetric"), t_end=0.1, dt=[0.01])
    bad = with_overrides(find_case("lagrange-top"), t_end=0.1, dt=[0.01])

    def case_truth(case, certify, budget_s):
        if case is bad:
            raise ValueError("no truth here")
        return "truth"

    monkeypatch.setattr(run_pool, "case_truth", case_truth)
    monkeypatch.setattr(run_pool, "sweep_run", lambda spec, truth, budgets=None: {"status": "ok"})
    monkeypatch.setattr(run_pool, "affinity", lambda spec: None)
    monkeypatch.setattr(run_pool, "base_row", lambda spec, grid: {"case": spec.case.name})
    specs = [SimpleNamespace(case=case, engine="mujoco", integrator="euler", dt=0.01) for case in (good, bad)]
    rows = []
    pool = ThreadPool()
    try:
        run_pool.run_local(specs, pool, lambda spec, row: rows.append(row), certify=False)
    finally:
        pool.executor.shutdown()
    by_case = {row.get("case", good.name): row for row in rows}
    assert by_case[good.name] == {"status": "ok"}
    assert by_case[bad.name]["status"] == "failed"
    assert by_case[bad.name]["message"] == "truth failed: ValueError: no truth here"
