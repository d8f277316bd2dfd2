"""The command line writes what it promises and fails with one line on bad input."""

import json
import subprocess
import sys

import pytest

from morphlab.cli import main


@pytest.mark.slow
def test_morphing_writes_tables_figures_and_json(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["morphing", "--out", str(out), "--quick"]) == 0
    printed = capsys.readouterr().out
    assert "Table 1" in printed and "Table 2" in printed
    data = json.loads((out / "morphing.json").read_text())
    for key in ("ks_max_stress_MPa", "max_error_mm", "rms_error_mm"):
        assert isinstance(data[key], float)
    names = {"t_w", "M_t", "x_A", "y_A", "E"}
    assert set(data["sensitivities"]["ks_max_stress_MPa"]) == names
    assert set(data["sensitivities"]["rms_error_mm"]) == names
    t = data["timing_s"]
    assert all(t[k] > 0 for k in ("primal", "direct", "finite_difference"))
    # the morphed shape meets the design bounds of the study (RMS < 1 mm, KS < yield 240 MPa)
    assert data["rms_error_mm"] < 1.0 and data["ks_max_stress_MPa"] < 240.0
    for fig in ("fig5b_motion", "fig6_stress", "fig7_profiles", "fig9_error_sens"):
        assert (out / f"{fig}.png").stat().st_size > 1000
    # the closing note quotes this run's figures (the quick run's differ from the study's)
    note = " ".join(printed[printed.index("Why our numbers"):].split())
    signs = data["formulations"]["study"]["table1_signs_as_paper"]
    assert f"Table 1 signs as the paper's: {signs} of 10." in note
    m_err = data["design"]["M_t"] * data["sensitivities"]["rms_error_mm"]["M_t"]
    assert f"(M_t de_rms/dM_t = {m_err:+.2f} mm)" in note
    assert f"(RMS {data['rms_error_mm']:.3f} vs 0.63 mm)" in note


@pytest.mark.parametrize("args, word", [
    (["--set", "t_w=abc"], "not a number"),
    (["--set", "nonsense=1"], "unknown design variable"),
    (["--set", "t_w=-2"], "thickness"),
])
def test_bad_input_exits_with_one_line(tmp_path, args, word):
    proc = subprocess.run([sys.executable, "-m", "morphlab.cli", "morphing", "--out",
                           str(tmp_path), "--no-timing", "--no-figures", *args],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and word in lines[0] and "Traceback" not in proc.stderr


def test_study_note_reads_its_figures_from_the_summary():
    """The closing note's conditional readings follow the numbers it is given (a summary made
    up here: the note computes nothing else)."""
    from morphlab.morphing import leading_edge as le

    paper = le.PAPER["table1"]
    ks = {v: -g for v, g in paper["ks_max_stress_MPa"].items()}  # every stress sign flipped
    err = dict(paper["rms_error_mm"])
    summary = {"design": dict(le.DEFAULTS), "ks_max_stress_MPa": 80.0, "rms_error_mm": 0.02,
               "sensitivities": {"ks_max_stress_MPa": ks, "rms_error_mm": err}}

    def note(**change):
        for key, (var, value) in change.items():
            summary["sensitivities"][key][var] = value
        return " ".join(le.why_different(summary).split())

    text = note(ks_max_stress_MPa=("M_t", 0.007), rms_error_mm=("M_t", 1e-5))
    # the five error signs and the torque's stress sign (set back to the paper's above)
    assert "Table 1 signs as the paper's: 6 of 10." in text
    assert "Unlike the paper's" in text and "(M_t dsigma/dM_t = 70 <= 80 MPa" in text
    assert "past it" in text and "(M_t de_rms/dM_t = +0.10 mm)" in text
    assert "The stress signs for x_A and y_A differ" in text
    assert "single-frame skin" not in text  # no comparison in this summary
    text = note(ks_max_stress_MPa=("M_t", 0.02), rms_error_mm=("M_t", -1e-5))
    assert "Like the paper's" in text and "short of it" in text
    ks["x_A"] = paper["ks_max_stress_MPa"]["x_A"]
    assert "The stress signs for y_A differ" in note()
