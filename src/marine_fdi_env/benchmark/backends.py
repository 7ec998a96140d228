"""Where chunks of episodes run: in this process (``serial``), a local process pool (``process``)
or a Ray cluster (``ray``).

A *task* is one chunk of episodes (a batch of the vector environment), never a single decision:
``fn(*args, progress=callback)`` runs it and returns its result; ``callback(x)`` reports that
``x`` more episodes' worth of work is done (fractions allowed, so a progress bar moves per
decision, not per chunk).  :func:`run_tasks` hands every result back to the calling process as
soon as its task finishes (in any order); the caller stores it, so an interruption loses only the
chunks in flight.

Reproducibility does not depend on the backend: a task's result is a function of its arguments
(episode seeds are derived from the scenario ids, engines are independent of their batch
neighbours), so serial, process and Ray runs agree bit for bit (tested).

Ray is optional (``pip install 'marine-fdi-env[ray]'``) and imported only when asked for.  With
``ray_address`` (or the ``RAY_ADDRESS`` environment variable; ``auto`` = the cluster ``ray start``
made on this machine) :func:`run_tasks` connects to an existing cluster; otherwise it starts a new
local instance with ``num_cpus = workers`` and no dashboard, and stops it at the end.  If Ray is already
initialised in this process (a test, a
notebook) that instance is used and left running.
"""

from __future__ import annotations

import math
import os
import signal
import time
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from ..errors import MissingExtra

__all__ = ["BACKENDS", "Backend", "run_tasks", "run_tasks_counted", "chunk_size"]

BACKENDS: tuple[str, ...] = ("serial", "process", "ray")
_PROGRESS_INTERVAL_S = 0.5  # workers report progress at most this often (one message each time)
_POLL_S = 0.1


@dataclass(frozen=True)
class Backend:
    """Where tasks run.  ``workers``: processes (``process``) or local Ray CPUs (``ray`` without
    an address; on a cluster Ray schedules on every CPU it has and ``workers`` only sizes chunks)."""

    name: str = "serial"
    workers: int = 1
    ray_address: str | None = None

    def __post_init__(self) -> None:
        if self.name not in BACKENDS:
            raise ValueError(f"--backend must be one of {', '.join(BACKENDS)}, got {self.name!r}")
        if not isinstance(self.workers, int) or isinstance(self.workers, bool) or self.workers < 1:
            raise ValueError(f"--workers must be a positive integer, got {self.workers!r}")
        if self.ray_address is not None and self.name != "ray":
            raise ValueError(f"--ray-address needs --backend ray (got --backend {self.name})")

    @classmethod
    def make(cls, name: str | None, workers: int = 1, ray_address: str | None = None) -> "Backend":
        """``name`` None: ``ray`` with an address, ``process`` with several workers, else ``serial``."""
        if name is None:
            name = "ray" if ray_address else "process" if isinstance(workers, int) and workers > 1 else "serial"
        return cls(name, workers, ray_address)


def chunk_size(n_items: int, batch_size: int, workers: int) -> int:
    """Episodes per task: at most ``batch_size``, in a number of chunks that is a multiple of the
    workers (156 episodes on 2 workers: 6 chunks of 26, not 32 x 4 + 28, which leaves one worker
    idle for the last round), each as large as that allows."""
    if n_items <= 0:
        return max(1, batch_size)
    w = max(1, workers)
    n_chunks = math.ceil(math.ceil(n_items / max(1, batch_size)) / w) * w
    return max(1, math.ceil(n_items / n_chunks))


def run_tasks(
    backend: Backend,
    fn: Callable,
    tasks: Sequence[tuple],
    *,
    on_result: Callable[[int, Any], None],
    on_progress: Callable[[int, float], None] | None = None,
) -> None:
    """Run ``fn(*tasks[i], progress=cb)`` for every i on ``backend``.

    ``on_result(i, result)`` and ``on_progress(i, x)`` are called in this process and thread.
    An exception of a task is raised here (the remaining tasks are cancelled); so is
    ``KeyboardInterrupt``, after the workers were stopped.
    """
    if not tasks:
        return
    finished: set[int] = set()

    def report(i, x):  # a report that arrives after its task's result is dropped
        if on_progress is not None and i not in finished:
            on_progress(i, x)

    def result(i, res):
        finished.add(i)
        on_result(i, res)

    if backend.name == "serial":
        for i, args in enumerate(tasks):
            result(i, fn(*args, progress=lambda x, i=i: report(i, x)))
    elif backend.name == "process":
        _run_process(backend, fn, tasks, result, report)
    else:
        _run_ray(backend, fn, tasks, result, report)


# ----------------------------------------------------------------------------- progress from workers
class _Throttled:
    """Sums progress and forwards it with ``send((task, amount))`` at most every 0.5 s."""

    def __init__(self, task: int, send: Callable[[tuple[int, float]], None]) -> None:
        self.task, self.send, self.pending, self.last = task, send, 0.0, time.monotonic()

    def __call__(self, x: float) -> None:
        self.pending += x
        now = time.monotonic()
        if now - self.last >= _PROGRESS_INTERVAL_S:
            self.flush()
            self.last = now

    def flush(self) -> None:
        if self.pending:
            try:
                self.send((self.task, self.pending))
            except Exception:  # noqa: BLE001 - progress is best effort, never a reason to fail a task
                pass
            self.pending = 0.0


# ----------------------------------------------------------------------------- process pool
_QUEUE = None


def _process_init(queue) -> None:
    global _QUEUE
    _QUEUE = queue
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C and stops the pool


def _process_task(fn, i, args):
    cb = _Throttled(i, _QUEUE.put)
    out = fn(*args, progress=cb)
    cb.flush()
    return out


def _drain(queue, report) -> None:
    import queue as _q

    while True:
        try:
            i, x = queue.get_nowait()
        except _q.Empty:
            return
        report(i, x)


def run_tasks_counted(
    backend: Backend,
    fn: Callable,
    tasks: Sequence[tuple],
    *,
    bar,
    on_result: Callable[[int, Any], None],
    settled: Callable[[], float],
    per_episode: int = 1,
) -> None:
    """:func:`run_tasks` with a progress bar that counts episodes (:func:`~marine_fdi_env.progress.progress_bar`).

    A task's progress reports move ``bar`` by ``x / per_episode`` (``per_episode``: the agents that share
    an episode's reports); when its result is stored by ``on_result``, the bar is set to ``settled()``
    (the episodes stored so far) plus what the tasks still in flight have reported.  The bar is closed
    at the end, also after an error or an interruption."""
    in_flight: dict[int, float] = {}

    def advance(i: int, x: float) -> None:
        in_flight[i] = in_flight.get(i, 0.0) + x
        bar.advance(x / per_episode)

    def result(i: int, res: Any) -> None:
        on_result(i, res)
        in_flight.pop(i, None)  # this task now counts as stored; the others as far as they got
        bar.set_done(settled() + sum(in_flight.values()) / per_episode)

    try:
        run_tasks(backend, fn, tasks, on_result=result, on_progress=advance)
    finally:
        bar.close()


def _run_process(backend, fn, tasks, on_result, report) -> None:
    import multiprocessing as mp

    ctx = mp.get_context()
    queue = ctx.Queue()
    with _sigint_blocked_for_children():  # the workers start with SIGINT blocked (and then ignore it)
        pool = ctx.Pool(min(backend.workers, len(tasks)), initializer=_process_init, initargs=(queue,))
    try:
        pending = {i: pool.apply_async(_process_task, (fn, i, args)) for i, args in enumerate(tasks)}
        while pending:
            time.sleep(_POLL_S)
            _drain(queue, report)
            for i in [i for i, r in pending.items() if r.ready()]:
                res = pending.pop(i).get()  # re-raises the task's exception
                _drain(queue, report)
                on_result(i, res)
        pool.close()
        pool.join()
    except BaseException:
        pool.terminate()
        pool.join()
        raise
    finally:
        queue.close()


# ----------------------------------------------------------------------------- Ray
def _import_ray():
    try:
        import ray
    except ImportError:
        raise MissingExtra("ray", "the ray backend") from None
    return ray


def ray_connect(backend: Backend):
    """(ray module, whether this call started Ray and should shut it down)."""
    ray = _import_ray()
    if ray.is_initialized():
        return ray, False
    import logging

    address = backend.ray_address or os.environ.get("RAY_ADDRESS") or None
    if address:
        where = "--ray-address" if backend.ray_address else "RAY_ADDRESS"
        try:
            ray.init(address=address, logging_level=logging.WARNING, log_to_driver=False)
        except Exception as e:  # noqa: BLE001 - Ray raises ConnectionError, RuntimeError, ... for a bad address
            msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise ValueError(f"{where} {address}: cannot connect to a Ray cluster ({msg})") from None
    else:
        # address="local": a new instance even if `ray start` left one on this machine (plain
        # ray.init() would join that one); join it with --ray-address auto
        try:
            with _sigint_blocked_for_children():
                ray.init(
                    address="local",
                    num_cpus=backend.workers,
                    include_dashboard=False,
                    logging_level=logging.WARNING,
                    log_to_driver=False,
                )
        except KeyboardInterrupt:  # Ctrl-C while Ray was starting: delivered once it had started
            if ray.is_initialized():
                ray.shutdown()
            raise
    return ray, True


class _sigint_blocked_for_children:
    """Block SIGINT while Ray (or the process pool) starts its processes, which inherit the signal mask.

    Ctrl-C in a terminal signals the whole process group: without this Ray's own processes
    (GCS, raylet, workers) died with it and the driver sometimes crashed at exit (a C++ stack
    trace, exit code 1, or a segfault) instead of stopping the tasks, keeping the finished chunks
    and exiting with 130.  A Ctrl-C during the start stays pending and reaches this process as
    ``KeyboardInterrupt`` when the mask is restored (nothing is lost)."""

    def __enter__(self):
        self.old = None
        if hasattr(signal, "pthread_sigmask"):
            self.old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        return self

    def __exit__(self, *exc):
        if self.old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, self.old)
        return False


def _ray_task(fn, i, args, queue):
    # fire and forget: Queue.put_nowait waits for the actor (ray.get), and a task blocked in ray.get
    # lends its CPU to the scheduler, which then starts more tasks than the node has CPUs
    cb = _Throttled(i, lambda item: queue.actor.put_nowait.remote(item))
    out = fn(*args, progress=cb)
    cb.flush()
    return out


def _run_ray(backend, fn, tasks, on_result, report) -> None:
    ray, started = ray_connect(backend)
    refs: dict = {}
    try:
        from ray.util.queue import Queue

        queue = Queue(actor_options={"num_cpus": 0})
        remote = ray.remote(num_cpus=1)(_ray_task)
        fn_ref = ray.put(fn)
        refs = {remote.remote(fn_ref, i, args, queue): i for i, args in enumerate(tasks)}
        pending = list(refs)
        while pending:
            ready, pending = ray.wait(pending, num_returns=1, timeout=_POLL_S)
            _drain_ray(queue, report)
            for ref in ready:
                res = ray.get(ref)  # re-raises the task's exception
                _drain_ray(queue, report)
                on_result(refs.pop(ref), res)
    except BaseException:
        if not started:  # on a shared cluster stop our tasks; a local instance is shut down below
            for ref in refs:
                try:
                    ray.cancel(ref, force=True)
                except Exception:  # noqa: BLE001 - already finished or gone
                    pass
        raise
    finally:
        if started:
            ray.shutdown()


def _drain_ray(queue, report) -> None:
    n = queue.qsize()
    if n:
        for i, x in queue.get_nowait_batch(n):
            report(i, x)
