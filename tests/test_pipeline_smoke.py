"""The whole pipeline on the smoke profile, stage by stage through the real command line:
render -> meta_train (Relation Network, Prototypical Network) -> accuracy (both) -> trials (fig8, fig9, fig10,
table3, accuracy_curve, generalisation, repetition, robot3d, networks; every episode recorded) -> report (twice: the
same bytes) -> replay of one recorded episode."""

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
# end to end, about 3 minutes on 2 cores: `make test-slow` runs it, `make test` does not
pytestmark = pytest.mark.slow


NO_PROFILE = ("report", "replay")


def stage(*args):
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "HYDRA_FULL_ERROR": "1"}
    out = subprocess.run(
        # report and replay have no scale of their own (the report reads it from the records)
        [
            sys.executable,
            "-m",
            "pipeline",
            *args,
            *(["profile=smoke"] * (args[0] not in NO_PROFILE)),
        ],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, f"{args[0]} failed:\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    assert out.stdout.splitlines()[-1].startswith("wrote "), (
        f"{args[0]} does not say where it wrote"
    )
    return out


def digest(folder: Path) -> dict:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    d = tmp_path_factory.mktemp("smoke")
    images, models, acc, runs = d / "images", d / "models", d / "accuracy", d / "runs"
    stage("render", f"out_dir={images}", f"figures_dir={images}/contact_sheets")
    stage(
        "meta_train",
        f"images_dir={images}",
        f"checkpoint={models}/rn.pt",
        f"metrics_file={models}/metrics.json",
        f"history_file={models}/history.csv",
    )
    stage(
        "meta_train",
        "model=protonet",
        f"images_dir={images}",
        f"checkpoint={models}/pn.pt",
        f"metrics_file={models}/protonet/metrics.json",
        f"history_file={models}/protonet/history.csv",
    )
    stage(
        "accuracy",
        f"recogniser.images_dir={images}",
        f"recogniser.checkpoint={models}/rn.pt",
        f"out_dir={acc}",
    )
    stage(
        "accuracy",
        "recogniser=protonet",
        f"recogniser.images_dir={images}",
        f"recogniser.checkpoint={models}/pn.pt",
        f"out_dir={d}/accuracy_protonet",
    )
    for exp in ("fig8", "fig9", "fig10", "table3"):
        stage(
            "trials",
            f"+experiment={exp}",
            f"out={runs}/{exp}",
            f"recogniser.checkpoint={models}/rn.pt",
            f"recogniser.images_dir={images}",
            "progress=false",
            f"metrics_dir={d}/metrics/{exp}",
            *protonet_pins(exp, f"{models}/pn.pt", images),
        )
    stage(
        "trials", "+experiment=accuracy_curve", f"out={runs}/accuracy_curve", "progress=false"
    )  # no model
    # 2 layouts per size x 7 methods; one process (two take longer to start than 42 tiny cells take)
    stage(
        "trials",
        "+experiment=generalisation",
        f"out={runs}/generalisation",
        f"recogniser.checkpoint={models}/rn.pt",
        f"recogniser.images_dir={images}",
        "progress=false",
        "workers=1",
    )
    stage(  # 2 layouts per r x 5 r x 6 templates (three recognisers)
        "trials",
        "+experiment=repetition",
        f"out={runs}/repetition",
        f"recogniser.checkpoint={models}/rn.pt",
        f"recogniser.images_dir={images}",
        *protonet_pins("repetition", f"{models}/pn.pt", images),
        "progress=false",
        "workers=1",
    )
    # the camera robot beside the grid (16 robot cells): one run of two episodes each
    stage(
        "trials",
        "+experiment=robot3d",
        f"out={runs}/robot3d",
        f"recogniser.checkpoint={models}/rn.pt",
        f"recogniser.images_dir={images}",
        *protonet_pins("robot3d", f"{models}/pn.pt", images),
        "runs=1",
        "episodes=2",
        "workers=1",
        "progress=false",
    )
    # five networks of each kind: the smoke network of its kind, and copies of it named as the
    # networks_* stages name theirs (the same weights: the plumbing, not the spread, is tested)
    stage(
        "trials",
        "+experiment=networks",
        f"out={runs}/networks",
        *network_pins(models, images),
        "workers=1",
        "progress=false",
    )
    report_args = [
        f"runs_dir={runs}",
        f"accuracy_dir={acc}",
        f"model_metrics={models}/metrics.json",
        f"protonet_accuracy_dir={d}/accuracy_protonet",
        f"protonet_metrics={models}/protonet/metrics.json",
        f"contact_dir={images}/contact_sheets",
        f"networks_accuracy_dir={d}/accuracy_networks",  # none: the repository's are not read
    ]
    stage("report", *report_args, f"out={d}/reports")
    return d, report_args


def protonet_pins(experiment: str, checkpoint, images) -> list[str]:
    """Overrides that point every cell of ``conf/experiment/<experiment>.yaml`` that runs
    the Prototypical Network (``recogniser_group: protonet``, listed or a layout template) at the
    smoke checkpoint and pictures."""
    import yaml

    from pipeline.config.folder import conf_dir

    spec = yaml.safe_load((conf_dir("experiment") / f"{experiment}.yaml").read_text())["experiment"]
    groups = {"experiment.cells": spec.get("cells") or {}}
    groups["experiment.layouts.cells"] = (spec.get("layouts") or {}).get("cells") or {}
    return [
        f"+{where}.{name}.recogniser.{key}={value}"
        for where, cells in groups.items()
        for name, cell in cells.items()
        if cell.get("recogniser_group") == "protonet"
        for key, value in (("checkpoint", checkpoint), ("images_dir", images))
    ]


def network_pins(models: Path, images: Path) -> list[str]:
    """Overrides that point every network of ``conf/experiment/networks.yaml`` at the smoke
    pictures and a smoke checkpoint: seed 0 of each kind at the smoke network of that kind, seed k
    at a copy of it under ``models/networks/`` with the name the experiment gives (the report
    tells the networks apart by that name)."""
    import yaml

    from pipeline.config.folder import conf_dir

    spec = yaml.safe_load((conf_dir("experiment") / "networks.yaml").read_text())["experiment"]
    smoke = {"relation_net": models / "rn.pt", "protonet": models / "pn.pt"}
    pins = []
    for name, cell in spec["cells"].items():
        named = (cell.get("recogniser") or {}).get("checkpoint")
        if named is None:
            continue
        checkpoint = smoke[cell["recogniser_group"]]
        if "_seed" in named:
            copy = models / "networks" / Path(named).name
            copy.parent.mkdir(parents=True, exist_ok=True)
            checkpoint = Path(shutil.copyfile(checkpoint, copy))
        pins += [
            f"experiment.cells.{name}.recogniser.checkpoint={checkpoint}",
            f"+experiment.cells.{name}.recogniser.images_dir={images}",
        ]
    return pins


def fixed_accuracy_p(experiment: str) -> float:
    """The accuracy ``p`` the experiment's ``fixed_accuracy`` cells pin."""
    import yaml

    from pipeline.config.folder import conf_dir

    spec = yaml.safe_load((conf_dir("experiment") / f"{experiment}.yaml").read_text())["experiment"]
    cells = (spec.get("layouts") or {}).get("cells") or spec.get("cells") or {}
    return next(
        c["recogniser"]["p"]
        for c in cells.values()
        if c.get("recogniser_group") == "fixed_accuracy"
    )


def test_every_experiment_is_recorded_and_reported(smoke):
    d, _ = smoke
    from pipeline.records import read_records

    recs = read_records(d / "runs" / "fig8" / "fewshot_dss" / "records.mcap")
    assert sorted(recs.episodes["run"].unique().tolist()) == [0, 1, 2]
    assert len(recs.episodes) == 3 * 20
    assert len(recs.meta.pictures) == 40  # the query pictures, stored once
    index = (d / "reports" / "index.md").read_text()
    assert index.startswith("# Smoke-scale test data, not the paper's scale")
    assert "**Built from** records of profile `smoke`: 3 runs x 20 episodes a cell" in index
    for title in (
        "Table 1",
        "Table 2",
        "Figure 7",
        "Figure 8",
        "Figure 9",
        "Figure 10",
        "Table 3",
        "Beyond the paper: collisions against recognition accuracy",
        "Beyond the paper: do the claims generalise over generated layouts?",
        "Beyond the paper: what drives the DSS gain?",
        "Beyond the paper: five networks of each kind",
        "**Verdict.**",
    ):
        assert title in index
    assert "ours, Prototypical Network" in index and "Prototypical Network recogniser" in index
    assert (
        len(read_records(d / "runs" / "fig8" / "fewshot_dss_protonet" / "records.mcap").episodes)
        == 3 * 20
    )
    assert (d / "reports" / "figures" / "fig8_collisions.png").stat().st_size > 1000
    assert (d / "reports" / "figures" / "contact_query.png").exists()
    claims = pd.read_csv(d / "reports" / "tables" / "generalisation_claims.csv")
    assert set(claims["size"]) == {"5x5", "7x7", "11x11"} and set(claims["layouts"]) == {2}
    assert (d / "reports" / "figures" / "generalisation_features.png").stat().st_size > 1000
    gains = pd.read_csv(d / "reports" / "tables" / "repetition.csv")
    assert set(gains["recogniser"]) == {
        "Relation Network",
        "Prototypical Network",
        f"fixed accuracy p = {fixed_accuracy_p('repetition'):g}",
    } and set(gains["layouts"]) == {2}
    spread = pd.read_csv(d / "reports" / "tables" / "networks.csv")
    assert len(spread) and (d / "reports" / "tables" / "networks_claims.csv").exists()
    assert "paper's Tables 1-2 recogniser" in index  # the *_paper cells of fig8-10, table3
    for rule in ("paper", "open_set", "range"):  # one table per decision rule, robot beside grid
        robot = pd.read_csv(d / "reports" / "tables" / f"robot3d_{rule}.csv")
        assert set(robot["maze"]) == {"5x5", "7x7"} and len(robot) == 4


def test_report_is_rebuilt_byte_for_byte(smoke):
    d, report_args = smoke
    stage("report", *report_args, f"out={d}/reports_again")
    assert digest(d / "reports") == digest(d / "reports_again")


def test_replay_of_a_recorded_episode(smoke):
    d, _ = smoke
    rrd = d / "replay.rrd"
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipeline",
            "replay",
            f"file={d}/runs/fig8/fewshot_dss/records.mcap",
            "run=1",
            "episode=3",
            f"out={rrd}",
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert rrd.stat().st_size > 0
    assert out.stdout.splitlines()[-1] == f"wrote {rrd}"


def test_same_experiment_and_seed_give_identical_summaries_and_records(smoke):
    d, _ = smoke
    images, models = d / "images", d / "models"
    stage(
        "trials",
        "+experiment=fig10",
        f"out={d}/again/fig10",
        f"recogniser.checkpoint={models}/rn.pt",
        f"recogniser.images_dir={images}",
        "progress=false",
    )
    for cell in ("restore", "carry"):
        first = json.loads((d / "runs" / "fig10" / cell / "summary.json").read_text())
        again = json.loads((d / "again" / "fig10" / cell / "summary.json").read_text())
        assert first == again
    from pipeline.records import read_records

    a = read_records(d / "runs" / "fig10" / "carry" / "records.mcap")
    b = read_records(d / "again" / "fig10" / "carry" / "records.mcap")
    for frame in ("steps", "episodes", "recognitions", "unsafe", "substitutions"):
        pd.testing.assert_frame_equal(
            getattr(a, frame).drop(columns="file"), getattr(b, frame).drop(columns="file")
        )
    assert len(a.steps) > 0 and len(a.substitutions) > 0
