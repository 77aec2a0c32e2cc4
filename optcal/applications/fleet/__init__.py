"""Fleets: calibrate many units on Dask, flag the odd ones, borrow strength from the population.

:mod:`~optcal.applications.fleet.inputs` (folders, globs, manifests → units), :mod:`~optcal.applications.fleet.unit`
(the per-unit tasks, the same code path as ``optcal calibrate``),
:mod:`~optcal.applications.fleet.population` (robust bands, flags, figures), :mod:`~optcal.applications.fleet.prior`
(empirical-Bayes population prior, the refit with it), :mod:`~optcal.applications.fleet.engine` (Dask),
:mod:`~optcal.applications.fleet.results` (table, summary, report), :mod:`~optcal.applications.fleet.synthetic`
(synthetic fleets with known truth).  Dask is needed only by the engine
(``pip install 'optcal[fleet]'``).
"""
