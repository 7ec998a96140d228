"""The reference diagnoser agent (thesis scheme): see :mod:`marine_fdi_env.diagnosis.agent`.

Kept in ``baselines/`` beside the other non-learned agents; the implementation lives in the
package so that the CLI and the environment use the same code.
"""

from marine_fdi_env.diagnosis.agent import BlockOutput, ReferenceDiagnoser

__all__ = ["ReferenceDiagnoser", "BlockOutput"]
