"""Wall-time budgets on a fake clock (harness.budget): every loop helper stops past the deadline, the steps are all
walked, a stored budget is redone only when raised, the message names its flag. Found by the mutation check
(tools/mutants.py, docs/mutants.md)."""
from __future__ import annotations

import types

import pytest

from stereodyn.harness import budget
from stereodyn.harness.budget import BudgetExceeded, Budgets


@pytest.fixture
def clock(monkeypatch):
    """budget's time.monotonic, moved by hand: clock.now += seconds."""
    fake = types.SimpleNamespace(now=1000.0)
    monkeypatch.setattr(budget, "time", types.SimpleNamespace(monotonic=lambda: fake.now))
    return fake


@pytest.mark.parametrize("span", [1, 256, 257, 5000])
def test_every_step_loop_helper_stops_past_the_deadline(clock, span):
    """pieces() checks the deadline whatever the span: the usual one between two samples (<= 256 steps, its fast
    path: issue 28, --run-budget no longer bounded the Python step loops) and a longer one."""
    with budget.within("run", 5.0):
        assert [list(r) for r in budget.pieces(0, span)][0][0] == 0  # in time: the steps
        budget.check()
        clock.now += 6.0
        with pytest.raises(BudgetExceeded, match="run budget exceeded"):
            list(budget.pieces(0, span))
        with pytest.raises(BudgetExceeded):
            budget.check()


def test_pieces_walk_every_step_once():
    walked = [k for piece in budget.pieces(3, 1000) for k in piece]
    assert walked == list(range(3, 1000))


def test_a_preparation_longer_than_its_budget_fails_even_if_it_could_not_be_stopped(clock):
    def compile_for(seconds):
        def make():
            clock.now += seconds  # a C++ compilation: no check inside
            return "model"
        return make
    assert budget.prepared(compile_for(4.0), 5.0) == "model"
    with pytest.raises(BudgetExceeded, match="prepare budget exceeded: stopped after 5 s of wall time "
                                             r"\(--prepare-budget raises it\)"):
        budget.prepared(compile_for(6.0), 5.0)


@pytest.mark.parametrize("stored, holds", [
    (None, True),                                   # not stopped by a budget: reuse
    ({"what": "run", "seconds": 60.0}, True),       # the same budget: it would stop again
    ({"what": "run", "seconds": 30.0}, False),      # raised since: redo
    ({"what": "run"}, False),                       # not what this version writes: redo
    ({"what": "nope", "seconds": 60.0}, False),
])
def test_a_stored_budget_holds_until_that_budget_is_raised(stored, holds):
    assert budget.still_holds(stored, Budgets(run_s=60.0)) is holds


@pytest.mark.parametrize("what, flag", [("run", "--run-budget"), ("prepare", "--prepare-budget"),
                                        ("truth", "--truth-budget")])
def test_the_message_names_the_flag_that_raises_that_budget(what, flag):
    message = f"{what} budget exceeded: stopped after 2.5 s of wall time ({flag} raises it)"
    assert str(BudgetExceeded(what, 2.5)) == message
