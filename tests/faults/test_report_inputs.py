"""The report's hostile inputs. Missing, empty, damaged, partial and mixed records: the report
refuses in one line naming the file or cell and keeps the previous report (docs/reliability.md
"The report")."""

from __future__ import annotations

from pathlib import Path

import pytest
from entry import cli
from fakes import FIG8_WITHOUT_MODELS

from faults._checks import FAST, digest, one_line_error
from pipeline.report.recogniser_table import recogniser_row

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """fig8 and fig9 recorded at a tiny scale, and a report built from them."""
    d = tmp_path_factory.mktemp("report")
    for exp in ("fig8", "fig9"):
        out = cli(
            "trials",
            f"+experiment={exp}",
            "recogniser=oracle",
            f"out={d}/runs/{exp}",
            *FAST,
            *(FIG8_WITHOUT_MODELS if exp == "fig8" else []),
        )
        assert out.returncode == 0, out.stderr
    out = cli(
        "report",
        f"runs_dir={d}/runs",
        f"accuracy_dir={d}/none",
        f"out={d}/reports",
        "allow_missing=true",
    )
    assert out.returncode == 0, out.stderr
    return d


def _report(d, runs, *extra):
    return cli("report", f"runs_dir={runs}", f"accuracy_dir={d}/none", f"out={d}/reports", *extra)


def test_report_refuses_missing_experiments_and_keeps_the_old_one(recorded):
    before = digest(recorded / "reports")
    one_line_error(
        _report(recorded, recorded / "runs"),
        "no complete records for experiment",
        "experiment fig10",
        "allow_missing=true",
    )
    assert digest(recorded / "reports") == before


@pytest.mark.parametrize("runs", ["absent", "empty"])
def test_report_with_no_records_changes_nothing(recorded, runs):
    (recorded / "empty").mkdir(exist_ok=True)
    before = digest(recorded / "reports")
    one_line_error(_report(recorded, recorded / runs, "allow_missing=true"), "nothing to report")
    assert digest(recorded / "reports") == before


@pytest.mark.parametrize("damage", ["truncate", "partial_only", "garbage"])
def test_report_refuses_damaged_records_and_keeps_the_old_one(recorded, tmp_path, damage):
    import shutil

    runs = tmp_path / "runs"
    shutil.copytree(recorded / "runs", runs)
    target = runs / "fig8" / "ssrl" / "records.mcap"
    if damage == "truncate":
        target.write_bytes(target.read_bytes()[: target.stat().st_size // 2])
    elif damage == "partial_only":
        target.rename(target.with_name("records.mcap.partial"))
    else:
        target.write_bytes(b"not an mcap file at all")
    before = digest(recorded / "reports")
    out = _report(recorded, runs)
    words = ["ssrl"] if damage == "partial_only" else ["fig8/ssrl/records.mcap"]
    one_line_error(out, *words)
    assert digest(recorded / "reports") == before


def test_report_refuses_cells_of_different_setups(recorded, tmp_path):
    import shutil

    runs = tmp_path / "runs"
    shutil.copytree(recorded / "runs", runs)
    other = tmp_path / "other"
    assert (
        cli(
            "trials",
            "+experiment=fig8",
            "recogniser=oracle",
            "seed=7",
            f"out={other}",
            *FAST,
            *FIG8_WITHOUT_MODELS,
        ).returncode
        == 0
    )
    shutil.rmtree(runs / "fig8" / "shield")
    shutil.copytree(other / "shield", runs / "fig8" / "shield")
    before = digest(recorded / "reports")
    one_line_error(_report(recorded, runs, "allow_missing=true"), "fig8/shield", "seed=7")
    assert digest(recorded / "reports") == before


def test_the_report_names_a_missing_metrics_file_in_its_cell(tmp_path):
    row = recogniser_row("Relation Network", tmp_path / "metrics.json", tmp_path / "study")
    assert row["test [95%]"] == f"no metrics file `{tmp_path / 'metrics.json'}`"
    assert row["query pictures [95%]"] == f"no study `{tmp_path / 'study' / 'summary.json'}`"
