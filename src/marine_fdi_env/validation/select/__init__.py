"""Select: which mechanisms the data name, by forward selection with cross-validation, and what is left unexplained.

* :mod:`.selection` - :func:`~.selection.select_causes`, the steps of the selection; :mod:`.rules` - its rules in
  one object;
* :mod:`.forward_step`, :mod:`.candidates`, :mod:`.evidence`, :mod:`.eligibility`, :mod:`.pairs`,
  :mod:`.calibration_candidates`, :mod:`.alternatives`, :mod:`.revision` - one step, a candidate's score, how a
  cause earns its place, the revision after the forward steps;
* :mod:`.unexplained`, :mod:`.window_scan`, :mod:`.calibration_scan`, :mod:`.data_scale` - what the final model
  leaves unexplained;
* :mod:`.replicas`, :mod:`.binomial` - would data like these name the same causes again.

Imports the data-in and fit stages only.
"""
