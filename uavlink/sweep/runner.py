"""The client side of a sweep: skip finished jobs, run the rest on Dask, write what comes back.

With no address it starts an embedded ``LocalCluster``: one worker process per core, one thread
each (jobs pin torch to one thread too). ``scheduler="tcp://HOST:8786"`` uses an existing cluster
(``dask scheduler`` + ``dask worker``, or dask-jobqueue / dask-kubernetes). Workers return policy
bytes and figures; only this process writes ``runs/<sweep>/``, so no shared filesystem is needed.

Fault handling is Dask's: a job whose worker dies is rescheduled on another worker (the scheduler's
``distributed.scheduler.allowed-failures``, 3 by default), and a job that raises is retried
``retries`` times. Ctrl-C cancels what is left, keeps every finished job, and a rerun picks up.
``workers=0`` runs the jobs in this process one after another, without Dask (debugging, baselines).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import signal
import sys
import time
import traceback
import warnings
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from uavlink.errors import require
from uavlink.sweep.jobs import result_path, run_job, write_job
from uavlink.sweep.spec import Job, SweepSpec

if TYPE_CHECKING:
    from dask.typing import Key

# The embedded cluster's settings: one job per worker at a time (none waits behind a long one);
# no statistical profiler (its 10 ms stack sampling takes the GIL from the job's thread); and
# glibc's own malloc trimming: Dask's MALLOC_TRIM_THRESHOLD_=65536 also turns off glibc's dynamic
# mmap threshold, so every large numpy temporary becomes an mmap + page faults (~8 % slower jobs).
LOCAL_CLUSTER_CONFIG = {
    "distributed.scheduler.worker-saturation": 1.0,
    "distributed.worker.profile.enabled": False,
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
}

# The embedded cluster's dashboard listens on loopback only (as its scheduler does): Dask's default
# serves it on every interface, a field laptop's network included.
DASHBOARD_ADDRESS = "127.0.0.1:8787"


class EngineError(RuntimeError):
    """The engine could not start (scheduler malformed or unreachable); one-line message. A missing
    Dask is ``require``'s UserError, with its install line."""


@dataclass
class SweepOutcome:
    sweep_dir: Path
    jobs: int
    skipped: int
    finished: int = 0
    failed: dict[str, str] = field(default_factory=dict)
    interrupted: bool = False
    wall_s: float = 0.0
    engine: str = ""
    job_s: list[float] = field(default_factory=list)  # each finished job's own time, on its worker
    cpu_s: list[float] = field(default_factory=list)  # and its process CPU time
    written: set[str] = field(default_factory=set)  # job folders written by this run


def plan(
    spec: SweepSpec, out_root: Path, done_keys: Collection[str] = ()
) -> tuple[Path, list[Job], list[Job]]:
    """(sweep folder, all jobs, jobs without a result.json whose key is not in ``done_keys``);
    writes nothing."""
    sweep_dir = out_root / spec.name
    jobs = spec.jobs()
    pending = [
        j for j in jobs if j.key not in done_keys and not result_path(sweep_dir, j).is_file()
    ]
    return sweep_dir, jobs, pending


def record_plan(spec: SweepSpec, sweep_dir: Path, jobs: list[Job]) -> None:
    """Make the sweep folder and record the sweep file and its job list in it."""
    sweep_dir.mkdir(parents=True, exist_ok=True)
    if spec.source is not None and spec.source.resolve() != (sweep_dir / "sweep.toml").resolve():
        shutil.copyfile(spec.source, sweep_dir / "sweep.toml")
    listing = [
        {"key": j.key, "name": j.name, "scenario": j.scenario, "seed": j.seed, "point": j.point}
        for j in jobs
    ]
    (sweep_dir / "jobs.json").write_text(json.dumps(listing, indent=1) + "\n")


def run_sweep(
    spec: SweepSpec,
    out_root: Path,
    scheduler: str | None = None,
    workers: int | None = None,
    retries: int = 2,
    progress: bool = True,
    log: Callable[[str], None] = lambda msg: print(msg, file=sys.stderr),
    done_keys: Collection[str] = (),
) -> SweepOutcome:
    """Run every job of ``spec`` that has no result yet (in ``out_root`` or, by key, in ``done_keys``:
    a shipped sweep record's jobs); returns what happened. Nothing is written before the engine
    runs: a scheduler that cannot be reached leaves no sweep folder behind."""
    start = time.perf_counter()
    if scheduler and workers != 0:
        _check_address(scheduler)
    sweep_dir, jobs, pending = plan(spec, out_root, done_keys)
    outcome = SweepOutcome(sweep_dir, len(jobs), len(jobs) - len(pending))

    def begin() -> None:
        record_plan(spec, sweep_dir, jobs)
        log(
            f"sweep {spec.name}: {len(jobs)} jobs, {outcome.skipped} already done, {len(pending)} to run "
            f"-> {sweep_dir}"
        )

    if pending and workers != 0:
        _run_on_dask(pending, sweep_dir, outcome, scheduler, workers, retries, progress, log, begin)
    else:
        begin()
        if pending:
            _run_in_process(pending, sweep_dir, outcome, progress, log)
    outcome.wall_s = time.perf_counter() - start
    return outcome


def _check_address(scheduler: str) -> None:
    """A malformed scheduler address fails here, in one line: ``Client`` raises deep inside and its
    half-built instance then waits in ``__del__`` for a connection that never was."""
    require("distributed")
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(scheduler)
        if scheme in ("tcp", "tls"):
            parse_host_port(location)
    except ValueError as exc:
        raise EngineError(
            f"--scheduler {scheduler!r} is not a Dask address ({exc}); e.g. tcp://HOST:8786"
        ) from None


def _run_in_process(
    pending: list[Job],
    sweep_dir: Path,
    outcome: SweepOutcome,
    progress: bool,
    log: Callable[[str], None],
) -> None:
    outcome.engine = "in-process, sequential"
    bar = _bar(len(pending), progress)
    done_line = _done_lines(bar, progress, len(pending), log)
    try:
        for job in pending:
            bar.set_postfix_str(f"running {job.name}")
            try:
                payload = run_job(job.to_dict(), str(sweep_dir.resolve()))
            except Exception as exc:  # noqa: BLE001 - a failed job must not stop the sweep
                _record_failure(sweep_dir, job, exc, traceback.format_exc(), outcome, bar)
            else:
                _record_success(sweep_dir, payload, outcome)
                done_line(outcome, payload)
            bar.update(1)
    except KeyboardInterrupt:
        outcome.interrupted = True
    finally:
        bar.close()


def _run_on_dask(
    pending: list[Job],
    sweep_dir: Path,
    outcome: SweepOutcome,
    scheduler: str | None,
    workers: int | None,
    retries: int,
    progress: bool,
    log: Callable[[str], None],
    begin: Callable[[], None],
) -> None:
    """The jobs on Dask; ``begin`` runs once the engine is up (and never when it cannot start)."""
    require("distributed")
    import dask
    from distributed import Client, LocalCluster, as_completed

    cluster = None
    try:
        if scheduler:
            try:
                client = Client(scheduler, timeout="20s", set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise EngineError(
                    f"cannot reach the Dask scheduler at {scheduler} ({exc})"
                ) from None
            outcome.engine = f"scheduler {scheduler}"
            with contextlib.suppress(TimeoutError):
                client.wait_for_workers(1, timeout=30)
        else:
            n = workers or os.cpu_count() or 1
            # Workers inherit an ignored SIGINT, so Ctrl-C reaches this process only and it shuts
            # the cluster down in order.
            previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
            try:
                # A busy dashboard port (another sweep's) moves to a free one; the dashboard line
                # below names it, so distributed's warning about the move is noise.
                with dask.config.set(LOCAL_CLUSTER_CONFIG), warnings.catch_warnings():
                    warnings.filterwarnings("ignore", message="Port .* is already in use")
                    cluster = LocalCluster(
                        n_workers=n,
                        threads_per_worker=1,
                        processes=True,
                        dashboard_address=DASHBOARD_ADDRESS,
                        silence_logs=logging.CRITICAL,
                    )  # failures: ours
            finally:
                signal.signal(signal.SIGINT, previous)
            client = Client(cluster, set_as_default=False)
            outcome.engine = f"local cluster, {n} worker process{'es' if n > 1 else ''} x 1 thread"
    except KeyboardInterrupt:
        if cluster is not None:
            cluster.close()
        outcome.interrupted = True
        begin()  # the sweep's folder, for the summary of nothing done
        return
    begin()
    info = client.scheduler_info()
    log(f"engine: {outcome.engine} ({len(info.get('workers', {}))} workers connected)")
    if "dashboard" in info.get("services", {}):
        import importlib.util

        hint = (
            ""
            if scheduler or importlib.util.find_spec("bokeh")
            else " (pip install bokeh for its pages)"
        )
        log(f"dashboard: {client.dashboard_link}{hint}")

    # The local cluster's workers write the sweep's folder; a remote scheduler's may not see it.
    snapshots = None if scheduler else str(sweep_dir.resolve())
    by_key: dict[Key, Job] = {}
    futures = []
    bar = _bar(len(pending), progress)
    done_line = _done_lines(bar, progress, len(pending), log)
    try:
        for job in pending:
            future = client.submit(
                run_job,
                job.to_dict(),
                snapshots,
                key=f"uavlink-sweep-{job.key}",
                pure=False,
                retries=retries,
            )
            by_key[future.key] = job
            futures.append(future)
        queue = as_completed(futures, loop=client.loop)
        remaining = set(futures)
        last_poll = 0.0
        while not queue.is_empty():
            batch = queue.next_batch(block=False)
            for future in batch:
                payload = _collect(future, by_key[future.key], sweep_dir, outcome, bar)
                if payload is not None:
                    done_line(outcome, payload)
                remaining.discard(future)
                bar.update(1)
            if time.monotonic() - last_poll > 1.0 or batch:
                last_poll = time.monotonic()
                running = _running(client, remaining)
                bar.set_postfix_str(f"running {running}, failed {len(outcome.failed)}")
            if not batch:
                time.sleep(0.05)
    except KeyboardInterrupt:
        outcome.interrupted = True
        for future in futures:  # keep what finished before the key was pressed
            if future.status == "finished" and by_key[future.key].name not in outcome.written:
                with contextlib.suppress(Exception):
                    _collect(future, by_key[future.key], sweep_dir, outcome, bar)
        with contextlib.suppress(Exception):
            client.cancel([f for f in futures if f.status == "pending"], force=True)
    finally:
        bar.close()
        with contextlib.suppress(Exception):
            client.close(timeout=10)
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=10)


def _collect(
    future: Any, job: Job, sweep_dir: Path, outcome: SweepOutcome, bar: Any
) -> dict[str, Any] | None:
    """Record a settled future's job; its result's payload if it finished, else None."""
    payload = None
    if future.status == "finished":
        try:
            payload = future.result()
        except Exception as exc:  # noqa: BLE001 - lost between status and fetch
            _record_failure(sweep_dir, job, exc, "", outcome, bar)
        else:
            _record_success(sweep_dir, payload, outcome)
    else:
        error = (
            future.exception() if future.status == "error" else RuntimeError(f"job {future.status}")
        )
        tb = "".join(traceback.format_tb(future.traceback())) if future.status == "error" else ""
        _record_failure(sweep_dir, job, error, tb, outcome, bar)
    future.release()
    return payload


def _record_success(sweep_dir: Path, payload: dict[str, Any], outcome: SweepOutcome) -> None:
    write_job(sweep_dir, payload)
    (sweep_dir / f"{payload['name']}.error.txt").unlink(missing_ok=True)
    outcome.finished += 1
    outcome.job_s.append(payload["timing"]["job_s"])
    outcome.cpu_s.append(payload["timing"]["cpu_s"])
    outcome.failed.pop(payload["name"], None)
    outcome.written.add(payload["name"])


def _record_failure(
    sweep_dir: Path, job: Job, exc: BaseException, tb: str, outcome: SweepOutcome, bar: Any
) -> None:
    line = f"{type(exc).__name__}: {exc}".splitlines()[0]
    outcome.failed[job.name] = line
    (sweep_dir / f"{job.name}.error.txt").write_text(f"{line}\n\n{tb}")
    bar.write(f"job {job.name} failed: {line} (details in {sweep_dir / (job.name + '.error.txt')})")


def _running(client: Any, remaining: set[Any]) -> int:
    """Jobs executing now: per worker, its assigned jobs up to its thread count."""
    keys = {f.key for f in remaining}
    try:
        processing = client.processing()
        threads = client.nthreads()
    except Exception:  # noqa: BLE001 - the count is cosmetic
        return 0
    return sum(
        min(sum(1 for k in tasks if k in keys), threads.get(w, 1))
        for w, tasks in processing.items()
    )


def _done_lines(
    bar: Any, progress: bool, total: int, log: Callable[[str], None]
) -> Callable[[SweepOutcome, dict[str, Any]], None]:
    """Where no bar shows (stderr is a log or a pipe) a long sweep would be silent for hours: one
    line per finished job there instead, with its PPO figure; nothing with ``progress`` off."""

    def done_line(outcome: SweepOutcome, payload: dict[str, Any]) -> None:
        if not progress or not bar.disable:
            return
        ppo = payload["evaluation"]["ppo"]
        log(
            f"job {payload['name']} done ({outcome.finished}/{total}): PPO {ppo['mean_rate_mbps']:.3f}"
            f" Mbps on {ppo['episodes']} episodes of seed {ppo['seed']}, "
            f"{payload['timing']['job_s'] / 60:.1f} min"
        )

    return done_line


def _bar(total: int, progress: bool) -> Any:
    from tqdm.auto import tqdm

    # disable=None: no bar when stderr is not a terminal (logs, pipes, CI)
    return tqdm(
        total=total,
        unit="job",
        disable=None if progress else True,
        dynamic_ncols=True,
        file=sys.stderr,
        bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} done [{elapsed}<{remaining}] {postfix}",
    )
