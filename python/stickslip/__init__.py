"""stickslip: the Python side of the stick-slip manipulator FMU.

The command ``stickslip`` (:mod:`stickslip.cli`) has the subcommands

* ``simulate``: the reference motion through the FMU with fmpy, as CSV (:mod:`stickslip.simulate`);
* ``study``: the source study's five cases (:mod:`stickslip.study`);
* ``sweep``: parameter grids and Monte Carlo samples on a Dask cluster (:mod:`stickslip.sweep`);
* ``bench``: variants per second of ``sweep`` on 1 and 2 workers (:mod:`stickslip.bench`).

Whether a number is converged (the same run with a tenfold tighter error tolerance, the
relative spread of every metric; ``--check-convergence`` of ``simulate`` and ``sweep``):
:mod:`stickslip.convergence`, :func:`stickslip.convergence.check_convergence`.

The reference motion lives in :mod:`stickslip.motion`, the FMU handling shared by all of
them (unpacking, the log capture, parameters by name) in :mod:`stickslip.fmu`.
"""
