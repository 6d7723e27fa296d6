"""The identification SPEC and its logs (python/stickslip/identify/spec.py) as users get them wrong:
each refusal is one line naming the field, and 150 seeded mutations of a valid SPEC and of its
log (keys deleted or renamed, values of the wrong type, NaN, ±inf, strings; rows shuffled, the
file truncated or garbled, cells not numbers, columns dropped; the TOML text mangled) either
load or are refused so, never anything else; ``stickslip identify`` prints the refusal as one
line and exits 2 with nothing written.
"""

from __future__ import annotations

import random
import subprocess

import numpy as np
import pytest

import fit_cases as fc
from helpers import require_fmu
from sweep_cluster import STICKSLIP
from test_fit import _mutate_data, _mutate_spec, _mutate_toml, _paths

N = 4  # the reference arm's joints


def _log(path, rows=60, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(rows) * 4e-3
    columns = {"t": t}
    for i in range(1, N + 1):
        columns[f"q{i}"] = 0.1 * np.sin(2 * np.pi * 0.5 * t + i)
        columns[f"tau{i}"] = rng.standard_normal(rows)
    fc.write_data(path, columns)
    return columns


def _doc(root) -> dict:
    return {
        "fmu": str(require_fmu()),
        "experiment": [
            {
                "data": "run.csv",
                "time": "t",
                "positions": {f"q[{i}]": f"q{i}" for i in range(1, N + 1)},
                "torques": {f"tau[{i}]": f"tau{i}" for i in (1, 3)},
            }
        ],
        "identify": {"friction": "viscous", "armature": True, "prior": 1e-3},
    }


def test_a_valid_spec_loads(tmp_path):
    from stickslip.identify.spec import load

    _log(tmp_path / "run.csv")
    spec = load(_doc(tmp_path), base_dir=tmp_path)
    assert spec.n == N and spec.friction == "viscous" and sorted(spec.experiments[0].tau) == [1, 3]


@pytest.mark.parametrize(
    "change, says",
    [
        (lambda d: d.pop("experiment"), "no [[experiment]]"),
        (lambda d: d["identify"].update(friction="stribeck"), "identify.friction = 'stribeck'"),
        (lambda d: d["identify"].update(prior=0.0), "identify.prior = 0.0"),
        (lambda d: d["identify"].update(prior=float("nan")), "identify.prior"),
        (lambda d: d["identify"].update(armature="yes"), "identify.armature = 'yes'"),
        (lambda d: d["identify"].update(speed=1), "unknown key `speed`"),
        (lambda d: d["experiment"][0]["positions"].pop("q[2]"), "missing q[2]"),
        (lambda d: d["experiment"][0]["torques"].update({"tau[9]": "tau1"}), "'tau[9]': must be tau[i] with i in 1..4"),
        (lambda d: d["experiment"][0].update(data="none.csv"), "no such file"),
        (lambda d: d["experiment"][0]["positions"].update({"q[1]": "nope"}), "column 'nope' is not in run.csv"),
        (lambda d: d.update(fmu="missing.fmu"), "fmu = 'missing.fmu': no such file"),
        (lambda d: d.update(heldout=[{**d["experiment"][0]}]), "two runs share a name"),
    ],
)
def test_a_bad_spec_is_refused_in_one_line_naming_the_field(tmp_path, change, says):
    from stickslip.identify.spec import IdentifySpecError, load

    _log(tmp_path / "run.csv")
    doc = _doc(tmp_path)
    change(doc)
    with pytest.raises(IdentifySpecError) as e:
        load(doc, base_dir=tmp_path)
    assert says in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_a_log_with_a_nan_or_time_going_back_is_refused_naming_its_line(tmp_path):
    from stickslip.identify.spec import IdentifySpecError, load

    columns = _log(tmp_path / "run.csv")
    columns["tau3"][10] = np.nan
    fc.write_data(tmp_path / "run.csv", columns)
    with pytest.raises(IdentifySpecError, match=r"run.csv line 12, column 'tau3': not a finite number"):
        load(_doc(tmp_path), base_dir=tmp_path)
    columns = _log(tmp_path / "run.csv")
    columns["t"][20] = columns["t"][18]
    fc.write_data(tmp_path / "run.csv", columns)
    with pytest.raises(IdentifySpecError, match="time does not increase"):
        load(_doc(tmp_path), base_dir=tmp_path)


def test_the_command_refuses_a_bad_spec_in_one_line_with_exit_2(tmp_path):
    _log(tmp_path / "run.csv")
    doc = _doc(tmp_path)
    doc["identify"]["friction"] = "magic"
    (tmp_path / "id.toml").write_text(fc.toml(doc))
    done = subprocess.run(
        [STICKSLIP, "identify", str(tmp_path / "id.toml"), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "identify.friction = 'magic'" in done.stderr
    assert not (tmp_path / "out").exists()


def test_fuzzed_specs_and_logs_load_or_are_refused_in_one_line(tmp_path):
    from stickslip.identify.spec import IdentifySpec, IdentifySpecError, load

    outcomes, problems = {"loaded": 0, "refused": 0}, []
    for case in range(150):
        rng = random.Random(case)
        root = tmp_path / f"case{case}"
        root.mkdir()
        columns = _log(root / "run.csv", seed=case)
        doc = _doc(root)
        what = []
        for _ in range(rng.choice([1, 1, 2, 3])):
            if rng.random() < 0.6 and list(_paths(doc)):
                what.append(_mutate_spec(doc, rng))
            else:
                what.append(_mutate_data(root / "run.csv", columns, rng))
        source = doc
        if rng.random() >= 0.4:
            source = fc.toml(doc)
            if rng.random() < 0.2:
                source = _mutate_toml(source, rng)
                what.append("toml text")
            (root / "id.toml").write_text(source)
        try:
            spec = load(doc, base_dir=root) if source is doc else load(root / "id.toml")
            assert isinstance(spec, IdentifySpec)
            outcomes["loaded"] += 1
        except IdentifySpecError as e:
            outcomes["refused"] += 1
            if not str(e).strip() or "\n" in str(e):
                problems.append((case, what, f"not one line: {e!r}"))
        except Exception as e:  # noqa: BLE001 -- the finding: any other exception
            problems.append((case, what, f"{type(e).__name__}: {e}"))
    print(outcomes)
    assert not problems, f"{len(problems)} of 150:\n" + "\n".join(map(str, problems))
