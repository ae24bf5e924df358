"""The README's results table is the one benchmarks/readme_table.py makes from the figures the
benchmarks published in docs/results/, and every page there names the command that made it."""
import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _generator():
    spec = importlib.util.spec_from_file_location("readme_table", ROOT / "benchmarks" / "readme_table.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_readme_results_table_is_generated():
    gen = _generator()
    assert gen.current((ROOT / "README.md").read_text()) == gen.render(ROOT / "docs" / "results")


def test_every_results_page_names_its_command():
    pages = sorted((ROOT / "docs" / "results").glob("*.md"))
    assert pages
    for page in pages:
        data = json.loads(page.with_suffix(".json").read_text())
        assert data["command"].startswith("./run.sh bench ")
        assert f"Produced by `{data['command']}`" in page.read_text(), page.name
        assert (ROOT / "benchmarks" / f"bench_{data['command'].split()[2]}.py").is_file(), page.name
