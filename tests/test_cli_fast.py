"""Refusals before imports (issue 42): every console script parses its arguments and reads and checks
its input files before it imports numba, scipy, pandas or matplotlib, so a bad input is refused in
well under a second of CPU, and ``--help`` / ``--version`` cost nothing. Measured here in a fresh
subprocess (CPU time from ``resource.getrusage(RUSAGE_CHILDREN)``; the heavy modules read from the
child's own ``sys.modules`` at the moment it exits)."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("numba", "scipy", "pandas", "matplotlib")
#: the budget of one refusal, in CPU seconds (the issue's target: each < 1 s)
BUDGET = 1.0

#: runs a console script's main in a child and prints, on its last stdout line, its exit status and
#: the heavy modules it had imported when it returned
WRAPPER = """
import json, sys
sys.argv[0] = {prog!r}
from {module} import {func} as main
try:
    code = main({argv!r})
except SystemExit as exc:
    code = exc.code
print(json.dumps({{"code": code, "heavy": [m for m in {heavy!r} if m in sys.modules]}}))
"""

COMMANDS = {
    "run-scenario": ("pyfmu_wrapper.cli.run_scenario", "main"),
    "diagnose": ("pyfmu_wrapper.cli.diagnose", "main_diagnose"),
    "make-benchmark": ("pyfmu_wrapper.cli.diagnose", "main_make_benchmark"),
    "score": ("pyfmu_wrapper.cli.diagnose", "main_score"),
    "build-fmus": ("pyfmu_wrapper.cli.build_fmus", "main"),
    "optimise": ("pyfmu_wrapper.cli.optimise", "main"),
    "reproduce": ("pyfmu_wrapper.cli.reproduce", "main"),
}


def run(prog: str, argv: list[str], cwd: Path) -> tuple[float, int, list[str], str, str]:
    """(CPU seconds of the child, exit status, heavy modules imported, stdout, stderr)."""
    module, func = COMMANDS[prog]
    code = WRAPPER.format(prog=prog, module=module, func=func, argv=argv, heavy=HEAVY)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    last = json.loads(p.stdout.strip().splitlines()[-1])
    return cpu, last["code"], last["heavy"], p.stdout, p.stderr


def alias_bomb(path: Path) -> Path:
    """About 700 bytes whose aliases expand to 9^12 values (a 'billion laughs')."""
    lines = ["schema_version: 2", "name: bomb", "a0: &a0 [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 12)]
    path.write_text("\n".join(lines) + "\n")
    return path


def million_list(path: Path) -> Path:
    """scenarios/linear_tmd.yaml with an explicit list of 10^6 frequencies (12 MB, no alias)."""
    text = (ROOT / "scenarios" / "linear_tmd.yaml").read_text()
    grid = "frequencies: {start: 10.0, stop: 30.0, count: 81}"
    assert grid in text
    values = ", ".join(f"{10 + 20 * i / 1e6:.7f}" for i in range(10**6))
    path.write_text(text.replace(grid, f"frequencies: [{values}]"))
    return path


def forced_without_force(folder: Path) -> Path:
    """A system dataset whose transient record has no force column and is not declared a free decay."""
    folder.mkdir()
    (folder / "r0.csv").write_text(
        "t,x,y\n" + "".join(f"{i / 256},{(i % 7) * 1e-3},{(i % 5) * 1e-3}\n" for i in range(600))
    )
    (folder / "dataset.yaml").write_text(
        "level: system\n"
        "nominal: {base: {mass: 100, stiffness: 4.0e4, damping: 100, force_amplitude: 200},\n"
        "          tmd: {mass: 9, stiffness: 4000, damping: 15, inertance: 1, inerter: ideal}}\n"
        "records:\n  - {file: r0.csv, kind: transient}\n"
    )
    return folder


@pytest.fixture(scope="module")
def bad_inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    return dict(
        bomb=alias_bomb(d / "bomb.yaml"),
        million=million_list(d / "million.yaml"),
        noforce=forced_without_force(d / "noforce"),
        dir=d,
    )


@pytest.mark.parametrize(
    "case, prog, argv, words",
    [
        ("bomb", "run-scenario", ["{bomb}", "--out", "{dir}/o1"], "expand to more than 200,000 values"),
        ("million", "run-scenario", ["{million}", "--out", "{dir}/o2"], "holds more than 100,000 values"),
        ("noforce", "diagnose", ["{noforce}", "--out", "{dir}/o3"], "no 'force' column"),
    ],
)
def test_a_bad_input_is_refused_in_well_under_a_second_before_any_heavy_import(bad_inputs, case, prog, argv, words):
    argv = [a.format(**bad_inputs) for a in argv]
    cpu, code, heavy, _, err = run(prog, argv, bad_inputs["dir"])
    assert code == 2 and words in err, err
    errors = [ln for ln in err.splitlines() if ln.startswith(f"{prog}: error:")]
    assert len(errors) == 1 and words in errors[0] and "Traceback" not in err  # one line (after any progress line)
    assert heavy == [], heavy
    assert cpu < BUDGET, (case, cpu)
    assert not any((bad_inputs["dir"] / o).exists() for o in ("o1", "o2", "o3"))  # nothing written


def test_a_long_list_is_refused_by_its_length_not_as_an_alias_bomb(bad_inputs):
    _, code, _, _, err = run("run-scenario", [str(bad_inputs["million"]), "--out", "x"], bad_inputs["dir"])
    assert code == 2
    assert "the list that starts on line" in err and "at most 100,000" in err
    assert "alias" not in err and "laughs" not in err


def test_a_missing_force_column_names_the_file_and_the_column(bad_inputs):
    _, code, _, _, err = run("diagnose", [str(bad_inputs["noforce"]), "--out", "x"], bad_inputs["dir"])
    assert code == 2
    assert f"{bad_inputs['noforce'] / 'r0.csv'}, column 'force'" in err and "kind: decay" in err


@pytest.mark.parametrize("prog", sorted(COMMANDS))
def test_help_and_version_are_instant(prog, tmp_path):
    version = metadata.version("pyfmu_wrapper")
    cpu_h, code_h, heavy_h, out_h, _ = run(prog, ["--help"], tmp_path)
    cpu_v, code_v, heavy_v, out_v, _ = run(prog, ["--version"], tmp_path)
    assert code_h == 0 and code_v == 0
    assert "usage:" in out_h and f"{prog} {version}" in out_v
    assert heavy_h == [] and heavy_v == [], (heavy_h, heavy_v)
    assert cpu_h < 0.5 * BUDGET and cpu_v < 0.5 * BUDGET, (cpu_h, cpu_v)


def test_a_folder_the_tool_cannot_create_is_one_line_exit_2(tmp_path):
    """--out under a file, and --out /proc/foo (a folder nobody can make a folder in, root included):
    exit 2, one line, no traceback, nothing computed."""
    locked = tmp_path / "file"
    locked.write_text("not a folder")
    outs = [str(locked / "sub")] + (["/proc/foo"] if Path("/proc/self").is_dir() else [])
    for out in outs:
        for prog, argv in (
            ("run-scenario", [str(ROOT / "scenarios" / "linear_tmd.yaml"), "--engine", "monolithic", "--quiet"]),
            ("make-benchmark", ["--example", "swept-sine"]),
        ):
            _, code, heavy, _, err = run(prog, [*argv, "--out", out], tmp_path)
            assert code == 2, err
            assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
            assert "cannot create" in err or "cannot be a folder" in err, err
            assert heavy == [], heavy
    assert locked.read_text() == "not a folder"
