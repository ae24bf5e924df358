"""Text that reaches an FMU's modelDescription.xml (a port's unit and description, the method, a
parameter's text, the FMU description) refuses bidirectional-text controls -- embeddings and
overrides U+202A-U+202E, isolates U+2066-U+2069, the marks U+200E, U+200F and U+061C -- as it
refuses control characters: shown in a master's variable list or a log they reorder the text
around them, so a unit or a description can read as another. Right-to-left letters themselves
are ordinary text and stay accepted."""
import json

import pytest

import fmu_support as fs
from cli_support import one_line, run_cli as run
from fdid_fmi.errors import InputError
from fdid_fmi.fmu import export_fmu
from fdid_fmi.model import check_text, load_model

BIDI = [0x202A, 0x202B, 0x202C, 0x202D, 0x202E, 0x2066, 0x2067, 0x2068, 0x2069, 0x200E, 0x200F, 0x061C]


@pytest.fixture(scope="module")
def model_dict(tmp_path_factory):
    p = tmp_path_factory.mktemp("text") / "m.json"
    fs.siso_model().save(p)
    return json.loads(p.read_text())


def _with(d, field, text):
    d = json.loads(json.dumps(d))
    if field == "method":
        d["method"] = text
    elif field == "parameter":
        d["inputs"][1]["params"]["note"] = text
    else:
        d["outputs"][0][field] = text
    return d


@pytest.mark.parametrize("code", BIDI, ids=lambda c: f"U+{c:04X}")
def test_every_direction_control_is_refused(code):
    with pytest.raises(InputError, match=f"bidirectional-text control character U\\+{code:04X} at position 4"):
        check_text(f"abc{chr(code)}def", "description")


@pytest.mark.parametrize("field", ["description", "unit", "method", "parameter"])
def test_model_file_fields_refuse_an_override(tmp_path, model_dict, field):
    p = tmp_path / "m.json"
    p.write_text(json.dumps(_with(model_dict, field, "mm\u202e/s" if field == "unit" else "tool \u202eedis")))
    with pytest.raises(InputError) as ei:
        load_model(p)
    msg = str(ei.value)
    assert msg.startswith(f"{p}: ") and "U+202E at position" in msg and "\n" not in msg
    assert "\u202e" not in msg             # the message itself shows the code, never the character


def test_right_to_left_letters_stay_accepted(tmp_path, model_dict):
    p = tmp_path / "m.json"
    p.write_text(json.dumps(_with(model_dict, "description", "מיקום הציר — موضع المحور")))
    assert load_model(p).outputs[0].description == "מיקום הציר — موضع المحور"


def test_export_refuses_an_override_before_writing(tmp_path):
    m = fs.siso_model()
    m.outputs[0].description = "position \u2066(mm)\u2069"
    out = tmp_path / "d.fmu"
    with pytest.raises(InputError, match="description has the bidirectional-text control character U\\+2066"):
        export_fmu(m, out)
    with pytest.raises(InputError, match="U\\+200F"):
        export_fmu(fs.siso_model(), out, description="axis x\u200f")
    assert not out.exists()


def test_command_line_says_it_in_one_line(capsys, tmp_path, model_dict):
    p = tmp_path / "m.json"
    p.write_text(json.dumps(_with(model_dict, "unit", "m\u202dm")))
    code, _, err = run(capsys, "export", p, "-o", tmp_path / "d.fmu")
    one_line(code, err, "m.json", "'x_pos'", "unit has the bidirectional-text control character U+202D")
    assert not (tmp_path / "d.fmu").exists()
