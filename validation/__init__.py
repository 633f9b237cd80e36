"""validation: the measurement proved end to end against simulated and rendered ground truth.

- :mod:`validation.case`: one case (scenario / render / measure) and its TOML form;
- :mod:`validation.e2e`: ``run_case(case)`` -- sim -> synth -> rollfric -> metrics, with
  per-stage timings (``rollfric validate``; ``rollfric bench`` calls it too);
- :mod:`validation.report`: the report directory of one case (plots, metrics);
- :mod:`validation.sweep`: grids of cases on Dask distributed, resumable tidy tables
  (``rollfric sweep``); example studies in ``validation/sweeps/*.toml``.
"""
