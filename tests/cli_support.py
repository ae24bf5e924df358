"""Running ``fdid`` in-process from tests, the check of a refusal (one error line), and the
trace files the tests hand to ``fdid``."""
import numpy as np

from fdid_fmi.cli import main


def run_cli(capsys, *args):
    """``fdid ARGS`` in-process: (exit code, stdout, stderr); argparse's exit is the code."""
    try:
        code = main([str(a) for a in args])
    except SystemExit as exc:            # argparse errors
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def one_line(code, err, *words):
    """Assert a refusal: exit code 2, one non-empty stderr line holding every one of ``words``,
    no traceback, no internal error. Returns the line."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, (code, err)
    assert len(lines) == 1 and "Traceback" not in err and "internal error" not in err, err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def write_positions_csv(tr, path):
    """A trace's time, commanded and measured positions as the CSV ``fdid`` reads
    (``t_s``, ``<axis>_cmd_mm``, ``<axis>_act_mm``; 10 significant digits)."""
    cols, hdr = [tr.t], ["t_s"]
    for a in tr.axes:
        for role in ("cmd", "act"):
            cols.append(tr.channels[tr.roles[a][role]].data)
            hdr.append(f"{a}_{role}_mm")
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=",".join(hdr), comments="", fmt="%.10g")
