"""Every malformed SPEC is refused by `stickslip sweep` before anything runs: exit 1, a
message naming the key or variable and the problem, and no result directory created.
The names are checked against the FMU's modelDescription: unknown names, inputs, outputs
and fixed parameters are refused with the reason. Also: the variant list of a valid SPEC
(grid order, grid x sample, seeded draws)."""

from __future__ import annotations

import pytest

from helpers import require_fmu
from stickslip import cli, spec

HEAD = 'stop_time = 0.1\ncommunication_step = 1e-3\nmotion = "reference"\n'
GRID = '[grid]\n"mu_k[3]" = [0.1, 0.2]\n'

MALFORMED = {
    "unknown name": (HEAD + '[grid]\n"mu_k[5]" = [0.1]\n', "unknown variable `mu_k[5]`"),
    "misspelt name": (HEAD + '[grid]\n"mu_kk[3]" = [0.1]\n', "did you mean mu_k[3]"),
    "input": (HEAD + '[grid]\n"q_star[1]" = [0.1]\n', "`q_star[1]` is an input: the motion sets it"),
    "output": (HEAD + '[grid]\n"eps" = [0.1]\n', "`eps` is an output, not a parameter"),
    "fixed parameter": (HEAD + '[grid]\n"h_max" = [1e-5]\n', "`h_max` is a fixed parameter"),
    "boolean fixed parameter": (HEAD + '[grid]\n"use_start_values" = [1]\n', "`use_start_values` is a fixed parameter"),
    "empty grid": (HEAD + "[grid]\n", "[grid] is empty"),
    "empty value list": (HEAD + '[grid]\n"mu_k[3]" = []\n', "grid `mu_k[3]` = []: must be a non-empty list"),
    "value not a number": (
        HEAD + '[grid]\n"mu_k[3]" = [0.1, "high"]\n',
        "grid `mu_k[3]`: 'high' is not a finite number",
    ),
    "value twice": (HEAD + '[grid]\n"mu_k[3]" = [0.1, 0.1]\n', "grid `mu_k[3]` lists a value twice"),
    "out of the FMU's range": (HEAD + '[grid]\n"k[1]" = [-1.0]\n', "`k[1]` = -1 is outside the FMU's range"),
    "uniform reversed": (
        HEAD + '[sample]\nn = 3\nseed = 1\n"k[1]" = { uniform = [2e6, 5e5] }\n',
        "sample `k[1]`: uniform = [2000000.0, 500000.0] needs low < high",
    ),
    "normal sd zero": (
        HEAD + '[sample]\nn = 3\nseed = 1\n"k[1]" = { normal = [1e6, 0] }\n',
        "needs a standard deviation > 0",
    ),
    "loguniform from zero": (
        HEAD + '[sample]\nn = 3\nseed = 1\n"v_s[3]" = { loguniform = [0, 1] }\n',
        "needs 0 < low < high",
    ),
    "one number": (
        HEAD + '[sample]\nn = 3\nseed = 1\n"k[1]" = { uniform = [5e5] }\n',
        "must be two finite numbers [low, high]",
    ),
    "unknown distribution": (
        HEAD + '[sample]\nn = 3\nseed = 1\n"k[1]" = { triangular = [1, 2] }\n',
        "sample `k[1]` = {'triangular': [1, 2]}: must be { uniform",
    ),
    "n zero": (HEAD + '[sample]\nn = 0\nseed = 1\n"k[1]" = { uniform = [5e5, 2e6] }\n', "[sample] `n` = 0"),
    "seed missing": (HEAD + '[sample]\nn = 3\n"k[1]" = { uniform = [5e5, 2e6] }\n', "[sample] `seed` = None"),
    "sample without parameters": (HEAD + "[sample]\nn = 3\nseed = 1\n", "[sample] draws no parameter"),
    "in grid and sample": (
        HEAD + GRID + '[sample]\nn = 3\nseed = 1\n"mu_k[3]" = { uniform = [0.1, 0.2] }\n',
        "['mu_k[3]'] both in [grid] and in [sample]",
    ),
    "nothing to sweep": (HEAD, "nothing to sweep"),
    "stop_time missing": ("communication_step = 1e-3\n" + GRID, "`stop_time` is missing"),
    "negative step": (
        "stop_time = 0.1\ncommunication_step = -1e-3\n" + GRID,
        "`communication_step` = -0.001: must be a positive number",
    ),
    "step longer than the run": (
        "stop_time = 0.1\ncommunication_step = 0.2\n" + GRID,
        "communication_step = 0.2 s is longer than stop_time",
    ),
    "not whole steps": (
        "stop_time = 0.1005\ncommunication_step = 1e-3\n" + GRID,
        "not a whole number of communication steps",
    ),
    "unknown key": (HEAD + "stoptime = 1\n" + GRID, "unknown key(s) ['stoptime']"),
    "not TOML": (HEAD + GRID + '"k[1]" = [1, \n', "not valid TOML"),
    "motion file missing": (
        'stop_time = 0.1\ncommunication_step = 1e-3\nmotion = "no/such.csv"\n' + GRID,
        "motion file 'no/such.csv' does not exist",
    ),
    "fmu missing": (HEAD + 'fmu = "no/such.fmu"\n' + GRID, "fmu 'no/such.fmu' does not exist"),
}


@pytest.mark.parametrize("body, message", MALFORMED.values(), ids=MALFORMED.keys())
def test_malformed_spec_refused_before_anything_runs(tmp_path, capsys, body, message):
    if 'fmu = "' not in body:
        body = (
            body.replace('motion = "reference"\n', f'motion = "reference"\nfmu = "{require_fmu()}"\n')
            if "motion" in body
            else f'fmu = "{require_fmu()}"\n' + body
        )
    path = tmp_path / "bad.toml"
    path.write_text(body)
    out = tmp_path / "out"
    assert cli.main(["sweep", str(path), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert message in err, err
    assert err.startswith(f"stickslip sweep: SPEC {path}") or "fmu" in message, err
    assert not out.exists()


def test_bad_motion_csv_refused(tmp_path, capsys):
    """A motion CSV without q_star of every joint is refused with the file and the columns."""
    csv = tmp_path / "m.csv"
    csv.write_text("time,q_star[1],q_star[2]\n0,0,0\n1,0.1,0\n")
    path = tmp_path / "spec.toml"
    path.write_text(f'stop_time = 0.1\ncommunication_step = 1e-3\nmotion = "{csv}"\nfmu = "{require_fmu()}"\n' + GRID)
    assert cli.main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert f"motion file {csv}: missing column(s) ['q_star[3]', 'q_star[4]']" in err, err


def test_variants_grid_order_times_samples():
    """Grid points in product order (last name fastest), each with the n samples in order;
    each parameter's draws depend only on (seed, its name), not on n or on the others."""
    s = spec.parse(
        HEAD + f'fmu = "{require_fmu()}"\n[grid]\n"mu_k[3]" = [0.1, 0.2]\n"h[1]" = [0, 10]\n'
        '[sample]\nn = 3\nseed = 5\n"k[1]" = { uniform = [5e5, 2e6] }\n'
    )
    v = s.variants()
    assert len(v) == len(s) == 12
    assert [(x["mu_k[3]"], x["h[1]"]) for x in v[::3]] == [(0.1, 0), (0.1, 10), (0.2, 0), (0.2, 10)]
    draws = [x["k[1]"] for x in v[:3]]
    assert [x["k[1]"] for x in v[3:6]] == draws and len(set(draws)) == 3
    more = spec.parse(
        HEAD + f'fmu = "{require_fmu()}"\n[sample]\nn = 5\nseed = 5\n'
        '"m[4]" = { normal = [4, 0.1] }\n"k[1]" = { uniform = [5e5, 2e6] }\n'
    ).variants()
    assert [x["k[1]"] for x in more[:3]] == draws
