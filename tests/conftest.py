"""Session settings for the tests.

Stable-Baselines3's ``learn()`` on a model without a logger of its own makes a folder per call under
``SB3_LOGDIR`` (else a new ``/tmp/SB3-<date>`` each time); the tests that build SB3 models directly share one.
"""

import os
import tempfile

os.environ.setdefault("SB3_LOGDIR", os.path.join(tempfile.gettempdir(), "marine_fdi_env-tests-sb3"))
