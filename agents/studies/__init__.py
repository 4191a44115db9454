"""The studies built on the controllers and the training: the reproduction of He et al. (2018),
the training wall time to a precise agent, and the model-mismatch study.

The package, one module per study: :mod:`~stewart_env.agents.studies.reproduce` (the paper's
case study), :mod:`~stewart_env.agents.studies.time_to_agent` and the subpackage
:mod:`~stewart_env.agents.studies.mismatch` (its modules by job).
"""

# The functions named as their modules (reproduce.reproduce, time_to_agent.time_to_agent) are not
# re-exported here: the name would hide the module (`import ...studies.time_to_agent as m` would
# give the function); stewart_env.agents re-exports reproduce.
from stewart_env.agents.studies.mismatch import MismatchSettings, run_mismatch
from stewart_env.agents.studies.time_to_agent import SeedResult, TimeToAgentError, TimeToAgentResult

__all__ = [
    "MismatchSettings",
    "SeedResult",
    "TimeToAgentError",
    "TimeToAgentResult",
    "run_mismatch",
]
