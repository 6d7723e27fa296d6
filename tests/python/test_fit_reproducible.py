"""The same SPEC and seed give the same fit (issue 41, item 5): fit.json equal, wall times
aside, whether the runs go to this process or to a cluster of two workers, and whether or not
a process that keeps a core busy runs beside the fit.

What could make them differ, and why it does not: the starts run in threads and their runs land
on whichever worker is free, so anything shared that keeps the order in which runs finish would
show it (the list of failed runs is sorted before it is written); an FMU instance is reused
across runs (fmi2Reset builds the engine anew, so a run does not depend on the worker's earlier
ones); the Latin hypercube's starts come from the SPEC's seed.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import fit_cases as fc
from sweep_cluster import STICKSLIP

TIMES = {"wall_s"}  # what may differ between two runs of the same fit


def _without_times(x):
    if isinstance(x, dict):
        return {k: _without_times(v) for k, v in x.items() if k not in TIMES}
    if isinstance(x, list):
        return [_without_times(v) for v in x]
    return x


HOG = "import time\nend = time.time() + 600\nwhile time.time() < end:\n    pass\n"


@pytest.mark.full
def test_the_same_spec_gives_the_same_fit_json_at_any_worker_count_and_load(tmp_path):
    """Two parameters of the reference arm (μ_k[1], k[3]) from 0.5 s, three starts (the user's,
    the equation-error stage's, a Latin hypercube point of seed 7), multiple shooting then
    single: once with every run in this process, once by the command on a cluster of two
    workers with a busy-looping process beside it. fit.json is the same but for wall_s, to the
    last bit of every number."""
    data = fc.write_data(tmp_path / "run.csv", fc.measured(0.5, seed=2))
    names = ["mu_k[1]", "k[3]"]
    spec = fc.spec(fc.experiment(data), names, {"mu_k[1]": 0.13, "k[3]": 6e5}, starts=3, seed=7)
    path = tmp_path / "fit.toml"
    path.write_text(fc.toml(spec))

    from stickslip.fit import fit

    fit(str(path), out=tmp_path / "alone", workers=0)
    hog = subprocess.Popen([sys.executable, "-c", HOG])
    try:
        done = subprocess.run(
            [STICKSLIP, "fit", str(path), "--out", str(tmp_path / "loaded"), "--workers", "2"],
            capture_output=True,
            text=True,
            timeout=900,
        )
    finally:
        hog.kill()
        hog.wait()
    assert done.returncode == 0, done.stderr
    alone, loaded = (json.loads((tmp_path / d / "fit.json").read_text()) for d in ("alone", "loaded"))
    assert alone["n_evaluations"] > 0
    a, b = _without_times(alone), _without_times(loaded)
    differing = [k for k in a if a[k] != b.get(k)]
    assert not differing, {k: (a[k], b.get(k)) for k in differing}
    assert (tmp_path / "alone" / "fitted.toml").read_text().replace(str(tmp_path / "alone"), "DIR") == (
        tmp_path / "loaded" / "fitted.toml"
    ).read_text().replace(str(tmp_path / "loaded"), "DIR")
