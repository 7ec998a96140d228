"""Explain: every explanation the data allow, its parameters' intervals and the measurement that would decide.

* :mod:`.search` - the model structures near the selection's answer;
* :mod:`.explanations` - the set the data do not decide between, ranked by evidence;
* :mod:`.profiles` - profile-likelihood intervals;
* :mod:`.deciding` - the measurement that would decide between two explanations;
* :mod:`.summary`, :mod:`.plots` - the explanations in the report: JSON keys, lines, Markdown, figure.

Imports the data-in, fit and select stages only.
"""
