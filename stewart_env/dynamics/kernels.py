"""The compiled kernels' Python face: the packed parameter layout and the kernels themselves.

The one implementation of the Stewart platform's kinematics and dynamics is C++, compiled into
one extension per instruction-set target when the package is installed, the fastest the
processor runs imported as ``stewart_env._core``; its sources are
``stewart_env/_core/cpp/physics/kernels.hpp`` (kinematics and dynamics), ``physics/rk4.hpp`` (the
integrator) and ``physics/laws.hpp`` (the compiled control laws); beside them
``tasks/task_kernels.hpp`` (the tasks' errors, termination and reward) and ``env/env_step.hpp``
(the environment's control step) compile the
per-step work of the tasks and the environment.  ``docs/physics.md`` in the repository is the full
account of the physics, with a table of every function of those files (its section 3.2).

Kernels take ``prm`` of shape (Np, N_PARAMS), one row per platform (Np == 1 broadcasts over the
batch), C-contiguous float64 arrays, and the model's switch bits ``flags`` (:data:`C1` ...
:data:`CENTROIDAL`, docs/physics.md section 6).  Each checks the shapes of its arrays and raises
ValueError naming the one that does not fit; values are the callers' to check
(:func:`stewart_env.dynamics.model.batch_args`).
"""

from stewart_env._core import (  # noqa: F401  (the kernels, re-exported)
    C1,
    C2,
    C3,
    C4,
    CENTROIDAL,
    N_PARAMS,
    PACKED_LAYOUT,
    first_nonfinite,
    forward_batch,
    inverse_batch,
    jacobian_batch,
    largest_rotation_error,
    leg_kinematics_batch,
    leg_sensors_batch,
    mass_bias_batch,
    rotation_errors_batch,
)


def _offsets(layout):
    """{key: slice} of each entry of a packed layout, and the row's length (plain Python, run
    once at import).  docs/physics.md section 2 (no paper equation)."""
    slices, start = {}, 0
    for key, shape in layout:
        size = 1
        for extent in shape:
            size *= extent
        slices[key] = slice(start, start + size)
        start += size
    return slices, start


#: {config key: slice} of each entry of :data:`PACKED_LAYOUT` (the C++ kernels' own layout, the
#: one source of it) in the packed row.
PACKED_SLICES, _ = _offsets(PACKED_LAYOUT)
OFF_MP = PACKED_SLICES["platform.mass"].start
OFF_DAMP = PACKED_SLICES["damping"].start
