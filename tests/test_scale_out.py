"""Issue 49: no serial phase in `stereodyn run`. The truths are pool tasks, a case's runs waiting only for their own
case's truth; the runs whose time decides an answer are timed on the workers, as many at once as workers, each on a
core of its own; the parent computes and times nothing."""
from __future__ import annotations

import os
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from types import SimpleNamespace

import pytest

from stereodyn.harness.run import pool as run_pool, timing
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


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="pins to cores")
def test_fewer_cores_than_workers_is_said_once_and_unpinned(monkeypatch, capsys):
    """timing_cores: a core per worker where there are enough; else unpinned (None each), said once on stderr."""
    monkeypatch.setattr(timing, "_SAID", set())
    monkeypatch.setattr(timing.os, "sched_getaffinity", lambda pid: {3, 1})
    assert timing.timing_cores(2) == [1, 3] and capsys.readouterr().err == ""
    assert timing.timing_cores(3) == [None] * 3 and timing.timing_cores(3) == [None] * 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "stereodyn: warning: timing on 3 workers unpinned (only 2 cores for 3 workers)" \
        in err, err


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="pins to cores")
def test_on_core_pins_every_thread_and_gives_the_mask_back():
    """on_core(core): every thread of the process on that core for the block (a thread started inside too), the
    mask it had afterwards. Break-checked: pinning only the calling thread fails the other thread's check."""
    before = os.sched_getaffinity(0)
    core = min(before)
    seen, go, done = {}, threading.Event(), threading.Event()

    def other():
        go.wait(10)
        seen["inside"] = os.sched_getaffinity(0)
        done.set()

    thread = threading.Thread(target=other)
    thread.start()
    with timing.on_core(core):
        go.set()
        assert done.wait(10)
        assert os.sched_getaffinity(0) == {core} and seen["inside"] == {core}
    thread.join()
    assert os.sched_getaffinity(0) == before


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="pins to cores")
def test_one_timing_per_core_at_a_time_across_threads(monkeypatch, tmp_path):
    """on_a_free_core (a Dask worker's timing): one more thread than cores each takes a core for 0.2 s; no two hold
    one core at once, never more holders than cores (the last waits for a free one), each thread pinned to its core
    alone, and its mask back afterwards. Break-checked: taking the lock non-exclusively (LOCK_SH) puts two threads on
    core 0 at once."""
    monkeypatch.setattr(timing, "LOCK_PREFIX", f"stereodyn-test-{os.getpid()}-{tmp_path.name}-")
    cores = sorted(os.sched_getaffinity(0))
    held, lock = [], threading.Lock()

    def timed():
        with timing.on_a_free_core():
            start, mine = time.monotonic(), os.sched_getaffinity(0)
            time.sleep(0.2)
            with lock:
                held.append((start, time.monotonic(), mine))
        with lock:
            held.append(("after", os.sched_getaffinity(0)))

    threads = [threading.Thread(target=timed) for _ in range(len(cores) + 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30)
    spans = [h for h in held if h[0] != "after"]
    assert len(spans) == len(cores) + 1 and all(len(mine) == 1 for *_, mine in spans), spans
    for k, (start, end, mine) in enumerate(spans):
        for other_start, other_end, theirs in spans[k + 1:]:
            if other_start < end and start < other_end:
                assert mine != theirs, spans
    afters = [h[1] for h in held if h[0] == "after"]
    assert len(afters) == len(cores) + 1 and all(after == set(cores) for after in afters), afters
    for core in cores:
        (Path(tempfile.gettempdir()) / f"{timing.LOCK_PREFIX}{core}.lock").unlink(missing_ok=True)
