"""Valid arguments of the fused step's compiled reset (``BatchStep.reset``), for the env tests
that change one of them at a time."""

from __future__ import annotations

import numpy as np


def batch_reset_arguments(core, m: int, **observation) -> dict:
    """Valid arguments of ``BatchStep.reset`` for the first m rows of ``core`` (a PlatformBatch),
    in its order; ``observation`` adds the start observation's (measured, observe, noise)."""
    state = tuple(np.ascontiguousarray(x[:m]) for x in core._state)
    return {
        "rows": np.arange(m, dtype=np.int64),
        "start": state,
        "leg_forces": None,
        "reference": state,
        "leg_lengths": np.empty((m, 6)),
        "leg_rates": np.empty((m, 6)),
        "condition": np.empty(m),
        "error_vectors": np.empty((4, m, 3)),
        "error_norms": np.empty((4, m)),
        **observation,
    }
