"""Makes the calibration example's measured runs (docs/calibration.md, "The data").

The reference arm's FMU is run with the parameters in TRUTH below (the fit is never told
them; calibration.toml starts 20-50 % away) over two motions, sampled every 1 ms:

* ``reference.csv``: the reference motion (shared/reference-manipulator.md), 2 s;
* ``out_and_back.csv``: examples/motions/pick_and_return.toml, joint 1 out and back (a
  reversal, a dwell and the way back), 3 s.

Columns: ``t`` (s), ``motor1`` .. ``motor4`` (the commanded q*_i: the motor encoders over
the gear ratio, taken as exact), ``link1`` (rad) and ``link3`` (m): the link-side encoders
of the flexible joints, quantized to their resolution (a 22-bit absolute encoder on joint
1: 2π/2^22 rad; a 1 µm linear scale on joint 3) and with Gaussian noise of standard
deviation 2e-6 rad and 1e-6 m (drawn from seed 1 for the first run, 2 for the second),
written with 10 significant digits.

    python examples/calibration/make_data.py [--fmu target/fmu/StickSlipManipulator.fmu]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from stickslip.fit.synthetic import measure, write_csv
from stickslip.fmu import DEFAULT_FMU
from stickslip.motion import load_motion_for

HERE = Path(__file__).resolve().parent
TRUTH = {
    "mu_k[1]": 0.15,
    "mu_s[1]": 0.19,
    "b_v[1]": 2.0,
    "mu_k[3]": 0.18,
    "mu_s[3]": 0.23,
    "k[3]": 6.5e5,
}
ENCODERS = {  # FMU output: (column, noise standard deviation, resolution)
    "q[1]": ("link1", 2e-6, 2 * math.pi / 2**22),
    "q[3]": ("link3", 1e-6, 1e-6),
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fmu", default=str(DEFAULT_FMU))
    a = p.parse_args()
    from fmpy import read_model_description

    md = read_model_description(a.fmu)
    out_and_back = load_motion_for(HERE.parents[0] / "motions" / "pick_and_return.toml", md)
    runs = {
        "reference.csv": dict(duration=2.0, motion=None, seed=1),
        "out_and_back.csv": dict(duration=3.0, motion=out_and_back, seed=2),
    }
    for name, run in runs.items():
        columns = measure(a.fmu, TRUTH, ENCODERS, **run)
        write_csv(columns, HERE / name, digits=10)
        print(f"make_data.py: {HERE / name}: {len(columns['t'])} samples")


if __name__ == "__main__":
    main()
