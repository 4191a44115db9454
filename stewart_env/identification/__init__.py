"""Dynamic parameter identification of a Stewart platform from measured motion and leg forces.

* :mod:`.regressor`: the inverse dynamics linear in the inertial parameters,
  ``J^T F + W = Y theta`` (docs/physics.md section 5.6);
* :mod:`.base`: the base (identifiable) parameters and their map back to a platform;
* :mod:`.excitation`: Fourier-series excitation trajectories optimised for the condition number;
* :mod:`.estimate`: filtering, ordinary, weighted and physically consistent least squares;
* :mod:`.experiment`: the whole experiment on a stand-in plant, as the ``identify`` command runs it;
* :mod:`.log`: the drive-log format (schema, checked reader and writer);
* :mod:`.recording`: the excitation as set points, and a stand-in plant's drive log;
* :mod:`.logged`: identification from a drive log (``identify --record``).

docs/guides/identification.md is the user's guide.
"""

from stewart_env.identification.regressor import N_THETA, THETA_NAMES, regressor_matrix, theta_of  # noqa: F401
