"""What rattlefit's tests, benchmarks and studies share; not imported by ``import rattlefit``.

- :mod:`rattlefit.testing.shared`: the independent simulator's recordings and their truth;
- :mod:`rattlefit.testing.results`: result files with their provenance;
- :mod:`rattlefit.testing.diagnose_sets`: the calibration sets of ``rattlefit diagnose``.
"""
