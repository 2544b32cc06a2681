"""`make-benchmark --part K/N`: a long generation shared by N processes writes the whole run's datasets."""

from __future__ import annotations


def test_transient_benchmark_parts_are_the_whole_runs_datasets(tmp_path):
    """make-benchmark --suite transient --part K/N: parts 1/2 and 2/2 hold exactly the datasets of the
    whole run, byte for byte, and their manifests split its rows."""
    import json

    from pyfmu_wrapper.cli.diagnose import main_make_benchmark

    common = ["--suite", "transient", "-n", "3", "--seconds", "2", "--seed", "5"]
    assert main_make_benchmark([*common, "--out", str(tmp_path / "whole")]) == 0
    for k in (1, 2):
        assert main_make_benchmark([*common, "--part", f"{k}/2", "--out", str(tmp_path / f"p{k}")]) == 0
    whole = json.loads((tmp_path / "whole" / "manifest.json").read_text())["datasets"]
    parts = {k: json.loads((tmp_path / f"p{k}" / "manifest.json").read_text())["datasets"] for k in (1, 2)}
    assert [r["dataset"] for r in parts[1]] == ["tr000", "tr002"] and [r["dataset"] for r in parts[2]] == ["tr001"]
    by_name = {r["dataset"]: r for r in whole}
    for k, rows in parts.items():
        for r in rows:
            assert {**r, "seconds": 0} == {**by_name[r["dataset"]], "seconds": 0}
            for f in sorted((tmp_path / "whole" / r["dataset"]).rglob("*")):
                if f.is_file():
                    rel = f.relative_to(tmp_path / "whole")
                    assert (tmp_path / f"p{k}" / rel).read_bytes() == f.read_bytes(), rel
