"""The networks section (pipeline/report/networks.py): each cell's spread across networks beside
its spread across runs, intervals over runs and over networks then runs, and claim 9 per network,
pinned on small exact cases made up here."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from pipeline.report import networks as N
from pipeline.report.experiments import Cell


def cell(name, method, maze, per_run, network=None):
    checkpoint = None
    if network is not None:
        file = "relation_net.pt" if network == 0 else f"networks/relation_net_seed{network}.pt"
        checkpoint = {"path": f"datasets/models/{file}"}
    return Cell(
        experiment="networks",
        name=name,
        info={
            "method": {"name": method, "safety": "fewshot" if network is not None else "ssrl"},
            "maze": maze,
            "recogniser": {"kind": "relation_net", "checkpoint": checkpoint}
            if checkpoint
            else None,
        },
        layout=[],
        obstacles={},
        episodes=pd.DataFrame(
            {"run": np.arange(len(per_run)), "episode": 0, "collisions": np.asarray(per_run)}
        ),
        recognitions=pd.DataFrame(),
        substitutions=pd.DataFrame(),
        config={"seed": 0, "recogniser": {}},
    )


class Exp:
    def __init__(self, cells):
        self.cells = {c.name: c for c in cells}
        self.folder = self.name = "networks"


def test_the_network_is_read_from_the_recorded_checkpoint():
    assert N.network_of(cell("a", "fewshot", "5x5", [1], network=0)) == 0
    assert N.network_of(cell("b", "fewshot", "5x5", [1], network=3)) == 3
    assert N.network_of(cell("c", "ssrl", "5x5", [1])) is None


def test_networks_that_agree_have_no_spread_and_equal_intervals():
    """Three networks with the same runs: no spread across networks, and resampling networks
    first adds nothing."""
    runs = [4.0, 6.0, 5.0, 5.0]
    exp = Exp([cell(f"f{k}", "fewshot", "5x5", runs, network=k) for k in range(3)])
    (row,) = N.spread_rows(N.run_table(exp))
    assert row["networks"] == 3 and row["each network (seed 0, 1, ...)"] == "5.00 / 5.00 / 5.00"
    assert row["s.d. across networks"] == "0.00" and row["mean"] == "5.00"
    assert row["s.d. across runs"] == f"{np.std(runs, ddof=1):.2f}"


def test_networks_that_differ_widen_the_interval_over_networks():
    """Constant runs within each network: the interval over runs collapses to the mean, the one
    over networks spans the networks' means."""
    exp = Exp([cell(f"f{k}", "fewshot", "5x5", [2.0 * k] * 6, network=k) for k in range(5)])
    (row,) = N.spread_rows(N.run_table(exp))
    assert row["95% CI, runs resampled"] == "[4.00, 4.00]"
    lo, hi = (float(x) for x in row["95% CI, networks then runs"].strip("[]").split(", "))
    assert 0.0 <= lo < 4.0 < hi <= 8.0
    assert row["s.d. across networks"] == f"{np.std([0, 2, 4, 6, 8], ddof=1):.2f}"


def dss(name, way, per_run, network, support="restore"):
    c = cell(name, "fewshot_dss", "5x5", per_run, network=network)
    c.info.update(substitution=way, support=support)
    c.info["method"]["dynamic_support"] = True
    return c


def test_claim_9_per_network_and_over_the_networks():
    """SSRL 7 every run; network 0 collides 9 (holds), network 1 collides 5 (does not hold)."""
    cells = [cell("ssrl", "ssrl", "5x5", [7.0] * 5)]
    cells += [cell("f0", "fewshot", "5x5", [9.0] * 5, network=0)]
    cells += [cell("f1", "fewshot", "5x5", [5.0] * 5, network=1)]
    claim9, *_ = N.CLAIMS
    rows = N.claim_rows(N.run_table(Exp(cells)), claim9)
    assert [r["network"] for r in rows] == [
        "seed 0",
        "seed 1",
        "the 2 networks (networks, then runs)",
    ]
    assert [r["verdict"] for r in rows] == ["holds", "does not hold", "not resolved"]
    assert rows[0]["difference, 5x5 [95% CI]"] == "2.00 [2.00, 2.00]"
    assert rows[0]["checks"] == "fewshot − ssrl"


def test_claims_11_and_12_pair_each_networks_own_settings():
    """Claim 11 holds for a network only when every way collides less than its static support
    set; claim 12 compares restoring with carrying over the runs after the first."""
    cells = [cell(f"f{k}", "fewshot", "5x5", [6.0] * 4, network=k) for k in range(2)]
    cells += [dss(f"w{w}n0", w, [2.0] * 4, 0) for w in (1, 2, 3, 4)]
    cells += [dss(f"w{w}n1", w, [2.0 if w < 4 else 8.0] * 4, 1) for w in (1, 2, 3, 4)]
    cells += [dss("c0", 1, [9.0, 1.0, 1.0, 1.0], 0, support="carry")]
    runs = N.run_table(Exp(cells))
    _, claim11, claim12 = N.CLAIMS
    rows = N.claim_rows(runs, claim11)
    assert [r["verdict"] for r in rows[:2]] == ["holds", "does not hold"]
    assert rows[1]["difference, 5x5 [95% CI]"].endswith("; -2.00 [-2.00, -2.00]")
    (network0, over) = N.claim_rows(runs, claim12)
    assert network0["difference, 5x5 [95% CI]"] == "1.00 [1.00, 1.00]"  # run 0 left out
    assert network0["verdict"] == "holds" and over["network"].startswith("the 1 network (")
    assert N.claim_rows(N.run_table(Exp(cells[:2])), claim11) == []  # no DSS cells: no rows


def test_every_checkpoint_the_experiment_names_is_made_by_a_dvc_stage():
    """The networks experiment names its checkpoints; each is the meta_train stage's or an out of
    a networks_* stage for one of its foreach seeds, so the two lists cannot drift apart."""
    root = Path(__file__).resolve().parents[1]
    cells = yaml.safe_load((root / "conf/experiment/networks.yaml").read_text())["experiment"]
    named = {c["recogniser"]["checkpoint"] for c in cells["cells"].values() if "recogniser" in c}
    stages = yaml.safe_load((root / "dvc.yaml").read_text())["stages"]
    made = set()
    for stage in stages.values():
        body = stage.get("do", stage)
        outs = [next(iter(o)) if isinstance(o, dict) else o for o in body.get("outs", [])]
        for item in stage.get("foreach", [None]):
            made |= {o.replace("${item}", str(item)) for o in outs}
    assert named and named <= made, sorted(named - made)
    assert len(named) == 10  # five of each kind


def test_the_section_writes_its_tables(tmp_path):
    from pipeline.report.build import Report

    rep = Report(tmp_path)
    rng = np.random.default_rng(0)
    cells = [cell("ssrl", "ssrl", "5x5", [7.0] * 20)]
    cells += [
        cell(f"f{k}", "fewshot", "5x5", 9 + k + rng.normal(0, 1, 20), network=k) for k in range(5)
    ]
    N.networks_section(rep, Exp(cells), [])
    table = pd.read_csv(tmp_path / "tables" / "networks.csv")
    assert table["networks"].tolist() == [5]
    claims = pd.read_csv(tmp_path / "tables" / "networks_claims.csv")
    assert len(claims) == 6 and set(claims["verdict"]) == {"holds"}
    assert "claim 9 (Figure 8) holds for Relation Network 5 of 5 networks" in "\n".join(
        rep.sections
    )


def test_rows_come_by_recogniser_method_and_maze_size():
    cells = [
        cell(f"{m}{k}_{z}", m, z, [1.0, 2.0], network=k)
        for z in ("11x11", "5x5", "7x7")
        for m in ("fewshot_dss", "fewshot")
        for k in range(2)
    ]
    rows = N.spread_rows(N.run_table(Exp(cells)))
    assert [(r["method"], r["maze"]) for r in rows] == [
        ("fewshot", "5x5"),
        ("fewshot", "7x7"),
        ("fewshot", "11x11"),
        ("fewshot_dss", "5x5"),
        ("fewshot_dss", "7x7"),
        ("fewshot_dss", "11x11"),
    ]
    assert N.maze_cells("random:7x7:16:3") == 49 and N.maze_cells("mazes/mine.txt") == 0
    same_size = [cell(f"f{z}", "fewshot", z, [1.0], network=0) for z in ("7x7", "random:7x7:16:3")]
    assert len(N.spread_rows(N.run_table(Exp(same_size)))) == 2


def test_a_network_names_each_picture_it_met_once():
    """Pictures 0 and 8 (chair, kettle) met in two runs: named chair and chair, so 1 of 2 right;
    the DSS cell's recognitions do not count (its support set changes)."""
    static = cell("f0", "fewshot", "5x5", [1.0, 1.0], network=0)
    static.recognitions = pd.DataFrame(
        {"run": [0, 1, 1], "picture": [0, 8, 0], "predicted": [0, 0, 0]}
    )
    dss = cell("d0", "fewshot_dss", "5x5", [1.0, 1.0], network=0)
    dss.info["method"]["dynamic_support"] = True
    dss.recognitions = pd.DataFrame({"run": [0], "picture": [8], "predicted": [1]})
    assert N.pictures_named(Exp([static, dss])) == {("Relation Network", 0): (1, 2)}
    assert N.break_even_5x5([]) is None


def test_substitution_ways_and_a_carried_support_set_get_rows_of_their_own():
    """Figures 9 and 10 across networks: the DSS cells of one maze differ by way and support mode,
    so each (way, support) is a row of its own, not pooled into one fewshot_dss row."""
    cells = []
    for way, support, runs in ((1, "restore", [3.0, 5.0]), (2, "restore", [1.0, 1.0])):
        for k in range(2):
            c = cell(f"w{way}{support}{k}", "fewshot_dss", "5x5", runs, network=k)
            c.info.update(substitution=way, support=support)
            c.info["method"]["dynamic_support"] = True
            cells.append(c)
    carry = cell("carry0", "fewshot_dss", "5x5", [0.0, 2.0], network=0)
    carry.info.update(substitution=1, support="carry")
    carry.info["method"]["dynamic_support"] = True
    rows = N.spread_rows(N.run_table(Exp([*cells, carry])))
    assert [(r["method"], r["mean"], r["networks"]) for r in rows] == [
        ("fewshot_dss way 1", "4.00", 2),
        ("fewshot_dss way 1 carry", "1.00", 1),
        ("fewshot_dss way 2", "1.00", 2),
    ]
