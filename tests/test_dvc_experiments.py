"""`dvc exp run -S <file>:<key>=<value>` on the real configs, at smoke scale, in a temporary git repo
holding a copy of pipeline/ (its configs in conf/) and a small dvc.yaml shaped like ours (a
trials foreach with the same kind of params, the oracle recogniser: no pictures or model needed)."""

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
pytestmark = pytest.mark.skipif(
    not (BIN / "dvc").exists(), reason="dvc is not installed beside this python"
)


def copy_package_and_configs(repo: Path) -> None:
    """pipeline/ and conf/ into ``repo``: the copy reads its own configs (pipeline/config/folder.py)."""
    for folder in ("pipeline", "conf"):
        shutil.copytree(ROOT / folder, repo / folder, ignore=shutil.ignore_patterns("__pycache__"))


DVC_YAML = """\
stages:
  trials:
    foreach: [fig10]
    do:
      cmd: python -m pipeline trials +experiment=${item} profile=smoke recogniser=oracle record=none
        progress=false out=runs/${item} metrics_dir=metrics/${item}
      deps:
        - pipeline/rl
        - pipeline/stages/trials.py
      params:
        - conf/trials.yaml: [seed]
        - conf/profile/smoke.yaml: [trials.runs, trials.episodes]
        - conf/experiment/${item}.yaml:
        - conf/method/fewshot_dss.yaml:
      outs:
        - runs/${item}
      metrics:
        - metrics/${item}:
            cache: false
"""


def run(
    repo: Path, *args: str, ok: bool = True, cwd: Path | None = None
) -> subprocess.CompletedProcess:
    env = {
        **os.environ,
        "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}",
        "PYTHONPATH": str(repo),
        "DVC_NO_ANALYTICS": "1",
        "GIT_AUTHOR_NAME": "test",
        "GIT_AUTHOR_EMAIL": "test@example.org",
        "GIT_COMMITTER_NAME": "test",
        "GIT_COMMITTER_EMAIL": "test@example.org",
    }
    out = subprocess.run(
        list(args), cwd=cwd or repo, env=env, capture_output=True, text=True, timeout=180
    )
    if ok:
        assert out.returncode == 0, f"{' '.join(args)}:\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    return out


def new_repo(path: Path, dvc_yaml: str) -> Path:
    """git + dvc repo with our .gitignore files and the site cache as setup.sh sets it (absolute, in
    .dvc/config.local)."""
    path.mkdir()
    (path / "dvc.yaml").write_text(dvc_yaml)
    run(path, "git", "init", "-q")
    run(path, "dvc", "init", "-q")
    shutil.copy(ROOT / ".dvc" / ".gitignore", path / ".dvc" / ".gitignore")
    shutil.copy(ROOT / ".gitignore", path / ".gitignore")
    run(path, "dvc", "config", "--local", "core.site_cache_dir", str(path / ".dvc" / "site_cache"))
    return path


def commit(repo: Path) -> None:
    run(repo, "git", "add", "-A")
    run(repo, "git", "commit", "-qm", "baseline")


def experiments(repo: Path) -> dict[str, dict]:
    """Experiment name -> its data (params and metrics) from `dvc exp show --json`."""
    shown = json.loads(run(repo, "dvc", "exp", "show", "--json").stdout)
    out = {}
    for row in shown:
        for exp in row.get("experiments") or []:
            for rev in exp["revs"]:
                out[rev["name"]] = rev["data"]
        out[row["name"] or row["rev"]] = row["data"]
    return out


@pytest.mark.slow  # a real `dvc exp run` of a trials stage: about 25 s
def test_exp_run_set_param_reruns_trials_and_shows_param_and_metrics(tmp_path):
    repo = new_repo(tmp_path / "repo", DVC_YAML)
    copy_package_and_configs(repo)
    run(repo, "dvc", "repro")
    commit(repo)
    assert run(repo, "dvc", "status").stdout.strip() == "Data and pipelines are up to date."

    out = run(
        repo,
        "dvc",
        "exp",
        "run",
        "-n",
        "two-runs",
        "-S",
        "conf/profile/smoke.yaml:trials.runs=2",
    )
    assert "Running stage 'trials@fig10'" in out.stdout
    exps = experiments(repo)
    base, two = exps["workspace"], exps["two-runs"]
    assert two["params"]["conf/profile/smoke.yaml"]["data"]["trials"] == {
        "runs": 2,
        "episodes": 20,
    }
    metrics = {Path(f).stem: m["data"] for f, m in two["metrics"].items()}
    assert set(metrics) == {"restore", "carry", "restore_paper", "carry_paper"}
    assert set(metrics["restore"]) == {"collisions", "ci_lower", "ci_upper", "converged"}
    assert (
        base["params"]["conf/profile/smoke.yaml"]["data"]["trials"]["runs"] == 2
    )  # applied to the workspace
    assert (
        json.loads((repo / "runs" / "fig10" / "restore" / "summary.json").read_text())["n_runs"]
        == 2
    )
    diff = run(repo, "dvc", "params", "diff", "--json").stdout
    assert json.loads(diff)["conf/profile/smoke.yaml"]["trials.runs"] == {
        "old": 3,
        "new": 2,
        "diff": -1,
    }

    # A key the file does not have (method files omit what they inherit): Hydra's struct mode
    # refuses `alpha=`; `++alpha=` adds it (or overrides it if present).
    method = "conf/method/fewshot_dss.yaml"
    refused = run(repo, "dvc", "exp", "run", "-S", f"{method}:alpha=0.05", ok=False)
    assert (
        refused.returncode != 0
        and "use +alpha=0.05: Key 'alpha' is not in struct" in refused.stderr
    )
    run(repo, "git", "checkout", "-q", ".")
    out = run(repo, "dvc", "exp", "run", "-n", "alpha", "-S", f"{method}:++alpha=0.05")
    assert "Running stage 'trials@fig10'" in out.stdout
    assert experiments(repo)["alpha"]["params"][method]["data"]["alpha"] == 0.05
    text = (repo / method).read_text()
    assert text.startswith("# Only what differs") and "alpha: 0.05" in text  # comments kept

    # DVC resolves the file's interpolations to apply -S: the stage files
    # (conf/<stage>.yaml, with ${profile...}) cannot take -S; edit them and `dvc exp run`
    # (README "DVC experiments").
    refused = run(repo, "dvc", "exp", "run", "-S", "conf/trials.yaml:seed=1", ok=False)
    assert (
        refused.returncode != 0
        and "Interpolation key 'profile.trials.runs' not found" in refused.stderr
    )


@pytest.mark.slow  # real `dvc repro` and `dvc exp run --temp`; fast: test_dvc_yaml.py's site cache test
def test_site_cache_from_any_cwd_and_in_a_temp_experiment(tmp_path):
    """The site cache form of setup.sh: `dvc exp run --temp` (a copy under .dvc/tmp) and dvc run from a
    subfolder work and write no second cache."""
    repo = new_repo(
        tmp_path / "repo",
        """\
stages:
  copy:
    cmd: python -c "import shutil; shutil.copy('p.yaml', 'out.yaml')"
    params: [{p.yaml: [n]}]
    outs: [out.yaml]
""",
    )
    (repo / "p.yaml").write_text("n: 1\n")
    (repo / "sub").mkdir()
    (repo / "sub" / "keep").write_text("")
    run(repo, "dvc", "repro")
    commit(repo)
    run(repo, "dvc", "exp", "run", "--temp", "-n", "temp", "-S", "p.yaml:n=2")
    assert experiments(repo)["temp"]["params"]["p.yaml"]["data"] == {"n": 2}
    assert "up to date" in run(repo, "dvc", "status", cwd=repo / "sub").stdout
    assert not (repo / "sub" / ".dvc").exists()
    assert run(repo, "git", "status", "--porcelain").stdout == ""  # the site cache is git-ignored


def _flags() -> dict[str, dict]:
    """The out flags of the real dvc.yaml that keep a user's files (pictures, records, metrics)
    through `dvc exp run`, and the trials command's tail (`overwrite=true`)."""
    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    trials = stages["trials"]["do"]

    def flags(entry) -> dict:  # a plain path has none
        return next(iter(entry.values())) if isinstance(entry, dict) else {}

    metrics = next(o for o in trials["outs"] if next(iter(o)).startswith("datasets/metrics/"))
    out = {
        "images": flags(stages["render"]["outs"][0]),
        "records": flags(trials["outs"][0]),
        "metrics": flags(metrics),
    }
    out["overwrite"] = "overwrite=true" if "overwrite=true" in trials["cmd"].split() else ""
    return out


def _snapshot(folder: Path) -> dict[str, str]:
    return {
        p.relative_to(folder).as_posix(): hashlib.md5(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.mark.slow
def test_exp_run_keeps_pictures_made_outside_dvc_and_refuses_a_bad_value(tmp_path):
    """Issue 31: pictures made by `python -m pipeline render` (not in DVC's cache, other bytes than
    dvc.lock's) survive `dvc exp run` of one stage and of all, and a bad `-S` value is refused
    naming the key, leaving pictures, records and the tracked metrics as they were."""
    flags = _flags()
    render = "python -m pipeline render profile=smoke out_dir=images contact_sheets=false"
    dvc_yaml = {
        "stages": {
            "render": {
                "cmd": render,
                "deps": ["pipeline/stages/render.py"],
                "params": [{"conf/profile/smoke.yaml": ["render.per_class"]}],
                "outs": [{"images": flags["images"]}],
            },
            "trials": {
                "foreach": ["fig10"],
                "do": {
                    "cmd": "python -m pipeline trials +experiment=${item} profile=smoke "
                    "recogniser=oracle record=episodes images_dir=images progress=false "
                    f"out=runs/${{item}} metrics_dir=metrics/${{item}} {flags['overwrite']}",
                    "deps": ["images", "pipeline/rl"],
                    "params": [{"conf/profile/smoke.yaml": ["trials.episodes"]}],
                    "outs": [{"runs/${item}": flags["records"]}],
                    "metrics": [{"metrics/${item}": flags["metrics"]}],
                },
            },
        }
    }
    repo = new_repo(tmp_path / "repo", yaml.safe_dump(dvc_yaml, sort_keys=False))
    (repo / ".gitignore").write_text((repo / ".gitignore").read_text() + "/images\n")
    copy_package_and_configs(repo)
    run(repo, "dvc", "repro")
    commit(repo)
    # a fresh clone's cache is empty; the user renders by hand, here other pictures (seed=1)
    shutil.rmtree(repo / ".dvc" / "cache")
    run(repo, *render.split(), "seed=1")
    run(repo, "dvc", "repro", "-s", "trials@fig10")  # records from these pictures, in the cache
    commit(repo)
    pictures, metrics = _snapshot(repo / "images"), _snapshot(repo / "metrics" / "fig10")
    records = _snapshot(repo / "runs" / "fig10")
    smoke = "conf/profile/smoke.yaml"
    for value, key in [("abc", "profile.trials.episodes"), ("-1", "profile.trials.episodes")]:
        bad = run(
            repo,
            "dvc",
            "exp",
            "run",
            "-s",
            "trials@fig10",
            "-S",
            f"{smoke}:trials.episodes={value}",
            ok=False,
        )
        assert bad.returncode != 0 and f"error: config key '{key}'" in bad.stdout + bad.stderr
        assert _snapshot(repo / "images") == pictures
        assert _snapshot(repo / "runs" / "fig10") == records
        assert _snapshot(repo / "metrics" / "fig10") == metrics and metrics
        run(repo, "git", "checkout", "-q", smoke)
    bad = run(repo, "dvc", "exp", "run", "-S", f"{smoke}:render.per_class=abc", ok=False)
    assert "error: config key 'profile.render.per_class'" in bad.stdout + bad.stderr
    assert _snapshot(repo / "images") == pictures
    run(repo, "git", "checkout", "-q", smoke)

    run(repo, "dvc", "exp", "run", "-s", "trials@fig10", "-S", f"{smoke}:trials.episodes=10")
    assert _snapshot(repo / "images") == pictures
    assert (
        json.loads((repo / "runs" / "fig10" / "restore" / "summary.json").read_text())["n_episodes"]
        == 10
    )
    run(repo, "dvc", "exp", "run", "-S", f"{smoke}:trials.episodes=12")  # all stages
    assert (repo / "images" / "manifest.csv").is_file()  # kept, or rendered again by its stage
