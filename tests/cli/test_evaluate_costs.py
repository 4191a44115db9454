"""``stewart-env evaluate`` shows each controller's constraint cost rate and limit hits."""

from __future__ import annotations

import json

from stewart_env.cli import main


def test_evaluate_shows_the_cost_rate_and_limit_hits(tmp_path, capsys):
    argv = ["evaluate", "--platform", "motion_simulator", "--episodes", "1", "--max-steps", "5", "--out", str(tmp_path)]
    assert main(argv) == 0
    header, _, row = capsys.readouterr().out.splitlines()[:3]
    columns = [c.strip() for c in header.strip("|").split("|")]
    assert columns[-2:] == ["cost rate", "limit hits (steps)"]
    cells = [c.strip() for c in row.strip("|").split("|")]
    record = json.loads((tmp_path / "results.json").read_text())[0]
    assert cells[-2] == format(record["cost_rate"], ".3g")
    hits = ", ".join(f"{name} {count}" for name, count in record["limit_hits"].items() if count) or "0"
    assert cells[-1] == hits
