"""The model spec: a dynamics model's name parsed once into its base model and switches.

A model name is a base model, ``classical``, ``improved`` or ``improved_centroidal``, optionally
followed by switches ``+c1`` .. ``+c4`` (any case, in any order), e.g. ``"improved+c1+c3"``.
:meth:`ModelSpec.parse` reads it once, wherever a name enters (the environment's ``model``, the
command line's ``--model``, an identification's settings, a result file), and every later step
takes the :class:`ModelSpec`; a spec given where a name is expected passes through unparsed.

One canonical name per kernel model
-----------------------------------
The kernels see only the flags (:attr:`ModelSpec.flags`): the switch bits C1..C4 and the
centroidal bit.  Two names with the same flags are the same model and get the same canonical name
(:attr:`ModelSpec.name`, also ``str(spec)``):

* ``classical`` is the improved model with all four switches on (He et al. 2018, section 2); its
  name stands for exactly that set, so ``"classical+c1"`` and ``"improved+c1+c2+c3+c4"`` are
  both ``"classical"``;
* otherwise the base name followed by its switches in order, ``"improved+c1+c3"``;
* ``improved_centroidal`` differs from ``improved`` in the centroidal bit, so
  ``"improved_centroidal+c1+c2+c3+c4"`` keeps its own name.

Every name that parsed before this spec parses to the same flags, so the model names stored in
result files (a mismatch study's ``study.json``, a run's ``run.json``) still load.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any

from stewart_env import _core
from stewart_env.errors import UsageError

__all__ = ["BASE_MODELS", "ModelSpec", "Switch"]


class Switch(enum.IntFlag):
    """The classical model's simplifications, each a switch on the improved model; the values are
    the kernels' flag bits (``_core.C1`` ...), so ``int(switches)`` is what a kernel takes.

    ``SIMPLIFICATIONS`` in :mod:`stewart_env.dynamics.model` says what each one assumes;
    docs/physics.md section 6 where each enters the equations.
    """

    C1 = _core.C1
    C2 = _core.C2
    C3 = _core.C3
    C4 = _core.C4


#: Every switch on: the classical model.
ALL_SWITCHES = Switch.C1 | Switch.C2 | Switch.C3 | Switch.C4
#: The base models, in the order the messages list them, and the kernel bits each sets beside its switches.
BASE_MODELS = {"improved": 0, "improved_centroidal": _core.CENTROIDAL, "classical": 0}
_SWITCH_NAMES = {s.name.lower(): s for s in Switch}


def _unknown_model(argument: str, base: str, hint: str) -> UsageError:
    return UsageError.about(
        argument,
        f"unknown model {base!r}; choose one of {', '.join(BASE_MODELS)}, optionally with switches '+c1'..'+c4'{hint}",
    )


@dataclass(frozen=True)
class ModelSpec:
    """A dynamics model: its base model and switches, in canonical form (see the module docstring).

    Build one with :meth:`parse`; the constructor canonicalises what it is given
    (``ModelSpec("improved", Switch.C1 | Switch.C2 | Switch.C3 | Switch.C4) == ModelSpec("classical")``).

    Args:
        base: ``"improved"``, ``"improved_centroidal"`` or ``"classical"``.
        switches: the switches on (for ``classical``, always all four).

    Attributes:
        base: the base model.
        switches: the switches on, a :class:`Switch`.

    Raises:
        UsageError: an unknown base or a switches value that is no :class:`Switch` (argument ``model``).

    Examples:
        >>> from stewart_env import ModelSpec, Switch
        >>> spec = ModelSpec.parse("Improved+C3+c1")
        >>> spec.name, spec.flags, spec.switches == Switch.C1 | Switch.C3
        ('improved+c1+c3', 5, True)
        >>> str(ModelSpec.parse("improved+c1+c2+c3+c4"))
        'classical'
    """

    base: str = "improved"
    switches: Switch = Switch(0)

    def __post_init__(self) -> None:
        if self.base not in BASE_MODELS:
            raise _unknown_model("model", self.base, "")
        if (
            not isinstance(self.switches, int)
            or isinstance(self.switches, bool)
            or self.switches & ~int(ALL_SWITCHES)
            or self.switches < 0
        ):
            raise UsageError.about("model", f"switches: expected a Switch (C1..C4), got {self.switches!r}")
        switches = Switch(int(self.switches))
        base = self.base
        if base == "classical":
            switches = ALL_SWITCHES
        elif base == "improved" and switches == ALL_SWITCHES:
            base = "classical"
        object.__setattr__(self, "base", base)
        object.__setattr__(self, "switches", switches)

    @property
    def flags(self) -> int:
        """The kernel flags, the switch bits and the centroidal bit (docs/physics.md section 6)."""
        return BASE_MODELS[self.base] | int(self.switches)

    @property
    def name(self) -> str:
        """The canonical name, ``"classical"`` or the base and its switches in order, e.g. ``"improved+c1+c3"``."""
        if self.base == "classical":
            return "classical"
        return self.base + "".join(f"+{s.name.lower()}" for s in Switch if s in self.switches)

    def __str__(self) -> str:
        return self.name

    @classmethod
    def parse(cls, model: Any, argument: str = "model", *, hint: str = "") -> ModelSpec:
        """The spec of a model name such as ``"improved+c1+c3"`` (a spec is returned as it is).

        Args:
            model: a model name (any case, switches in any order, repeats allowed) or a ModelSpec.
            argument: the name of the argument ``model`` came in, which the error names.
            hint: text added to the message on an unknown base model (e.g. another value the
                caller accepts), starting with ``"; "``.

        Returns:
            The :class:`ModelSpec`.

        Raises:
            UsageError: not a string, an unknown base model or switch; ``err.argument`` is ``argument``.
        """
        if isinstance(model, ModelSpec):
            return model
        if not isinstance(model, str):
            raise UsageError.about(argument, f"expected a name such as 'improved', got {model!r}")
        base, *names = model.strip().lower().split("+")
        if base not in BASE_MODELS:
            raise _unknown_model(argument, base, hint)
        switches = Switch(0)
        for s in names:
            if s not in _SWITCH_NAMES:
                raise UsageError.about(argument, f"unknown switch {s!r} in {model!r}; switches are c1, c2, c3, c4")
            switches |= _SWITCH_NAMES[s]
        return cls(base, switches)
