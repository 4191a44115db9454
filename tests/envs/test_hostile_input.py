"""Configs, spec dicts and install locations that come from others: every bad one fails fast with a
short ConfigError naming the key or the file, and never quotes a file's content."""

import copy
import json
import math
import os
import re
import shutil
import stat
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

import stewart_env
from stewart_env.params import MAX_CONFIG_BYTES, ConfigError, PlatformParams, load_platform
from stewart_env.randomization import Randomization

CONFIG_DIR = Path(__file__).resolve().parents[2] / "configs" / "platforms"
DASGUPTA = CONFIG_DIR / "dasgupta1998.yaml"
# Longest message a hostile input may produce: the path, the key list of an unknown-key error
# (about 140 characters) and a 60-character excerpt fit well within it.
MAX_MESSAGE = 400

SHADOW_LIKE = (
    "root:$6$Zx9Qw1Ab$kT3vPq8sLmN2rYwXcD5fGhJ7uIo0pEaSbCzVxB4nM6:19700:0:99999:7:::\n"
    "daemon:*:19700:0:99999:7:::\n"
    "alice:$6$Yy8Rr2Cd$Qw3eRt5yUi7oPa9sDf1gHj2kLz4xCv6bNm8QwErTy0:19700:0:99999:7:::\n"
)


@pytest.fixture(scope="module")
def dasgupta_config():
    return yaml.safe_load(DASGUPTA.read_text(encoding="utf-8"))


def load_error(path, seconds: float = 1.0) -> ConfigError:
    """The ConfigError of loading `path`, after checking that it came within `seconds` and short.
    The default 1 s: a refusal needs a stat or a few KB of parsing, milliseconds, and a busy CI
    machine may be 100x slower."""
    start = time.perf_counter()
    with pytest.raises(ConfigError) as info:
        load_platform(path)
    assert time.perf_counter() - start < seconds
    message = str(info.value)
    assert len(message) <= MAX_MESSAGE + len(str(path))
    return info.value


def assert_not_quoted(message: str, content: str) -> None:
    """No 8-character stretch of `content` (beyond blanks and the file name) is in `message`."""
    for line in content.splitlines():
        for i in range(len(line) - 7):
            window = line[i : i + 8]
            assert window.strip() != window or window not in message, f"{window!r} quoted in {message!r}"


def write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


# ---------------------------------------------------------------------------------------------
# Files that are not platform configs


def test_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "robot.yaml"
    os.mkfifo(fifo)
    errors = []
    reader = threading.Thread(target=lambda: errors.append(load_error(fifo)), daemon=True)
    reader.start()
    reader.join(timeout=5.0)  # opening a FIFO for reading blocks until a writer comes
    assert not reader.is_alive(), "load_platform blocked on a FIFO"
    assert str(errors[0]) == f"{fifo}: not a regular file (a FIFO, socket or device)"


def test_devices_are_refused(tmp_path):
    assert str(load_error("/dev/zero")).startswith("/dev/zero: not a platform config")
    link = tmp_path / "zero.yaml"
    link.symlink_to("/dev/zero")
    assert str(load_error(link)) == f"{link}: not a regular file (a FIFO, socket or device)"


def test_directory_is_refused(tmp_path):
    directory = tmp_path / "robot.yaml"
    directory.mkdir()
    assert str(load_error(directory)) == f"{directory}: a directory, not a config file"


#: The refusal of a file whose name is not a config's.
NOT_A_CONFIG_NAME = (
    "not a platform config: a config file's name ends in .yaml or .yml; a shipped platform is named "
    "by a string alone, with no path (dasgupta1998, motion_simulator)"
)


@pytest.mark.parametrize("name", ["config.txt", "config.yaml.bak", "config", "passwd"])
def test_only_yaml_suffixes_are_read(tmp_path, name):
    path = tmp_path / name
    shutil.copy(DASGUPTA, path)
    assert str(load_error(path)) == f"{path}: {NOT_A_CONFIG_NAME}"


@pytest.mark.parametrize("name", ["robot.yml", "robot.YAML"])
def test_yml_and_upper_case_suffixes_are_configs(tmp_path, name):
    path = tmp_path / name
    shutil.copy(DASGUPTA, path)
    assert load_platform(path).replace(name="dasgupta1998") == load_platform("dasgupta1998")


def test_symlink_to_a_config_is_followed(tmp_path):
    link = tmp_path / "robot.yaml"
    link.symlink_to(DASGUPTA)
    assert load_platform(link).base_joints.shape == (6, 3)


def test_etc_passwd_is_never_quoted(tmp_path):
    assert str(load_error("/etc/passwd")) == f"/etc/passwd: {NOT_A_CONFIG_NAME}"
    content = Path("/etc/passwd").read_text(encoding="utf-8")
    copy_ = write(tmp_path / "passwd.yaml", content)
    error = load_error(copy_)
    assert error.key == ""
    assert_not_quoted(str(error), content)


def test_shadow_like_file_is_never_quoted(tmp_path):
    # Each line ends in ':', so YAML reads the lines as keys of a mapping.
    error = load_error(write(tmp_path / "shadow.yaml", SHADOW_LIKE))
    assert re.match(
        r".*/shadow\.yaml: unknown key \(text of 77 characters\), \(text of 26 characters\), "
        r"\(text of 78 characters\) \(expected 'base_joints', ",
        str(error),
    )
    assert_not_quoted(str(error), SHADOW_LIKE)
    as_text = SHADOW_LIKE.replace(":::\n", "\n")  # now one multi-line plain scalar
    error = load_error(write(tmp_path / "shadow2.yaml", as_text))
    assert re.fullmatch(r".*/shadow2\.yaml: expected a mapping, got text of \d+ characters", str(error))
    assert_not_quoted(str(error), as_text)


def test_yaml_syntax_error_names_the_line_but_does_not_quote_it(tmp_path):
    text = "damping:\n  universal: [1.0e-4, hunter2-password\n"
    error = load_error(write(tmp_path / "broken.yaml", text))
    assert str(error) == (
        f"{tmp_path / 'broken.yaml'}: not valid YAML: line 3, column 1: "
        "while parsing a flow sequence; expected ',' or ']', but got '<stream end>'"
    )
    assert_not_quoted(str(error), text)


def test_oversize_file_is_refused_before_reading(tmp_path):
    big = write(tmp_path / "big.yaml", "#" * MAX_CONFIG_BYTES + "\n")
    assert str(load_error(big)) == f"{big}: larger than {MAX_CONFIG_BYTES} bytes ({MAX_CONFIG_BYTES + 1} bytes)"
    sparse = tmp_path / "sparse.yaml"
    with open(sparse, "wb") as f:
        f.truncate(1 << 40)  # 1 TB on paper, no blocks on disk: reading it would take hours
    assert str(load_error(sparse)).endswith(f"larger than {MAX_CONFIG_BYTES} bytes ({1 << 40} bytes)")


def test_file_of_the_largest_size_is_read(tmp_path):
    text = DASGUPTA.read_text(encoding="utf-8")
    padded = write(tmp_path / "padded.yaml", text + "#" * (MAX_CONFIG_BYTES - len(text.encode()) - 1) + "\n")
    assert padded.stat().st_size == MAX_CONFIG_BYTES
    assert load_platform(padded).platform.mass == 40.0


def test_missing_file_and_binary_file(tmp_path):
    missing = tmp_path / "missing.yaml"
    assert str(load_error(missing)) == f"{missing}: cannot read the file: No such file or directory"
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"platform: \xff\xfe secret")
    assert str(load_error(binary)) == f"{binary}: not UTF-8 text (invalid byte at offset 10)"


@pytest.mark.parametrize("name", ["a" * 5000, "no\0such", "../../etc/passwd"])
def test_strange_names_fail_as_config_errors(name):
    error = load_error(name)
    assert len(str(error)) <= MAX_MESSAGE + len(name)


def test_non_path_arguments_are_refused():
    for value in (None, 3, b"dasgupta1998.yaml"):
        with pytest.raises(ConfigError, match=r"^expected a platform name or a path, got "):
            load_platform(value)


# ---------------------------------------------------------------------------------------------
# YAML that costs too much to build


def billion_laughs(levels: int = 9) -> str:
    lines = ['lol0: &lol0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, levels + 1):
        lines.append(f"lol{i}: &lol{i} [" + ", ".join([f"*lol{i - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def test_billion_laughs_fails_fast_with_a_short_message(tmp_path):
    text = billion_laughs()
    assert len(text) < 4096  # expands to 9**10 = 3.5e9 strings
    error = load_error(write(tmp_path / "laughs.yaml", text))
    assert re.fullmatch(
        r".*/laughs\.yaml: not valid YAML: line \d, column \d+: "
        r"more than 5000 values \(after expanding aliases\)",
        str(error),
    )


@pytest.mark.parametrize(
    "text, problem",
    [
        ("base_joints: [" + ", ".join(["1.0"] * 150_000) + "]\n", "more than 5000 values"),
        ("a0: &a0 [1.0]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, 40_000)), "more than 5000 values"),
        (
            "a0: &a0 [1.0]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, 40)),
            "nested more than 32 levels deep (after expanding aliases)",
        ),
    ],
)
def test_long_documents_stop_early(tmp_path, text, problem):
    # The first two are about 1 MB each, which PyYAML would take 10-20 s to parse; refused after
    # 5000 values, about 0.3 s, or a few seconds on a busy machine.
    error = load_error(write(tmp_path / "long.yaml", text), seconds=5.0)
    assert re.fullmatch(r".*/long\.yaml: not valid YAML: line \d+, column \d+: " + re.escape(problem), str(error))


def test_a_few_aliases_are_fine(tmp_path, dasgupta_config):
    text = DASGUPTA.read_text(encoding="utf-8").replace(
        "hooke_axes: [0.0, 0.0, 1.0]", "hooke_axes: [&up [0.0, 0.0, 1.0], *up, *up, *up, *up, *up]"
    )
    assert load_platform(write(tmp_path / "aliases.yaml", text)).hooke_axes.tolist() == [[0.0, 0.0, 1.0]] * 6


def test_duplicate_keys_are_refused_but_merges_may_override(tmp_path):
    text = config_text("  mass: 40.0 ", "  mass: 40.0\n  mass: 4000.0 ")
    line = next(i for i, row in enumerate(text.splitlines(), 1) if row.startswith("  mass: 4000.0"))
    error = load_error(write(tmp_path / "twice.yaml", text))
    assert str(error).endswith(
        f"not valid YAML: line {line}, column 3: while constructing a mapping; duplicate key 'mass'"
    )
    text = config_text("  mass: 1.0 ", "  <<: {mass: 9.0, com: [0.0, 0.0, 0.0]}\n  mass: 1.0 ")
    assert load_platform(write(tmp_path / "override.yaml", text)).upper_leg[0].mass == 1.0


def test_recursive_alias_is_refused(tmp_path):
    error = load_error(write(tmp_path / "loop.yaml", "base_joints: &a [*a]\n"))
    assert str(error).endswith("not valid YAML: line 1, column 14: an alias refers to its own anchor")


def test_deeply_nested_yaml_is_refused_before_recursing(tmp_path):
    text = "base_joints: " + "[" * 200_000 + "]" * 200_000 + "\n"
    # 400 KB, refused at the 33rd bracket: 0.3 s, or a few seconds on a busy machine.
    error = load_error(write(tmp_path / "deep.yaml", text), seconds=5.0)
    assert str(error).endswith("not valid YAML: line 1, column 45: nested more than 32 levels deep")


def test_long_integer_literals_are_refused(tmp_path):
    # Sexagesimal integers (1:2:3) take quadratic time in their length.
    for literal in ("1" * 5000, "1:" * 300_000 + "1"):
        # The 600 KB literal is scanned whole (about 1 s, several on a busy machine) but not
        # converted: that took tens of seconds for the sexagesimal one.
        error = load_error(write(tmp_path / "long.yaml", f"platform: {{mass: {literal}}}\n"), seconds=10.0)
        assert str(error).endswith(f"line 1, column 18: an integer literal of {len(literal)} characters")


# ---------------------------------------------------------------------------------------------
# Numbers that are not finite float64 values


def config_text(replace: str, by: str) -> str:
    text = DASGUPTA.read_text(encoding="utf-8")
    assert replace in text
    return text.replace(replace, by, 1)


@pytest.mark.parametrize(
    "replace, by, message",
    [
        pytest.param(
            "mass: 40.0",
            "mass: " + "1" + "0" * 400,
            r"platform\.mass: not a finite number \(10000000000{10,}[.][.][.]",
            id="int_10**400",
        ),
        pytest.param("mass: 40.0", "mass: .inf", r"platform\.mass: not a finite number \(inf\)", id="inf"),
        pytest.param("mass: 40.0", "mass: .nan", r"platform\.mass: not a finite number \(nan\)", id="nan"),
        pytest.param(
            "mass: 40.0", "mass: 1.0e+400", r"platform\.mass: not a finite number \(inf\)", id="float_overflow"
        ),
        pytest.param(
            "mass: 40.0", "mass: 1.0e+13", r"platform\.mass: magnitude above 1e\+12, got 1e\+13", id="too_large"
        ),
        pytest.param("mass: 40.0", "mass: true", r"platform\.mass: must be a number, got True", id="bool"),
        pytest.param("mass: 1.0 ", "mass: yes ", r"upper_leg\.mass: must be a number, got True", id="yaml11_bool"),
        pytest.param(
            "[1.5, -0.15, -0.6]",
            "[1.5, -.inf, -0.6]",
            r"base_joints\[4\]\[1\]: not a finite number \(-inf\)",
            id="nested_inf",
        ),
        pytest.param(
            "[0.17, 0.595, -0.4]",
            "[0.17, false, -0.4]",
            r"platform_joints\[0\]\[1\]: must be a number, got False",
            id="nested_bool",
        ),
        pytest.param(
            "max_condition: 1000.0",
            "max_condition: 1" + "0" * 400,
            r"limits\.max_condition: not a finite number \(1000",
            id="limit_10**400",
        ),
        pytest.param(
            "leg_force: [-2000.0, 2000.0]",
            "leg_force: [-2000.0, 1.0e+300]",
            r"limits\.leg_force\[1\]: magnitude above 1e\+12, got 1e\+300",
            id="limit_huge",
        ),
        pytest.param(
            "gravity: [0.0, 0.0, -9.81]",
            "gravity: [0.0, [[[[[[1.0]]]]]], -9.81]",
            r"gravity\[1\]: must be a number, got \[\[\[\[[.][.][.]\]\]\]\]",
            id="nested_list_in_a_vector",
        ),
        pytest.param(
            "mass: 40.0", "mass: 4.0e-7", r"platform\.mass: must be >= 1e-06 kg, got 4e-07", id="platform_mass_tiny"
        ),
    ],
)
def test_bad_numbers_in_yaml_name_their_key(tmp_path, replace, by, message):
    path = write(tmp_path / "robot.yaml", config_text(replace, by))
    error = load_error(path)
    assert error.source == str(path)
    assert error.key and str(error).startswith(f"{path}: {error.key}: ")
    assert len(error.problem) <= 120
    assert re.match(message, str(error).removeprefix(f"{path}: ")), str(error)


def test_python_values_beyond_float_range(dasgupta_config):
    for value, shown in [
        (10**400, "(1000000000"),
        (-(10**400), "(-100000000"),
        (10**5000, "(an integer of about 5000 digits)"),
        (np.float64("inf"), "(inf)"),
    ]:
        config = copy.deepcopy(dasgupta_config)
        config["base_joints"][3][1] = value
        with pytest.raises(ConfigError) as info:
            PlatformParams.from_dict(config)
        assert str(info.value).startswith(f"base_joints[3][1]: not a finite number {shown}")
        assert len(str(info.value)) < 120


def test_tiny_platform_inertia_is_refused(dasgupta_config):
    dasgupta_config = copy.deepcopy(dasgupta_config)
    dasgupta_config["platform"]["inertia"] = [1e-16, 1e-16, 1e-16]
    with pytest.raises(
        ConfigError, match=r"^platform\.inertia: smallest principal moment 1e-16 is below 1e-15 kg m\^2$"
    ):
        PlatformParams.from_dict(dasgupta_config)


def test_huge_and_deep_lists_fail_fast(dasgupta_config):
    deep: list = [1.0]
    for _ in range(100_000):
        deep = [deep]  # deeper than Python's recursion limit
    for path, value, message in [
        (
            ("base_joints",),
            [[0.0, 0.0, 0.0]] * 1_000_000,
            r"^base_joints: expected shape \(6, 3\), got a sequence of 1000000 items$",
        ),
        (("platform", "com"), np.zeros(10**6), r"^platform\.com: expected shape \(3,\), got \(1000000,\)$"),
        (("base_joints",), deep, r"^base_joints\[0\]\[0\]: must be a number, got \[\[\[\[[.][.][.]\]\]\]\]$"),
        (("upper_leg",), [{}] * 10**6, r"^upper_leg: expected one mapping or a list of six, got a list of 1000000$"),
    ]:
        config = copy.deepcopy(dasgupta_config)
        config[path[0]] = value if len(path) == 1 else {**config[path[0]], path[1]: value}
        start = time.perf_counter()
        with pytest.raises(ConfigError, match=message):
            PlatformParams.from_dict(config)
        assert time.perf_counter() - start < 0.5  # nothing is walked: lengths are checked first


def test_unknown_keys_are_quoted_only_when_they_look_like_names(dasgupta_config):
    config = copy.deepcopy(dasgupta_config)
    config["platfrom"] = 1
    config["x" * 500] = 2
    config[("a", 1)] = 3
    config["p4ssw0rd:secret"] = 4
    with pytest.raises(ConfigError) as info:
        PlatformParams.from_dict(config)
    assert str(info.value).startswith(
        "unknown key 'platfrom', (text of 500 characters), (a tuple of 2 items) and 1 more (expected "
    )


# ---------------------------------------------------------------------------------------------
# Fuzzing: one leaf of a valid config replaced by a hostile value


def key_paths(node, path=()):
    """Every key path of a config, containers included."""
    yield path
    children = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for key, child in children:
        yield from key_paths(child, (*path, key))


def key_name(path) -> str:
    """The key path as error messages write it: ``limits.leg_force[1]``."""
    text = ""
    for key in path:
        text += f"[{key}]" if isinstance(key, int) else (f".{key}" if text else key)
    return text


def inside(key: str, outer: str) -> bool:
    """Whether key path `key` is `outer` or lies under it."""
    return key == outer or key.startswith((outer + ".", outer + "["))


def get(node, path):
    for key in path:
        node = node[key]
    return node


HUGE_LIST = [1.0] * 100_000
# Values that are no finite number in range: an error must name their own key path.
NOT_A_NUMBER = [
    math.nan,
    math.inf,
    -math.inf,
    1e308 * 10,
    10**400,
    -(10**400),
    1e13,
    "1.0",
    "abc",
    None,
    True,
    False,
    HUGE_LIST,
    {},
    {"mass": 1.0},
    [[[[1.0]]]],
]
# Finite numbers: may be valid, or make another check fail (e.g. the leg stroke).
NUMBERS = [-1, 0, -1.0, 1e-320, 1e12, -1e12, 0.5, 7]


@pytest.fixture(scope="module")
def all_paths(dasgupta_config):
    return [p for p in key_paths(dasgupta_config) if p]


@settings(max_examples=100, deadline=None)
@given(data=st.data())
def test_fuzz_one_hostile_leaf(dasgupta_config, all_paths, data):
    path = data.draw(st.sampled_from(all_paths), label="path")
    value = data.draw(st.sampled_from(NOT_A_NUMBER + NUMBERS), label="value")
    config = copy.deepcopy(dasgupta_config)
    get(config, path[:-1])[path[-1]] = value
    try:
        params = PlatformParams.from_dict(config)
    except ConfigError as err:
        assert err.key, f"no key named in {err}"
        assert str(err).startswith(f"{err.key}: ") and len(str(err)) <= MAX_MESSAGE
        if any(value is v for v in NOT_A_NUMBER):
            # The error is about the value or, for a nested list, about an item inside it.
            name = key_name(path)
            assert inside(name, err.key) or inside(err.key, name), f"{name} replaced, but {err} names another key"
        return
    saved = params.to_dict()
    leaves = [leaf for leaf in (get(saved, p) for p in key_paths(saved)) if not isinstance(leaf, (dict, list))]
    assert len(leaves) > 100 and all(isinstance(x, float) and math.isfinite(x) for x in leaves)


# ---------------------------------------------------------------------------------------------
# Randomisation specs


@pytest.mark.parametrize(
    "spec, message",
    [
        ({"mass": (0.5, math.inf)}, r"^randomization\['mass'\]\[1\]: not a finite number \(inf\)$"),
        ({"mass": (math.nan, 2.0)}, r"^randomization\['mass'\]\[0\]: not a finite number \(nan\)$"),
        ({"mass": (10**400, 2.0)}, r"^randomization\['mass'\]\[0\]: not a finite number \(1000"),
        ({"inertia": (True, 2.0)}, r"^randomization\['inertia'\]\[0\]: must be a number, got True$"),
        ({"inertia": ("0.5", 2.0)}, r"^randomization\['inertia'\]\[0\]: must be a number, got '0\.5'"),
        ({"mass": (2.0, 0.5)}, r"^randomization\['mass'\]: expected low <= high, got \(2\.0, 0\.5\)$"),
        ({"mass": (1e-4, 2.0)}, r"^randomization\['mass'\]: factors must be > 0 and within \[0\.001, 1000\]"),
        (
            {"legs.inertia": (0.5, 1e4)},
            r"^randomization\['legs\.inertia'\]: factors must be > 0 and within \[0\.001, 1000\]",
        ),
        (
            {"damping.prismatic": (0.0, 1e6)},
            r"^randomization\['damping\.prismatic'\]: factors must be >= 0 and <= 1000",
        ),
        ({"com": (-1e4, 1.0)}, r"^randomization\['com'\]: factors must be within \[-1000, 1000\]"),
        ({"com": "0.9, 1.1"}, r"^randomization\['com'\]: expected \(low, high\), got '0\.9, 1\.1'$"),
        ({"com": (0.9, 1.0, 1.1)}, r"^randomization\['com'\]: expected \(low, high\), got \(0\.9, 1\.0, 1\.1\)$"),
        ({"com": {"low": 0.9, "high": 1.1}}, r"^randomization\['com'\]: expected \(low, high\), got \{"),
        ({"com": None}, r"^randomization\['com'\]: expected \(low, high\), got None$"),
        ({"com": np.array(1.0)}, r"^randomization\['com'\]: expected \(low, high\), got array\(1\.\)$"),
        ({"com": np.ones((2, 2))}, r"^randomization\['com'\]: expected \(low, high\), got array\("),
        (
            {"mass": HUGE_LIST},
            r"^randomization\['mass'\]: expected \(low, high\), got \[1\.0, 1\.0, 1\.0, 1\.0, [.][.][.]\]$",
        ),
        (
            {"x" * 1000: (1.0, 1.0)},
            r"^randomization: unknown key\(s\) \(text of 1000 characters\); valid keys: platform\.mass, ",
        ),
        ({3: (1.0, 1.0)}, r"^randomization: unknown key\(s\) \(an int\); valid keys"),
        (
            [("mass", (0.9, 1.1))],
            r"^randomization: expected a dict of key -> \(low, high\), got \[\('mass', \(0\.9, 1\.1\)\)\]$",
        ),
        ("mass", r"^randomization: expected a dict of key -> \(low, high\), got 'mass'$"),
    ],
)
def test_bad_randomization_specs_name_their_key(spec, message):
    with pytest.raises(ConfigError, match=message) as info:
        Randomization(spec)
    assert len(str(info.value)) <= MAX_MESSAGE


def test_randomization_accepts_the_extreme_valid_ranges():
    spec = {"mass": (1e-3, 1e3), "com": (-1e3, 1e3), "damping": (0.0, 1e3), "inertia": np.array([0.5, 2.0])}
    assert Randomization(spec).ranges == {
        "mass": (1e-3, 1e3),
        "inertia": (0.5, 2.0),
        "com": (-1e3, 1e3),
        "damping": (0.0, 1e3),
    }


# ---------------------------------------------------------------------------------------------
# Read-only installs: nothing is compiled or cached at run time


def _unprivileged_prefix(tmp_path: Path) -> list[str] | None:
    """A command prefix under which this Python cannot write to a 0555 directory it owns, or None.

    chmod does not stop root, so root runs the child without capabilities (setpriv keeps uid 0,
    so that the interpreter under /root stays readable) or as nobody."""
    if os.geteuid() != 0:
        return []
    probe = tmp_path / "probe"
    probe.mkdir()
    (probe / "readable").write_text("yes")
    probe.chmod(0o555)
    candidates = []
    if shutil.which("setpriv"):
        candidates.append(["setpriv", "--securebits=+noroot,+noroot_locked", "--bounding-set=-all", "--inh-caps=-all"])
        candidates.append(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"])
    if shutil.which("runuser"):
        candidates.append(["runuser", "-u", "nobody", "--"])
    # The child must read the directory (the install will live in tmp_path too) but not write it.
    code = f"print(open({str(probe / 'readable')!r}).read()); open({str(probe / 'x')!r}, 'w')"
    for prefix in candidates:
        try:
            result = subprocess.run([*prefix, sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
        except OSError:
            continue
        if result.stdout == "yes\n" and "PermissionError" in result.stderr:
            return prefix
    return None


@pytest.fixture
def read_only_install(tmp_path):
    """(run, root): `run(code, tempdir=None)` runs Python code in a child that imports
    stewart_env from a read-only copy of the package, with a read-only HOME; `tempdir` is the
    child's temporary directory (a fresh writable one by default)."""
    prefix = _unprivileged_prefix(tmp_path)
    if prefix is None:
        pytest.skip(
            "running as root and no way to drop the privilege to write read-only directories (setpriv or runuser)"
        )
    install = tmp_path / "install"
    package_dir = Path(stewart_env.__file__).resolve().parent
    shutil.copytree(package_dir, install / "stewart_env", ignore=shutil.ignore_patterns("__pycache__"))
    # the compiled extensions (one per instruction-set target, and the processor's features):
    # beside the sources in a normal install, elsewhere in an editable one
    for extension in Path(stewart_env._core._kernels.__file__).parent.glob("_*.so"):
        if not (install / "stewart_env" / "_core" / extension.name).exists():
            shutil.copy2(extension, install / "stewart_env" / "_core" / extension.name)
    shutil.copytree(package_dir.parent / "configs", install / "configs", ignore=shutil.ignore_patterns("__pycache__"))
    home = tmp_path / "home"
    home.mkdir()
    writable_tmp = tmp_path / "tmp"
    writable_tmp.mkdir()
    writable_tmp.chmod(0o777)  # for a child that runs as nobody
    for directory in (install, home):
        for root, _, files in os.walk(directory):
            for name in files:
                os.chmod(os.path.join(root, name), 0o444)
            os.chmod(root, 0o555)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "PYTHON", "XDG_"))}
    # the child starts without site (-S), so no editable install's path hook can point it at a
    # checkout: it finds stewart_env in the copy and the other packages in this Python's site dirs
    site_dirs = [p for p in sys.path if Path(p).name in ("site-packages", "dist-packages")]
    env.update(
        HOME=str(home),
        PYTHONPATH=os.pathsep.join([str(install), *site_dirs]),
        TMPDIR=str(writable_tmp),
        PYTHONDONTWRITEBYTECODE="1",
    )

    def run(code: str, tempdir: Path | None = None) -> subprocess.CompletedProcess:
        setup = f"import tempfile; tempfile.tempdir = {str(tempdir)!r}\n" if tempdir else ""
        script = setup + textwrap.dedent(code)
        return subprocess.run(
            [*prefix, sys.executable, "-S", "-W", "always", "-c", script],
            env=env,
            cwd=str(home),
            capture_output=True,
            text=True,
            timeout=300,
        )

    yield run, tmp_path
    for root, _, _ in os.walk(tmp_path):  # let pytest remove the tree
        os.chmod(root, stat.S_IRWXU)


CHILD = """
import json
import warnings
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    import stewart_env
    import gymnasium as gym
    import numpy as np
    from stewart_env import rotations
    print("FILE", stewart_env.__file__)
    phi, angle = rotations.rotation_error(rotations.rpy_to_matrix([0.0, 0.0, 0.5]), np.eye(3))
    print("ANGLE", round(float(angle), 12))
    env = gym.make("StewartPlatform-v0")
    env.reset(seed=0)
    obs, reward, *_ = env.step(np.zeros(6))
    print("STEP", bool(np.isfinite(obs).all() and np.isfinite(reward)))
    print("MASS", stewart_env.load_platform("dasgupta1998").platform.mass)
print("WARNINGS", json.dumps([str(w.message) for w in caught if "stewart_env" in str(w.filename)]))
"""


def child_output(result: subprocess.CompletedProcess) -> dict[str, str]:
    assert result.returncode == 0, result.stderr[-3000:]
    return dict(line.split(" ", 1) for line in result.stdout.splitlines())


def test_a_read_only_install_runs_and_writes_nothing(read_only_install):
    run, root = read_only_install
    out = child_output(run(CHILD, tempdir=root / "home"))  # not even a temporary directory to write
    assert out["FILE"] == str(root / "install" / "stewart_env" / "__init__.py")
    assert out["ANGLE"] == "0.5"  # a yaw of 0.5 rad
    assert out["STEP"] == "True"
    assert out["MASS"] == "40.0"
    assert json.loads(out["WARNINGS"]) == []
    assert not list(root.glob("install/**/__pycache__")) and not list(root.glob("home/*"))
    assert not list(root.glob("tmp/*"))


# ---------------------------------------------------------------------------------------------
# What a step and a reset are given: one check for the single and the vector environment


def _faces():
    """(name, environment, action shape) of the three ways in: the class, gymnasium.make (with
    its checking wrappers, past their first reset and steps) and the vector environment."""
    import gymnasium as gym

    from stewart_env.envs import StewartPlatformEnv, StewartPlatformVectorEnv

    made = gym.make("StewartPlatform-v1")
    made.reset(seed=0)
    for _ in range(2):  # gymnasium's checker compares its first steps' data; a failed reset before confuses it
        made.step(np.zeros(6))
    return [
        ("class", StewartPlatformEnv(), (6,)),
        ("gymnasium.make", made, (6,)),
        ("vector", StewartPlatformVectorEnv(num_envs=2), (2, 6)),
    ]


@pytest.fixture(scope="module")
def faces():
    envs = _faces()
    yield envs
    for _, env, _ in envs:
        env.close()


@pytest.mark.parametrize("options", [[1, 2], 5, "reset_mask", ("a", 1), np.zeros(3)])
def test_reset_options_that_are_not_a_mapping_are_named(faces, options):
    for face, env, _ in faces:
        with pytest.raises(ValueError, match=r"^reset: options: expected a dict \(or None\), got ") as caught:
            env.reset(seed=0, options=options)
        assert isinstance(caught.value, TypeError), face  # a wrong kind, as everywhere in the package


def test_unknown_reset_options_are_named(faces):
    for face, env, _ in faces:
        valid = "valid: 'reset_mask'" if face == "vector" else "this environment takes none"
        with pytest.raises(ValueError, match=rf"^reset: options: unknown option\(s\) 'start'; {valid}$"):
            env.reset(seed=0, options={"start": 1})


@pytest.mark.parametrize(
    "options, message",
    [
        (5, r"expected a dict \(or None\) per row, got int"),
        (["a", "b"], r"expected a dict \(or None\) per row, got str"),
        ([{}, {}, {}], r"expected one dict for every row or a list of 2, got a list of 3"),
    ],
)
def test_sb3_set_options_that_cannot_be_options_are_named(options, message):
    pytest.importorskip("stable_baselines3")
    from stewart_env.envs import StewartPlatformSB3VecEnv

    venv = StewartPlatformSB3VecEnv(num_envs=2)
    with pytest.raises(ValueError, match=rf"^set_options: options: {message}$"):
        venv.set_options(options)
    venv.close()


def test_sb3_reset_with_options_set_names_them():
    pytest.importorskip("stable_baselines3")
    from stewart_env.envs import StewartPlatformSB3VecEnv

    venv = StewartPlatformSB3VecEnv(num_envs=2)
    venv.set_options({"start": 1})
    with pytest.raises(ValueError, match=r"^reset: options: unknown option\(s\) 'start'; this environment takes none$"):
        venv.reset()
    venv.set_options(None)  # cleared: the next reset takes none
    assert venv.reset().shape[0] == 2
    venv.close()


def test_tensors_that_require_grad_are_read_detached(faces):
    torch = pytest.importorskip("torch")
    for face, env, shape in faces:
        env.reset(seed=3)
        plain = env.step(np.full(shape, 0.1))[1]
        env.reset(seed=3)
        action = torch.full(shape, 0.1, dtype=torch.float64, requires_grad=True)
        assert np.array_equal(env.step(action)[1], plain), face  # the same numbers, bit for bit
        assert action.requires_grad and action.grad is None  # the caller's tensor is left as it was


def test_masked_arrays_are_refused_with_masked_entries_and_read_without(faces):
    for face, env, shape in faces:
        env.reset(seed=3)
        plain = env.step(np.full(shape, 0.1))[1]
        env.reset(seed=3)
        unmasked = np.ma.masked_array(np.full(shape, 0.1), mask=np.zeros(shape, bool))
        assert np.array_equal(env.step(unmasked)[1], plain), face
        mask = np.zeros(shape, bool)
        mask.flat[1] = True
        hidden = np.ma.masked_array(np.full(shape, 0.1), mask=mask)
        hidden.data.flat[1] = 1e300  # under the mask: never used
        with pytest.raises(
            ValueError,
            match=r"^action: a masked array with 1 masked value\(s\); give plain numbers, "
            r"e.g. action.filled\(0.0\)",
        ):
            env.step(hidden)
