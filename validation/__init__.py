"""validation: the measurement proved end to end against simulated and rendered ground truth.

- :mod:`validation.case`: one case (scenario / render / measure) and its TOML form;
- :mod:`validation.e2e`: ``run_case(case)`` -- sim -> synth -> rollfric -> metrics, with
  per-stage timings (``rollfric validate``; ``rollfric bench`` calls it too);
- :mod:`validation.metrics`: one case's metrics against the truth;
- :mod:`validation.report`: the report directory of one case (plots, metrics);
- :mod:`validation.sweep`: a sweep file and its cases (``rollfric sweep``); example studies
  in ``validation/sweeps/*.toml``; :mod:`validation.sweep_run` runs them on Dask distributed
  into resumable tidy tables (:mod:`validation.sweep_table`) and plots
  (:mod:`validation.sweep_plots`).
"""
