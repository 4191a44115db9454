"""The loop closed on a stand-in machine (stewart_env.agents.studies.own_platform): excitation,
record, identification from the file, computed torque on the identified model."""

import json

import pytest

from stewart_env.agents.studies import own_platform


@pytest.mark.slow
def test_computed_torque_on_the_identified_model_tracks_as_on_the_true_one(tmp_path):
    summary = own_platform.run(
        tmp_path, plant="improved", perturb=0.2, duration=6.0, period=3.0, episodes=2, random=True
    )
    for name in ("excitation.csv", "record.csv", "truth.yaml", "identified/platform.yaml", "summary.md"):
        assert (tmp_path / name).is_file()
    assert json.loads((tmp_path / "summary.json").read_text())["tracking"] == summary["tracking"]
    rows = summary["tracking"]
    # the bar: within 1.5x of computed torque on the machine's true parameters
    assert rows["identified"]["rms_position_error_mm"] <= 1.5 * rows["true"]["rms_position_error_mm"]
    # a 20 % wrong model tracks worse than either (else the comparison shows nothing)
    assert rows["nominal"]["rms_position_error_mm"] > rows["identified"]["rms_position_error_mm"]
    assert "| identified |" in (tmp_path / "summary.md").read_text()


def test_the_script_takes_one_folder(capsys):
    assert own_platform.main([]) == 2
    assert own_platform.main(["--out", "x"]) == 2
    assert "usage: python -m stewart_env.agents.studies.own_platform OUT" in capsys.readouterr().err
