"""Dynamics models by name, and the argument handling around the compiled kernels.

Names
-----
``classical``            Dasgupta & Mruthyunjaya (1998) as He et al. (2018) describe it: the
                         improved model with all four simplifications C1-C4 switched on.
``improved``             He et al. (2018), exact rigid-body dynamics; leg moments about the base
                         joints B_i and platform moments about P with body-point inertias
                         (the paper's eq. 49 form).
``improved_centroidal``  the same dynamics with every inertia about its body's CoM (eq. 55 form);
                         agrees with ``improved`` to rounding.

A name may carry switches after ``+``, e.g. ``"improved+c1"`` or ``"improved+c2+c3"``;
:data:`SIMPLIFICATIONS` says what each switch assumes.  :class:`~stewart_env.dynamics.spec.ModelSpec`
parses a name once (its module says which name is canonical); everything that takes a name takes
a spec too.

``docs/physics.md`` in the repository carries the derivation: the two improved forms in its
section 5, the switches c1-c4 and where each enters the equations in its section 6.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Sequence

import numpy as np

from stewart_env import _core, validation
from stewart_env.dynamics import kernels as K
from stewart_env.dynamics.spec import BASE_MODELS, ModelSpec, Switch
from stewart_env.params import ConfigError, PlatformParams
from stewart_env.rotations import rpy_to_matrix

#: Each switch's name and kernel bit (the values of :class:`~stewart_env.dynamics.spec.Switch`).
SWITCHES = {s.name.lower(): int(s) for s in Switch}
#: The classical model's simplifications, each a switch on the improved model: switch -> what it assumes.
SIMPLIFICATIONS = {
    "c1": "the leg does not spin about its own axis",
    "c2": "the universal joint's reaction moment lies along the leg (instead of the normal of the joint's two axes)",
    "c3": "parallel-axis part counted twice in the legs' Euler equations",
    "c4": "parallel-axis part counted twice in the platform's Euler equation",
}
#: The base models' names.
MODEL_NAMES = tuple(BASE_MODELS)


def parse_model_name(name: str | ModelSpec) -> tuple[str, int]:
    """Canonical name and kernel flags of a model name such as ``"improved+c1+c3"``: the
    :attr:`~ModelSpec.name` and :attr:`~ModelSpec.flags` of :meth:`ModelSpec.parse`, which new
    code calls instead.

    Args:
        name: a model name or a :class:`ModelSpec`.

    Returns:
        The pair (canonical name, kernel flags).

    Raises:
        UsageError: an unknown model or switch (a ValueError whose ``argument`` is ``"model"``).
    """
    spec = ModelSpec.parse(name)
    return spec.name, spec.flags


def _packed_value(params: PlatformParams, key: str):
    """The numbers of one entry of the packed layout (a config key such as ``"upper_leg.com"``)."""
    head, _, field = key.partition(".")
    value = getattr(params, head)
    if head == "damping":
        return value.universal, value.prismatic, value.spherical
    if not field:
        return value
    if isinstance(value, tuple):  # six legs
        return [getattr(body, field) for body in value]
    return getattr(value, field)


def _check_platform(name: str, params) -> None:
    """Raise ValueError naming ``name`` unless ``params`` is a PlatformParams."""
    if not isinstance(params, PlatformParams):
        raise ValueError(f"{name}: expected a PlatformParams (stewart_env.load_platform), got {type(params).__name__}")


def pack_params(params: PlatformParams) -> np.ndarray:
    """Kernel parameter row of a platform, in the order of ``kernels.PACKED_LAYOUT``.

    docs/physics.md section 2 lists the parameters, their symbols and frames.

    Args:
        params: the platform's parameters.

    Returns:
        The row (N_PARAMS,), float64.

    Raises:
        ValueError: ``params`` not a PlatformParams.
    """
    _check_platform("params", params)
    row = np.empty(K.N_PARAMS)
    for key, _ in K.PACKED_LAYOUT:
        row[K.PACKED_SLICES[key]] = np.ravel(_packed_value(params, key))
    return row


def check_home_condition(params: PlatformParams, packed: np.ndarray | None = None) -> None:
    """Raise ConfigError naming ``limits.max_condition`` unless the leg Jacobian (rows
    [e_i, (R p_i) x e_i], docs/physics.md section 4.4) at the platform's home pose has a
    condition number of at most ``params.limits.max_condition``: a model starts where the
    environment does not stop at once for a singularity.

    PlatformParams checks the rest of the home pose itself; this part needs the kernels'
    Jacobian (the one implementation), so the model checks it when a platform becomes a model.
    ``packed`` is the platform's :func:`pack_params` row when already at hand.

    Args:
        params: the platform.
        packed: its :func:`pack_params` row, if at hand (default: packed here).
    """
    _check_platform("params", params)
    row = pack_params(params) if packed is None else packed
    jacobian = np.empty((1, 6, 6))
    K.jacobian_batch(row[None], params.home_position[None], rpy_to_matrix(params.home_rpy)[None], jacobian)
    condition = float(np.linalg.cond(jacobian[0]))
    if not condition <= params.limits.max_condition:
        raise ConfigError(
            "limits.max_condition",
            f"the Jacobian's condition number at the home pose is {condition:.4g}, above {params.limits.max_condition}",
        )


#: Largest deviation |R^T R - I| (any entry) and |det R - 1| a rotation argument may show.  Products
#: of float64 rotations stay below 1e-12, and one rebuilt from float32 numbers (eps 6e-8) below
#: 1e-6; a matrix off by more is not a rotation, and the kernels would treat it as one silently.
ROTATION_TOLERANCE = 1e-6

# The wrench of a call that gives none, shared: the kernels never write their inputs.
_NO_WRENCH = np.zeros(6)


def batch_args(n_params: int, **arrays) -> tuple[int, bool, dict[str, np.ndarray]]:
    """Bring state arguments to one batch size: the argument check of every public entry point.

    Each keyword is ``name=(value, tail_shape)``.  A value of shape ``tail_shape`` is one platform;
    ``(N,) + tail_shape`` is a batch.  Every (3,3) argument is a rotation and must be orthonormal
    with determinant +1 within :data:`ROTATION_TOLERANCE`.  Returns (N, batched, contiguous
    float64 arrays of shape (N,) + tail_shape).  Raises ValueError naming the argument on None, a
    masked array with masked entries (:func:`stewart_env.validation.plain`), a wrong shape,
    mismatched batch sizes, a non-finite value or a matrix that is not a rotation.

    An argument that already is a C-contiguous float64 array of the right size is returned as a
    view, not copied: the kernels only read their inputs.

    Args:
        n_params: the number of parameter rows of the model (1: one platform, broadcast to the states' batch).
        **arrays: ``name=(value, tail_shape)`` of each state argument, e.g. ``position=(p, (3,))``.
    """
    sizes = {}
    out = {}
    rotations = []
    for name, (value, tail) in arrays.items():
        if tail == (3, 3):
            rotations.append(name)
        if type(value) is not np.ndarray:
            if value is None:
                raise ValueError(f"{name}: expected an array of numbers of shape {tail}, got None")
            value = validation.plain(name, value)
        try:
            # an array converts only from a kind that holds real numbers: complex parts or text never pass
            a = (
                value.astype(np.float64, casting="same_kind", copy=False)
                if type(value) is np.ndarray
                else np.asarray(value, dtype=np.float64)
            )
        except (TypeError, ValueError):
            got = f"an array of {value.dtype}" if type(value) is np.ndarray else type(value).__name__
            raise ValueError(f"{name}: expected an array of numbers of shape {tail}, got {got}") from None
        if a.shape == tail:
            a = a[None]
        elif a.ndim != len(tail) + 1 or a.shape[1:] != tail:
            raise ValueError(f"{name}: expected shape {tail} or (N, *{tail}), got {a.shape}")
        else:
            sizes[name] = a.shape[0]
        out[name] = np.ascontiguousarray(a)
    bad = K.first_nonfinite(tuple(out.values()))
    if bad >= 0:
        raise ValueError(f"{list(out)[bad]}: contains NaN or inf")
    for name in rotations:
        check_rotation(name, out[name])
    if not sizes and n_params == 1:
        return 1, False, out
    distinct = set(sizes.values())
    if n_params > 1:
        distinct.add(n_params)
    if len(distinct) > 1:
        raise ValueError(f"batch sizes disagree: {sizes}" + (f", parameters: {n_params}" if n_params > 1 else ""))
    n = distinct.pop() if distinct else 1
    for name, a in out.items():
        if a.shape[0] != n:
            out[name] = np.ascontiguousarray(np.broadcast_to(a, (n,) + a.shape[1:]))
    return n, True, out


def check_rotation(name: str, R: np.ndarray) -> None:
    """Raise ValueError naming ``name`` unless every R (N,3,3) is a rotation within
    :data:`ROTATION_TOLERANCE` (orthonormal, determinant +1).

    Args:
        name: the argument's name, which the error gives.
        R: the rotation matrices (N,3,3) of {P} in {B}.
    """
    if not K.largest_rotation_error(R) <= ROTATION_TOLERANCE:
        orth = np.empty(R.shape[0])
        det = np.empty(R.shape[0])
        K.rotation_errors_batch(R, orth, det)
        rows = np.flatnonzero(~((orth <= ROTATION_TOLERANCE) & (np.abs(det - 1.0) <= ROTATION_TOLERANCE)))
        where = f" in batch rows {rows[:10].tolist()}" if R.shape[0] > 1 else ""
        raise ValueError(
            f"{name}: not a rotation matrix{where} (|R^T R - I| = {orth[rows[0]]:.2e}, "
            f"det R = {det[rows[0]]:.6g}; tolerance {ROTATION_TOLERANCE:g})"
        )


#: The most RK4 steps one call may take (the kernels' int64).
MAX_STEPS = 2**63 - 1


def check_step(dt, steps) -> tuple[float, int]:
    """The time step and step count of an RK4 call: ``dt`` a positive finite number of seconds
    and ``steps`` a non-negative integer (not a bool) up to :data:`MAX_STEPS`, returned as a
    float and an int.  Raises ValueError naming ``dt`` or ``steps`` otherwise.

    Args:
        dt: the RK4 time step, s.
        steps: the number of steps.
    """
    if type(dt) is float and 0.0 < dt < math.inf and type(steps) is int and 0 <= steps <= MAX_STEPS:
        return dt, steps
    return (validation.real("dt", dt, 0.0, math.inf, low_open=True), validation.integer("steps", steps, 0, MAX_STEPS))


def _row_numbers(rows) -> list[int]:
    """The batch rows a ``with_*`` call replaces, as ints; ValueError naming ``rows`` unless they
    are integers (a sequence, range or integer array)."""
    if isinstance(rows, np.ndarray) and rows.ndim == 1 and rows.dtype.kind in "iu":
        return rows.tolist()  # a batch's row indices (np.flatnonzero): one call, not one per row
    try:
        return [operator.index(r) for r in rows]
    except TypeError:
        raise ValueError(f"rows: expected a sequence of integer batch rows, got {type(rows).__name__}") from None


class ParamsRows(Sequence):
    """The :class:`PlatformParams` of a model's parameter rows, built when first asked for.

    A row set from packed numbers (:meth:`Dynamics.with_packed_rows`) carries a zero-argument
    function that builds its PlatformParams, or a pair (function, j) of a function that builds
    those of the j-th of the rows set together; ``rows[i]`` calls it once and keeps the result.
    ``len`` and the packed numbers never need it, so a randomised reset builds no PlatformParams.
    """

    def __init__(self, items):
        self._items = list(items)

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return tuple(self[j] for j in range(*i.indices(len(self))))
        item = self._items[i]
        if not isinstance(item, PlatformParams):
            item = item[0](item[1]) if type(item) is tuple else item()
            if not isinstance(item, PlatformParams):
                raise TypeError(f"params: the source of row {i} built a {type(item).__name__}, not PlatformParams")
            self._items[i] = item
        return item

    def __eq__(self, other) -> bool:
        return isinstance(other, (ParamsRows, tuple)) and tuple(self) == tuple(other)

    __hash__ = None

    def __repr__(self) -> str:
        return f"ParamsRows({len(self)} rows)"


class Dynamics:
    """A dynamics model of one platform, or of a batch of platforms (one parameter set per row).

    The model is immutable: the ``with_*`` methods return new ones.  Its :meth:`workspace` holds
    the preallocated arrays of a controller loop (a method :mod:`stewart_env.dynamics.workspace`
    defines, beside the data it makes, so that this module imports no module built on it).
    :func:`~stewart_env.make_dynamics` is the usual way to make one.

    Args:
        name: the model's name (see the module docstring), e.g. ``"improved+c1"``, or its
            :class:`~stewart_env.dynamics.spec.ModelSpec`.
        params: one platform's parameters, or a non-empty sequence of them (one per batch row).

    Attributes:
        spec: the model's :class:`~stewart_env.dynamics.spec.ModelSpec`.
        name: the canonical name, e.g. ``"improved+c1"``.
        flags: the kernel switch bits.
        packed: (Np, N_PARAMS), read-only C-contiguous float64: the packed parameter rows (assigning
            to it stores a copy of the numbers given).
        params: the :class:`PlatformParams` of each row of ``packed`` (a sequence; rows set from
            packed numbers are built when first read, see :meth:`with_packed_rows`).

    Raises:
        ValueError: an unknown name or switch, or ``params`` not PlatformParams.
        ConfigError: a platform whose home pose is conditioned beyond its limits.max_condition
            (``check_home_condition``).
    """

    def __init__(self, name: str | ModelSpec, params: PlatformParams | Sequence[PlatformParams]):
        self.spec = ModelSpec.parse(name)
        self.name, self.flags = self.spec.name, self.spec.flags
        if isinstance(params, PlatformParams):
            plist = (params,)
        elif isinstance(params, Sequence) and not isinstance(params, str):
            plist = tuple(params)
        else:
            plist = ()
        if not plist or not all(isinstance(p, PlatformParams) for p in plist):
            raise ValueError(
                f"params: expected a PlatformParams or a non-empty sequence of them, got {type(params).__name__}"
            )
        self.params = ParamsRows(plist)
        rows: dict[int, np.ndarray] = {}
        for p in plist:  # a platform repeated over a batch is packed and checked once
            if id(p) not in rows:
                rows[id(p)] = pack_params(p)
                check_home_condition(p, rows[id(p)])
        self._packed = np.stack([rows[id(p)] for p in plist])
        self._packed.setflags(write=False)

    @property
    def packed(self) -> np.ndarray:
        """The packed parameter rows (Np, N_PARAMS), a read-only C-contiguous float64 array that the
        model owns.

        Assigning to it stores a copy of the numbers given (any real array of that shape, such as
        a strided view, a Fortran-ordered or a float32 array), so later changes to the array given
        do not reach the model.

        Raises:
            ValueError: on assignment, not real numbers of shape (Np, N_PARAMS), NaN or inf, or a
                masked array with masked entries (the message names ``packed``).
        """
        return self._packed

    @packed.setter
    def packed(self, value) -> None:
        shape = (len(self.params), K.N_PARAMS)
        if value is None:
            raise ValueError(f"packed: expected an array of real numbers of shape {shape}, got None")
        rows = validation.real_array("packed", value, shape)
        owned = np.array(rows, dtype=np.float64, order="C", copy=True)
        owned.setflags(write=False)
        self._packed = owned

    def __setstate__(self, state: dict) -> None:
        if "packed" in state:  # pickled before packed became a property
            state["_packed"] = state.pop("packed")
        self.__dict__.update(state)
        # an unpickled model (e.g. sent to a worker process) is as read-only as the original
        self._packed.setflags(write=False)

    def __repr__(self) -> str:
        more = ", ..." if len(self.params) > 1 else ""
        return f"Dynamics({self.name!r}, platforms={len(self.params)} [{self.params[0].name}{more}])"

    def params_of(self, row: int) -> PlatformParams:
        """The PlatformParams of a parameter row (built now if the row was set from packed numbers).

        Args:
            row: the parameter row.

        Returns:
            The row's :class:`PlatformParams`.

        Raises:
            ValueError: ``row`` not an integer in [0, Np - 1].
        """
        return self.params[validation.integer("row", row, 0, len(self.params) - 1)]

    def with_params(self, params: PlatformParams | Sequence[PlatformParams]) -> Dynamics:
        """The same model on other parameters (e.g. one randomised set per batch row).

        Args:
            params: one platform's parameters, or a sequence (one per batch row).

        Returns:
            The new :class:`Dynamics`.
        """
        return Dynamics(self.name, params)

    def with_rows(self, rows: Sequence[int], params: Sequence[PlatformParams]) -> Dynamics:
        """The same model with the parameters of some batch rows replaced.

        The other rows keep their packed parameters, so only the new rows are packed.

        Args:
            rows: the batch rows to replace.
            params: their new parameters, one each.

        Returns:
            The new :class:`Dynamics`.

        Raises:
            ValueError: not one PlatformParams per row.
            ConfigError: a platform whose home pose is conditioned beyond its limits.
        """
        rows = _row_numbers(rows)
        if not isinstance(params, Sequence):
            raise ValueError(f"params: expected a sequence of PlatformParams, one per row, got {type(params).__name__}")
        if len(rows) != len(params):
            raise ValueError(f"params: expected one per row ({len(rows)}), got {len(params)}")
        for p in params:
            if not isinstance(p, PlatformParams):
                raise ValueError(f"params: expected PlatformParams, got {type(p).__name__}")
        packed = [pack_params(p) for p in params]
        for p, row in zip(params, packed):
            check_home_condition(p, row)
        return self.with_packed_rows(rows, packed, params)

    def with_packed_rows(self, rows: Sequence[int], packed_rows, sources) -> Dynamics:
        """The same model with parameter rows ``rows`` replaced by packed numbers, no PlatformParams
        built: a new model, this one unchanged (:meth:`set_packed_rows` replaces them in place).

        The rows are trusted: the caller promises they are a valid platform's, as ``pack_params`` and
        ``scale_packed`` write them; only their finiteness is checked, and a row that is no
        platform's (e.g. a zero platform inertia) gives NaN accelerations.

        Args:
            rows: the batch rows to replace.
            packed_rows: (len(rows), N_PARAMS), e.g. from
                :meth:`stewart_env.randomization.Randomization.scale_packed`.
            sources: one per row, each a PlatformParams or a zero-argument function returning the
                PlatformParams the row was packed from (built only when ``params[row]`` is read);
                or one function of j returning those of row ``rows[j]``.

        Returns:
            The new :class:`Dynamics`.

        Raises:
            ValueError: wrong rows, shapes, counts or non-finite numbers (the message names the argument).
        """
        rows, packed_rows = self._checked_rows(rows, packed_rows, sources)
        new = object.__new__(Dynamics)
        new.spec, new.name, new.flags = self.spec, self.name, self.flags
        new.params = ParamsRows(self.params._items)
        new._packed = self._packed.copy()
        new._write_rows(rows, packed_rows, sources)
        return new

    def set_packed_rows(self, rows: Sequence[int], packed_rows, sources) -> None:
        """Replace parameter rows ``rows`` by packed numbers in place: :meth:`with_packed_rows`
        without the copy of every row, for the owner of a model that nobody else holds (a batch
        of the environment at a reset, which copies its model before it changes it once it has
        handed it out).  Every holder of :attr:`packed` (a compiled step's record of this model)
        sees the new rows.

        Args:
            rows: the batch rows to replace.
            packed_rows: (len(rows), N_PARAMS), as :meth:`with_packed_rows` takes them.
            sources: as :meth:`with_packed_rows` takes them.

        Raises:
            ValueError: wrong rows, shapes, counts or non-finite numbers (the message names the
                argument); the model is then unchanged.
        """
        rows, packed_rows = self._checked_rows(rows, packed_rows, sources)
        packed = self._packed
        if not packed.flags.owndata:
            # a copy of its own to write into (a packed array that is a view of another's)
            packed = self._packed = packed.copy()
        self._write_rows(rows, packed_rows, sources)

    def _set_checked_rows(self, rows: np.ndarray, packed_rows: np.ndarray, sources) -> None:
        """:meth:`set_packed_rows` for rows already checked by their writer, as the environment's
        reset writes them (``scale_randomized_rows`` refuses a non-finite row): ``rows`` (m,) int64
        within the batch, ``packed_rows`` (m, N_PARAMS) C-contiguous float64, ``sources`` one
        function of j (:meth:`with_packed_rows`); nothing checked again."""
        packed = self._packed
        if not packed.flags.owndata:
            packed = self._packed = packed.copy()
        items = self.params._items
        for j, r in enumerate(rows.tolist()):
            items[r] = (sources, j)
        packed.setflags(write=True)  # its own array: read-only again below
        try:
            packed[rows] = packed_rows
        finally:
            packed.setflags(write=False)

    def _checked_rows(self, rows, packed_rows, sources) -> tuple[list[int], np.ndarray]:
        """The rows (ints) and packed rows (C-contiguous float64) of :meth:`with_packed_rows`,
        checked; ValueError naming the argument otherwise."""
        rows = _row_numbers(rows)
        if packed_rows is None:
            raise ValueError(f"packed_rows: expected an array of shape ({len(rows)}, {K.N_PARAMS}), got None")
        packed_rows = np.ascontiguousarray(validation.plain("packed_rows", packed_rows), dtype=np.float64)
        if packed_rows.shape != (len(rows), K.N_PARAMS):
            raise ValueError(f"packed_rows: expected shape ({len(rows)}, {K.N_PARAMS}), got {packed_rows.shape}")
        if isinstance(sources, Sequence):
            if len(sources) != len(rows):
                raise ValueError(f"sources: expected one per row ({len(rows)}), got {len(sources)}")
            for source in sources:
                if not (isinstance(source, PlatformParams) or callable(source)):
                    raise ValueError(
                        f"sources: expected PlatformParams or a function returning them, got {type(source).__name__}"
                    )
        elif not callable(sources):
            raise ValueError(
                f"sources: expected a sequence, one per row, or a function of the row, got {type(sources).__name__}"
            )
        if K.first_nonfinite((packed_rows,)) >= 0:
            raise ValueError("packed_rows: contains NaN or inf")
        size = len(self.params)
        for r in rows:
            if not 0 <= r < size:
                raise ValueError(f"rows: {r} is outside the batch of {size} parameter rows")
        return rows, packed_rows

    def _write_rows(self, rows: list[int], packed_rows: np.ndarray, sources) -> None:
        """Write checked rows (:meth:`_checked_rows`) into this model's own packed array and params."""
        items = self.params._items
        if isinstance(sources, Sequence):
            for r, source in zip(rows, sources):
                items[r] = source
        else:
            for j, r in enumerate(rows):
                items[r] = (sources, j)
        packed = self._packed
        packed.setflags(write=True)  # its own array (a copy or the model's): read-only again below
        try:
            packed[rows] = packed_rows
        finally:
            packed.setflags(write=False)

    def subset(self, rows: Sequence[int]) -> Dynamics:
        """The model of some of its parameter rows, in the order of ``rows`` (e.g. the rows a batch
        resets): the same numbers row for row.

        Args:
            rows: the parameter rows to keep (integers in [0, Np - 1]).

        Returns:
            The new :class:`Dynamics`, of len(rows) parameter rows.

        Raises:
            ValueError: rows that are not integers within the model's rows.
        """
        rows = _row_numbers(rows)
        for r in rows:
            if not 0 <= r < len(self.params):
                raise ValueError(f"rows: {r} is outside the batch of {len(self.params)} parameter rows")
        if not rows:
            raise ValueError("rows: expected at least one row")
        new = object.__new__(Dynamics)
        new.spec, new.name, new.flags = self.spec, self.name, self.flags
        new.params = ParamsRows(self.params._items[r] for r in rows)
        new._packed = self._packed[rows]
        new._packed.setflags(write=False)
        return new

    def forward(self, position, rotation, velocity, angular_velocity, leg_forces, external_wrench=None):
        """Forward dynamics: platform accelerations under given leg forces.

        Solves M [a; alpha] + h = J^T F + W (docs/physics.md section 5.4).  All quantities are in
        {B}; every argument may carry a leading batch dimension N.

        Args:
            position: (3,) position of P's origin, m.
            rotation: (3,3) rotation matrix of {P} in {B}.
            velocity: (3,) velocity of P's origin, m/s.
            angular_velocity: (3,) angular velocity, rad/s.
            leg_forces: (6,) actuator forces F along the legs, N, positive extends the leg.
            external_wrench: (6,) [force at P, N; moment, N m], or None for none.

        Returns:
            The pair (lin_acc, ang_acc), acceleration a of P's origin (m/s^2) and angular
            acceleration alpha (rad/s^2), each (3,) or (N,3).

        Raises:
            ValueError: a wrong shape, a non-finite value or a rotation that is not orthonormal.

        Examples:
            The holding forces of :meth:`inverse` keep the platform at rest:

            >>> import numpy as np, stewart_env as se
            >>> params = se.load_platform("dasgupta1998")
            >>> model = se.make_dynamics("improved", params)
            >>> pose = (params.home_position, np.eye(3), np.zeros(3), np.zeros(3))
            >>> forces = model.inverse(*pose, np.zeros(3), np.zeros(3))
            >>> lin_acc, ang_acc = model.forward(*pose, forces)
            >>> bool(np.abs(lin_acc).max() < 1e-9 and np.abs(ang_acc).max() < 1e-9)
            True
        """
        out = np.empty(6)
        # one platform's float64 arrays, valid: checked and solved in one compiled call
        if _core.forward_one_checked(
            self._packed,
            self.flags,
            position,
            rotation,
            velocity,
            angular_velocity,
            leg_forces,
            _NO_WRENCH if external_wrench is None else external_wrench,
            ROTATION_TOLERANCE,
            out,
        ):
            return out[:3], out[3:]
        n, batched, a = self._args(
            position,
            rotation,
            velocity,
            angular_velocity,
            leg_forces=(leg_forces, (6,)),
            external_wrench=external_wrench,
        )
        out = np.empty((n, 6))
        K.forward_batch(
            self._packed,
            self.flags,
            a["position"],
            a["rotation"],
            a["velocity"],
            a["angular_velocity"],
            a["leg_forces"],
            a["external_wrench"],
            out,
        )
        return (out[:, :3], out[:, 3:]) if batched else (out[0, :3], out[0, 3:])

    def inverse(self, position, rotation, velocity, angular_velocity, lin_acc, ang_acc, external_wrench=None):
        """Inverse dynamics: the leg forces that produce the given accelerations.

        docs/physics.md section 5.5.  All quantities are in {B}; every argument may carry a
        leading batch dimension N.

        Args:
            position: (3,) position of P's origin, m.
            rotation: (3,3) rotation matrix of {P} in {B}.
            velocity: (3,) velocity of P's origin, m/s.
            angular_velocity: (3,) angular velocity, rad/s.
            lin_acc: (3,) acceleration a of P's origin, m/s^2.
            ang_acc: (3,) angular acceleration alpha, rad/s^2.
            external_wrench: (6,) [force at P, N; moment, N m], or None for none.

        Returns:
            The leg forces F (6,) or (N,6), N.

        Raises:
            ValueError: a wrong shape, a non-finite value or a rotation that is not orthonormal.

        Examples:
            The forces that hold the 40 kg platform at rest at its home pose:

            >>> import numpy as np, stewart_env as se
            >>> params = se.load_platform("dasgupta1998")
            >>> model = se.make_dynamics("improved", params)
            >>> forces = model.inverse(params.home_position, np.eye(3), np.zeros(3), np.zeros(3),
            ...                        np.zeros(3), np.zeros(3))
            >>> print(np.round(forces, 1))
            [193.9 145.4 153.1 172.3 159.6 188.9]
        """
        out = np.empty(6)
        if _core.inverse_one_checked(
            self._packed,
            self.flags,
            position,
            rotation,
            velocity,
            angular_velocity,
            lin_acc,
            ang_acc,
            _NO_WRENCH if external_wrench is None else external_wrench,
            ROTATION_TOLERANCE,
            out,
        ):
            return out
        n, batched, a = self._args(
            position,
            rotation,
            velocity,
            angular_velocity,
            lin_acc=(lin_acc, (3,)),
            ang_acc=(ang_acc, (3,)),
            external_wrench=external_wrench,
        )
        acc = np.empty((n, 6))
        acc[:, :3] = a["lin_acc"]
        acc[:, 3:] = a["ang_acc"]
        out = np.empty((n, 6))
        K.inverse_batch(
            self._packed,
            self.flags,
            a["position"],
            a["rotation"],
            a["velocity"],
            a["angular_velocity"],
            acc,
            a["external_wrench"],
            out,
        )
        return out if batched else out[0]

    def mass_and_bias(self, position, rotation, velocity, angular_velocity, external_wrench=None):
        """Mass matrix and bias of the equations of motion M [a; alpha] + h = J^T F.

        Both come from the assembly :meth:`forward` solves (docs/physics.md section 5.4; paper eq. 49
        or 55), so forward(F) = M^-1 (J^T F - h).

        Args:
            position: (3,) position of P's origin, m.
            rotation: (3,3) rotation matrix of {P} in {B}.
            velocity: (3,) velocity of P's origin, m/s.
            angular_velocity: (3,) angular velocity, rad/s.
            external_wrench: (6,) [force at P, N; moment, N m], or None for none.

        Returns:
            The pair (M, h).  M (6,6) or (N,6,6) maps [a; alpha] (acceleration of P's origin, m/s^2;
            angular acceleration, rad/s^2; {B}) to the wrench at P it takes (N; N m; {B}), legs
            included; it depends on the pose only.  h (6,) or (N,6), N and N m in {B}, is the wrench
            the legs must supply at zero acceleration, i.e. the velocity products (Coriolis,
            centripetal, gyroscopic), gravity and joint friction, minus ``external_wrench``.

        Raises:
            ValueError: a wrong shape, a non-finite value or a rotation that is not orthonormal.
        """
        n, batched, a = self._args(position, rotation, velocity, angular_velocity, external_wrench=external_wrench)
        M = np.empty((n, 6, 6))
        h = np.empty((n, 6))
        K.mass_bias_batch(
            self._packed,
            self.flags,
            a["position"],
            a["rotation"],
            a["velocity"],
            a["angular_velocity"],
            a["external_wrench"],
            M,
            h,
        )
        return (M, h) if batched else (M[0], h[0])

    def mass_matrix(self, position, rotation, velocity=None, angular_velocity=None):
        """The mass matrix M of :meth:`mass_and_bias`.

        It does not depend on the rates, which may be left out.

        Args:
            position: (3,) position of P's origin, m.
            rotation: (3,3) rotation matrix of {P} in {B}.
            velocity: (3,) velocity of P's origin, m/s (default zero: M does not depend on it).
            angular_velocity: (3,) angular velocity, rad/s (default zero).

        Returns:
            M (6,6) or (N,6,6) in kg, kg m, kg m^2; {B}, moments about P.
        """
        zero = np.zeros(3)
        return self.mass_and_bias(
            position,
            rotation,
            zero if velocity is None else velocity,
            zero if angular_velocity is None else angular_velocity,
        )[0]

    def bias(self, position, rotation, velocity, angular_velocity, external_wrench=None):
        """The bias h of :meth:`mass_and_bias`.

        Args:
            position: (3,) position of P's origin, m.
            rotation: (3,3) rotation matrix of {P} in {B}.
            velocity: (3,) velocity of P's origin, m/s.
            angular_velocity: (3,) angular velocity, rad/s.
            external_wrench: (6,) [force at P, N; moment, N m], or None for none.

        Returns:
            h (6,) or (N,6), [force, N; moment about P, N m] in {B}.
        """
        return self.mass_and_bias(position, rotation, velocity, angular_velocity, external_wrench)[1]

    def _args(self, position, rotation, velocity, angular_velocity, external_wrench=None, **extra):
        if external_wrench is None:
            external_wrench = _NO_WRENCH
        return batch_args(
            self._packed.shape[0],
            position=(position, (3,)),
            rotation=(rotation, (3, 3)),
            velocity=(velocity, (3,)),
            angular_velocity=(angular_velocity, (3,)),
            external_wrench=(external_wrench, (6,)),
            **extra,
        )


def make_dynamics(name: str | ModelSpec, params: PlatformParams | Sequence[PlatformParams]) -> Dynamics:
    """The dynamics model ``name`` (see the module docstring) on ``params``.

    Args:
        name: the model's name, ``"improved"``, ``"improved_centroidal"`` or ``"classical"``,
            optionally with switches such as ``"+c1"`` (any case), or its
            :class:`~stewart_env.dynamics.spec.ModelSpec`.
        params: one platform's parameters, or a sequence of them (one per batch row).

    Returns:
        The :class:`Dynamics` model.

    Raises:
        ValueError: an unknown name or switch, or ``params`` not PlatformParams.
        ConfigError: a platform whose home pose is conditioned beyond its limits.

    Examples:
        >>> import stewart_env as se
        >>> model = se.make_dynamics("improved+C3+c1", se.load_platform("dasgupta1998"))
        >>> model.name
        'improved+c1+c3'
    """
    return Dynamics(name, params)
