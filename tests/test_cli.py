"""The command line: one line per stage in ``--help``, the schema's help per stage, the line naming what a
stage wrote, and an ``out`` with results refused unless ``overwrite=true``."""

import hashlib
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.__main__ import available_stages
from pipeline.errors import ConfigError
from pipeline.stages import trials
from pipeline.stages._common import CONF_DIR, load_config
from pipeline.stages._help import describe

ROOT = Path(__file__).resolve().parents[1]
TINY = ["method=ssrl", "maze=5x5", "runs=2", "episodes=3", "progress=false"]


def pipeline(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pipeline", *args],
        check=False,
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )


def digest(folder: Path) -> dict:
    return {
        p.name: hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.iterdir())
        if p.is_file()
    }


def test_help_lists_every_stage_with_the_first_line_of_its_docstring():
    out = pipeline("--help")
    assert out.returncode == 0
    for stage in available_stages():
        text = describe(stage)
        assert 20 < len(text) and text.endswith("."), (
            f"{stage}: its docstring's first line is not a sentence"
        )
        assert any(line.split() == [stage, *text.split()] for line in out.stdout.splitlines()), (
            out.stdout
        )


def test_a_stage_help_is_its_schema_with_the_stage_named():
    """The text itself is pinned in tests/test_config_help.py; here, the command line prints it."""
    from pipeline.stages._help import stage_help

    out = pipeline("trials", "method=ssrl", "--help")
    assert out.returncode == 0 and out.stderr == "", out.stderr
    assert out.stdout == stage_help("trials", CONF_DIR)
    assert out.stdout.startswith(f"python -m pipeline trials [key=value ...]: {describe('trials')}")
    assert "  overwrite: bool = false" in out.stdout.splitlines()


def test_a_stage_ends_with_the_line_naming_what_it_wrote(tmp_path):
    out = pipeline("trials", *TINY, f"out={tmp_path}/a")
    assert out.returncode == 0, out.stderr
    assert (
        out.stdout.splitlines()[-1] == f"wrote {tmp_path}/a/summary.json, {tmp_path}/a/records.mcap"
    )


def test_an_out_holding_results_is_refused_unless_overwrite(tmp_path):
    out = tmp_path / "a"
    assert pipeline("trials", *TINY, f"out={out}").returncode == 0
    before = digest(out)
    refused = pipeline("trials", *TINY, "seed=3", f"out={out}")
    assert refused.returncode == 2 and refused.stdout == ""
    assert (
        refused.stderr.count("\n") == 1
        and "overwrite=true" in refused.stderr
        and str(out) in refused.stderr
    )
    assert digest(out) == before and sorted(p.name for p in out.iterdir()) == [
        "records.mcap",
        "summary.json",
    ]
    replaced = pipeline("trials", *TINY, "seed=3", f"out={out}", "overwrite=true")
    assert replaced.returncode == 0, replaced.stderr
    assert digest(out) != before


def test_an_out_with_only_hidden_entries_is_not_refused(tmp_path):
    (tmp_path / ".staging-1").mkdir()  # the partial records of an interrupted run
    trials.refuse_overwrite(load_config("trials", [f"out={tmp_path}"]), tmp_path)


def test_the_outs_dvc_yaml_declares_are_replaced(tmp_path, monkeypatch):
    (tmp_path / "dvc.yaml").write_text(
        "stages:\n  t:\n    foreach: [a, b]\n    do:\n      cmd: x\n      outs:\n"
        "        - runs/${item}\n        - runs/${item}.json:\n            cache: false\n"
    )
    assert trials.dvc_outs(tmp_path / "dvc.yaml") == {
        tmp_path / f"runs/{n}" for n in ("a", "b", "a.json", "b.json")
    }
    monkeypatch.setattr(trials, "DVC_YAML", tmp_path / "dvc.yaml")
    for name in ("a", "c"):
        (tmp_path / "runs" / name).mkdir(parents=True)
        (tmp_path / "runs" / name / "summary.json").write_text("{}")
    cfg = load_config("trials", [f"out={tmp_path}/runs/a"])
    trials.refuse_overwrite(cfg, tmp_path / "runs" / "a")
    with pytest.raises(ConfigError, match="overwrite=true"):
        trials.refuse_overwrite(cfg, tmp_path / "runs" / "c")


def test_the_pipelines_trials_outs_are_declared():
    declared = trials.dvc_outs(trials.DVC_YAML)
    for name in ("fig8", "fig9", "fig10", "table3", "accuracy_curve"):
        assert (ROOT / "datasets" / "runs" / name).resolve() in declared
    assert (ROOT / "datasets" / "runs" / "adhoc").resolve() not in declared


@pytest.mark.parametrize("args", [["--help"], ["trials", "--help"]])
def test_help_into_a_reader_that_is_gone_ends_quietly(args):
    """``python -m pipeline --help | head``: status 141 and no traceback when the reader left first."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "pipeline", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    proc.stdout.close()  # like `| head -0`: the reader is gone before anything is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141 and "Traceback" not in err and "BrokenPipe" not in err, err
