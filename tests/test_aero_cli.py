"""The main command includes the flight loads and aerodynamics by default."""

import json

import pytest

from morphlab.cli import main


@pytest.mark.slow
def test_morphing_command_writes_the_flight_loads(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["morphing", "--out", str(out), "--quick", "--no-timing"]) == 0
    printed = capsys.readouterr().out
    assert "Table 1" in printed and "Flight loads and aerodynamics" in printed
    data = json.loads((out / "flight_loads.json").read_text())
    assert set(data["conditions"]) == {"high_speed", "thermalling"}
    shapes = {(r["configuration"], r["shape"]) for r in data["rows"]}
    assert ("thermalling", "realized, loaded (torque)") in shapes
    assert ("thermalling", "paper's single frame, vacuum") in shapes
    eq = data["equilibria"]["thermalling/accurate/torque"]
    assert eq["history"][-1]["node_change_mm"] < eq["tol_mm"]
    assert 0.0 < eq["deflection_rms_mm"] <= eq["deflection_max_mm"]
    assert len(eq["deflection_mm"]) == len(eq["pressure_mpa"]) == 31
    report = (out / "report.txt").read_text()
    assert "Table 1" in report and "Flight loads and aerodynamics" in report
    for fig in ("fig10_cp", "fig11_skin_load"):
        assert (out / f"{fig}.png").stat().st_size > 1000


def test_no_aero_skips_them(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["morphing", "--out", str(out), "--quick", "--no-timing", "--no-figures",
                 "--no-aero"]) == 0
    assert "Flight loads" not in capsys.readouterr().out
    assert not (out / "flight_loads.json").exists()
