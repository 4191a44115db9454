"""ModelSpec: a model name parsed once, one canonical name per set of kernel flags."""

from __future__ import annotations

import dataclasses
import itertools
import pickle
import re

import pytest

import stewart_env as se
from stewart_env import _core
from stewart_env.dynamics.model import MODEL_NAMES, SWITCHES, parse_model_name
from stewart_env.dynamics.spec import ModelSpec, Switch
from stewart_env.errors import UsageError

# The kernel flags every name had before ModelSpec (parse_model_name as released), for every base
# and every subset of switches: the spec must give the same model to the kernels.
FLAGS_BEFORE = {
    "classical": 15,
    "classical+c1": 15,
    "classical+c2": 15,
    "classical+c3": 15,
    "classical+c4": 15,
    "classical+c1+c2": 15,
    "classical+c1+c3": 15,
    "classical+c1+c4": 15,
    "classical+c2+c3": 15,
    "classical+c2+c4": 15,
    "classical+c3+c4": 15,
    "classical+c1+c2+c3": 15,
    "classical+c1+c2+c4": 15,
    "classical+c1+c3+c4": 15,
    "classical+c2+c3+c4": 15,
    "classical+c1+c2+c3+c4": 15,
    "improved": 0,
    "improved+c1": 1,
    "improved+c2": 2,
    "improved+c3": 4,
    "improved+c4": 8,
    "improved+c1+c2": 3,
    "improved+c1+c3": 5,
    "improved+c1+c4": 9,
    "improved+c2+c3": 6,
    "improved+c2+c4": 10,
    "improved+c3+c4": 12,
    "improved+c1+c2+c3": 7,
    "improved+c1+c2+c4": 11,
    "improved+c1+c3+c4": 13,
    "improved+c2+c3+c4": 14,
    "improved+c1+c2+c3+c4": 15,
    "improved_centroidal": 16,
    "improved_centroidal+c1": 17,
    "improved_centroidal+c2": 18,
    "improved_centroidal+c3": 20,
    "improved_centroidal+c4": 24,
    "improved_centroidal+c1+c2": 19,
    "improved_centroidal+c1+c3": 21,
    "improved_centroidal+c1+c4": 25,
    "improved_centroidal+c2+c3": 22,
    "improved_centroidal+c2+c4": 26,
    "improved_centroidal+c3+c4": 28,
    "improved_centroidal+c1+c2+c3": 23,
    "improved_centroidal+c1+c2+c4": 27,
    "improved_centroidal+c1+c3+c4": 29,
    "improved_centroidal+c2+c3+c4": 30,
    "improved_centroidal+c1+c2+c3+c4": 31,
}


def every_name():
    for base in MODEL_NAMES:
        for r in range(5):
            for switches in itertools.combinations(("c1", "c2", "c3", "c4"), r):
                yield "+".join((base, *switches))


def test_every_base_and_subset_of_switches_keeps_its_kernel_flags():
    names = list(every_name())
    assert sorted(names) == sorted(FLAGS_BEFORE)
    for name in names:
        assert ModelSpec.parse(name).flags == FLAGS_BEFORE[name], name
        assert parse_model_name(name)[1] == FLAGS_BEFORE[name], name


def test_the_switches_are_the_kernels_bits():
    assert [int(s) for s in Switch] == [_core.C1, _core.C2, _core.C3, _core.C4]
    assert SWITCHES == {"c1": _core.C1, "c2": _core.C2, "c3": _core.C3, "c4": _core.C4}
    assert ModelSpec.parse("improved_centroidal").flags == _core.CENTROIDAL
    assert ModelSpec.parse("improved+c2+c4").switches == Switch.C2 | Switch.C4


def test_one_canonical_name_per_set_of_kernel_flags():
    by_flags: dict[int, set[str]] = {}
    for name in every_name():
        by_flags.setdefault(FLAGS_BEFORE[name], set()).add(ModelSpec.parse(name).name)
    assert all(len(names) == 1 for names in by_flags.values()), by_flags
    assert len(by_flags) == 32  # 16 switch sets, with and without the centroidal bit
    # classical is the improved model with every switch on, whichever way it is spelled
    for name in ("classical", "classical+c1", "Classical+C3+c1", "improved+c4+c3+c2+c1"):
        assert ModelSpec.parse(name) == ModelSpec("classical") and str(ModelSpec.parse(name)) == "classical"
    # the centroidal bit is a different kernel flag set: its own name
    assert ModelSpec.parse("improved_centroidal+c1+c2+c3+c4").name == "improved_centroidal+c1+c2+c3+c4"
    assert ModelSpec.parse(" Improved+c3+C1+c3 ").name == "improved+c1+c3"


def test_the_constructor_canonicalises_and_the_spec_is_immutable():
    spec = ModelSpec("improved", Switch.C1 | Switch.C2 | Switch.C3 | Switch.C4)
    assert (spec.base, spec.switches, spec.flags) == ("classical", Switch.C1 | Switch.C2 | Switch.C3 | Switch.C4, 15)
    assert ModelSpec("classical", Switch.C1) == ModelSpec("classical") and hash(spec) == hash(ModelSpec("classical"))
    with pytest.raises(dataclasses.FrozenInstanceError):
        spec.base = "improved"
    with pytest.raises(UsageError, match=r"^model: switches: expected a Switch") as info:
        ModelSpec("improved", 64)
    assert info.value.argument == "model"


@pytest.mark.parametrize("name", list(every_name()))
def test_round_trip(name):
    spec = ModelSpec.parse(name)
    assert ModelSpec.parse(str(spec)) == spec and ModelSpec.parse(spec) is spec
    assert pickle.loads(pickle.dumps(spec)) == spec


@pytest.mark.parametrize(
    "value, argument, problem",
    [
        (
            "newton",
            "model",
            r"unknown model 'newton'; choose one of improved, improved_centroidal, classical, "
            r"optionally with switches '\+c1'..'\+c4'$",
        ),
        ("improved+c5", "plant", r"unknown switch 'c5' in 'improved\+c5'; switches are c1, c2, c3, c4$"),
        (3, "internal_model", r"expected a name such as 'improved', got 3$"),
        (None, "model", r"expected a name such as 'improved', got None$"),
    ],
)
def test_errors_name_the_argument_as_data(value, argument, problem):
    with pytest.raises(UsageError) as info:
        ModelSpec.parse(value, argument)
    err = info.value
    assert isinstance(err, ValueError) and err.argument == argument
    assert re.match(problem, err.problem) and str(err) == f"{argument}: {err.problem}"


def test_everything_that_takes_a_name_takes_a_spec():
    params = se.load_platform("dasgupta1998")
    spec = se.ModelSpec.parse("improved+c2")
    model = se.make_dynamics(spec, params)
    assert model.spec is spec and (model.name, model.flags) == ("improved+c2", 2)
    from stewart_env.envs import StewartPlatformEnv

    env = StewartPlatformEnv(model=spec)
    assert env.unwrapped.model.name == "improved+c2" and env.unwrapped.model.flags == 2
    env.close()
    from stewart_env.agents.controllers.computed_torque import ComputedTorque
    from stewart_env.agents.controllers.pd import TaskSpacePD

    assert ComputedTorque(params, spec).internal_model == "improved+c2"
    assert TaskSpacePD(params, gravity_model=spec).gravity_model == "improved+c2"


def test_controllers_name_their_own_model_argument():
    from stewart_env.agents.controllers.computed_torque import ComputedTorque
    from stewart_env.agents.controllers.pd import TaskSpacePD

    params = se.load_platform("dasgupta1998")
    with pytest.raises(UsageError, match=r"^internal_model: unknown model 'newton'") as info:
        ComputedTorque(params, "newton")
    assert info.value.argument == "internal_model"
    with pytest.raises(UsageError, match=r"^gravity_model: unknown switch 'c9'") as info:
        TaskSpacePD(params, gravity_model="improved+c9")
    assert info.value.argument == "gravity_model"


def test_the_environment_names_mujoco_beside_the_models():
    from stewart_env.envs.config import model_argument, model_spec

    assert model_spec("MuJoCo") is None and model_argument(" mujoco ") == "mujoco"
    assert model_argument("classical+c2") == "classical"
    with pytest.raises(UsageError, match=r"^model: unknown model 'nope'.*; or 'mujoco'") as info:
        model_argument("nope")
    assert info.value.argument == "model"
    # an unknown switch is no unknown model: no MuJoCo hint
    with pytest.raises(UsageError, match=r"^model: unknown switch 'c7' in 'improved\+c7'; switches are c1, c2, c3, c4"):
        model_argument("improved+c7")


def test_an_identify_report_of_another_spelling_of_the_model_is_the_same_model():
    """Reports written before the canonical names said ``classical+c1`` where they now say ``classical``."""
    from stewart_env.identification import base as base_mod
    from stewart_env.identification import experiment

    params = se.load_platform("dasgupta1998")
    model = se.make_dynamics("classical", params)
    base = base_mod.base_parameters(model)
    report = {
        "platform": params.name,
        "settings": {"model": "classical+c1", "noise_force": 1.0},
        "fitted_duration": 5.0,
        "base_parameters": [{"name": n, "wls": 1.0, "wls_std": 0.1} for n in base.names],
    }
    settings = experiment.Settings(model="classical", noise_force=1.0)
    experiment._check_reference(report, settings, params, base, model.spec)  # accepted: the same kernel flags
    for other in ("improved", "improved+c9"):
        report["settings"]["model"] = other
        with pytest.raises(UsageError, match="^--predicted-by: a report of dasgupta1998's classical base parameters"):
            experiment._check_reference(report, settings, params, base, model.spec)
