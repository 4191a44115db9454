"""The repository passes ruff's checks, the rules of ``[tool.ruff]`` in pyproject.toml (the ``test``
extra installs ruff), and every public function of the package that takes arguments says what each
one is in an ``Args:`` section (ruff's D417 checks the section's entries only when it is there)."""

from __future__ import annotations

import ast
import fnmatch
import importlib.util
import re
import shutil
import subprocess
import sys

import pytest

from conftest import REPOSITORY

pytestmark = pytest.mark.lint

#: The folders of the package's public API, whose public functions need an ``Args:`` section.
API_FOLDERS = ("stewart_env", "agents")


def ruff_command() -> list[str]:
    """ruff as this Python's module, else from the PATH; the test is skipped without it."""
    if importlib.util.find_spec("ruff") is not None:
        return [sys.executable, "-m", "ruff"]
    if executable := shutil.which("ruff"):
        return [executable]
    pytest.skip("ruff is not installed (the test extra: pip install -e '.[test]')")


def run_ruff(*arguments: str) -> subprocess.CompletedProcess:
    return subprocess.run([*ruff_command(), *arguments], cwd=REPOSITORY, capture_output=True, text=True, timeout=300)


def test_ruff_check_passes():
    result = run_ruff("check", "--no-cache", "--output-format", "concise", ".")
    assert result.returncode == 0, result.stdout + result.stderr


def test_ruff_format_check_passes():
    result = run_ruff("format", "--no-cache", "--check", ".")
    assert result.returncode == 0, result.stdout + result.stderr


def _per_file_ignores() -> dict[str, list[str]]:
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10: tomli, from the docs extra
        tomllib = pytest.importorskip("tomli", reason="reading pyproject.toml on Python 3.10 needs tomli")
    pyproject = tomllib.loads((REPOSITORY / "pyproject.toml").read_text(encoding="utf-8"))
    return pyproject["tool"]["ruff"]["lint"]["per-file-ignores"]


def _exempt(relative: str, ignores: dict[str, list[str]]) -> bool:
    """Whether pyproject.toml exempts the file from D417 (and so from this test)."""
    return any(
        fnmatch.fnmatch(relative, pattern) and ({"D", "D4", "D41", "D417"} & set(codes))
        for pattern, codes in ignores.items()
    )


def _public_functions(tree: ast.Module):
    """The module's public functions and the public methods of its public classes, each with the
    names of its arguments (without self and cls); properties and their setters take none."""

    def walk(body, in_class: bool):
        for node in body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                yield from walk(node.body, in_class=True)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.name.startswith("_"):
                decorators = [ast.unparse(decorator) for decorator in node.decorator_list]
                if any(d == "property" or d.endswith((".setter", "overload")) for d in decorators):
                    continue
                arguments = node.args
                names = [a.arg for a in (*arguments.posonlyargs, *arguments.args, *arguments.kwonlyargs)]
                if in_class and names and names[0] in ("self", "cls") and "staticmethod" not in decorators:
                    names = names[1:]
                names += [a.arg for a in (arguments.vararg, arguments.kwarg) if a is not None]
                yield node, names

    yield from walk(tree.body, in_class=False)


def test_public_functions_document_their_arguments():
    ignores = _per_file_ignores()
    missing = []
    for folder in API_FOLDERS:
        for path in sorted((REPOSITORY / folder).rglob("*.py")):
            relative = path.relative_to(REPOSITORY).as_posix()
            private = any(
                part.startswith("_") and part not in ("__init__.py", "__main__.py")
                for part in path.relative_to(REPOSITORY).parts
            )
            if private or _exempt(relative, ignores):
                continue
            for function, names in _public_functions(ast.parse(path.read_text(encoding="utf-8"))):
                docstring = ast.get_docstring(function) or ""
                if names and not re.search(r"^Args:$", docstring, flags=re.M):
                    missing.append(f"{relative}:{function.lineno}: {function.name}({', '.join(names)})")
    assert not missing, "public functions without an Args: section:\n" + "\n".join(missing)


def test_a_function_without_args_is_found(tmp_path):
    tree = ast.parse(
        'def public(x):\n    """Does."""\n\n\nclass Public:\n    def method(self, y):\n'
        '        """Args:\n            y: a number.\n        """\n\n    @property\n    def value(self):\n'
        '        """The value."""\n\n\ndef _private(z):\n    pass\n'
    )
    assert [(f.name, names) for f, names in _public_functions(tree)] == [("public", ["x"]), ("method", ["y"])]
    assert _exempt("stewart_env/tasks/base.py", {"stewart_env/tasks/*": ["D102", "D417"]})
    assert not _exempt("stewart_env/tasks/base.py", {"stewart_env/tasks/*": ["I001"]})
