"""``python -m marine_fdi_env.cli``: the ``marine-fdi`` command."""

from .main import console_main

console_main()
