"""Recordings rattlefit's own model did not make, for judging it: not part of the installed
package, importable from the repository's root (the tests put it on ``sys.path`` through
pytest's ``pythonpath``; the studies through ``studies/common.py``).

- :mod:`validation.diagnose_sets`: the calibration sets of ``rattlefit diagnose``, clean
  recordings of another model form and recordings with an effect written in another form
  than the catalogue's (``python -m validation.diagnose_sets``);
- :mod:`validation.second_rig`: a second, structurally different simulator of an idle-rattle
  rig and its validation sets (``python -m validation.second_rig.validation_set``).
"""
