"""A FIFO, a device or a directory given where a file is expected (a trace, a model, an FMU) is
refused at once with one line that says what it is: reading a FIFO would block for a writer, a
character device such as /dev/zero would never end."""
import os
from pathlib import Path

import pytest

import fmu_support as fs
from cli_support import one_line, run_cli as run
from fdid_fmi.errors import InputError
from fdid_fmi.io import read_trace
from fdid_fmi.io.common import check_file


@pytest.fixture
def fifo(tmp_path):
    p = tmp_path / "trace.csv"
    try:
        os.mkfifo(p)
    except (AttributeError, OSError) as exc:
        pytest.skip(f"no FIFO can be made here ({exc})")
    return p


def test_fifo_as_a_trace_is_named(fifo):
    with pytest.raises(InputError) as ei:
        read_trace(fifo)                  # returns at once: never opened, so no writer is awaited
    assert str(ei.value) == f"{fifo}: is a FIFO (named pipe), not a regular file"


@pytest.mark.parametrize("dev", ["/dev/null", "/dev/zero"])
def test_character_device_as_a_trace_is_named(dev):
    if not Path(dev).exists():
        pytest.skip(f"{dev} is absent")
    with pytest.raises(InputError, match="is a character device, not a regular file"):
        read_trace(dev)


def test_directory_is_named(tmp_path):
    with pytest.raises(InputError, match="is a directory, not a regular file"):
        check_file(tmp_path)


@pytest.mark.parametrize("cmd", ["simulate", "validate", "export"])
def test_the_command_line_says_it_in_one_line(capsys, tmp_path, fifo, cmd):
    """The FIFO in each place a user gives a file: as the trace, the model, the FMU."""
    model = tmp_path / "m.json"
    fs.siso_model().save(model)
    csv = tmp_path / "run.csv"
    csv.write_text("t_s,x_cmd_mm,x_mm\n" + "".join(f"{k * 1e-3:.3f},{k * 1e-3},{k * 1e-3}\n" for k in range(200)))
    argv = {"simulate": ["simulate", model, fifo, "-o", tmp_path / "p.csv"],
            "validate": ["validate", fifo, csv],
            "export": ["export", fifo, "-o", tmp_path / "d.fmu"]}[cmd]
    code, _, err = run(capsys, *argv)
    one_line(code, err, f"{fifo}: is a FIFO (named pipe), not a regular file")
