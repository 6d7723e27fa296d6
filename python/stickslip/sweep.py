"""``stickslip sweep SPEC --out DIR``: the variants of a SPEC on a Dask cluster, every row kept.

* The cluster: a ``dask.distributed`` LocalCluster of ``--workers`` processes with one thread
  each, or an existing cluster at ``--scheduler tcp://host:port``. Workers share no file system
  with the caller: the FMU's bytes go to every worker, also to workers that join later, in a
  worker plugin (:class:`FmuPlugin`), and each worker unpacks them once.
* One task per variant (:func:`stickslip.variant.run_variant`), at most a few per worker
  thread queued at a time; a task whose worker died is run again elsewhere (``retries``).
* Results (:class:`ResultStore`): finished rows are written as parquet part files in
  ``DIR/parts/`` every few seconds, and ``DIR/results.parquet`` is consolidated from them
  at the end, also after Ctrl-C or a lost scheduler. ``DIR/sweep.json`` records what the
  results belong to (the SPEC's hash and the FMU's); rerunning the same command runs only
  the variants without a row, another SPEC or FMU into the same DIR is refused.
* The convergence check (``--check-convergence``, :mod:`stickslip.convergence`): the task
  of a checked variant runs it a second time with a tenfold tighter error tolerance and
  adds ``<metric>_spread`` columns; which variants are checked (a seeded fraction) and how
  is part of what sweep.json records, so a checked and an unchecked sweep are different
  results.
"""

from __future__ import annotations

import itertools
import json
import os
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

from distributed import WorkerPlugin

from .cluster import ClusterError, connect
from .convergence import COLUMNS as CHECK_COLUMNS
from .convergence import describe, run_checked, selected_runs, spread_columns, tightened
from .fmu import content_hash, model_description
from .motion import TableMotion, load_motion_for, reference_inputs
from .progress import Progress
from .spec import Spec, SpecError, check_against
from .variant import metric_names, plugin_name, run_variant

FLUSH_SECONDS = 5.0  # a part file at least this often while rows come in
FLUSH_ROWS = 500  # ... or when this many rows are waiting
WORKER_WAIT = 120.0  # s to wait for the first worker of a cluster
LOST = "lost"  # status of a variant whose task failed outside the FMU: run again on a rerun


class SweepError(ClusterError):
    """A sweep that cannot start or continue; the message says why and what to do."""


class FmuPlugin(WorkerPlugin):
    """Carries the FMU's bytes to every worker (also to those that join later) and unpacks
    them there once, when the worker starts or when the plugin is registered."""

    def __init__(self, data: bytes, digest: str):
        self.data = data
        self.digest = digest
        self.name = plugin_name(digest)

    def setup(self, worker=None):
        from .fmu import unpacked

        unpacked(self.data, self.digest)


class Check:
    """The convergence check of a sweep: the fraction of its variants checked (chosen by
    :func:`stickslip.convergence.selected_runs` from the SPEC's seed) and, optionally, the
    check run's parameter values (``rerun``; default: the FMU's error_tolerance / 10, or its
    fixed sub-step halved, :func:`stickslip.convergence.tightened`)."""

    def __init__(self, fraction: float = 1.0, rerun: dict | None = None):
        if not 0 < fraction <= 1:
            raise SpecError(f"--convergence-fraction {fraction:g}: must be in (0, 1]")
        self.fraction = float(fraction)
        self.rerun = dict(rerun) if rerun else None
        self.method = "given"

    def resolve(self, md) -> None:
        """The check run's values for this FMU (its start values of the settings)."""
        if self.rerun is None:
            try:
                self.rerun, self.method = tightened({}, md)
            except ValueError as e:
                raise SpecError(f"--check-convergence: {e}") from None
        else:
            self.method = f"given: {describe(self.rerun)}"

    def record(self, n: int, seed: int) -> dict:
        """What sweep.json records of the check (part of what identifies the results)."""
        return {
            "fraction": self.fraction,
            "rerun": self.rerun,
            "method": self.method,
            "checked": len(selected_runs(n, self.fraction, seed)),
        }


class ResultStore:
    """The rows of one sweep in DIR: part files, the consolidated results.parquet, sweep.json."""

    def __init__(self, out: Path, spec: Spec, fmu_digest: str, columns: list, convergence: dict | None = None):
        import pyarrow as pa

        self.out = Path(out)
        self.parts = self.out / "parts"
        self.record = {
            "spec_sha256": spec.digest(),
            "fmu_sha256": fmu_digest,
            "spec": spec.canonical(),
            "variants": len(spec),
        }
        if convergence is not None:
            self.record["convergence"] = convergence
        meta = self.out / "sweep.json"
        if meta.exists():
            old = json.loads(meta.read_text(encoding="utf-8"))
            if old.get("fmu_sha256") != fmu_digest:
                raise SweepError(
                    f"{self.out} holds results of another FMU (sha256 {old.get('fmu_sha256', '?')[:12]}, "
                    f"now {fmu_digest[:12]}); use another --out, or remove {self.out}"
                )
            if old.get("spec_sha256") != self.record["spec_sha256"]:
                changed = sorted(
                    k
                    for k in set(old.get("spec", {})) | set(self.record["spec"])
                    if old.get("spec", {}).get(k) != self.record["spec"].get(k)
                )
                raise SweepError(
                    f"{self.out} holds results of another SPEC (changed: {', '.join(changed)}); "
                    f"use another --out, or remove {self.out} to start over"
                )
            if old.get("convergence") != convergence:
                raise SweepError(
                    f"{self.out} holds results of a sweep {_check_text(old.get('convergence'))}, "
                    f"this one is {_check_text(convergence)}; use another --out, or remove "
                    f"{self.out} to start over"
                )
        try:
            self.parts.mkdir(parents=True, exist_ok=True)
            meta.write_text(json.dumps(self.record, indent=1), encoding="utf-8")
        except OSError as e:
            raise SweepError(f"cannot write the results into {self.out}: {e.strerror}") from None
        types = {
            "run": pa.int64(),
            "status": pa.string(),
            "message": pa.string(),
            "worker": pa.string(),
            "finished": pa.timestamp("us", tz="UTC"),
            "convergence_status": pa.string(),
            "convergence_message": pa.string(),
        }
        self.schema = pa.schema([(c, types.get(c, pa.float64())) for c in columns])
        self.waiting = []
        self.last_flush = time.monotonic()
        self.session = f"{datetime.now(UTC):%Y%m%dT%H%M%S}-{os.getpid()}"
        self.written = 0

    def rows(self):
        """Every row in the part files, the last one per run (a pandas DataFrame, by run)."""
        import pandas as pd
        import pyarrow.parquet as pq

        tables = [pq.read_table(f, schema=self.schema) for f in sorted(self.parts.glob("*.parquet"))]
        if not tables:
            return pd.DataFrame({f.name: pd.Series(dtype=f.type.to_pandas_dtype()) for f in self.schema})
        import pyarrow as pa

        df = pa.concat_tables(tables).to_pandas()
        return df.sort_values(["run", "finished"]).drop_duplicates("run", keep="last").reset_index(drop=True)

    def done(self) -> set:
        """Run ids with a row that is not :data:`LOST`."""
        df = self.rows()
        return set(int(r) for r in df.loc[df["status"] != LOST, "run"])

    def add(self, row: dict) -> None:
        self.waiting.append(row | {"finished": datetime.now(UTC)})
        if len(self.waiting) >= FLUSH_ROWS or time.monotonic() - self.last_flush >= FLUSH_SECONDS:
            self.flush()

    def flush(self) -> None:
        """Writes the waiting rows as one part file (written whole, then renamed into place)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        self.last_flush = time.monotonic()
        if not self.waiting:
            return
        self.written += 1
        name = self.parts / f"part-{self.session}-{self.written:05d}.parquet"
        tmp = name.with_suffix(".tmp")
        pq.write_table(pa.Table.from_pylist(self.waiting, schema=self.schema), tmp)
        os.replace(tmp, name)
        self.waiting = []

    def consolidate(self):
        """DIR/results.parquet from every part file; returns its rows."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        self.flush()
        df = self.rows()
        tmp = self.out / "results.parquet.tmp"
        pq.write_table(pa.Table.from_pandas(df, schema=self.schema, preserve_index=False), tmp)
        os.replace(tmp, self.out / "results.parquet")
        return df


def _check_text(convergence: dict | None) -> str:
    if not convergence:
        return "without --check-convergence"
    return (
        f"with --check-convergence --convergence-fraction {convergence.get('fraction', '?'):g} "
        f"({describe(convergence.get('rerun') or {})})"
    )


def _motion(spec: Spec, md):
    """The SPEC's motion: the reference cycloids, a motion file (TOML, docs/motion.md) checked
    against the FMU's joints, or the older CSV table (:class:`TableMotion`)."""
    if spec.motion == "reference":
        from .motion import reference_motion_refusal

        refusal = reference_motion_refusal(spec.fmu)
        if refusal:
            raise SpecError(f'motion = "reference": {refusal}')
        return reference_inputs
    joints = sum(1 for v in md.modelVariables if v.causality == "input" and v.name.startswith("q_star["))
    try:
        if Path(spec.motion).suffix.lower() != ".csv":
            return load_motion_for(spec.motion, md)
        return TableMotion.from_csv(spec.motion, joints)
    except ValueError as e:
        raise SpecError(str(e)) from None


def prepare(spec: Spec, out, check: Check | None = None) -> tuple:
    """Everything checked before a worker is asked for anything: (FMU bytes, its hash, the
    motion, the store, the metric names). Raises :class:`SpecError` or :class:`SweepError`
    naming the problem."""
    data = spec.fmu.read_bytes()
    digest = content_hash(data)
    try:
        md = model_description(data)
    except Exception as e:  # noqa: BLE001 -- any unreadable FMU
        raise SpecError(f"fmu {spec.fmu}: not a readable FMU ({e})") from None
    check_against(spec, md)
    motion = _motion(spec, md)
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    missing = [n for n in ("eps", "Q_friction", "W_drive") if n not in outputs]
    if missing:
        raise SpecError(f"fmu {spec.fmu}: has no output(s) {missing} for the metrics")
    metrics = metric_names(outputs)
    columns = ["run", *spec.parameters, "status", "message", "wall_s", "cpu_s", "t_end", *metrics, "worker", "finished"]
    convergence = None
    if check is not None:
        check.resolve(md)
        columns += CHECK_COLUMNS + spread_columns(metrics)
        convergence = check.record(len(spec), spec.seed)
    return data, digest, motion, ResultStore(Path(out), spec, digest, columns, convergence), metrics


def run_sweep(
    spec: Spec,
    out,
    scheduler: str | None = None,
    workers: int | None = None,
    timeout: float | None = None,
    retries: int = 2,
    progress_tty: bool | None = None,
    check: Check | None = None,
) -> dict:
    """Runs the variants of ``spec`` that have no row in ``out`` yet; returns {"rows": the
    consolidated DataFrame, "ran": how many ran now, "interrupted": bool, "seconds": wall time
    from the first task submitted to the last row, "workers": number of worker threads,
    "metrics": the metric names, "convergence": what sweep.json records of the check or None}.
    ``check``: the convergence check (:class:`Check`), None for none."""
    data, digest, motion, store, metrics = prepare(spec, out, check)
    variants = spec.variants()
    done = store.done()
    todo = [i for i in range(len(variants)) if i not in done]
    checked = selected_runs(len(variants), check.fraction, spec.seed) if check is not None else None
    print(
        f"sweep: {len(variants)} variants, {len(done)} already in {store.out}, {len(todo)} to run"
        + (f"; convergence check of {len(checked)} ({check.method})" if check is not None else ""),
        flush=True,
    )
    stats = {
        "ran": 0,
        "interrupted": False,
        "seconds": 0.0,
        "workers": 0,
        "metrics": metrics,
        "convergence": store.record.get("convergence"),
    }
    if todo:
        task = _task(check, checked, metrics)
        try:
            _execute(
                spec,
                store,
                variants,
                todo,
                data,
                digest,
                motion,
                scheduler,
                workers,
                timeout,
                retries,
                progress_tty,
                stats,
                task,
            )
        except KeyboardInterrupt:
            stats["interrupted"] = True
            print(
                f"\nsweep: interrupted; {len(done) + stats['ran']} of {len(variants)} variants in {store.out}. "
                "Run the same command again to continue.",
                file=sys.stderr,
                flush=True,
            )
        finally:
            stats["rows"] = store.consolidate()
    else:
        stats["rows"] = store.consolidate()
    return stats


def _task(check: Check | None, checked: set | None, metrics: list):
    """(the function a worker runs for a variant, its extra arguments for run ``run``)."""
    if check is None:
        return run_variant, lambda run: ()
    return run_checked, lambda run: (metrics, check.rerun if run in checked else None)


def _execute(
    spec,
    store,
    variants,
    todo,
    data,
    digest,
    motion,
    scheduler,
    workers,
    timeout,
    retries,
    progress_tty,
    stats,
    task=None,
):
    from distributed import as_completed

    client, cluster = connect(scheduler, workers)
    progress = None
    try:
        client.register_plugin(FmuPlugin(data, digest), name=plugin_name(digest))
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT)
        except TimeoutError:
            raise SweepError(f"no worker joined the scheduler {scheduler} within {WORKER_WAIT:g} s") from None
        threads = sum(client.nthreads().values())
        stats["workers"] = threads
        window = 4 * threads + 8  # tasks queued at once: enough to keep every thread busy
        progress = Progress(
            len(variants),
            "sweep: {percent:3d} % ({done}/{total} done, {failed} not ok, {running} running), "
            "{rate:.2f} variants/s, ETA {eta:.0f} s",
            already=len(variants) - len(todo),
            tty=progress_tty,
            unit="variant",
        )
        failed = 0
        queue = iter(todo)
        pending = {}

        function, extra = task or _task(None, None, [])
        # a checked sweep's tasks differ from an unchecked one's (and between check settings)
        tag = (
            ""
            if function is not run_checked
            else "c" + content_hash(json.dumps(store.record.get("convergence"), sort_keys=True).encode())[:6]
        )

        def submit(run):
            args = (digest, run, variants[run], spec.stop_time, spec.communication_step, motion)
            args += (*extra(run), timeout) if function is run_checked else (timeout,)
            f = client.submit(
                function,
                *args,
                key=f"variant{tag}-{digest[:8]}-{store.record['spec_sha256'][:8]}-{run}",
                retries=retries,
                pure=False,
            )
            pending[f] = run
            return f

        start = time.perf_counter()
        flow = as_completed([submit(r) for r in itertools.islice(queue, window)])
        last_threads = time.monotonic()
        for f in flow:
            run = pending.pop(f)
            try:
                row = f.result()
            except Exception as e:  # noqa: BLE001 -- the task, not the variant, failed
                if _scheduler_lost(e):
                    raise SweepError(
                        f"lost the Dask scheduler ({type(e).__name__}: {e}); the finished rows "
                        f"are in {store.out}, run the same command again to continue"
                    ) from None
                row = {"run": run, **variants[run], "status": LOST, "message": f"{type(e).__name__}: {e}"}
            store.add(row)
            stats["ran"] += 1
            nxt = next(queue, None)
            if nxt is not None:
                flow.add(submit(nxt))
            if time.monotonic() - last_threads > 2.0:
                threads, last_threads = sum(client.nthreads().values()), time.monotonic()
            failed += row["status"] != "ok"
            progress.advance(failed=failed, running=min(len(pending), threads))
        stats["seconds"] = time.perf_counter() - start
    finally:
        if progress is not None:
            progress.close()
        store.flush()
        try:
            client.close(timeout=10)
            if cluster is not None:
                cluster.close(timeout=10)
        except Exception:  # noqa: BLE001 -- closing after a lost scheduler
            pass


def _scheduler_lost(e: Exception) -> bool:
    """A future that failed because the connection to the scheduler is gone (its futures are
    cancelled then), not because of its task."""
    from concurrent.futures import CancelledError

    from distributed.comm.core import CommClosedError

    return isinstance(e, (CancelledError, CommClosedError, OSError))
