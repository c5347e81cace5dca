"""Run many independent cases on dask.distributed (frequency sweeps, parameter studies).

By default a local cluster sized to the cores, one single-threaded worker process per core
(Taichi threads capped at 1 so that workers do not fight for cores); with ``scheduler`` an existing
cluster is used with the same code (``dask scheduler`` / ``dask worker`` started by the user).
A failed case never stops the others: its record carries ``status: "failed"`` and the error.

Draining: with ``drain`` (a check, e.g. :func:`drain_file_check`: "does OUT/DRAIN exist?") the
cases are handed to the cluster no faster than it has threads, and once the check says yes no
further case starts: the runs in flight finish and are kept, then :class:`Drained` names the cases
that never started.  It ends a long study at a chosen moment without losing the runs in flight.
A signal (SIGTERM: stop now) loses what they did since their last checkpoint (at most
dem.run.write.CHECKPOINT_SECONDS, or a batch's paced interval: dem.run.write.CheckpointPace):
the next batch into the same directories resumes them from it
(dem.run.resume), or starts them over where they cannot resume.

Each case writes its own output directory (summary.json, frames.npz, ...) under ``out_root``.

Batched (``batch`` K): on a GPU the cases are packed K to an engine (the last group smaller)
and each group is one task, one process (dem.run.batched: K scenes in one Taichi engine, each
point written into its own directory exactly as a lone run); dask spreads the groups over the
workers.  On the CPU each case runs alone, as without ``batch``
(dem.run.batched.engine_groups: an engine of K on one single-threaded worker steps its scenes
more slowly than K lone engines, and leaves the other workers idle), except with
``DEM_DEVICE_ARRAYS=1``, the CPU proxy of a GPU batch (K to an engine, as on a GPU).
A failed point never ends its batch-mates; the records stay one per case.  ``arch``: Taichi's
arch of the tasks, "cpu" or "cuda" (with cuda and no ``n_workers``, one local worker: the GPU is
one device).
"""

from __future__ import annotations

import os
import time
import traceback
from pathlib import Path
from typing import Callable

from dem.case import Case


class Drained(Exception):
    """The drain check said stop: the runs in flight finished, ``not_started`` (names) never
    began.  Their records were passed to ``on_done`` like any other."""

    def __init__(self, not_started: list[str]):
        super().__init__(f"drained: {len(not_started)} case(s) not started")
        self.not_started = not_started


DRAIN_FILE = "DRAIN"
# seconds to wait for a dask scheduler's port to answer before calling it unreachable (a
# scheduler on the same network answers in milliseconds; dask's own wait is 30 s)
SCHEDULER_CONNECT_SECONDS = 5.0


class SchedulerUnreachable(ValueError):
    """``--scheduler`` names an address where no scheduler answers (bad input: exit code 2)."""


def check_scheduler(address: str, timeout: float = SCHEDULER_CONNECT_SECONDS) -> None:
    """Raise SchedulerUnreachable unless a TCP connection to the scheduler's address opens within
    ``timeout`` s: checked before a sweep or an ensemble writes anything.  Addresses as dask
    takes them: tcp://HOST:PORT or HOST:PORT (port 8786 when none is given)."""
    import socket
    from urllib.parse import urlsplit

    text = address if "://" in address else f"tcp://{address}"
    try:
        parts = urlsplit(text)
        host, port = parts.hostname, parts.port or 8786
    except ValueError as err:
        raise SchedulerUnreachable(f"--scheduler {address}: not an address ({err}); give "
                                   f"tcp://HOST:PORT") from None
    if parts.scheme not in ("tcp", "tls") or not host:
        raise SchedulerUnreachable(f"--scheduler {address}: not an address; give "
                                   f"tcp://HOST:PORT")
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as err:
        why = err.strerror or ("no answer" if isinstance(err, TimeoutError) else
                               type(err).__name__)
        raise SchedulerUnreachable(
            f"--scheduler {address}: no scheduler answers there ({why}, waited up to "
            f"{timeout:g} s); start one with `dask scheduler`, or leave --scheduler out for a "
            f"local cluster") from None
    # something answers: it must speak dask's protocol (a wrong port may hold another server)
    from dask.distributed import Client

    try:
        Client(address, timeout=timeout).close()
    except Exception as err:  # noqa: BLE001 - whatever the handshake raises, the address is bad
        raise SchedulerUnreachable(
            f"--scheduler {address}: what answers there is not a dask scheduler "
            f"({type(err).__name__}); check the address and port") from None


def drain_file_check(path: Path) -> Callable[[], bool]:
    """The drain check of a file: True once ``path`` exists (``touch OUT/DRAIN``)."""
    path = Path(path)
    return path.exists


def clear_drain_file(path: Path, say=None) -> None:
    """Remove a drain file left by an earlier stop, so that a new start is not drained at once."""
    path = Path(path)
    if path.exists():
        path.unlink()
        if say is not None:
            say(f"removed {path}, left by an earlier drain")


def _run_one(name: str, case_json: str, out_dir: str, threads: int, max_steps: int | None,
             post: Callable | None, analyses: tuple = ()) -> dict:
    """Task body (runs on a worker): simulate one case, return its summary (or the error)."""
    os.environ.setdefault("DEM_THREADS", str(threads))
    from dem import ti_runtime

    ti_runtime.init(threads=threads)
    from dem.run import run_case

    from dem.rundir import claim

    t0 = time.perf_counter()
    case = Case.model_validate_json(case_json)
    rd = None
    try:
        # the point's own directory: a lock against a second sweep writing into it; an
        # unfinished earlier attempt goes on from its restart point (dem.run.resume), or its
        # leftovers are cleared (the sweep owns its point dirs)
        rd = claim(out_dir, case.model_dump_json(indent=1), force=True, what="point",
                   resume=True)
        res = run_case(case, out_dir, progress=False, max_steps=max_steps, analyses=analyses,
                       resume=True)
        record = {"name": name, "status": "ok", "out_dir": out_dir, "summary": res.summary}
        if post is not None:
            record["post"] = post(case, res, out_dir)
        return record
    except Exception as err:  # noqa: BLE001 - a failed point is reported, never fatal
        return {"name": name, "status": "failed", "out_dir": out_dir,
                "error": f"{type(err).__name__}: {err}", "traceback": traceback.format_exc(),
                "wall_seconds": time.perf_counter() - t0}
    finally:
        if rd is not None:
            rd.release()


def _run_group(names: list[str], case_jsons: list[str], out_dirs: list[str], threads: int,
               max_steps: int | None, post: Callable | None, analyses: tuple = (),
               arch: str = "cpu") -> list[dict]:
    """Task body of a group (runs on a worker): the cases in one engine
    (dem.run.batched.run_cases_in_one_engine), one record per case; a group that cannot start
    (cases that cannot share an engine, no CUDA) gives every case a failed record."""
    os.environ.setdefault("DEM_THREADS", str(threads))
    t0 = time.perf_counter()
    try:
        from dem.run.batched import run_cases_in_one_engine

        cases = [(n, Case.model_validate_json(j)) for n, j in zip(names, case_jsons)]
        return run_cases_in_one_engine(cases, out_dirs, max_steps=max_steps, analyses=analyses,
                                       resume=True, arch=arch, post=post, threads=threads)
    except Exception as err:  # noqa: BLE001 - a failed group is reported, never fatal
        tb = traceback.format_exc()
        return [{"name": n, "status": "failed", "out_dir": d,
                 "error": f"{type(err).__name__}: {err}", "traceback": tb,
                 "wall_seconds": time.perf_counter() - t0} for n, d in zip(names, out_dirs)]


def run_batch(cases: list[tuple[str, Case]], out_root: str | Path, scheduler: str | None = None,
              n_workers: int | None = None, max_steps: int | None = None,
              post: Callable | None = None, on_done: Callable[[dict], None] | None = None,
              analyses: tuple = (), drain: Callable[[], bool] | None = None,
              batch: int | None = None, arch: str = "cpu") -> list[dict]:
    """Run (name, case) pairs; returns one record per case, in the order given.

    batch: pack the cases K to an engine on a GPU, one task per group; on the CPU ignored, one
    case per task (module docstring); None: one case per task, each in an engine of its own
    (with ``arch`` "cpu": today's path, dem.run).
    arch: "cpu" or "cuda" (Taichi's arch of every task).

    analyses: handed to dem.run.run_case (functions merged into each run's summary.json, e.g.
    dem_cli.commands.run.RUN_ANALYSES; module-level functions, so that they pickle to the workers).

    post(case, RunResult, out_dir) -> dict runs on the worker after a successful run (keep its
    result small: it travels back to the client).  on_done(record) is called on the client as
    each case finishes (progress reporting).  drain() -> bool: checked before each case is handed
    to the cluster; once True nothing more starts and, after the runs in flight, :class:`Drained`
    is raised (module docstring).  Without it every case is handed over at once.
    """
    from dask.distributed import Client, LocalCluster, as_completed

    out_root = Path(out_root)
    out_root.mkdir(parents=True, exist_ok=True)
    if batch is not None and batch < 1:
        raise ValueError(f"--batch must be >= 1, got {batch}")
    # the tasks: lists of indices into cases, dem.run.batched.engine_groups: K in order on a
    # GPU or on the CPU proxy of one (DEM_DEVICE_ARRAYS=1), each a group task; on the CPU one
    # case each, a plain run as without --batch (dem.run)
    proxy = os.environ.get("DEM_DEVICE_ARRAYS") == "1"
    grouped = arch != "cpu" or (batch is not None and proxy)
    if batch is not None or arch != "cpu":
        from dem.run.batched import engine_groups

        groups = engine_groups(len(cases), batch or 1, arch, device_arrays=proxy)
    else:
        groups = [[i] for i in range(len(cases))]
    cluster = None
    if scheduler is None:
        n_workers = n_workers or (1 if arch == "cuda" else None) or os.cpu_count() or 1
        # the worker processes inherit DEM_THREADS=1 (one Taichi thread each); the calling
        # process gets its own setting back, so a later Taichi start here is unaffected
        saved = os.environ.get("DEM_THREADS")
        os.environ["DEM_THREADS"] = "1"
        try:
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
        finally:
            if saved is None:
                os.environ.pop("DEM_THREADS", None)
            else:
                os.environ["DEM_THREADS"] = saved
        client = Client(cluster)
    else:
        client = Client(scheduler)
        if drain is not None:
            client.wait_for_workers(1)  # their threads set how many cases are handed over
    try:
        def free_threads() -> int:
            if drain is None:
                return len(groups)
            return max(1, sum(client.nthreads().values())) - len(futures)

        futures = {}
        waiting = list(range(len(groups)))
        done = as_completed()
        drained = False

        def submit(j: int):
            idx = groups[j]
            if not grouped:
                name, case = cases[idx[0]]
                return client.submit(_run_one, name, case.model_dump_json(),
                                     str(out_root / name), 1, max_steps, post, tuple(analyses),
                                     key=f"dem-{idx[0]}-{name}", pure=False)
            names = [cases[i][0] for i in idx]
            return client.submit(_run_group, names, [cases[i][1].model_dump_json() for i in idx],
                                 [str(out_root / n) for n in names], 1, max_steps, post,
                                 tuple(analyses), arch, key=f"dem-group-{j}-{names[0]}",
                                 pure=False)

        def hand_over() -> None:
            nonlocal drained
            while waiting and not drained and free_threads() > 0:
                if drain is not None and drain():
                    drained = True
                    break
                j = waiting.pop(0)
                fut = submit(j)
                futures[fut] = j
                done.add(fut)

        hand_over()
        records: list[dict | None] = [None] * len(cases)
        for fut in done:
            j = futures.pop(fut)
            idx = groups[j]
            try:
                recs = fut.result()
                recs = recs if grouped else [recs]
            except Exception as err:  # noqa: BLE001 - worker died: still report the points
                recs = [{"name": cases[i][0], "status": "failed",
                         "error": f"{type(err).__name__}: {err}"} for i in idx]
            for i, rec in zip(idx, recs):
                records[i] = rec
                if on_done is not None:
                    on_done(rec)
            hand_over()
        if waiting:
            raise Drained([cases[i][0] for j in waiting for i in groups[j]])
        return records
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_one(name: str, case_json: str, out_dir: str, threads: int, max_steps: int | None,
            post: Callable | None = None, analyses: tuple = ()) -> dict:
    """One point's task body outside dask (studies.prediction.pool runs it in a process of its
    own): simulate the case into ``out_dir`` (resuming an unfinished attempt) and return its
    record, as a dask worker does."""
    return _run_one(name, case_json, out_dir, threads, max_steps, post, analyses)
