"""The action delay of a batch: each row's action reaches the platform a fixed number of control
steps after the policy gives it, as the command of a real machine passes through its fieldbus and
drive (docs/physics.md, "Limits and constraint costs").

:class:`ActionDelay` is a ring of the last ``delay_steps`` actions of every row. Each
:meth:`~ActionDelay.push` stores the step's actions and gives back those pushed ``delay_steps``
steps earlier; until a row has had that many pushes since its start, it gives back the action the
row was started with (:meth:`~ActionDelay.reset_rows`: the command the machine held before the
episode, zeros by default). ``delay_steps=0`` is the identity: push gives back the actions pushed.
"""

from __future__ import annotations

import numpy as np

from stewart_env.validation import integer

__all__ = ["MAX_DELAY_STEPS", "ActionDelay"]

#: The longest delay, control steps (as the observation's delay, ``observation_delay``).
MAX_DELAY_STEPS = 1000


class ActionDelay:
    """A ring buffer that delays every row's actions by ``delay_steps`` control steps.

    Args:
        n: the batch size (rows), >= 1.
        delay_steps: the delay in control steps, in [0, MAX_DELAY_STEPS]; 0 for none.
        dim: the action's size, >= 1 (six leg commands by default).

    Attributes:
        n: the batch size.
        delay_steps: the delay, control steps.
        dim: the action's size.

    Raises:
        UsageError: an argument out of its range (the message names it).

    With ``delay_steps=2``, pushing 1, 2, 3, 4 gives back 0, 0, 1, 2 (the start action, zeros,
    then the actions two steps late).
    """

    def __init__(self, n: int, delay_steps: int, dim: int = 6):
        self.n = integer("n", n, 1, 2**31 - 1)
        self.delay_steps = integer("delay_steps", delay_steps, 0, MAX_DELAY_STEPS)
        self.dim = integer("dim", dim, 1, 2**31 - 1)
        # Slot head holds the oldest action, the one push gives back before writing the new one
        # over it; the head is an array so that a compiled step can advance it in place.
        self._ring = np.zeros((self.delay_steps, self.n, self.dim))
        self._head = np.zeros(1, dtype=np.int64)
        self._out = np.zeros((self.n, self.dim))

    def __repr__(self) -> str:
        return f"ActionDelay(n={self.n}, delay_steps={self.delay_steps}, dim={self.dim})"

    def push(self, action: np.ndarray) -> np.ndarray:
        """Store this step's actions and give back those of ``delay_steps`` steps ago.

        Args:
            action: (n, dim) the actions the policy gives now.

        Returns:
            The actions that reach the platform now, (n, dim) float64 (``action``'s values when
            ``delay_steps`` is 0). The array is the buffer's own, overwritten by the next push.

        Raises:
            ValueError: an action of another shape (the message names ``action``).
        """
        action = np.asarray(action, dtype=np.float64)
        if action.shape != (self.n, self.dim):
            raise ValueError(f"action: expected shape {(self.n, self.dim)}, got {action.shape}")
        if self.delay_steps == 0:
            self._out[:] = action
            return self._out
        head = int(self._head[0])
        self._out[:] = self._ring[head]
        self._ring[head] = action
        self._head[0] = (head + 1) % self.delay_steps
        return self._out

    def reset_rows(self, rows: np.ndarray | slice | None = None, action: np.ndarray | None = None) -> None:
        """Start rows afresh: every slot of their ring holds ``action``, so that their next
        ``delay_steps`` pushes give it back.

        Args:
            rows: the rows to start, int indices or a bool mask (n,); None for every row.
            action: the action the rows held before their start, (dim,) for all of them or
                (m, dim) per row; None for zeros.

        Raises:
            ValueError: an action of a shape that fits neither.
        """
        rows = slice(None) if rows is None else rows
        fill = 0.0 if action is None else np.asarray(action, dtype=np.float64)
        if action is not None:
            m = np.zeros(self.n)[rows].shape[0]
            if fill.shape not in ((self.dim,), (m, self.dim)):
                raise ValueError(f"action: expected shape {(self.dim,)} or {(m, self.dim)}, got {fill.shape}")
        self._ring[:, rows] = fill

    def pending(self) -> np.ndarray:
        """The actions in flight, oldest first: (delay_steps, n, dim), a copy; the next push gives
        back the first."""
        return np.roll(self._ring, -int(self._head[0]), axis=0).copy()
