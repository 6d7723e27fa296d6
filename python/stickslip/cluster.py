"""The Dask cluster of ``stickslip sweep`` and ``stickslip fit``: its command-line arguments
and the client.

``--scheduler ADDRESS`` connects to an existing cluster; otherwise a LocalCluster of
``--workers`` processes (one thread each, no dashboard: nothing listens on port 8787 and no
port warning reaches the console). ``stickslip fit --workers 0`` runs every FMU run in its
own process instead.
"""

from __future__ import annotations

import argparse
import os
import threading


class ClusterError(RuntimeError):
    """The scheduler at ``--scheduler`` cannot be reached."""


def cluster_arguments(p: argparse.ArgumentParser, in_process: bool = False) -> None:
    """--scheduler ADDRESS | --workers N (see :func:`connect`); ``in_process``: --workers 0
    runs everything in this process."""
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://host:8786")
    where.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help=f"worker processes of the local cluster (default: the number of cores, {os.cpu_count()}"
        + ("; 0: every run in this process)" if in_process else ")"),
    )


def connect(scheduler: str | None, workers: int | None):
    """(client, cluster or None): a client of the scheduler at ``scheduler``, or of a new
    LocalCluster of ``workers`` processes (default: one per core) that the caller closes."""
    import logging

    from distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="20s"), None
        except (OSError, ValueError) as e:
            raise ClusterError(f"cannot reach the Dask scheduler at {scheduler}: {e}") from None
    cluster = LocalCluster(
        n_workers=workers or os.cpu_count() or 1,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    return Client(cluster), cluster


class Connecting:
    """:func:`connect` started in a thread now, so that the caller's own work (reading the data,
    filtering it) goes on while the LocalCluster's workers start (about a second on 2 cores).
    ``prepare(client)``, where given, runs in the thread too, once connected (a worker plugin's
    registration, which waits for every worker to set it up). :meth:`result` waits for both;
    :meth:`close` ends what was started, for a caller that fails before it needs the cluster."""

    def __init__(self, scheduler: str | None, workers: int | None, prepare=None):
        self._result, self._error = None, None
        self._thread = threading.Thread(target=self._run, args=(scheduler, workers, prepare), name="stickslip-connect")
        self._thread.start()

    def _run(self, scheduler, workers, prepare) -> None:
        try:
            self._result = connect(scheduler, workers)
            if prepare is not None:
                prepare(self._result[0])
        except BaseException as e:  # noqa: BLE001 -- raised again in the caller's thread by result()
            self._error = e

    def result(self):
        """(client, cluster or None), as :func:`connect` returns them, or the exception of the
        connection or of ``prepare`` (what was started is closed then)."""
        self._thread.join()
        if self._error is not None:
            self.close()
            raise self._error
        return self._result

    def close(self) -> None:
        """Waits for the start to end and closes the client and the cluster it made."""
        self._thread.join()
        if self._result is not None:
            client, cluster = self._result
            client.close()
            if cluster is not None:
                cluster.close()
