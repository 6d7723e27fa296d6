"""Damped drives with backlash step through the FMU (issue 23's reproducer).

The reference arm with drive damping h = 50 in both flexible joints and clearances
Delta[1] = 4.62e-4 rad, Delta[3] = 3e-5 m, mu_k = 0.19 and mu_s = 0.21 in both: under the
study's (2.1) as written, the damper pulled while the flanks separated and every run ended
in fmi2Discard at t = 0.080 s ("Newmark iteration did not converge"), with fixed 2e-6 s
sub-steps and with error control alike. With the flank released where (2.1) would pull
(src/forces/drive.rs) the whole 2 s reference motion completes at 1 ms communication steps,
every output stays finite, the drive forces of the joints with clearance never pull
(sign(F_drive) = sign(eps_joint) wherever the drive transmits force), and the energy
account closes: E - E0 = W_drive - Q_friction - Q_damping to 1e-6 of the drive work.
"""

import numpy as np
import pytest

from helpers import Slave, input_vector

REPRODUCER = {
    "h[1]": 50.0,
    "h[3]": 50.0,
    "Delta[1]": 4.62e-4,
    "Delta[3]": 3e-5,
    "mu_k[1]": 0.19,
    "mu_s[1]": 0.21,
    "mu_k[3]": 0.19,
    "mu_s[3]": 0.21,
}


@pytest.mark.parametrize("stepping", [{}, {"h_min": 2e-6, "h_max": 2e-6}], ids=["error-control", "fixed-2e-6"])
def test_damped_drives_with_backlash_complete_the_reference_motion(stepping):
    names = [
        "eps",
        "F_drive[1]",
        "F_drive[3]",
        "eps_joint[1]",
        "eps_joint[3]",
        "E_kin",
        "E_pot",
        "E_spring",
        "W_drive",
        "Q_friction",
        "Q_damping",
        "n_stick[1]",
        "n_stick[3]",
    ]
    with Slave("damped-clearance") as s:
        s.initialize(start_values={**REPRODUCER, **stepping})
        vrs = s.vars.vrs(names)
        rows = []
        for k in range(2000):
            t = k * 1e-3
            s.set_inputs(input_vector(t))
            s.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=1e-3)
            rows.append(s.fmu.getReal(vrs))
        out = dict(zip(names, np.array(rows).T, strict=True))
    assert all(np.isfinite(v).all() for v in out.values())
    for j, gap in ((1, 4.62e-4), (3, 3e-5)):
        force, deflection = out[f"F_drive[{j}]"], out[f"eps_joint[{j}]"]
        engaged = force != 0.0
        assert engaged.any() and (~engaged).any(), f"joint {j}: both engaged and free phases expected"
        assert (np.sign(force[engaged]) == np.sign(deflection[engaged])).all(), f"joint {j}: a flank pulled"
        assert (np.abs(deflection[engaged]) >= gap).all()
    energy = out["E_kin"] + out["E_pot"] + out["E_spring"]
    account = energy - energy[0] - (out["W_drive"] - out["Q_friction"] - out["Q_damping"])
    assert np.abs(account).max() <= 1e-6 * np.abs(out["W_drive"]).max()
    assert out["Q_damping"][-1] > 0.0
