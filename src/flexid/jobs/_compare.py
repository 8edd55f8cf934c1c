"""Compare optimisers on identical plants: same data, same initial populations, same budgets.

:func:`compare` runs every optimiser of a :class:`~flexid.config.ComparisonSpec` for
``runs`` seeds.  Run ``r`` of every optimiser uses the same seed (spawned from the
comparison seed with ``numpy.random.SeedSequence``), hence the same initial population, and
the same FE budget.  Least squares, the exact optimum of the one-step cost, is the reference
row.  Every finished run is written at once to a :class:`~flexid.jobs.store.ResultStore`; a rerun
skips finished runs, so a comparison killed part-way resumes.  Runs execute serially, in
worker processes (``workers``) or on a dask.distributed cluster (``scheduler``); the numbers do
not depend on where they ran.

An optimiser cannot end or hang a comparison: whatever it raises (``SystemExit`` too, not
``KeyboardInterrupt``) is a failed run with its reason; in worker processes, a run that kills
its process is a failed run and the process is replaced, and a run longer than
``run_timeout`` seconds is ended (its process killed and replaced) and recorded as failed.
With one worker and a time limit, each run is done in a child process, the only way to end a
Python function that never returns.  Serially without a limit, the runs of an optimiser that
is not trusted (a plugin's, see :func:`~flexid.optimisers.registry.is_trusted`) are done in
a child process too, after the others: one that ends its process is a failed run.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import signal
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from multiprocessing import get_context, parent_process
from multiprocessing.connection import wait
from pathlib import Path
from typing import Any

import numpy as np

from .. import kernels
from .._validate import checked_keywords, positive_int
from ..data.records import IOData, prepare_data, split_parts
from ..errors import ConfigError, ModelOrderError
from ..fit.estimation import build_problem, check_search, structure_of
from ..models.families import family_named, family_of
from ..models.vocabulary import GREYBOX, LEAST_SQUARES
from ..optimisers import Budget, get, minimize
from ..optimisers.registry import is_trusted
from ..validation.verdict import between_outputs, joint_tests
from ._comparison_result import ComparisonResult, _f
from .specs import ComparisonSpec, OptimiserSpec, _check_run_timeout
from .store import ResultStore

__all__ = [
    "ComparisonResult",
    "build_data",
    "check_spec",
    "compare",
    "frequency_views",
    "load_result",
    "run_seed",
]


# ================================================================================ context
def run_seed(comparison_seed: int, run: int) -> int:
    """Seed of run ``run``: child ``run`` of ``SeedSequence(comparison_seed)``, as an int.

    It does not depend on the number of runs, so adding runs keeps the earlier ones.
    """
    child = np.random.SeedSequence(comparison_seed, spawn_key=(run,))
    return int(child.generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))


def build_data(spec: ComparisonSpec) -> IOData | list[IOData]:
    """The record of a comparison: simulated from the plant, or read from the file (a list
    of records when ``[data] file`` lists several)."""
    d = spec.data
    if d.file is not None:
        from ..data.records import load

        options = _file_options(d)
        if isinstance(d.file, list):
            return [load(f, **options) for f in d.file]
        return load(d.file, **options)
    from ..data.datasets import generate

    options: dict[str, Any] = {"seed": d.seed}
    for key in ("preset", "signal", "n_samples", "noise_std"):
        value = getattr(d, key)
        if value is not None:
            options[key] = value
    if d.signal_options:
        options["signal_options"] = dict(d.signal_options)
    if d.plant_params:
        options["plant_params"] = dict(d.plant_params)
    if d.outputs is not None:
        options["outputs"] = d.outputs
    return generate(d.plant, sensors=d.sensors, **options)


def _file_options(d: Any) -> dict[str, Any]:
    """The reading options of ``[data]``'s files."""
    pairs = (("inputs", d.inputs), ("outputs", d.outputs), ("dt", d.dt))
    return {k: v for k, v in pairs if v is not None}


def _records_digest(records: list[IOData]) -> str:
    """SHA-256 of several records' digests in order (one record: its own digest)."""
    if len(records) == 1:
        return _record_digest(records[0])
    joined = ",".join(_record_digest(r) for r in records)
    return hashlib.sha256(joined.encode()).hexdigest()


def _record_digest(data: IOData) -> str:
    """SHA-256 of a record's numbers: its samples, sample time and channel names.

    Parameters
    ----------
    data : IOData
        The record as read.

    Returns
    -------
    str
        64 hexadecimal digits; equal for two records exactly when their inputs and outputs
        (as little-endian float64), sample times and channel names are.
    """
    head = {
        "dt": float(data.dt).hex(),
        "inputs": list(data.input_names),
        "outputs": list(data.output_names),
        "u": list(data.u.shape),
        "y": list(data.y.shape),
    }
    h = hashlib.sha256(json.dumps(head, sort_keys=True).encode())
    h.update(np.ascontiguousarray(data.u, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(data.y, dtype="<f8").tobytes())
    return h.hexdigest()


class _Context:
    """What every run of a comparison shares: records, structure, cost, box."""

    def __init__(
        self, spec: ComparisonSpec, est: IOData | tuple[IOData, ...], val: IOData
    ) -> None:
        self.spec = spec
        self.est = est
        self.val = val
        #: the estimation records (one, or several fitted together)
        self.records = est if isinstance(est, tuple) else (est,)
        self.dt = self.records[0].dt
        m = spec.model
        try:
            if m.structure == GREYBOX:  # the spec names a model, not orders
                self.structure = m.greybox_model()
            else:
                first = self.records[0]
                self.structure = structure_of(m.structure, first.n_inputs, first.n_outputs,
                                              **m.orders())  # fmt: skip
        except ModelOrderError as exc:
            raise ConfigError(f"[model]: {exc}") from None
        #: the structure's family, which every model-specific step of a run asks
        self.family = family_of(self.structure)
        for record in (*self.records, val):
            self.structure.check_samples(record.n_samples)
        self.estimation = build_problem(
            est, self.structure, spec.cost, spec.search, bounds=spec.bounds
        )
        if len(self.records) > 1:
            self.structure = self.estimation.structure  # ARX: the polynomial family's there
        if not np.isfinite(self.theta_ls).all():  # the start row every comparison has
            raise ConfigError(
                f"[model]: {self.structure!r} has no finite start "
                f"({self.family.start_name(self.structure)}): "
                + ("give every input the same nf (its F polynomials differ in order)"
                   if m.structure in ("oe", "bj") else "give it other orders")
            )

    @property
    def theta_ls(self) -> np.ndarray:
        """Least-squares estimate, shape (n_params,)."""
        return self.estimation.theta_ls

    @classmethod
    def from_spec(cls, spec: ComparisonSpec) -> _Context:
        d = spec.data
        record = build_data(spec)
        validation = None
        if d.validation is not None:
            from ..data.records import load

            validation = load(d.validation, **_file_options(d))
        if d.file is not None:
            # a file's path does not say which numbers it held: its digest goes into the key,
            # so runs on an edited file never join the runs on what it held before
            records = record if isinstance(record, list) else [record]
            every = [*records, *([validation] if validation is not None else [])]
            d = replace(d, digest=_records_digest(every))
            spec = replace(spec, data=d)
        if spec.model.structure == GREYBOX:
            # a grey-box model reads its own channels, and is validated by running on from
            # the record's start: its "validation record" is the whole record
            if d.validation is not None or isinstance(d.file, list):
                raise ConfigError(
                    "[data] validation or several files: a grey-box comparison runs on one "
                    "record from its start"
                )
            if d.detrend:
                raise ConfigError("[data] detrend: a grey-box model's physics see the raw record")
            if isinstance(d.split, (str, list, tuple)):
                raise ConfigError(
                    "[data] split: a grey-box comparison splits at one sample (a fraction or "
                    "an index): its validation runs on from the record's start"
                )
            return cls(spec, split_parts(record, d.split)[0], record)
        several = family_named(spec.model.structure).several_outputs
        est, val = prepare_data(record, output=d.output, split=d.split, detrend=d.detrend,
                                validation=validation, several=several)  # fmt: skip
        return cls(spec, est, val)

    def respecified(self, **changes: Any) -> _Context:
        """This context under a specification that differs only in what the records and the
        problem do not depend on: ``name``, ``optimisers``, ``runs``, ``budget``."""
        unknown = set(changes) - {"name", "optimisers", "runs", "budget"}
        if unknown:
            raise ValueError(f"respecified: {sorted(unknown)} change the context")
        new = copy.copy(self)
        new.spec = replace(self.spec, **changes)
        return new

    def payload(self) -> dict[str, Any]:
        """Picklable arguments to rebuild the context in a worker process."""
        return {"spec": self.spec.to_dict(), "est": self.est, "val": self.val}


#: Contexts a dask worker keeps (the tasks of a suite's comparisons interleave on a worker).
_CONTEXTS_KEPT = 16
_WORKER_CONTEXT: dict[str, _Context] = {}


def _context_from_payload(payload: Mapping[str, Any]) -> _Context:
    """The context of a payload, built once per process and comparison (least recently used
    first out beyond :data:`_CONTEXTS_KEPT`)."""
    spec = ComparisonSpec.from_dict(payload["spec"])
    cached = _WORKER_CONTEXT.pop(spec.key, None)
    if cached is None:
        cached = _Context(spec, payload["est"], payload["val"])
        while len(_WORKER_CONTEXT) >= _CONTEXTS_KEPT:
            del _WORKER_CONTEXT[next(iter(_WORKER_CONTEXT))]
    _WORKER_CONTEXT[spec.key] = cached  # last: the most recently used
    return cached


# ================================================================================ one run
def _store_history(result) -> dict[str, list]:
    """The run's best-so-far cost as a step function of FE, exact to the evaluation.

    One row per evaluation that lowered the best cost (its FE count and the new best), then
    the run's last FE with the final best, as IOHprofiler's on-improvement logger writes a
    run; a run that never found a finite cost has only the last row.
    """
    fe = [int(v) for v in result.improvements["fe"]]
    best = [float(v) for v in result.improvements["best"]]
    if result.nfev and (not fe or fe[-1] != result.nfev):
        fe.append(int(result.nfev))
        best.append(float(result.fun))
    return {"fe": fe, "best": best}


def _report_numbers(report: Any) -> dict[str, Any]:
    err = report.error_range_one_step
    return {
        "fit_one_step": float(report.fit_one_step),
        "fit_simulation": float(report.fit_simulation),
        "rmse_one_step": float(report.rmse_one_step),
        "error_min": float(err[0]),
        "error_max": float(err[1]),
        "correlation_passed": bool(report.passed),
        # the share inside the record's frequency band (None: no verdict, said in the report)
        "frequency_share": (
            None if report.frequency_verdict == "-" else float(report.frequency.share[0])
        ),
    }


def _validation_numbers(model, ctx: _Context) -> dict[str, Any]:
    """The held-out numbers of a run's model; with several outputs, the first output's and
    each output's under ``outputs``."""
    if len(getattr(model, "output_names", ())) > 1:  # the record's names, in order
        names = list(ctx.val.output_names)
        model = model.named(list(ctx.val.input_names), names)
        reports = [
            ctx.family.validate(
                model, ctx.val, max_lag=ctx.spec.max_lag, initial=ctx.spec.validate_initial,
                split=None, dt=None, output=o, estimated_on=ctx.records[0],
            ).at_level(ctx.spec.alpha)
            for o in names
        ]
        joint = all(t.passed for t in joint_tests(reports, between_outputs(reports)))
        each = {o: _report_numbers(r) for o, r in zip(names, reports, strict=True)}
        # the headline is the first output's numbers with the joint verdict of every output
        return {**each[names[0]], "correlation_passed": joint, "outputs": each}
    report = ctx.family.held_out(model, ctx.records[0], ctx.val, max_lag=ctx.spec.max_lag,
                                 initial=ctx.spec.validate_initial)  # fmt: skip
    return _report_numbers(report.at_level(ctx.spec.alpha))


def _least_squares_record(ctx: _Context) -> dict[str, Any]:
    t0 = time.perf_counter()
    model = ctx.structure.model(ctx.theta_ls, dt=ctx.dt)
    cost = ctx.estimation.cost_ls
    record = {
        "label": LEAST_SQUARES,
        "optimiser": LEAST_SQUARES,
        "params": {},
        "fingerprint": LEAST_SQUARES,
        "run": 0,
        "seed": 0,
        "status": "ok",
        "cost": cost,
        "nfev": 0,
        "nit": 0,
        "stop": ctx.family.start_stop,
        # what a result of a family without built-in words says of the start and the search
        "start_name": ctx.family.start_name(ctx.structure),
        "search_text": ctx.estimation.describe(),
        "history": {"fe": [0], "best": [cost]},
    }
    record.update(ctx.family.model_numbers(model, ctx.estimation, ctx.records))
    record["validation"] = _validation_numbers(model, ctx)
    oe = ctx.estimation.output_error_reference()
    if oe is not None:
        # the simulation cost's own optimum (least squares is not): the reference of targets
        oe_model = ctx.structure.model(oe.theta, dt=ctx.dt)
        record["output_error"] = {
            "cost": float(oe.cost),
            "theta": [float(v) for v in oe.theta],
            "stable": bool(oe.stable),
            "nfev_equivalent": int(oe.nfev_equivalent),
            "wall_time": float(oe.wall_time),
            "validation": _validation_numbers(oe_model, ctx),
            "local_minimum": bool(oe.local_minimum),
            "on_cap": bool(oe.on_cap),
        }
        if getattr(ctx.estimation, "reference_name", None):  # a family's own words
            record["output_error"]["name"] = ctx.estimation.reference_name
    record["wall_time"] = time.perf_counter() - t0
    return record


def _record_head(opt: OptimiserSpec, run: int, seed: int) -> dict[str, Any]:
    """The fields of a run record that say which run it is."""
    return {
        "label": opt.display,
        "optimiser": opt.name,
        "params": dict(opt.params),
        "fingerprint": opt.fingerprint(),
        "run": run,
        "seed": seed,
    }


def _failed_record(task: tuple, reason: str, wall_time: float) -> dict[str, Any]:
    """The record of a run that ended without a result (its process died or timed out).

    Parameters
    ----------
    task : tuple
        ``(optimiser spec as a dict, run, seed)``.
    reason : str
        Why the run failed, stored as its ``error``.
    wall_time : float
        Seconds from the start of the run to its end.

    Returns
    -------
    dict
        A record with status ``"failed"``.
    """
    opt_dict, run, seed = task
    record = _record_head(OptimiserSpec(**opt_dict), run, seed)
    record.update(status="failed", error=reason, wall_time=wall_time)
    return record


def _run(ctx: _Context, opt: OptimiserSpec, run: int, seed: int) -> dict[str, Any]:
    """One optimiser run; whatever the optimiser raises becomes a failed record, never a crash."""
    record = _record_head(opt, run, seed)
    t0 = time.perf_counter()
    try:
        budget = Budget(max_fe=ctx.spec.max_fe)
        result = minimize(opt.name, ctx.estimation.problem, budget, seed, params=opt.params)
        model = ctx.structure.model(ctx.estimation.theta(result.x), dt=ctx.dt)
        record.update(
            status="ok",
            cost=float(result.fun),
            nfev=int(result.nfev),
            nit=int(result.nit),
            stop=result.stop,
            history=_store_history(result),
            x=[float(v) for v in result.x],
        )
        record.update(ctx.family.model_numbers(model, ctx.estimation, ctx.records))
        record["validation"] = _validation_numbers(model, ctx)
    except KeyboardInterrupt:  # the user's Ctrl-C (or the command's SIGTERM) ends everything
        raise
    except BaseException as exc:
        # an optimiser that raises, calls sys.exit or raises GeneratorExit is recorded and
        # the others go on: a plugin cannot end the comparison
        text = str(exc)
        record.update(
            status="failed",
            error=f"{type(exc).__name__}: {text}" if text else type(exc).__name__,
            traceback=traceback.format_exc(limit=8),
        )
    record["wall_time"] = time.perf_counter() - t0
    return record


def _do(ctx: _Context, task: tuple | None) -> dict[str, Any]:
    """One task of a comparison: its reference record (``task`` None) or one optimiser run
    (``(optimiser spec as a dict, run, seed)``)."""
    if task is None:
        return _least_squares_record(ctx)
    opt_dict, run, seed = task
    return _run(ctx, OptimiserSpec(**opt_dict), run, seed)


def _run_task(payload: Mapping[str, Any], task: tuple | None) -> dict[str, Any]:
    """A task on a dask worker.  Its compiled kernels run on one thread, as dask's worker
    processes run NumPy's BLAS (``OMP_NUM_THREADS=1``): a machine's cores are its worker
    processes', not one task's."""
    before = kernels.set_threads(1)
    try:
        return _do(_context_from_payload(payload), task)
    finally:
        kernels.set_threads(before)  # a worker inside the caller's process (processes=False)


# ================================================================================ workers
#: Longest wait (s) between two looks at the worker processes: a worker that died without
#: its pipe showing it (a child process of its own holds the pipe) is still noticed.
_POLL = 1.0
#: Seconds an idle worker is given to exit when told to, before it is killed.
_GRACE = 2.0


def _worker_main(conn: Any) -> None:
    """Body of a worker process: do the tasks the parent sends, of any comparison.

    Messages from the parent: ``(payload, key, task)``, the payload given the first time the
    worker gets a task of comparison ``key`` (None after that: the worker keeps the context
    it built), ``task`` as for :func:`_do`; ``None``, or the parent's end, stops the worker.
    Messages to the parent: ``("ready", None)`` once started, ``("done", record)`` per task,
    ``("error", traceback)`` if a context cannot be built.
    """
    # Ctrl-C reaches every process of the terminal's group: the parent alone answers it (it
    # ends the workers), so that a run is not cut short into a failed record
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _exit_with_parent()
    kernels.set_threads(1)  # the worker processes share the cores already
    contexts: dict[str, _Context] = {}
    conn.send(("ready", None))
    while True:
        try:
            message = conn.recv()
        except EOFError:  # the parent has ended
            return
        if message is None:
            return
        payload, key, task = message
        if payload is not None:
            try:
                contexts[key] = _Context(
                    ComparisonSpec.from_dict(payload["spec"]), payload["est"], payload["val"]
                )
            except BaseException:
                conn.send(("error", traceback.format_exc()))
                return
        conn.send(("done", _do(contexts[key], task)))


def _exit_with_parent() -> None:
    """End this process as soon as its parent ends, even in the middle of a run.

    A parent killed with SIGKILL cannot stop its workers: without this, a worker would finish
    its run (or never, in a run that never returns) for a result nobody reads.
    """
    parent = parent_process()
    if parent is None:
        return

    def watch() -> None:
        parent.join()  # returns when the parent's end of the sentinel pipe closes
        os._exit(1)

    threading.Thread(target=watch, name="flexid-parent-watch", daemon=True).start()


#: The thread counts of NumPy's BLAS (OpenBLAS, MKL, OpenMP) in a worker process, as dask's
#: worker processes set them: each worker is one of the machine's cores, and a BLAS thread
#: per core in every worker would run cores-times-workers threads that wait on one another
#: (the gradient references then run several times slower).  A value the user set is kept.
_WORKER_BLAS_THREADS = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                        "MKL_NUM_THREADS": "1"}  # fmt: skip


@contextmanager
def _worker_environment() -> Iterator[None]:
    """Within it, a process started by spawn gets one BLAS thread (unless the user set the
    counts); the parent's environment is restored after."""
    added = {k: v for k, v in _WORKER_BLAS_THREADS.items() if k not in os.environ}
    os.environ.update(added)
    try:
        yield
    finally:
        for key in added:
            os.environ.pop(key, None)


class _Worker:
    """A worker process, the parent's end of its pipe and the run it is doing."""

    def __init__(self, mp: Any, what: str = "worker process") -> None:
        self.what = what  # how a failed run's reason names the process that died
        self.conn, child = mp.Pipe()
        self.process = mp.Process(target=_worker_main, args=(child,), name="flexid-worker")
        try:
            with _worker_environment():  # a spawned child reads it when it starts
                self.process.start()
        finally:
            child.close()  # the child's copy is the only one left: its death is the pipe's EOF
        self.ready = False
        self.keys: set[str] = set()  # the comparisons whose context the worker holds
        self.item: tuple[int, tuple | None] | None = None  # (job index, task) being done
        self.started = 0.0

    @property
    def busy(self) -> bool:
        return self.item is not None

    def assign(self, job: int, key: str, payload: Callable[[], Mapping], task: tuple | None
               ) -> bool:  # fmt: skip
        """Send a task of comparison ``key`` to this (idle, ready) worker, with the
        comparison's payload if it has not had it; False if the worker is gone."""
        try:
            self.conn.send((None if key in self.keys else payload(), key, task))
        except OSError:
            return False
        self.keys.add(key)
        self.item = (job, task)
        self.started = time.monotonic()
        return True

    def check(self, run_timeout: float | None) -> tuple[tuple[int, dict] | None, bool]:
        """Read the worker's messages; end it if its run is over time.

        Parameters
        ----------
        run_timeout : float or None
            The per-run time limit in seconds (a reference task has none).

        Returns
        -------
        done : (int, dict) or None
            The job index and record of a finished task: done, or a run failed because the
            process died or ran out of time.
        alive : bool
            False once the process has ended (it is then to be replaced).

        Raises
        ------
        RuntimeError
            If the worker could not build a comparison's context, ended before it started,
            or died while it computed a reference (which no failed record stands for).
        """
        ended = False
        try:
            while self.conn.poll():
                kind, value = self.conn.recv()
                if kind == "ready":
                    self.ready = True
                elif kind == "done":
                    (job, _), self.item = self.item, None
                    return (job, value), True
                else:
                    raise RuntimeError(f"a flexid worker process could not start:\n{value}")
        except (EOFError, OSError):  # the process has ended, or is ending
            ended = True
            self.process.join(_GRACE)
        if ended or not self.process.is_alive():
            self.kill()
            code = self.process.exitcode
            if not self.ready:
                # the usual cause: spawn runs the caller's script again in the child, and an
                # unguarded script starts the comparison there too, which multiprocessing stops
                raise RuntimeError(
                    f"a flexid worker process ended before it started (exit code {code}).\n"
                    "A script that runs a comparison in child processes (workers, a time limit "
                    "or an\nuntrusted plugin) must start it under "
                    '`if __name__ == "__main__":`: the children\nimport the script again.'
                )
            if self.item is None:
                return None, False
            reason = f"{self.what} died (exit code {code})"
            if code is not None and code < 0:
                reason = f"{self.what} died (exit code {code}, {_signal_name(-code)})"
            return self._fail(reason), False
        deadline = self.deadline(run_timeout)
        if deadline is not None and time.monotonic() >= deadline:
            self.kill()
            return self._fail(f"time limit of {run_timeout:g} s exceeded"), False
        return None, True

    def deadline(self, run_timeout: float | None) -> float | None:
        """When this worker's run exceeds the time limit (monotonic clock), if it is running
        an optimiser run (a reference has no limit)."""
        if self.item is None or self.item[1] is None or run_timeout is None:
            return None
        return self.started + run_timeout

    def _fail(self, reason: str) -> tuple[int, dict[str, Any]]:
        (job, task), self.item = self.item, None
        if task is None:
            raise RuntimeError(f"a flexid worker process computing a reference: {reason}")
        return job, _failed_record(task, reason, time.monotonic() - self.started)

    def kill(self) -> None:
        """End the process at once (a run that never returns cannot be asked to)."""
        if self.process.is_alive():
            self.process.kill()
        self.process.join()

    def stop(self) -> None:
        """End the process: an idle one is told to exit, a busy one is killed."""
        if self.item is None and self.process.is_alive():
            try:
                self.conn.send(None)
            except OSError:
                pass
            else:
                self.process.join(_GRACE)
        self.kill()
        self.conn.close()


def _signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def _wait_timeout(pool: Sequence[_Worker], run_timeout: float | None) -> float:
    """How long to wait for the pool: the poll interval, or less when a run's time limit
    falls due sooner."""
    deadlines = [d for w in pool if (d := w.deadline(run_timeout)) is not None]
    timeout = _POLL
    if deadlines:
        timeout = min(timeout, max(0.0, min(deadlines) - time.monotonic()))
    return timeout


def _execute_processes(
    jobs: Sequence[_Job], items: Sequence[tuple[int, tuple | None]], workers: int,
    run_timeout: float | None, what: str = "worker process",
) -> Iterator[tuple[int, dict]]:
    """Yield ``(job index, record)`` from ``workers`` worker processes as tasks complete.

    One pool serves every comparison: a worker is sent a comparison's payload with its first
    task of that comparison.  A worker that dies or exceeds ``run_timeout`` in a run yields
    that run as failed and is replaced; ``what`` names the process in the failed run's
    reason.  However the generator ends (done, an exception, closed early, an interrupt),
    every worker process has ended when it does.
    """
    mp = get_context("spawn")  # a fresh interpreter: no threads or locks copied by fork
    payloads: dict[int, Mapping] = {}

    def payload_of(job: int) -> Callable[[], Mapping]:
        def payload() -> Mapping:
            if job not in payloads:
                payloads[job] = jobs[job].ctx.payload()
            return payloads[job]

        return payload

    queue = deque(items)
    pool: list[_Worker] = []

    def needed() -> int:
        """Workers there is work for: the tasks going on and the tasks waiting."""
        return min(workers, len(queue) + sum(w.busy for w in pool))

    try:
        while len(pool) < needed():
            pool.append(_Worker(mp, what))
        while queue or any(w.busy for w in pool):
            for w in pool:
                if w.ready and not w.busy and queue:
                    job, task = queue.popleft()
                    if not w.assign(job, jobs[job].key, payload_of(job), task):
                        queue.appendleft((job, task))  # the worker is gone: check() replaces it
            timeout = _wait_timeout(pool, run_timeout)
            wait([w.conn for w in pool] + [w.process.sentinel for w in pool], timeout)
            for w in list(pool):
                done, alive = w.check(run_timeout)
                if not alive:
                    pool.remove(w)
                    w.stop()
                    if len(pool) < needed():
                        pool.append(_Worker(mp, what))
                if done is not None:
                    yield done
    finally:
        for w in pool:
            w.stop()


# ================================================================================ compare
def _check_optimisers(spec: ComparisonSpec) -> None:
    """Fail early on unknown optimisers or hyper-parameters."""
    for opt in spec.optimisers:
        get(opt.name)(**opt.params)


def _check_labels(spec: ComparisonSpec, records: Iterable[Mapping[str, Any]]) -> None:
    """Fail early on a label stored for this comparison with other settings."""
    stored = {}
    for r in records:
        stored.setdefault(r["label"], r.get("fingerprint"))
    for opt in spec.optimisers:
        fp = stored.get(opt.display)
        if fp is not None and fp != opt.fingerprint():
            raise ConfigError(
                f"label {opt.display!r} is stored for this comparison with other settings; "
                "give the new settings another label or use another store"
            )


def _checked_context(spec: ComparisonSpec) -> _Context:
    """The shared context of a valid specification; raises before anything is written."""
    _check_optimisers(spec)
    check_search(spec.search)
    return _Context.from_spec(spec)


@checked_keywords
def check_spec(spec: ComparisonSpec) -> None:
    """Raise if ``spec`` cannot run: unknown optimisers or hyper-parameters, a bad plant,
    data file, orders, cost or bounds.  Nothing is run or written (the record is built, then
    dropped); :func:`compare` does the same check before it opens the store.

    Parameters
    ----------
    spec : ComparisonSpec
        The comparison to check.

    Raises
    ------
    ConfigError, UnknownOptimiserError, HyperParameterError, DataError, ModelOrderError
    """
    _checked_context(spec)


@dataclass
class _Job:
    """A comparison being run: its context, store key, the records it has, what it needs."""

    ctx: _Context
    key: str
    records: list[dict[str, Any]]
    #: ``(optimiser spec as a dict, run, seed)`` of every run still to do
    tasks: list[tuple]
    #: whether its reference record (least squares, and the gradient reference) is to compute
    reference: bool

    @property
    def spec(self) -> ComparisonSpec:
        return self.ctx.spec


def _open_job(ctx: _Context, db: ResultStore | None, retry_failed: bool) -> _Job:
    """The records a store holds for a comparison, and the tasks it still needs."""
    spec = ctx.spec
    key = spec.key
    records: list[dict[str, Any]] = []
    done: set[tuple[str, int]] = set()
    if db is not None:
        stored = db.runs(key)  # damaged rows are left out (and named): they run again
        _check_labels(spec, stored)
        done = {
            (r["label"], r["run"])
            for r in stored
            if not (retry_failed and r["status"] == "failed")
        }
        records = [r for r in stored if (r["label"], r["run"]) in done]
    tasks = [
        ({"name": o.name, "params": dict(o.params), "label": o.label}, r, run_seed(spec.seed, r))
        for r in range(spec.runs)
        for o in spec.optimisers
        if (o.display, r) not in done
    ]
    return _Job(ctx, key, records, tasks, (LEAST_SQUARES, 0) not in done)


@checked_keywords
def compare(
    spec: ComparisonSpec,
    *,
    store: str | Path | ResultStore | None = None,
    workers: int = 1,
    scheduler: str | Any | None = None,
    progress: bool | Callable[[dict], Any] = False,
    retry_failed: bool = False,
    run_timeout: float | None = None,
) -> ComparisonResult:
    """Run (or resume) a comparison and return its statistics.

    Parameters
    ----------
    spec : ComparisonSpec
        What to compare (see :mod:`flexid.config`).
    store : path or ResultStore, optional
        SQLite result store.  Each finished run is written at once; runs already in the store
        are skipped, except damaged ones (named in a :class:`~flexid.errors.StoreWarning`),
        which run again.  Without a store the results live in memory only.
    workers : int
        Processes to run in parallel (1 = in this process).  The numbers do not depend on it.
        The reference (least squares and the gradient reference) is a task of the pool too.
    scheduler : str or distributed.Client, optional
        Address of a dask.distributed scheduler (requires the ``dask`` extra), or a client.
    progress : bool or callable
        Show a progress bar (``True``) or call ``progress(record)`` after each run.
    retry_failed : bool
        Run again the runs stored as failed (default: keep them).
    run_timeout : float, optional
        Wall-time limit of one optimiser run in seconds (default: ``spec.run_timeout``,
        itself None, no limit, unless set).  A run over it is ended, its worker process
        killed and replaced, and it is recorded as failed ("time limit of X s exceeded");
        the comparison goes on.  With ``workers=1`` a limit makes each run a child process
        of its own.  Not available with ``scheduler``.

    Returns
    -------
    ComparisonResult

    Raises
    ------
    ConfigError, UnknownOptimiserError, HyperParameterError, DataError, StoreError
        Before any run starts, for an invalid specification (and before the store is
        opened, so an invalid specification leaves no file behind), or for a store that is
        read-only or not a flexid store (left as it was).

    Notes
    -----
    An optimiser that raises (``SystemExit`` and ``GeneratorExit`` included) or, in a
    worker process, ends its process, gives a failed run with the reason; the other runs go
    on.  With ``workers=1``, the runs of an optimiser not registered as trusted (a plugin's,
    see :func:`~flexid.optimisers.registry.is_trusted`) are done in a child process after
    the others, so that one ending its process is a failed run too.  ``KeyboardInterrupt``
    ends the comparison, worker processes included; the runs finished before it are in the
    store.
    """
    t0 = time.perf_counter()
    ctx = _checked_context(spec)  # the whole specification, before the store is opened
    (result,) = _compare_contexts(
        [ctx], store=store, workers=workers, scheduler=scheduler, progress=progress,
        retry_failed=retry_failed, run_timeout=run_timeout, t0=t0,
    )  # fmt: skip
    return result


def _compare_contexts(
    contexts: Sequence[_Context],
    *,
    store: str | Path | ResultStore | None,
    workers: int = 1,
    scheduler: str | Any | None = None,
    progress: bool | Callable[[dict], Any] = False,
    retry_failed: bool = False,
    run_timeout: float | None = None,
    t0: float | None = None,
    title: str | None = None,
) -> list[ComparisonResult]:
    """:func:`compare` of several checked comparisons, their tasks in one pool or graph.

    The references of every comparison come first (the longest tasks, so the workers start
    them early), then the runs, comparison by comparison; each finished task is written at
    once under its comparison's key.  Arguments as for :func:`compare`; ``run_timeout``
    None takes the first that a comparison sets (one pool has one limit); ``title`` heads
    the progress bar (default: the comparison's name, or how many there are).
    """
    t0 = time.perf_counter() if t0 is None else t0
    workers = positive_int(workers, "workers", error=ConfigError)
    run_timeout = _pool_timeout(contexts, run_timeout, scheduler)
    owns_store = store is not None and not isinstance(store, ResultStore)
    db = ResultStore(store) if owns_store else store
    try:
        jobs = [_open_job(ctx, db, retry_failed) for ctx in contexts]
        if db is not None:  # every label checked before the first comparison is recorded
            for job in jobs:
                db.add_comparison(job.key, job.spec.name, job.spec.to_dict())
        if title is None:
            title = jobs[0].spec.name if len(jobs) == 1 else f"{len(jobs)} comparisons"
        bar = _progress(progress, sum(len(job.tasks) for job in jobs), title)
        where = _short_names(jobs)
        done = _execute(jobs, _work_items(jobs), workers, scheduler, run_timeout)
        try:
            for i, record in done:
                if db is not None:
                    db.write_run(jobs[i].key, record)
                jobs[i].records.append(record)
                if record["label"] != LEAST_SQUARES:
                    bar(record, where[i])
        finally:
            done.close()  # ends the worker processes now, also when the loop body raised
            bar(None, "")
        elapsed = time.perf_counter() - t0
        path = str(db.path) if db is not None else None
        return [
            ComparisonResult.from_records(
                job.spec, job.key, job.records, store_path=path, elapsed=elapsed
            )
            for job in jobs
        ]
    finally:
        if owns_store and db is not None:
            db.close()


def _pool_timeout(
    contexts: Sequence[_Context], run_timeout: float | None, scheduler: Any
) -> float | None:
    """The run time limit of a pool: the one given, else the first a comparison sets."""
    if run_timeout is None:
        run_timeout = next((c.spec.run_timeout for c in contexts if c.spec.run_timeout), None)
    else:
        run_timeout = _check_run_timeout(run_timeout, "run_timeout")
    if run_timeout is not None and scheduler is not None:
        raise ConfigError(
            "run_timeout is not available with a dask scheduler (a dask task cannot be "
            "stopped); use workers instead"
        )
    return run_timeout


def _work_items(jobs: Sequence[_Job]) -> list[tuple[int, tuple | None]]:
    """``(job index, task)`` of every task: the references first, then the runs."""
    items: list[tuple[int, tuple | None]] = [
        (i, None) for i, job in enumerate(jobs) if job.reference
    ]
    return items + [(i, task) for i, job in enumerate(jobs) for task in job.tasks]


def _short_names(jobs: Sequence[_Job]) -> list[str]:
    """How a progress line names each job's comparison among several: its name less the
    folders all the names share (nothing when there is one)."""
    if len(jobs) == 1:
        return [""]
    parts = [job.spec.name.split("/") for job in jobs]
    k = 0
    while all(len(q) > k + 1 and q[k] == parts[0][k] for q in parts):
        k += 1
    return ["/".join(q[k:]) + ": " for q in parts]


def _execute(
    jobs: Sequence[_Job],
    items: Sequence[tuple[int, tuple | None]],
    workers: int,
    scheduler: Any,
    run_timeout: float | None,
) -> Iterator[tuple[int, dict]]:
    """Yield ``(job index, record)`` as tasks complete (serial, processes or dask)."""
    if not items:
        return
    if scheduler is not None:
        yield from _execute_dask(jobs, items, scheduler)
        return
    if workers == 1 and run_timeout is None:
        yield from _execute_serial(jobs, items)
        return
    yield from _execute_processes(jobs, items, workers, run_timeout)


def _execute_serial(
    jobs: Sequence[_Job], items: Sequence[tuple[int, tuple | None]]
) -> Iterator[tuple[int, dict]]:
    """Yield ``(job index, record)`` of the tasks done one at a time.

    The references and the runs of trusted optimisers are done in this process, in order,
    as fast as ever; then the runs of the others in one child process of the worker pool,
    which a run that ends it (``os._exit``, a segfault) cannot take this process down with:
    the run is failed, the process replaced.  Where a run is done does not change its numbers.
    """
    trusted = [task is None or is_trusted(task[0]["name"]) for _, task in items]
    here = [item for item, ok in zip(items, trusted, strict=True) if ok]
    away = [item for item, ok in zip(items, trusted, strict=True) if not ok]
    for i, task in here:
        yield i, _do(jobs[i].ctx, task)
    if away:
        yield from _execute_processes(jobs, away, 1, None, what="the optimiser's child process")


def _execute_dask(
    jobs: Sequence[_Job], items: Sequence[tuple[int, tuple | None]], scheduler: Any
) -> Iterator[tuple[int, dict]]:
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError:
        raise ConfigError(
            "--scheduler needs dask.distributed: pip install 'flexid[dask]'"
        ) from None
    client = scheduler if isinstance(scheduler, Client) else None
    own = client is None
    if own:
        try:
            client = Client(scheduler, timeout="20s")
        except OSError as exc:
            raise ConfigError(f"cannot reach the dask scheduler at {scheduler!r}: {exc}") from None
    try:
        # one future per comparison with a key of its own: a dict given to scatter is
        # scattered value by value under its own keys ("spec", "est", "val"), and a
        # content-hashed key (hash=True) is shared too; another comparison on this scheduler
        # releasing a shared key cancels these runs ("lost dependencies")
        used = sorted({i for i, _ in items})
        scattered = client.scatter([jobs[i].ctx.payload() for i in used], broadcast=True,
                                   hash=False)  # fmt: skip
        payloads = dict(zip(used, scattered))
        futures = {
            client.submit(_run_task, payloads[i], task, pure=False): i for i, task in items
        }
        for future in dask_completed(futures):
            yield futures[future], future.result()
    finally:
        if own:
            client.close()


def _progress(
    progress: bool | Callable, total: int, name: str
) -> Callable[[dict | None, str], None]:
    """A callback ``bar(record, where)`` per finished run (``where`` names its comparison
    among several, or is empty); ``bar(None, "")`` closes it."""
    if callable(progress) and not isinstance(progress, bool):
        return lambda record, where: None if record is None else progress(record)
    if not progress or total == 0:
        return lambda record, where: None
    from .progress import ProgressBar

    bar = ProgressBar(total, f"{name}")

    def update(record: dict | None, where: str) -> None:
        if record is None:
            bar.close()
        else:
            cost = _f(record.get("cost", math.nan))
            bar.update(1, f"{where}{record['label']} run {record['run']}: {cost}")

    return update


@checked_keywords
def frequency_views(result: ComparisonResult, run: str = "best") -> tuple[Any, dict[str, Any]]:
    """The held-out record's frequency-response estimate and the models to draw on it.

    The comparison's records and problem are posed again from its specification (the data
    file must still hold what it held), and the models rebuilt from the stored runs: the
    start (least squares), the reference and each optimiser's best run.

    Parameters
    ----------
    result : ComparisonResult
        The comparison (from :func:`compare` or :func:`load_result`).
    run : {"best", "median"}, optional
        Each optimiser's run of lowest cost (default) or of median cost (the lower middle
        one of an even number).

    Returns
    -------
    estimate : FrequencyResponseEstimate
        ``tfestimate`` of the held-out record, every input and output.
    models : dict of str to model
        ``label -> model``: the start and the reference first, then each optimiser's chosen
        run (``"pso (best of 5)"``, ``"pso (median of 5)"``); empty for models without a
        frequency response.

    Raises
    ------
    FlexidError
        When the data cannot be read again or the estimate cannot be made.
    """
    from ..validation.frequency import frf

    if run not in ("best", "median"):
        raise ConfigError(f"run must be 'best' or 'median', not {run!r}")
    ctx = _Context.from_spec(result.spec)
    models: dict[str, Any] = {result.start_label: ctx.structure.model(ctx.theta_ls, dt=ctx.dt)}
    oe = result.reference.get("output_error")
    if oe and "theta" in oe:
        models[result.reference_label] = ctx.structure.model(np.asarray(oe["theta"]), dt=ctx.dt)
    for label, runs in result.records.items():
        ok = [r for r in runs if r["status"] == "ok" and "x" in r]
        if ok:
            ranked = sorted(ok, key=lambda r: r["cost"])
            chosen = ranked[0] if run == "best" else ranked[(len(ranked) - 1) // 2]
            theta = ctx.estimation.theta(np.asarray(chosen["x"], dtype=float))
            models[f"{label} ({run} of {len(ok)})"] = ctx.structure.model(theta, dt=ctx.dt)
    models = {k: m for k, m in models.items() if hasattr(m, "frequency_response")}
    return frf(ctx.val), models


@checked_keywords
def load_result(store: str | Path | ResultStore, key: str | None = None) -> list[ComparisonResult]:
    """Comparison results rebuilt from a store (all comparisons, or the one with ``key``).

    Parameters
    ----------
    store : str, pathlib.Path or ResultStore
        The SQLite store (a path or an open store).
    key : str, optional
        A comparison key; default every comparison in the store.

    Returns
    -------
    list of ComparisonResult
        One result per comparison read.
    """
    db = store if isinstance(store, ResultStore) else ResultStore(store, readonly=True)
    try:
        entries = [db.comparison(key)] if key else db.comparisons()
        results = []
        for entry in entries:
            spec = ComparisonSpec.from_dict(entry["spec"])
            results.append(
                ComparisonResult.from_records(
                    spec, entry["key"], db.runs(entry["key"]), store_path=str(db.path)
                )
            )
        return results
    finally:
        if db is not store:
            db.close()
