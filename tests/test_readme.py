"""The README's two commands, and .ci/run running exactly the README's test command (plus the linters), then
the numeric tests once more on another processor's arithmetic."""

import re
import shlex
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


#: the environment of .ci/run's second test run: numba compiled for a generic x86-64 CPU, OpenBLAS's kernels of
#: another core than any current host's, numpy's SIMD loops at their baseline
OTHER_CPU_ENV = {
    "NUMBA_CPU_NAME": "generic",
    "OPENBLAS_CORETYPE": "Prescott",
    "NPY_DISABLE_CPU_FEATURES": "$npy_dispatch",
}
#: test files that hold numbers and must be in the second run
NUMERIC_AT_LEAST = {
    "tests/test_registry.py",
    "tests/test_solver.py",
    "tests/test_physics.py",
    "tests/test_frame.py",
    "tests/test_frame_model.py",
    "pyfmu_wrapper/models/linear_tmd/tests/test_linear_tmd.py",
}


def _ci_text():
    return (ROOT / ".ci" / "run").read_text()


def _ci_test_runs():
    """The command lines of .ci/run that run pytest, in order (comments left out)."""
    return [ln.strip() for ln in _ci_text().splitlines() if "pytest" in ln and not ln.strip().startswith("#")]


def test_ci_runs_the_readme_test_command_with_the_linters_before_the_tests():
    test_steps = _steps(_bash_blocks((ROOT / "README.md").read_text())[1])
    runs = _ci_test_runs()
    assert runs, ".ci/run runs no tests"
    assert "set -euo pipefail" in _ci_text().splitlines(), "a failing step must fail CI"
    # the first test run is the README's command (the whole suite, before anything else is tested)
    ci_steps = _steps(runs[0])
    # without the linter steps, .ci/run's command is exactly the README's
    assert [s for s in ci_steps if s not in LINTER_STEPS] == test_steps
    # every linter runs, and before the tests (a lint failure stops CI before the long test run)
    pytest_at = next(i for i, s in enumerate(ci_steps) if "pytest" in s)
    for linter in LINTER_STEPS:
        assert linter in ci_steps and ci_steps.index(linter) < pytest_at, linter
    # any other test run is the second run below, nothing else
    for line in runs[1:]:
        env, _ = _other_cpu_run(line)
        assert env == OTHER_CPU_ENV, line


def _other_cpu_run(line):
    """(environment, test files) of .ci/run's second test run: ``VAR=value ... python -m pytest "${NUMERIC_TESTS[@]}"``,
    one plain command (no &&, ||, ;: its failure fails CI under set -e)."""
    assert not re.search(r"&|\||;", line), line
    words = shlex.split(line, posix=True)
    env = {}
    while words and re.fullmatch(r"[A-Z_]+=.*", words[0]):
        key, _, value = words.pop(0).partition("=")
        env[key] = value
    assert words == ["python", "-m", "pytest", "${NUMERIC_TESTS[@]}"], line
    block = re.search(r"^NUMERIC_TESTS=\((.*?)\)$", _ci_text(), flags=re.S | re.M)
    assert block, "NUMERIC_TESTS=( ... ) not found in .ci/run"
    return env, block.group(1).split()


def test_ci_runs_the_numeric_tests_again_on_another_processors_arithmetic():
    """.ci/run's second test run: after the README's command, the numeric tests with numba compiled for a
    generic CPU, OpenBLAS's kernels of another core and numpy at its baseline; every file exists, those that hold
    the solver's, the physics', the registry's, the frame's and the linear model's numbers are among them."""
    runs = _ci_test_runs()
    assert len(runs) == 2, runs
    env, files = _other_cpu_run(runs[1])
    assert env == OTHER_CPU_ENV
    assert files and len(set(files)) == len(files), files
    for f in files:
        assert (ROOT / f).is_file() and re.fullmatch(r"(tests|pyfmu_wrapper/models/\w+/tests)/test_\w+\.py", f), f
    assert set(files) >= NUMERIC_AT_LEAST, NUMERIC_AT_LEAST - set(files)
    # numpy's dispatched features, read from numpy itself (the names change between numpy releases)
    assert re.search(r"^npy_dispatch=\$\(python -c '.*__cpu_dispatch__.*'\)$", _ci_text(), flags=re.M)


def test_main_scenario_exists():
    assert (ROOT / "scenarios" / "full_case1.yaml").is_file()


def test_readme_describes_the_default_build_as_build_fmus_makes_it():
    """The README's words on ``build-fmus``: native by default, the platforms the native build emits, the
    Python-hosted build behind ``--python``; the command line's default is that native build."""
    from pyfmu_wrapper.cli.build_fmus import DEFAULT_VARIANT
    from pyfmu_wrapper.fmubuild.native_obj import TRIPLES

    text = " ".join((ROOT / "README.md").read_text().split())
    assert DEFAULT_VARIANT == "native"
    assert "`build-fmus` builds them native by default" in text
    assert "platforms " + ", ".join(list(TRIPLES)[:-1]) + f" and {list(TRIPLES)[-1]} in one archive" in text
    assert "glibc >= 2.17" in text and "`build-fmus --python` builds the Python-hosted reference" in text
