"""Reports people can read: a verdict on a calibration and a self-contained HTML page.

* :mod:`optcal.applications.quality.evidence` gathers the measured facts (held-out error, noise floor, model
  check, determination, coverage, outliers, the diagnosis's effects), and
  :mod:`optcal.applications.quality.simulation_band` places χ² and the held-out rms among refits of
  simulations of the fitted model;
* :mod:`optcal.applications.quality.verdict` judges them: ``good``, ``usable with care`` or ``not usable``,
  with the reasons in plain words and numbers;
* :mod:`optcal.report.parameters` states the calibration in engineers' units with confidence intervals;
* :mod:`optcal.report.document` assembles the content of a report per command
  (:mod:`optcal.report.fleet_report` for ``optcal fleet``, :mod:`optcal.report.plan_report` for
  ``optcal plan``), and :mod:`optcal.report.render` renders it with Jinja2 into one HTML file
  (figures inline).
"""
