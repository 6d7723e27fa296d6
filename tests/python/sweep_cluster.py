"""A real Dask cluster on loopback for the sweep tests: a `dask scheduler` and `dask worker`
processes (the venv's dask command), on free ports of 127.0.0.1, stopped at the end.

Each worker runs without a nanny (one process, so that killing it kills the worker) and
with its own TMPDIR, where the sweep's worker plugin unpacks the FMU it received.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from helpers import require_fmu

DASK = str(Path(sys.executable).with_name("dask"))
STICKSLIP = str(Path(sys.executable).with_name("stickslip"))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Cluster:
    def __init__(self, root: Path):
        self.root = root
        self.address = f"tcp://127.0.0.1:{free_port()}"
        self.scheduler = None
        self.workers = []  # (process, its TMPDIR)

    def start_scheduler(self):
        port = self.address.rsplit(":", 1)[1]
        self.scheduler = subprocess.Popen(
            [DASK, "scheduler", "--host", "127.0.0.1", "--port", port, "--no-dashboard"],
            stdout=subprocess.DEVNULL,
            stderr=open(self.root / "scheduler.log", "w"),
        )

    def start_worker(self):
        k = len(self.workers)
        tmp = self.root / f"worker{k}"
        tmp.mkdir()
        env = dict(os.environ, TMPDIR=str(tmp))
        p = subprocess.Popen(
            [
                DASK,
                "worker",
                self.address,
                "--host",
                "127.0.0.1",
                "--nthreads",
                "1",
                "--no-nanny",
                "--no-dashboard",
                "--local-directory",
                str(tmp),
                "--death-timeout",
                "60",
            ],
            stdout=subprocess.DEVNULL,
            stderr=open(self.root / f"worker{k}.log", "w"),
            env=env,
        )
        self.workers.append((p, tmp))

    def wait(self, n: int, timeout: float = 60.0):
        """Until n workers are registered with the scheduler."""
        from distributed import Client

        with Client(self.address, timeout=timeout) as c:
            c.wait_for_workers(n, timeout=timeout)

    def stop(self):
        """SIGTERM to every process, SIGKILL to those still running 3 s later: a worker
        still inside a variant (the timeout test's run far too long) finishes its FMU call
        before it closes, which took 15 s."""
        for p in [w for w, _ in self.workers] + [self.scheduler]:
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + 3
        for p in [w for w, _ in self.workers] + [self.scheduler]:
            if p is None:
                continue
            try:
                p.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


@contextmanager
def loopback_cluster(root: Path, workers: int = 2):
    root.mkdir(parents=True, exist_ok=True)
    c = Cluster(root)
    try:
        c.start_scheduler()
        for _ in range(workers):
            c.start_worker()
        c.wait(workers)
        yield c
    finally:
        c.stop()
        shutil.rmtree(root, ignore_errors=True)


def sweep(*args, **kw) -> subprocess.CompletedProcess:
    """`stickslip sweep ARGS` as a user runs it; its output captured (not a terminal)."""
    return subprocess.run([STICKSLIP, "sweep", *map(str, args)], capture_output=True, text=True, **kw)


def _interruptible():
    """In the child before exec: SIGINT back to its default disposition. A shell that
    starts a command in the background without job control (`cmd &` in a script, as CI
    runners and nohup wrappers do) sets SIGINT to ignored, children inherit that, and
    Python then installs no KeyboardInterrupt handler: the sweep would never see the
    Ctrl-C the tests send. A user's terminal gives the default."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def sweep_process(*args) -> subprocess.Popen:
    """`stickslip sweep ARGS` running, its output on a pipe, interruptible by SIGINT."""
    return subprocess.Popen(
        [STICKSLIP, "sweep", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        preexec_fn=_interruptible,
    )


def write_spec(path, body: str, stop_time=0.1, step=1e-3):
    """A SPEC file at `path`: the reference motion through the FMU under test, then `body`."""
    path.write_text(
        f'stop_time = {stop_time}\ncommunication_step = {step}\nmotion = "reference"\nfmu = "{require_fmu()}"\n' + body
    )
    return path
