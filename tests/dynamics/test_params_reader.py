"""The platform config reader's bounded YAML loader says a depth problem by its type, as the
package's own bounded loader does (``DocumentError.nested``)."""

from __future__ import annotations

import pytest

from stewart_env.files import DocumentError, load_yaml
from stewart_env.params.reader import _ConfigLoader

#: 33 levels: one beyond the config loader's bound, written out and through a chain of aliases.
NESTED = "base_joints: " + "[" * 33 + "]" * 33 + "\n"
ALIASED = "a0: &a0 [1.0]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, 40))


@pytest.mark.parametrize(
    "text, problem",
    [
        (NESTED, "line 1, column 45: nested more than 32 levels deep"),
        (ALIASED, "nested more than 32 levels deep (after expanding aliases)"),
    ],
    ids=["written", "aliased"],
)
def test_a_config_nested_too_deeply_is_a_nested_document_error(text, problem):
    with pytest.raises(DocumentError) as caught:
        load_yaml(text, _ConfigLoader)
    assert caught.value.nested
    assert caught.value.problem.endswith(problem)


def test_a_config_beyond_another_bound_is_not_nested():
    with pytest.raises(DocumentError) as caught:
        load_yaml("base_joints: [" + ", ".join(["1.0"] * 6000) + "]\n", _ConfigLoader)
    assert not caught.value.nested and "more than 5000 values" in caught.value.problem
