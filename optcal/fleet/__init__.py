"""Fleets: calibrate many units on Dask, flag the odd ones, borrow strength from the population.

:mod:`~optcal.fleet.inputs` (folders, globs, manifests → units), :mod:`~optcal.fleet.unit`
(the per-unit tasks, the same code path as ``optcal calibrate``),
:mod:`~optcal.fleet.population` (robust bands, flags, figures), :mod:`~optcal.fleet.prior`
(empirical-Bayes population prior, the refit with it), :mod:`~optcal.fleet.engine` (Dask),
:mod:`~optcal.fleet.results` (table, summary, report), :mod:`~optcal.fleet.synthetic`
(synthetic fleets with known truth).  Dask is needed only by the engine
(``pip install 'optcal[fleet]'``).
"""
