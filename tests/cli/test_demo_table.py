"""The demo's table fits an 80-column terminal; --out keeps the table of every metric."""

from stewart_env.agents.evaluation.evaluation import (
    COMPACT_COLUMNS,
    COST_RATE,
    LIMIT_HITS,
    METRICS,
    compact_table,
    markdown_table,
)
from stewart_env.cli import main


def test_the_demo_prints_a_table_an_80_column_terminal_shows_and_writes_every_metric_with_out(tmp_path, capsys):
    assert main(["demo", "--episodes", "1", "--out", str(tmp_path / "report")]) == 0
    out = capsys.readouterr().out
    table_lines = out.split("report written to")[0].splitlines()  # the report's path is as long as it is
    assert max(len(line) for line in table_lines) <= 80, out
    header = next(line for line in out.splitlines() if line.startswith("controller"))
    assert header.split() == ["controller", "model", *" ".join(COMPACT_COLUMNS.values()).split()]
    assert "report written to" in out
    table = (tmp_path / "report" / "results.md").read_text()
    head = next(line for line in table.splitlines() if line.startswith("| controller"))
    # every metric, with the task, episodes and ended-early columns: 15 columns
    # controller, model, task, episodes, every metric, ended early, then the cost rate and the limit hits
    assert len(head.strip("|").split("|")) == 4 + len(METRICS) + 1 + 2
    assert head.rstrip(" |").endswith(f"{COST_RATE} | {LIMIT_HITS}")
    assert all(m.title in head for m in METRICS)


def test_without_out_the_demo_says_how_to_get_every_metric(capsys):
    assert main(["demo", "--episodes", "1"]) == 0
    assert "--out DIR writes DIR/results.md" in capsys.readouterr().out


def test_the_compact_table_keeps_the_markdown_table_unchanged_and_takes_its_columns():
    from stewart_env.agents import PDPolicy, evaluate

    results = [evaluate(PDPolicy, {"model": "improved", "task": "setpoint"}, episodes=1, max_steps=20, label="PD")]
    full = markdown_table(results)
    assert full.splitlines()[0].count("|") == 4 + len(METRICS) + 2 + 2  # 15 columns, then the two of the costs
    lines = compact_table(results, {"success": "ok", "peak_leg_force": "force N"}).splitlines()
    assert lines[0].split() == ["controller", "model", "ok", "force", "N"]
    assert lines[1].split()[:2] == ["PD", "improved"] and len(lines) == 2
