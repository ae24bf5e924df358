"""Running ``fdid`` in-process from tests, and the check of a refusal: one error line."""
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
