"""`mecanum-mav demo`: the whole product in one command."""

from __future__ import annotations

from mecanum_mav.app.cli import main


def test_demo_runs_the_mission_prints_a_table_per_leg_and_writes_the_figure(tmp_path, capsys):
    png = tmp_path / "demo.png"
    assert main(["demo", "--side", "0.6", "--png", str(png)]) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if line[:1].isdigit()]
    assert len(rows) == 5  # four sides of the square and the diagonal
    for row in rows:
        *_, seconds, cross_cm, arrival_cm = row.split()
        assert float(seconds) > 0.5
        assert float(cross_cm) < 5.0 and float(arrival_cm) < 10.0
    assert "heading within" in out and "of north" in out
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
