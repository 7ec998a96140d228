"""Report: the validation report of a dataset, its Markdown, its plots, and what ``validate --check`` prints.

* :mod:`.build` - :func:`~.build.run_validation` (load, select, explain, assemble the JSON report), the fitted
  engine, the hold-out;
* :mod:`.conclusion` - what the data allow, the report's lead;
* :mod:`.markdown`, :mod:`.plots` - the report as Markdown and figures;
* :mod:`.data_check` - ``validate --check`` and ``--columns``: the dataset as the pipeline will use it.

The last stage: imports every other stage; only the command line imports it.
"""
