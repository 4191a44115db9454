"""The cueing results study: its goals, its table and its refusals."""

from __future__ import annotations

import math

import pytest

from stewart_env.agents.studies.cueing_results import (
    GOALS,
    CueingResultsSettings,
    goals_reached,
    results_table,
    summarize,
)
from stewart_env.errors import UsageError


def metrics(rms: float, false_f: float, corr: float, stroke: float = 0.5, failed: float = 0.0) -> dict:
    return {
        "rms_specific_force_error": rms,
        "false_specific_force_cues": false_f,
        "false_angular_velocity_cues": 1.0,
        "specific_force_correlation": corr,
        "stroke_use": stroke,
        "failed": failed,
    }


def test_goals_compare_the_means_with_washouts():
    washout = {
        "rms_specific_force_error": 1.0,
        "false_cues": 10.0,
        "specific_force_correlation": 0.5,
        "stroke_violations": 0.0,
    }
    better = {
        "rms_specific_force_error": 0.8,
        "false_cues": 7.0,
        "specific_force_correlation": 0.5,
        "stroke_violations": 0.0,
    }
    assert goals_reached(washout, better) == {m: True for m, _, _ in GOALS}  # the bounds themselves reach
    worse = {
        "rms_specific_force_error": 0.81,
        "false_cues": 7.1,
        "specific_force_correlation": 0.49,
        "stroke_violations": 0.2,
    }
    assert goals_reached(washout, worse) == {m: False for m, _, _ in GOALS}


def test_summary_and_table_of_two_seeds():
    settings = CueingResultsSettings(seeds=(0, 1), episodes=2, manoeuvres=("braking",))
    washout = {"episodes": [metrics(1.0, 4.0, 0.3), metrics(1.2, 6.0, 0.5)]}
    ppo = {
        0: {"episodes": [metrics(0.5, 1.0, 0.6), metrics(0.7, 1.0, 0.8)]},
        1: {"episodes": [metrics(0.6, 2.0, 0.7), metrics(0.6, 2.0, 0.7, stroke=1.0)]},
    }
    results = summarize(settings, washout, ppo)
    entry = results["manoeuvres"]["braking"]
    assert entry["washout"]["rms_specific_force_error"][0] == pytest.approx(1.1)
    assert entry["ppo"]["rms_specific_force_error"][0] == pytest.approx(0.6)
    assert entry["washout"]["false_cues"][0] == pytest.approx(6.0)  # specific force and angular velocity summed
    assert entry["ppo"]["stroke_violations"][0] == pytest.approx(0.25)  # one episode at the end stop
    assert entry["goals"] == {
        "rms_specific_force_error": True,
        "false_cues": True,
        "specific_force_correlation": True,
        "stroke_violations": False,
    }
    low, high = entry["ppo"]["rms_specific_force_error"][1:]
    assert low <= 0.6 <= high and math.isfinite(low)
    text = results_table(results)
    assert "| braking | ppo (residual on washout) | 0.600 [" in text
    assert "ended at a limit" in text
    assert "PPO (ppo_cueing_residual): 2 training seed(s) (0, 1), 2 held-out episode(s) per manoeuvre" in text
    assert "| braking | reached | reached | reached | not reached |" in text


def test_bad_settings_are_named():
    with pytest.raises(UsageError, match="episodes: must be 1 to 10, got 11"):
        CueingResultsSettings(episodes=11)
    with pytest.raises(UsageError, match="manoeuvres"):
        CueingResultsSettings(manoeuvres=("no_such_motion",))
    with pytest.raises(UsageError, match="seeds"):
        CueingResultsSettings(seeds=())


def test_command_refuses_a_bad_episode_count(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from stewart_env.cli import main

    assert main(["cueing-results", "--out", str(tmp_path / "out"), "--episodes", "11"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "stewart-env cueing-results: error: argument --episodes: must be 1 to 10, got 11"
    assert not (tmp_path / "out").exists()  # nothing written


def test_the_config_is_checked_and_names_its_kind():
    assert CueingResultsSettings().label == "ppo (residual on washout)"  # the default: the residual config
    assert CueingResultsSettings(config="ppo_cueing").label == "ppo"
    assert CueingResultsSettings(config="ppo_cueing_mpc").label == "ppo (from the MPC's imitation)"
    assert CueingResultsSettings(config="ppo_cueing_mpc_residual").label == "ppo (residual on the MPC)"
    with pytest.raises(UsageError, match="config: .*needs env_kwargs action_mode: pose"):
        CueingResultsSettings(config="ppo")  # the set-point task's config: force mode


def test_a_config_with_two_kinds_is_refused(tmp_path):
    config = tmp_path / "two.yml"
    config.write_text(
        "StewartPlatform-v1:\n  n_timesteps: 10\n  residual_washout: {scale: 0.2}\n"
        "  residual_mpc: {residual_scale: 1.0}\n  env_kwargs: {action_mode: pose}\n"
    )
    with pytest.raises(UsageError, match="config: .*two.yml: give one of residual_washout, residual_mpc, not 2"):
        CueingResultsSettings(config=str(config))


def test_command_refuses_an_unknown_config(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from stewart_env.cli import main

    assert main(["cueing-results", "--out", str(tmp_path / "out"), "--config", "ppo_fast"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("stewart-env cueing-results: error: argument --config: unknown shipped config 'ppo_fast'")
    assert "\n" not in err and not (tmp_path / "out").exists()


def test_help_shows_the_interval_as_a_percentage(capsys):
    from stewart_env.cli import main

    with pytest.raises(SystemExit):
        main(["cueing-results", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "with 95 % intervals" in out  # argparse prints a description as written: no %% escape


def test_a_models_cost_is_the_paired_difference_with_the_exact_models_agents():
    settings = CueingResultsSettings(seeds=(0, 1), episodes=2, manoeuvres=("braking",), agent_models=("Classical",))
    assert settings.agent_models == ("classical",)  # the canonical name: its folder and its rows
    washout = {"episodes": [metrics(1.0, 4.0, 0.3), metrics(1.2, 6.0, 0.5)]}
    ppo = {
        0: {"episodes": [metrics(0.5, 1.0, 0.6), metrics(0.7, 1.0, 0.8)]},
        1: {"episodes": [metrics(0.6, 2.0, 0.7), metrics(0.6, 2.0, 0.7)]},
    }
    # every episode 0.1 m/s^2 worse and one false cue more: the cost is exactly that, in every resample
    classical = {
        s: {"episodes": [metrics(m["rms_specific_force_error"] + 0.1, m["false_specific_force_cues"] + 1.0, 0.2)
                         for m in e["episodes"]]}
        for s, e in ppo.items()
    }  # fmt: skip
    results = summarize(settings, washout, ppo, {"classical": classical})
    model = results["manoeuvres"]["braking"]["models"]["classical"]
    assert model["seeds"] == [0, 1]
    assert model["cost"]["rms_specific_force_error"] == pytest.approx([0.1, 0.1, 0.1])
    assert model["cost"]["false_cues"] == pytest.approx([1.0, 1.0, 1.0])
    assert model["cost"]["specific_force_correlation"][0] == pytest.approx(0.2 - 0.7)
    assert model["ppo"]["rms_specific_force_error"][0] == pytest.approx(0.7)
    assert results["agent_models"] == {"classical": [0, 1]}
    text = results_table(results)
    assert "| braking | ppo (residual on washout), trained on classical | 0.700 [" in text
    assert "| braking | classical | +0.100 [+0.100, +0.100] | +1.0 [+1.0, +1.0] | -0.50 [" in text


def test_a_models_cost_uses_the_seeds_both_have():
    settings = CueingResultsSettings(seeds=(0, 1), episodes=1, manoeuvres=("braking",), agent_models=("classical",))
    washout = {"episodes": [metrics(1.0, 4.0, 0.3)]}
    ppo = {0: {"episodes": [metrics(0.5, 1.0, 0.6)]}, 1: {"episodes": [metrics(0.9, 1.0, 0.6)]}}
    classical = {1: {"episodes": [metrics(1.2, 1.0, 0.6)]}}  # seed 0's agent missing
    model = summarize(settings, washout, ppo, {"classical": classical})["manoeuvres"]["braking"]["models"]["classical"]
    assert model["seeds"] == [1]
    assert model["cost"]["rms_specific_force_error"][0] == pytest.approx(0.3)  # against seed 1's 0.9, not the mean


@pytest.mark.parametrize(
    ("models", "message"),
    [
        (("improved",), "give distinct models other than 'improved'"),
        (("classical", "CLASSICAL"), "give distinct models"),
        (("newtonian",), "unknown model 'newtonian'"),
    ],
)
def test_bad_agent_models_are_named(models, message):
    with pytest.raises(UsageError, match=message) as err:
        CueingResultsSettings(agent_models=models)
    assert err.value.argument == "agent_models"


def test_command_names_a_bad_agent_model(tmp_path, capsys):
    from stewart_env.cli import main

    assert main(["cueing-results", "--out", str(tmp_path / "s"), "--agent-models", "newtonian"]) == 2
    err = capsys.readouterr().err
    assert "argument --agent-models: unknown model 'newtonian'; choose one of improved" in err
    assert "Traceback" not in err
    assert not (tmp_path / "s").exists()


def test_the_mpcs_rows_and_goals_beside_washouts():
    settings = CueingResultsSettings(seeds=(0,), episodes=2, manoeuvres=("braking",), mpc_previews=(10, 100))
    washout = {"episodes": [metrics(1.0, 4.0, 0.3), metrics(1.2, 6.0, 0.5)]}
    mpc = {
        10: {"episodes": [metrics(1.0, 9.0, 0.6), metrics(1.0, 9.0, 0.6)]},
        100: {"episodes": [metrics(0.8, 2.0, 0.9), metrics(0.8, 2.0, 0.9)]},
    }
    results = summarize(settings, washout, {}, None, mpc)
    entry = results["manoeuvres"]["braking"]
    assert results["mpc_previews"] == [10, 100]
    # 0.8 <= 0.8 x 1.1 and 3 <= 0.7 x 6 (false cues f + ω); 1.0 > 0.88 and 10 > 4.2
    assert entry["mpc"]["100"]["goals"] == {m: True for m, _, _ in GOALS}
    assert entry["mpc"]["10"]["goals"] == {
        "rms_specific_force_error": False,
        "false_cues": False,
        "specific_force_correlation": True,
        "stroke_violations": True,
    }
    text = results_table(results)
    assert "| braking | mpc (preview 100) | 0.800 [0.800, 0.800] | 3.0 [3.0, 3.0] |" in text
    assert "| braking | mpc (preview 10) | reached" not in text
    assert "| braking | mpc (preview 10) | not reached | not reached | reached | reached |" in text


@pytest.mark.parametrize("previews, message", [((101,), r"\[0, 100\], got 101"), ((10, 10), "distinct previews")])
def test_bad_mpc_previews_are_named(previews, message):
    with pytest.raises(UsageError, match=message) as err:
        CueingResultsSettings(mpc_previews=previews)
    assert err.value.argument == "mpc_previews"


def test_command_names_a_bad_mpc_preview(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    from stewart_env.cli import main

    assert main(["cueing-results", "--out", str(tmp_path / "s"), "--mpc-preview", "-1"]) == 2
    err = capsys.readouterr().err
    assert (
        err.strip()
        == "stewart-env cueing-results: error: argument --mpc-preview: expected an integer in [0, 100], got -1"
    )
    assert not (tmp_path / "s").exists()
