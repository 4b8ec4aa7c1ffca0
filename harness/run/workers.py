"""The worker processes of `stereodyn run`, each watched by its parent: a worker past its budget is ended from outside.

A budget is checked cooperatively inside a run (harness.budget); a plug-in whose prepare() or run() sleeps, or loops
without checking, or one long compiled call (MJX's rollout) would hold its worker forever. So each worker tells its
parent every deadline it enters or leaves (budget.watch: seconds left, which budget, how large), and the parent kills
(SIGKILL) a worker still inside a deadline budget.grace(seconds) after it, fails the task with that budget
(EndedPastBudget, a budget.BudgetExceeded) and starts a replacement. A worker that dies by itself (a crash in an SDK)
fails its task only (WorkerDied) and is replaced too. A task that ends with what is not an Exception (a plug-in's
SystemExit, GeneratorExit, or KeyboardInterrupt, which cannot be Ctrl-C here: a worker ignores it) fails with TaskEnded,
an Exception: its caller makes it that run's failed row, never the command's exit. Each worker leads a process group
of its own, killed whole when the parent ends the worker (harness/run/processes.py: what a plug-in forked dies with
it).

concurrent.futures' ProcessPoolExecutor cannot do this: it cannot end one task, and a killed worker breaks the whole
executor. This pool keeps its interface where the callers use it (submit() -> Future, consumed with
concurrent.futures.as_completed) and its contracts (harness/run/pool.py): spawned workers tied to the parent and deaf
to Ctrl-C (harness/run/processes.py), tasks started in the order submitted, one at a time per worker.

One thread of the parent does all the talking: it hands queued tasks to idle workers, reads what they send (a deadline,
a result), and wakes at the earliest deadline plus grace. The clock is the parent's: a worker sends the seconds left,
not a time.
"""
from __future__ import annotations

import atexit
import multiprocessing
import os
import secrets
import signal
import sys
import threading
import time
from collections import deque
from concurrent.futures import Future
from dataclasses import dataclass
from multiprocessing.connection import wait

from ...reference import plugins
from .. import budget
from ..errors import InternalError, as_internal
from .processes import end_group, end_group_of, kill_group, own_process_group, starting_workers


class EndedPastBudget(budget.BudgetExceeded):
    """A task whose worker was ended by the parent: still inside its budget `grace_s` after the deadline."""

    def __init__(self, what: str, seconds: float, grace_s: float):
        super().__init__(what, seconds)
        self.args = (f"{budget.message(what, seconds)}; it did not stop by itself and its worker was ended "
                     f"{grace_s:.3g} s later",)


class WorkerDied(RuntimeError):
    """A task whose worker process died under it (a crash inside an SDK, the memory killer, a plug-in's os._exit)."""


class TaskEnded(RuntimeError):
    """A task that raised what is not an Exception (SystemExit, GeneratorExit, a KeyboardInterrupt a plug-in raised):
    in a worker that is the task's failure, never the end of the command."""


def died(exitcode: int | None) -> WorkerDied:
    """WorkerDied naming how the process ended: its exit code, or the signal that killed it."""
    if exitcode is not None and exitcode < 0:
        try:
            how = f"killed by {signal.Signals(-exitcode).name}"
        except ValueError:
            how = f"killed by signal {-exitcode}"
    else:
        how = f"exit code {exitcode}"
    return WorkerDied(f"worker process died ({how})")


@dataclass(frozen=True)
class Affinity:
    """What a task needs a worker to have paid for (an engine: its SDK imported, its models compiled) and what that
    costs: key (the engine's name), startup_s (s, the start-up a worker pays once for the key; 0: nothing worth
    keeping a worker for), cost_s (s, the task's own estimated run time)."""

    key: str
    startup_s: float = 0.0
    cost_s: float = 0.0


class _Worker:
    """A worker process, the parent's end of its pipe, its mark (the environment of what it starts carries it:
    processes.WORKER_ENV), whether it is ready (initialized), its task (future), the deadline it reported and the
    affinity keys of the tasks it was given (paid: the start-ups it has paid for)."""

    def __init__(self, context, initializer, initargs):
        self.conn, child = context.Pipe()
        self.marker = secrets.token_hex(8)
        self.process = context.Process(target=_serve, args=(child, initializer, initargs, self.marker), daemon=False)
        self.process.start()
        child.close()
        self.ready = False
        self.future: Future | None = None
        self.deadline: tuple[float, str, float] | None = None  # (parent's monotonic time, what, seconds)
        self.paid: set[str] = set()

    def ends(self) -> float | None:
        """When the parent ends it: its deadline plus the budget's grace (None: no deadline holds)."""
        return None if self.deadline is None else self.deadline[0] + budget.grace(self.deadline[2])


class WatchedPool:
    """`jobs` spawned worker processes, each started with initializer(*initargs), each task watched against the
    budget its worker says it is in. submit(fn, *args) -> Future; shutdown() lets them exit, kill() ends them now."""

    def __init__(self, jobs: int, initializer, initargs: tuple = ()):
        self._context = multiprocessing.get_context("spawn")  # the parent holds threads and LLVM state: no fork
        self._jobs, self._initializer, self._initargs = jobs, initializer, initargs
        self._queue: deque[tuple[Future, object, tuple, Affinity | None]] = deque()
        self._lock = threading.Lock()
        self._wake_r, self._wake_w = self._context.Pipe(duplex=False)
        self._closing = False
        self._workers: list[_Worker] = []
        self._start_workers(jobs)
        self._thread = threading.Thread(target=self._loop, name="stereodyn-pool", daemon=True)
        self._thread.start()

    @property
    def jobs(self) -> int:
        """How many workers it keeps."""
        return self._jobs

    @property
    def pids(self) -> list[int]:
        """The workers' process ids, now."""
        return [w.process.pid for w in list(self._workers)]

    def submit(self, fn, *args, affinity: Affinity | None = None) -> Future:
        """fn(*args) on a worker; affinity: the start-up the task needs (_take: a task goes preferably to a worker
        that has paid for it)."""
        future = Future()
        with self._lock:
            if self._closing:
                raise RuntimeError("submit on a pool that was shut down")
            self._queue.append((future, fn, args, affinity))
        self._wake()
        return future

    def map(self, fn, items) -> list:
        """[fn(item) for item in items] on the workers, in order; the first failure raises (a bug of ours included)."""
        futures = [self.submit(fn, item) for item in items]
        return [future.result() for future in futures]

    def shutdown(self) -> None:
        """Every task is done: let the idle workers exit on their own (Python joins them at exit at the latest)."""
        with self._lock:
            self._closing = True
        self._wake()
        self._thread.join()

    def kill(self) -> None:
        """End the workers now (Ctrl-C, an error): the tasks not done are cancelled."""
        with self._lock:
            self._closing = True
        for worker in list(self._workers):
            kill_group(worker.process.pid, worker.marker)  # the worker and what it started
            worker.process.kill()
        self._wake()

    def _wake(self) -> None:
        try:
            self._wake_w.send_bytes(b"")
        except OSError:  # the thread is gone already
            pass

    def _start_workers(self, count: int) -> None:
        with starting_workers():  # tied to this process, deaf to Ctrl-C, from their first moment
            self._workers += [_Worker(self._context, self._initializer, self._initargs) for _ in range(count)]

    # ------------------------------------------------------------------------------------------ the parent's thread
    def _loop(self) -> None:
        try:
            while self._step():
                pass
        except BaseException as exc:  # a bug here must not leave callers waiting forever
            for worker in self._workers:
                kill_group(worker.process.pid, worker.marker)
                worker.process.kill()
            self._fail_all(exc)
            raise
        finally:
            self._wake_r.close()
            self._wake_w.close()

    def _fail_all(self, exc: BaseException) -> None:
        with self._lock:
            queued, self._queue = [future for future, *_ in self._queue], deque()
        for future in queued + [w.future for w in self._workers if w.future is not None]:
            if not future.cancel() and not future.done():
                future.set_exception(exc)

    def _step(self) -> bool:
        """Hand out tasks, wait for news or the first deadline, handle it; False once the pool is closed."""
        if self._closing:
            for worker in self._workers:
                if worker.future is None and worker.process.is_alive():
                    # What its tasks left (processes.py), killed here, while this thread lives: a worker this thread
                    # started dies by its parent-death signal once the thread ends, and its children that left its
                    # group are init's then (the parent's shutdown did this after the join and lost that race in CI).
                    end_group_of(worker.process.pid)
                    try:
                        worker.conn.send(None)  # exit now, on its own
                    except OSError:
                        pass
            self._fail_all(WorkerDied("the pool was ended before this task finished"))
            return False
        self._hand_out()
        ends = [end for end in (w.ends() for w in self._workers) if end is not None]
        by_conn = {w.conn: w for w in self._workers}
        by_sentinel = {w.process.sentinel: w for w in self._workers}
        ready = wait([self._wake_r, *by_conn, *by_sentinel],
                     max(0.0, min(ends) - time.monotonic()) if ends else None)
        while self._wake_r.poll():
            self._wake_r.recv_bytes()
        for conn in [c for c in ready if c in by_conn]:
            self._hear(by_conn[conn])
        for sentinel in [s for s in ready if s in by_sentinel]:
            worker = by_sentinel[sentinel]
            self._hear(worker)  # what it sent before it died
            self._remove(worker, None)  # its task fails saying how it ended
        now = time.monotonic()
        for worker in list(self._workers):
            if worker.future is not None and worker.ends() is not None and now > worker.ends():
                _, what, seconds = worker.deadline
                kill_group(worker.process.pid)  # first: while it lives, its orphans are its children
                worker.process.kill()
                self._remove(worker, EndedPastBudget(what, seconds, budget.grace(seconds)))
        return True

    def _hand_out(self) -> None:
        """The queued tasks to the ready idle workers, in the order submitted; new workers for those that died."""
        with self._lock:
            if self._closing:
                return
            if self._queue and len(self._workers) < self._jobs:
                self._start_workers(self._jobs - len(self._workers))
            for worker in self._workers:
                while worker.ready and worker.future is None and self._queue:
                    index = self._take(worker)
                    if index is None:  # what is left is better served by the workers that paid for it
                        break
                    future, fn, args, affinity = self._queue[index]
                    del self._queue[index]
                    if not future.set_running_or_notify_cancel():
                        continue
                    try:
                        worker.conn.send((fn, args))
                    except Exception as exc:  # arguments that do not pickle: that task fails
                        future.set_exception(exc)
                        continue
                    worker.future, worker.deadline = future, None
                    if affinity is not None:
                        worker.paid.add(affinity.key)

    def _take(self, worker: _Worker) -> int | None:
        """The index of the queued task an idle worker takes: the first (the queue is in submission order, the
        longest runs first) that costs it no start-up another worker has paid for: no affinity or none worth keeping
        (startup_s 0), one it has paid for, or one no worker has paid for yet. Failing that, the first task anyway
        when the queued work of its key exceeds a start-up (both cores busy beat one start-up saved), else None: the
        worker waits, and the key's tasks go to the workers that paid for it."""
        others = set().union(*(w.paid for w in self._workers if w is not worker))
        for index, (_, _, _, affinity) in enumerate(self._queue):
            if affinity is None or affinity.startup_s <= 0.0 or affinity.key in worker.paid \
                    or affinity.key not in others:
                return index
        head = self._queue[0][3]
        left = sum(a.cost_s for *_, a in self._queue if a is not None and a.key == head.key)
        return 0 if left > head.startup_s else None

    def _hear(self, worker: _Worker) -> None:
        """Read every message the worker has sent: ("ready",) once initialized, a deadline ("deadline", (seconds
        left, what, seconds) or None) or its task's end ("done", ok, value)."""
        while True:
            try:
                if not worker.conn.poll():
                    return
                kind, *body = worker.conn.recv()
            except (EOFError, OSError):  # its end is closed: the sentinel says it died
                return
            except Exception as exc:  # a result the parent cannot unpickle fails its task, not the pool
                kind, body = "done", [False, exc]
            if kind == "ready":
                worker.ready = True
            elif kind == "deadline":
                left = body[0]
                worker.deadline = None if left is None else (time.monotonic() + left[0], left[1], left[2])
            elif worker.future is not None:
                future, worker.future, worker.deadline = worker.future, None, None
                ok, value = body
                if ok:
                    future.set_result(value)
                else:
                    future.set_exception(value)

    def _remove(self, worker: _Worker, failure: BaseException | None) -> None:
        """A dead (or killed) worker: its task fails with `failure` (None: WorkerDied, how it ended); _hand_out starts another when tasks wait. One
        that died before it was ready (its start-up fails) while no other is ready fails the queued tasks too, rather
        than be replaced forever."""
        # What it started (a plug-in's children), while its pid holds the group's id; one that died abruptly has left
        # its orphans to init: those its mark finds.
        kill_group(worker.process.pid, worker.marker)
        worker.process.join()
        failure = failure or died(worker.process.exitcode)
        worker.conn.close()
        self._workers.remove(worker)
        if worker.future is not None and not worker.future.done():
            worker.future.set_exception(failure)
        if not worker.ready and not any(w.ready for w in self._workers):
            with self._lock:
                queued, self._queue = [future for future, *_ in self._queue], deque()
            for future in queued:
                if future.set_running_or_notify_cancel():
                    future.set_exception(WorkerDied(f"a worker process died while starting (exit code "
                                                    f"{worker.process.exitcode})"))


# ---------------------------------------------------------------------------------------------------- in the worker
def _serve(conn, initializer, initargs, marker: str | None = None) -> None:
    """A worker's life: its initializer, then one task at a time until told to stop (None) or the parent is gone."""
    own_process_group(marker)  # before any plug-in's code: what it starts is this worker's to end
    initializer(*initargs)
    sending = threading.Lock()  # a plug-in's own thread may enter a budget too

    def send(message) -> None:
        with sending:
            try:
                conn.send(message)
            except OSError:  # the parent closed its end (the pool was shut down, or it died): nobody listens
                end_group()
                os._exit(0)

    budget.watch(lambda left: send(("deadline", left)))
    send(("ready",))
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            _exit()
        except Exception as exc:  # a task that does not unpickle here (its function's module is not importable)
            send(("done", False, exc))
            continue
        if task is None:
            _exit()
        fn, args = task
        try:
            message = ("done", True, fn(*args))
        except BaseException as exc:  # the parent decides what a failed task means; our own bug is said so here,
            message = ("done", False, _failure(exc))  # where its traceback is (harness.errors)
        try:
            send(message)
        except Exception as exc:  # a result or exception that does not pickle
            send(("done", False, RuntimeError(f"{type(exc).__name__}: {plugins.text_of(exc)}")))


def _failure(exc: BaseException) -> BaseException:
    """What a failed task sends back: our own bug as InternalError (harness.errors), an Exception as it is, anything
    else (SystemExit, GeneratorExit, a KeyboardInterrupt, which Ctrl-C cannot be here) as TaskEnded."""
    failure = as_internal(exc)
    if isinstance(failure, (Exception, InternalError)):
        return failure
    text = " ".join(plugins.text_of(exc).split())
    return TaskEnded(f"{type(exc).__name__}: {text}" if text else type(exc).__name__)


# The exit handlers' time in a worker at its end, s: a bound, not a measured need (Genesis's gs.destroy is the one
# handler we know matters there), so that one that never returns cannot hold the command.
EXIT_HANDLERS_S = 10.0


def _run_exit_handlers() -> None:
    try:
        atexit._run_exitfuncs()
    except BaseException:  # a handler's error or exit: the worker ends anyway (atexit prints what it can)
        pass


def _exit() -> None:
    """End the worker: its exit handlers run (an SDK may write its caches there: Genesis's gs.destroy ends Quadrants'
    program), the interpreter's teardown does not. Freeing every module and model of the SDKs one by one took each
    worker of the quick suite with every extra 15-17 s of CPU after its last task (py-spy), on the cores the report
    was drawing on, and the command's exit waited for it (multiprocessing joins its children). The handlers get
    EXIT_HANDLERS_S: a plug-in's that never returns (atexit.register(time.sleep, 1000)) hung the worker, and the
    command with it, after the report was written (issue 46's fourteenth attack)."""
    handlers = threading.Thread(target=_run_exit_handlers, name="stereodyn-exit-handlers", daemon=True)
    handlers.start()
    handlers.join(EXIT_HANDLERS_S)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):  # closed, or replaced by None
            pass
    end_group()  # what a plug-in started and left in this worker's group
    os._exit(0)
