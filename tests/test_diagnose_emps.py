"""``fdid diagnose`` on real data (EMPS) refuses a model it cannot diagnose. The diagnosis that
finds the force pulses of DATA_EMPS_PULSES (the unused ``pulses_N`` channel, added, checked
through the FMUs) is a check of ``benchmarks/bench_end_to_end.py`` (``checks/diagnose_emps.py``).
"""
from fdid_fmi.cli import main
from fdid_fmi.io import read_trace


def test_cli_refuses_a_quasi_static_model(shared_data, tmp_path, capsys):
    from fdid_fmi.identify import identify_quasi_static
    tr = read_trace(shared_data / "emps" / "DATA_EMPS.mat")
    q = identify_quasi_static(tr)
    p = tmp_path / "qs.json"
    q.save(p)
    rc = main(["diagnose", str(p), "--train", str(shared_data / "emps" / "DATA_EMPS_PULSES.mat")])
    assert rc == 2
    assert "quasi-static" in capsys.readouterr().err
