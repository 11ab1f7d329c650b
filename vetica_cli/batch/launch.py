"""Launchers: where a study's tasks run.  A launcher gets the task function passed in
(hydra's ``Launcher.launch(job)``): ``launch(fn, args, on_result)`` calls
``fn(a)`` for every ``a`` of ``args`` and hands each result to ``on_result(i,
result)`` in this process as it finishes, in any order.

* :class:`SerialLauncher`: in this process, in order (``--jobs 1``);
* :class:`LokyLauncher`: ``jobs`` loky worker processes (joblib);
* :class:`DaskLauncher`: a Dask cluster through joblib's dask backend (a given
  scheduler, or a local cluster of ``jobs`` single-threaded worker processes).

Inner numba/BLAS threads are capped at one per worker (:data:`THREAD_VARS`) so
two workers use two cores.  A launcher is opened before any output is written,
so an unreachable scheduler exits with one line and leaves nothing.

A loky worker watches the sweep that started it from the moment it starts (the pool's
initializer, :func:`worker_init`, before any task arrives) and exits within
:data:`PARENT_POLL_S` seconds once the sweep is gone (``kill -9`` of the sweep at any
moment, even while the worker is still starting): loky would otherwise keep its idle
workers for five minutes, and with them its two resource trackers and their semaphores in
/dev/shm, which the trackers remove when the last worker has exited.  A Dask worker the
sweep started directly starts the same watch with its first task (:func:`indexed_call`).  What a ``kill -9`` of the whole process group leaves
in /dev/shm (nobody is left to remove it) the next loky sweep removes
(:func:`remove_orphaned_shm`).
"""

from __future__ import annotations

import os
import re
import shutil
import threading
import time
import warnings
from abc import ABC, abstractmethod
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..errors import InputError

THREAD_VARS = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
BACKENDS = ("loky", "dask")


def cores() -> int:
    """CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def jobs_warning(jobs: int) -> str | None:
    """The warning for ``--jobs`` above the cores here (the workers share them), else None."""
    n = cores()
    return f"warning: --jobs {jobs} is more than the {n} cores here; the workers will share them" if jobs > n else None


BLAS_VARS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")  # what BLAS and OpenMP read at load


def user_threads() -> int | None:
    """The BLAS/OpenMP threads the environment asks for (the first of :data:`BLAS_VARS` set to a
    positive integer; the user's own setting, or the cap :func:`cap_blas_threads` put there), None
    when none is set."""
    for var in BLAS_VARS:
        try:
            n = int(os.environ.get(var, ""))
        except ValueError:
            continue
        if n >= 1:
            return n
    return None


def cap_blas_threads() -> None:
    """One BLAS/OpenMP thread for this process and its children, unless the user set any of
    :data:`BLAS_VARS` (then their setting stands, whole).  Effective only before numpy loads
    BLAS (the command line calls it first): OpenBLAS then starts no thread pool, whose threads
    cost ~0.1 CPU-s of every process here without computing anything, and the fits' small
    least-squares problems run on one thread as in the workers (:func:`one_thread`)."""
    if not any(var in os.environ for var in BLAS_VARS):
        for var in BLAS_VARS:
            os.environ[var] = "1"


@contextmanager
def one_thread(threads: int | None = None):
    """While the block runs, the BLAS and OpenMP pools loaded in this process use ``threads``
    threads (threadpoolctl; None: the environment's :func:`user_threads`, else 1); restored
    afterwards.  A process's BLAS starts as many threads as there are cores: a serial fit on
    them spent 5.6-22x the CPU for the same table.  (numba's own pool is left alone: no kernel
    here is parallel, and starting the pool to size it would fix its size for the process.)"""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=threads or user_threads() or 1):
        yield


def cap_threads() -> None:
    """One numba/BLAS thread per process unless the user chose otherwise."""
    for var in THREAD_VARS:
        os.environ.setdefault(var, "1")


PARENT_POLL_S = 0.5  # [s] how often a worker checks that the sweep that started it is alive
_watching: list = []  # the parent pid this process watches (at most one watchdog per process)


def watch_parent(sweep_pid: int) -> bool:
    """In a worker process started by the sweep process ``sweep_pid`` (its parent): start, once,
    a daemon thread that ends this process when the parent is gone (the worker is re-parented,
    ``os.getppid()`` changes).  Does nothing in the sweep process itself (serial launcher, an
    in-process Dask cluster) or in a process the sweep did not start directly (a Dask nanny's
    worker, a remote cluster).  Returns whether a watchdog runs in this process."""
    if _watching or os.getpid() == sweep_pid or os.getppid() != sweep_pid:
        return bool(_watching)
    _watching.append(sweep_pid)

    def watch() -> None:
        while os.getppid() == sweep_pid:
            time.sleep(PARENT_POLL_S)
        os._exit(1)  # the sweep is gone: nobody will read this worker's results

    threading.Thread(target=watch, name="vetica-parent-watch", daemon=True).start()
    return True


def worker_init(sweep_pid: int) -> None:
    """The loky pool's initializer: runs in every worker as it starts, before its first task.
    A loky worker is a child of the sweep process ``sweep_pid``; if it has already been
    re-parented, the sweep died while the worker was starting and the worker exits at once,
    else it watches the sweep (:func:`watch_parent`)."""
    if os.getppid() != sweep_pid:
        os._exit(1)
    watch_parent(sweep_pid)


SHM = Path("/dev/shm")  # where loky's named semaphores and joblib's memmapping folders live (Linux)
_SHM_OWNED = (re.compile(r"^sem\.loky-(\d+)-"), re.compile(r"^joblib_memmapping_folder_(\d+)_"))


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def remove_orphaned_shm(shm: Path = SHM) -> int:
    """Remove loky's semaphores and joblib's memmapping folders in ``shm`` whose creating
    process (the pid in the name) is gone and that belong to this user: what a ``kill -9``
    of a whole sweep process group leaves (no resource tracker survives to remove them).
    Entries of live processes are never touched.  Returns how many were removed."""
    if not shm.is_dir():
        return 0
    removed = 0
    for entry in shm.iterdir():
        m = next((m for m in (r.match(entry.name) for r in _SHM_OWNED) if m), None)
        if m is None or _pid_alive(int(m.group(1))):
            continue
        try:
            if entry.lstat().st_uid != os.getuid():
                continue
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink()
            removed += 1
        except OSError:  # removed meanwhile, or not ours to remove
            continue
    return removed


def indexed_call(fn: Callable, i: int, arg: Any, sweep_pid: int | None = None) -> tuple[int, Any]:
    """``(i, fn(arg))``: a job that names its own place in the argument list (module level:
    joblib pickles it).  With ``sweep_pid`` the worker first makes sure it watches the sweep
    process (:func:`watch_parent`)."""
    if sweep_pid is not None:
        watch_parent(sweep_pid)
    return i, fn(arg)


class Launcher(ABC):
    """Runs a task function over a list of arguments (module docstring)."""

    @abstractmethod
    def launch(self, fn: Callable, args: list, on_result: Callable[[int, Any], None]) -> None:
        """Call ``fn(args[i])`` for every i; ``on_result(i, result)`` in this process as each finishes."""

    def close(self) -> None:
        """Release workers or the cluster connection."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


class SerialLauncher(Launcher):
    """In this process, in order, with BLAS and OpenMP capped at one thread (:func:`one_thread`:
    or the threads the user set in the environment) as in a worker (the environment variables
    of :func:`cap_threads` come too late for a process whose BLAS is loaded)."""

    def launch(self, fn, args, on_result) -> None:
        with one_thread():
            for i, a in enumerate(args):
                on_result(i, fn(a))


class _JoblibLauncher(Launcher):
    """Unordered results through a joblib backend (subclasses choose the backend)."""

    def _config(self):
        raise NotImplementedError

    def launch(self, fn, args, on_result) -> None:
        from joblib import Parallel, delayed

        if not args:
            return
        config, par_kw = self._config()
        with config:
            par = Parallel(return_as="generator_unordered", batch_size=1, **par_kw)
            me = os.getpid()
            results = par(delayed(indexed_call)(fn, i, a, me) for i, a in enumerate(args))
            try:
                for i, res in results:
                    on_result(i, res)
            except BaseException:  # Ctrl-C, SIGTERM, an error in on_result: stop the workers now
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # joblib's note on cancelled tasks: the caller reports
                    results.close()
                raise


class LokyLauncher(_JoblibLauncher):
    """``jobs`` loky worker processes, one inner thread each."""

    def __init__(self, jobs: int):
        self.jobs = jobs

    def _config(self):
        from joblib import parallel_config

        return (parallel_config(backend="loky", n_jobs=self.jobs, inner_max_num_threads=1, initializer=worker_init,
                                initargs=(os.getpid(),)), {"pre_dispatch": "n_jobs"})  # fmt: skip


class DaskLauncher(_JoblibLauncher):
    """A Dask cluster: the scheduler at ``scheduler``, or a local cluster of ``jobs``
    single-threaded worker processes.  Connects on construction."""

    def __init__(self, jobs: int, scheduler: str | None = None):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise InputError("--backend dask needs dask and distributed: pip install -e '.[dask]'") from None
        self.client = self.cluster = None
        if scheduler:
            try:
                self.client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError(f"--scheduler {scheduler!r}: cannot connect ({type(exc).__name__})") from None
        else:
            self.cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None,
                                        env={v: "1" for v in THREAD_VARS})  # fmt: skip
            self.client = Client(self.cluster)

    def _config(self):
        from joblib import parallel_config

        return parallel_config(backend="dask", n_jobs=-1, wait_for_workers_timeout=60), {}

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def check_launcher_options(backend: str = "loky", jobs: int = 2, scheduler: str | None = None) -> None:
    """InputError (one line) for a bad ``--backend``, ``--jobs`` or ``--scheduler`` combination."""
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InputError(f"--jobs {jobs}: expected an integer >= 1")
    if backend not in BACKENDS:
        raise InputError(f"--backend {backend!r} is not allowed; expected loky or dask")
    if scheduler and backend != "dask":
        raise InputError("--scheduler needs --backend dask")


def make_launcher(backend: str = "loky", jobs: int = 2, scheduler: str | None = None) -> Launcher:
    """The launcher for the CLI's ``--backend``, ``--jobs`` and ``--scheduler``; InputError
    (one line) for a bad combination or an unreachable scheduler."""
    check_launcher_options(backend, jobs, scheduler)
    cap_threads()
    if backend == "dask":
        return DaskLauncher(jobs, scheduler)
    return SerialLauncher() if jobs == 1 else LokyLauncher(jobs)
