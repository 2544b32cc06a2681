"""The README's two commands, and .ci/run running exactly the README's test command."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bash_blocks(text):
    return [b.strip() for b in re.findall(r"```bash\n(.*?)```", text, flags=re.S)]


def test_readme_has_exactly_two_commands():
    blocks = _bash_blocks((ROOT / "README.md").read_text())
    assert len(blocks) == 2
    assert all(len(b.splitlines()) == 1 for b in blocks)
    assert "run-scenario scenarios/full_case1.yaml" in blocks[0]
    assert '.[test]' in blocks[1] and "pytest" in blocks[1]


def test_ci_runs_the_readme_test_command():
    test_cmd = _bash_blocks((ROOT / "README.md").read_text())[1]
    ci_lines = [ln.strip() for ln in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert test_cmd in ci_lines


def test_main_scenario_exists():
    assert (ROOT / "scenarios" / "full_case1.yaml").is_file()
