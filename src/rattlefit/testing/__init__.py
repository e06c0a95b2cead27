"""What rattlefit's tests, benchmarks and studies share; not imported by ``import rattlefit``.

- :mod:`rattlefit.testing.shared`: the independent simulator's recordings and their truth;
- :mod:`rattlefit.testing.results`: result files with their provenance.

The recordings of other model forms that judge rattlefit live outside the package, in the
repository's ``validation/``.
"""
