"""The README's two commands, and .ci/run running exactly the README's test command (plus the linters)."""

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
    assert ".[test]" in blocks[1] and "pytest" in blocks[1]


# the steps .ci/run may add to the README's test command: the linters configured in pyproject.toml
LINTER_STEPS = ("ruff check .", "ruff format --check .", "mypy")


def _steps(command):
    return [s.strip() for s in command.split("&&")]


def test_ci_runs_the_readme_test_command_with_the_linters_before_the_tests():
    test_steps = _steps(_bash_blocks((ROOT / "README.md").read_text())[1])
    ci_lines = [ln.strip() for ln in (ROOT / ".ci" / "run").read_text().splitlines()]
    runs = [_steps(ln) for ln in ci_lines if "pytest" in ln and not ln.startswith("#")]
    assert len(runs) == 1, ".ci/run must run the tests in exactly one command line"
    ci_steps = runs[0]
    # without the linter steps, .ci/run's command is exactly the README's
    assert [s for s in ci_steps if s not in LINTER_STEPS] == test_steps
    # every linter runs, and before the tests (a lint failure stops CI before the long test run)
    pytest_at = next(i for i, s in enumerate(ci_steps) if "pytest" in s)
    for linter in LINTER_STEPS:
        assert linter in ci_steps and ci_steps.index(linter) < pytest_at, linter


def test_main_scenario_exists():
    assert (ROOT / "scenarios" / "full_case1.yaml").is_file()
