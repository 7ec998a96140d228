"""``python -m marine_fdi_env.info``: version, where the package and its agents and training code are
installed, which optional extras are importable; ``--imports``: the check of the package's layers
(:mod:`marine_fdi_env.layers`).  The command is :func:`marine_fdi_env.cli.info.info_main`."""

if __name__ == "__main__":
    import sys

    from marine_fdi_env.cli.info import info_main

    sys.exit(info_main())
