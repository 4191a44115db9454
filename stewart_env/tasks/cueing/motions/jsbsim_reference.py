"""Flight references from JSBSim (the extra ``jsbsim``): one of the aircraft models JSBSim ships
flown through a scripted manoeuvre, its motion at the pilot's eye point written as a motion file.

The aircraft (by default ``c172x``, JSBSim's Cessna 172) is trimmed in level flight at the given
altitude and calibrated airspeed, then the manoeuvre's control inputs are added to the trim's, open loop
(:data:`MANOEUVRES`); JSBSim integrates at a whole number of steps a sample, at least 120 Hz,
and the motion is sampled every ``dt``.  The
specific force is JSBSim's acceleration at the pilot's eye point (``accelerations/a-pilot-*``:
the aerodynamic, thrust and ground forces over the mass, with the rotation's terms at the eye
point), the angular velocity its body rates, both turned from JSBSim's axes (x forward, y right,
z down, feet) to the head frame's (x forward, y left, z up, metres).  The atmosphere is calm and
no input is random, so the same arguments give the same file, byte for byte.

From a shell::

    python -m stewart_env.tasks.cueing.motions.jsbsim_reference OUT.csv [MANOEUVRE [AIRCRAFT]]
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from stewart_env.errors import UsageError
from stewart_env.extras import require
from stewart_env.tasks.cueing.motion import VehicleMotion
from stewart_env.tasks.cueing.motions.motion_file import write_motion

__all__ = ["MANOEUVRES", "jsbsim_motion", "main", "write_jsbsim_reference"]

_FEET = 0.3048
#: JSBSim's slowest integration rate, Hz: it steps at dt / k, k the fewest steps a sample reaching it.
JSBSIM_RATE_HZ = 120.0


@contextlib.contextmanager
def _quiet_stdout():
    """The process's standard output sent to the null device for the block: JSBSim's C++ prints
    its banner there when a model is made, which would mix with a script's output."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _doublet(t: float, start: float, width: float, size: float) -> float:
    """+size for ``width`` seconds from ``start``, then -size as long, then 0."""
    if start <= t < start + width:
        return size
    if start + width <= t < start + 2.0 * width:
        return -size
    return 0.0


#: The manoeuvres: the control's property and its command (normalised, -1..1) by time, s.
MANOEUVRES: dict[str, tuple[str, Callable[[float], float]]] = {
    "aileron_doublet": ("fcs/aileron-cmd-norm", lambda t: _doublet(t, 1.0, 1.0, 0.3)),
    "elevator_doublet": ("fcs/elevator-cmd-norm", lambda t: _doublet(t, 1.0, 0.5, 0.1)),
    "rudder_doublet": ("fcs/rudder-cmd-norm", lambda t: _doublet(t, 1.0, 1.0, 0.3)),
}


def jsbsim_motion(
    manoeuvre: str = "aileron_doublet",
    aircraft: str = "c172x",
    duration: float = 15.0,
    dt: float = 0.01,
    altitude_ft: float = 4000.0,
    airspeed_kt: float = 100.0,
) -> VehicleMotion:
    """Fly ``aircraft`` through ``manoeuvre`` in JSBSim and return its motion at the pilot's eye.

    Args:
        manoeuvre: a key of :data:`MANOEUVRES`.
        aircraft: a model JSBSim ships (its folder under JSBSim's ``aircraft``).
        duration: the length of the flight after the trim, s, in (0, 600].
        dt: the sampling period, s, in (0, 0.1].
        altitude_ft: the trim altitude, ft above sea level.
        airspeed_kt: the trim calibrated airspeed, kt.

    Returns:
        The motion, named ``jsbsim_<aircraft>_<manoeuvre>``.

    Raises:
        ImportError: JSBSim is not installed (``stewart_env.extras.MissingExtra``, naming the extra ``jsbsim``).
        UsageError: an unknown manoeuvre or aircraft, a duration or dt out of range, a trim that fails.
    """
    require("jsbsim", "a JSBSim flight reference")
    import jsbsim

    if manoeuvre not in MANOEUVRES:
        raise UsageError.about(
            "manoeuvre", f"unknown manoeuvre {manoeuvre!r}; the manoeuvres are {', '.join(MANOEUVRES)}"
        )
    if not (isinstance(duration, (int, float)) and 0.0 < duration <= 600.0):
        raise UsageError.about("duration", f"must be a number of seconds in (0, 600], got {duration!r}")
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and 0.0 < dt <= 0.1):
        raise UsageError.about("dt", f"must be a number of seconds in (0, 0.1], got {dt!r}")
    substeps = math.ceil(dt * JSBSIM_RATE_HZ - 1e-9)
    root = Path(jsbsim.get_default_root_dir())
    if not aircraft or not (root / "aircraft" / aircraft / f"{aircraft}.xml").is_file():
        raise UsageError.about("aircraft", f"JSBSim ships no aircraft {aircraft!r} (under {root / 'aircraft'})")
    with _quiet_stdout():
        fdm = jsbsim.FGFDMExec(str(root))
        fdm.set_debug_level(0)
        fdm.load_model(aircraft)
    fdm.set_dt(dt / substeps)
    fdm["ic/h-sl-ft"] = float(altitude_ft)
    fdm["ic/vc-kts"] = float(airspeed_kt)
    fdm["ic/gamma-deg"] = 0.0
    fdm["ic/psi-true-deg"] = 0.0
    fdm.run_ic()
    fdm["propulsion/set-running"] = -1
    fdm["fcs/mixture-cmd-norm"] = 0.87
    fdm["fcs/throttle-cmd-norm"] = 0.8
    fdm.run()
    try:
        fdm["simulation/do_simple_trim"] = 1
    except jsbsim.TrimFailureError as err:
        raise UsageError.about(
            "airspeed_kt", f"{aircraft} does not trim at {airspeed_kt} kt and {altitude_ft} ft ({err})"
        ) from None
    control, command = MANOEUVRES[manoeuvre]
    trimmed = fdm[control]  # the manoeuvre's input adds to the trim's
    n = int(round(duration / dt)) + 1
    force, omega = np.empty((n, 3)), np.empty((n, 3))
    start = fdm.get_sim_time()
    for k in range(n):
        # JSBSim's body axes (y right, z down, feet) to the head frame's (y left, z up, metres)
        force[k] = [fdm[f"accelerations/a-pilot-{a}-ft_sec2"] for a in "xyz"]
        omega[k] = [fdm[f"velocities/{a}-rad_sec"] for a in "pqr"]
        for _ in range(substeps):
            fdm[control] = trimmed + command(fdm.get_sim_time() - start)
            fdm.run()
    force *= np.array([_FEET, -_FEET, -_FEET])
    omega *= np.array([1.0, -1.0, -1.0])
    name = f"jsbsim_{aircraft}_{manoeuvre}"
    source = f"JSBSim {jsbsim.__version__} {aircraft} {manoeuvre} at {altitude_ft:g} ft, {airspeed_kt:g} kt"
    return VehicleMotion(name, float(dt), force, omega, source=source, meta={"aircraft": aircraft})


def write_jsbsim_reference(path: str | Path, manoeuvre: str = "aileron_doublet", aircraft: str = "c172x", **kwargs):
    """Fly :func:`jsbsim_motion` and write it as a motion file (whole or not at all).

    Args:
        path: the CSV file.
        manoeuvre: a key of :data:`MANOEUVRES`.
        aircraft: a model JSBSim ships.
        **kwargs: the other arguments of :func:`jsbsim_motion`.

    Returns:
        The path written.

    Raises:
        ImportError: JSBSim is not installed (``stewart_env.extras.MissingExtra``).
        UsageError: as :func:`jsbsim_motion`.
        stewart_env.files.WriteError: the file cannot be written.
    """
    return write_motion(jsbsim_motion(manoeuvre, aircraft, **kwargs), path)


def main(argv: list[str] | None = None) -> int:
    """``python -m stewart_env.tasks.cueing.motions.jsbsim_reference OUT.csv [MANOEUVRE [AIRCRAFT]]``.

    Args:
        argv: the arguments (by default ``sys.argv[1:]``).

    Returns:
        0 when the file is written; 2 (with one line on stderr) for a request that cannot be done.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    if not 1 <= len(argv) <= 3 or argv[0].startswith("-"):
        print(
            f"usage: python -m {__name__} OUT.csv [MANOEUVRE [AIRCRAFT]] (manoeuvres: {', '.join(MANOEUVRES)})",
            file=sys.stderr,
        )
        return 2
    try:
        path = write_jsbsim_reference(*argv)
    except UsageError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
