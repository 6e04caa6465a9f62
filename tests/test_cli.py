"""The command line: one line per stage in ``--help``, the schema's help per stage, the line naming what a
stage wrote, and an ``out`` with results refused unless ``overwrite=true``; the installed ``safenav``
command, which runs the stages and the records tool through their own entry points."""

import hashlib
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest
import yaml
from entry import cli

from pipeline.__main__ import available_stages
from pipeline.config.compose import CONF_DIR, load_config
from pipeline.config.help import describe
from pipeline.errors import ConfigError
from pipeline.stages import trials

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
    from pipeline.config.help import stage_help

    out = pipeline("trials", "method=ssrl", "--help")
    assert out.returncode == 0 and out.stderr == "", out.stderr
    assert out.stdout == stage_help("trials", CONF_DIR)
    assert out.stdout.startswith(f"python -m pipeline trials [key=value ...]: {describe('trials')}")
    assert "  overwrite: bool = false" in out.stdout.splitlines()


def test_a_stage_ends_with_the_line_naming_what_it_wrote(tmp_path):
    out = cli("trials", *TINY, f"out={tmp_path}/a")
    assert out.returncode == 0, out.stderr
    assert (
        out.stdout.splitlines()[-1] == f"wrote {tmp_path}/a/summary.json, {tmp_path}/a/records.mcap"
    )


def test_an_out_holding_results_is_refused_unless_overwrite(tmp_path):
    out = tmp_path / "a"
    assert cli("trials", *TINY, f"out={out}").returncode == 0
    before = digest(out)
    refused = cli("trials", *TINY, "seed=3", f"out={out}")
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
    replaced = cli("trials", *TINY, "seed=3", f"out={out}", "overwrite=true")
    assert replaced.returncode == 0, replaced.stderr
    assert digest(out) != before


def test_an_out_with_only_hidden_entries_is_not_refused(tmp_path):
    (tmp_path / ".staging-1").mkdir()  # the partial records of an interrupted run
    trials.refuse_overwrite(load_config("trials", [f"out={tmp_path}"]), tmp_path)


def test_an_out_that_dvc_yaml_declares_is_refused_like_any_other(tmp_path, monkeypatch):
    """Nothing at run time reads ``dvc.yaml``: a declared out that holds results is refused like
    any other unless the command gives ``overwrite=true`` (as dvc.yaml's trials stages do)."""
    (tmp_path / "dvc.yaml").write_text(
        "stages:\n  t:\n    cmd: python -m pipeline trials out=runs/a\n    outs:\n      - runs/a\n"
    )
    monkeypatch.chdir(tmp_path)
    (tmp_path / "runs" / "a").mkdir(parents=True)
    (tmp_path / "runs" / "a" / "summary.json").write_text("{}")
    cfg = load_config("trials", ["out=runs/a"])
    with pytest.raises(ConfigError, match="overwrite=true"):
        trials.refuse_overwrite(cfg, Path("runs/a"))
    trials.refuse_overwrite(replace(cfg, overwrite=True), Path("runs/a"))


def test_each_trials_stage_writes_into_its_persistent_out_with_overwrite():
    """The ``out`` a trials stage's command composes is the stage's declared out, which DVC keeps
    (``persist``: a refused config leaves it in place), so the command gives ``overwrite=true``."""
    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    trials_stage = stages["trials"]
    for item in trials_stage["foreach"]:
        cmd = trials_stage["do"]["cmd"].replace("${item}", item).split()
        assert cmd[:4] == ["python", "-m", "pipeline", "trials"], cmd
        cfg = load_config("trials", cmd[4:])
        declared = trials_stage["do"]["outs"]
        outs = [next(iter(o)).replace("${item}", item) for o in declared]
        assert outs == [cfg.out, cfg.index_file, cfg.metrics_dir] and cfg.overwrite, (item, outs)
        assert all(next(iter(o.values())).get("persist") for o in declared), declared


def test_overwrite_removes_the_cells_the_previous_run_had_and_this_one_has_not(tmp_path):
    """``overwrite=true`` (dvc.yaml's trials, whose outs persist) replaces the previous run's
    results: its cells that this run has not are removed, anything else in ``out`` is kept."""
    small = [
        "profile=smoke",
        "recogniser=oracle",
        "record=none",
        "progress=false",
        f"out={tmp_path}",
    ]
    assert cli("trials", "+experiment=fig9", *small).returncode == 0
    (tmp_path / "notes.txt").write_text("mine")
    done = cli("trials", "+experiment=fig10", *small, "overwrite=true")
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "carry",
        "carry_paper",
        "notes.txt",
        "restore",
        "restore_paper",
        "summary.json",
    ]


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


def test_an_experiment_run_by_hand_into_its_dvc_out_says_whose_folder_it_is(tmp_path, monkeypatch):
    """The experiment's declared out is its DVC stage's cached out: run by hand (no ``DVC_STAGE``
    in the environment, which DVC sets for its stages), the stage says that DVC owns it."""
    small = ["+experiment=fig10", "profile=smoke", "recogniser=oracle", "record=none"]
    monkeypatch.delenv("DVC_STAGE", raising=False)
    done = cli("trials", *small, "progress=false", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr.strip() == (
        "note: datasets/runs/fig10 is the out of DVC's stage trials@fig10: `dvc checkout` and "
        "`dvc exp run` put back the copy dvc.lock names (or delete this one when DVC has none); "
        "`dvc commit trials@fig10` makes this one DVC's"
    )
    monkeypatch.setenv("DVC_STAGE", "trials@fig10")
    again = cli("trials", *small, "progress=false", "overwrite=true", cwd=tmp_path)
    assert again.returncode == 0 and again.stderr == ""


#: The installed command of pyproject.toml's ``[project.scripts]``, beside this interpreter.
SAFENAV = Path(sys.executable).with_name("safenav")


def safenav(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    """The installed ``safenav`` script run as a user runs it (the script is what is tested)."""
    assert SAFENAV.is_file(), (
        f"no {SAFENAV}: reinstall the package (make setup, pip install -e .) to create the "
        "command pyproject.toml declares"
    )
    return subprocess.run(
        [str(SAFENAV), *args], check=False, capture_output=True, text=True, cwd=cwd, timeout=300
    )


def test_pyproject_declares_safenav_as_the_cli_entry_point():
    import tomllib

    from pipeline import cli
    from pipeline.config.help import CONSOLE_SCRIPT

    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts == {"safenav": "pipeline.cli:console_script"}
    assert callable(cli.console_script)
    assert CONSOLE_SCRIPT in scripts  # the name a stage's --help prints


def test_a_stage_help_names_the_command_it_was_run_by():
    by_script = safenav("trials", "--help")
    assert by_script.returncode == 0, by_script.stderr
    lines = by_script.stdout.splitlines()
    assert lines[0].startswith("safenav trials [key=value ...]: ")
    assert lines[-1].endswith(": safenav trials --help-all")
    by_module = subprocess.run(
        [sys.executable, "-m", "pipeline", "trials", "--help"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert by_module.stdout.splitlines()[0].startswith("python -m pipeline trials [key=value")
    assert by_module.stdout.replace("python -m pipeline", "safenav") == by_script.stdout


def test_safenav_help_lists_every_stage_and_every_tool():
    from pipeline.cli import available_tools, summary

    out = safenav("--help")
    assert out.returncode == 0 and out.stderr == "", out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == "usage: safenav <stage> [key=value ...]"
    for stage in available_stages():
        assert any(line.split() == [stage, *describe(stage).split()] for line in lines), stage
    assert available_tools() == ["records"]
    assert summary("records") == "what record files hold, one line a file or a table of its runs."
    assert any(line.split() == ["records", *summary("records").split()] for line in lines)
    assert not set(available_stages()) & set(available_tools())  # one meaning per command
    bare = safenav()
    assert bare.returncode == 2 and bare.stdout == out.stdout


def test_safenav_runs_a_stage_and_the_records_tool_as_python_m_does(tmp_path):
    ran = safenav("trials", *TINY, f"out={tmp_path}/a", cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    assert (
        ran.stdout.splitlines()[-1] == f"wrote {tmp_path}/a/summary.json, {tmp_path}/a/records.mcap"
    )
    listed = safenav("records", f"{tmp_path}/a", "--runs")
    assert listed.returncode == 0, listed.stderr
    by_module = subprocess.run(
        [sys.executable, "-m", "pipeline.records", f"{tmp_path}/a", "--runs"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert listed.stdout == by_module.stdout and "2 runs, 6 episodes" in listed.stdout
    stage_help = safenav("trials", "--help")  # the same text, under the name it was run by
    by_module_help = pipeline("trials", "--help").stdout
    assert stage_help.returncode == 0
    assert stage_help.stdout == by_module_help.replace("python -m pipeline", "safenav")


def test_safenav_records_help_names_the_command():
    out = safenav("records", "--help")
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("usage: safenav records [-h] [--runs] path\n")
    missing = safenav("records", "no/such/folder")
    assert missing.returncode == 2
    assert missing.stderr == "error: no/such/folder: no such record file or folder\n"


@pytest.mark.parametrize("command", ["nosuch", "record", "--runs"])
def test_safenav_refuses_an_unknown_command_in_one_line(command):
    out = safenav(command, "method=ssrl")
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr == (
        f"error: unknown command {command!r}; stages: {', '.join(available_stages())}; "
        "tools: records (safenav --help)\n"
    )


def test_safenav_help_into_a_reader_that_is_gone_ends_quietly():
    proc = subprocess.Popen(
        [str(SAFENAV), "--help"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141 and "Traceback" not in err, err
