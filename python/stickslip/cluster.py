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
