"""pytest configuration for tests/python, and the one fixture several modules share: ``cluster``,
a loopback Dask cluster per module (the sweep tests: test_sweep_cluster.py, test_convergence.py).

Marker ``slow``: long-running tests (e.g. full reference simulations through the FMU, the
statistical checks of the fit and the identification). A plain ``pytest`` deselects them; run
them with ``pytest --runslow`` or ``RUN_SLOW=1 pytest``, only them with ``pytest -m slow
--runslow``. ``scripts/test.sh`` (CI) runs every test with ``--runslow``; ``--quick`` leaves
the slow ones out.

Marker ``full``: tests CI runs but the inner loop (``scripts/test.sh --quick``, which
deselects them with ``-m "not full"``) leaves out: those that need the win64 or darwin64
binaries or a second master, start Dask clusters, or take more than a few seconds each.
"""

import os

import pytest


def _truthy(value):
    return value.strip().lower() in ("1", "true", "yes", "on")


def pytest_addoption(parser):
    parser.addoption(
        "--runslow",
        action="store_true",
        default=False,
        help="also run tests marked @pytest.mark.slow (same as env RUN_SLOW=1)",
    )


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "slow: long-running test; deselected unless --runslow or RUN_SLOW=1",
    )
    config.addinivalue_line(
        "markers",
        "full: in CI's full run, not in the inner loop (scripts/test.sh --quick deselects it)",
    )


def _run_slow(config):
    return config.getoption("--runslow") or _truthy(os.environ.get("RUN_SLOW", ""))


def pytest_collection_modifyitems(config, items):
    if _run_slow(config):
        return
    selected, deselected = [], []
    for item in items:
        (deselected if item.get_closest_marker("slow") else selected).append(item)
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = selected


def pytest_report_header(config):
    state = "included" if _run_slow(config) else "deselected (use --runslow or RUN_SLOW=1)"
    return f"slow tests: {state}"


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """A loopback Dask cluster (tests/python/sweep_cluster.py) for the sweep tests of one module."""
    from helpers import require_fmu
    from sweep_cluster import loopback_cluster

    require_fmu()
    with loopback_cluster(tmp_path_factory.mktemp("dask")) as c:
        yield c
