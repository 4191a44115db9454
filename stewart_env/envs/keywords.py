"""The environments' keyword arguments, made from the configuration records (one source).

Every face of the batch (the single environment, the vector environment, the SB3 adapter) takes
the arguments of :data:`~stewart_env.envs.config.RECORDS` as keywords.  :func:`signature` builds
the ``__signature__`` that ``inspect.signature`` and ``help()`` show (every argument keyword-only,
with its default), and :func:`check_arguments` refuses an unknown keyword as Python would, saying
where a keyword that is no longer taken went (:data:`MOVED`).
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from stewart_env.envs.config import RECORDS, defaults
from stewart_env.tasks import RewardWeights
from stewart_env.validation import check_keywords

__all__ = ["DEFAULTS", "MOVED", "PARAMETERS", "check_arguments", "with_signature"]

#: Every keyword argument of the environments and its default (the arguments table of the card).
DEFAULTS: dict[str, Any] = defaults()
#: Keywords that are no longer environment arguments, and where they went (said in the error).
MOVED = {
    name: f"the reward weights are options of the task: pass task_options={{{name!r}: ...}}"
    for name in RewardWeights.__dataclass_fields__
}
#: The environment arguments as signature parameters: keyword-only, in the records' order.
PARAMETERS: tuple[inspect.Parameter, ...] = tuple(
    inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default, annotation=f.type)
    for record in RECORDS
    for f in dataclasses.fields(record)
    if f.init
)


def check_arguments(owner: str, arguments: Mapping[str, Any], own: Sequence[str] = ()) -> None:
    """Refuse a keyword of ``arguments`` that is neither one of ``own`` nor an environment
    argument, as Python refuses it in a call of ``owner.__init__`` (an ArgumentError, both a
    TypeError and a ValueError).

    Args:
        owner: the class whose ``__init__`` is called, as the error names it.
        arguments: the keyword arguments given.
        own: the keywords of that class besides the environment arguments.
    """
    check_keywords(f"{owner}.__init__", arguments, (*own, *DEFAULTS), MOVED)


def with_signature(*own: inspect.Parameter) -> Callable[[Callable], Callable]:
    """Decorate an ``__init__(self, <own>, **arguments)`` with the signature it accepts: ``self``,
    the parameters ``own`` of that face, then every environment argument (:data:`PARAMETERS`).
    The check of the keywords stays the ``__init__``'s (:func:`check_arguments`).

    Args:
        *own: the parameters of the decorated ``__init__`` before the environment arguments.
    """
    self = inspect.Parameter("self", inspect.Parameter.POSITIONAL_OR_KEYWORD)

    def decorate(init: Callable) -> Callable:
        init.__signature__ = inspect.Signature([self, *own, *PARAMETERS])
        return init

    return decorate
