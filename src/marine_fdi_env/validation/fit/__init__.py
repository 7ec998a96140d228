"""Fit: the measured dataset as a fitting problem and the model extended by named mechanisms.

* :mod:`.problem` - :class:`~.problem.FitProblem`: targets, channels, tolerances, one candidate model's predictions;
* :mod:`.nuisance` - the base model's uncertain parameters, fitted within their uncertainty;
* :mod:`.mechanisms` - the library of physical mechanisms and sensor calibrations;
* :mod:`.fitting`, :mod:`.held_out_state` - fitting a combination, cross-validation, valve openings at held-out
  points;
* :mod:`.synthesize` - synthetic "measured" data from the model with hidden mechanisms.

Imports the data-in stage (:mod:`.measured`) only.
"""
