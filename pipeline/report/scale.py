"""What the report was built from: the scale of its records, stated in its first lines.

Each record file embeds the config its cell ran with, including the profile's ``trials`` block
(runs, episodes, layouts) and the cell's own ``runs`` and ``episodes``. A cell's profile is the
one of ``conf/profile/`` whose ``trials`` block it recorded (the stage hands them over as
``profiles``). Records of different profiles in one report are refused unless asked for, and
records of the ``smoke`` profile say so in the report's title.
"""

from __future__ import annotations

from collections import defaultdict

from pipeline.errors import UserError

#: The profile whose records are too small to stand for the paper (named in the title).
SMOKE = "smoke"


class MixedScalesError(UserError):
    """The records of one report come from different profiles."""


def profile_of(config: dict | None, profiles: dict[str, dict]) -> str:
    """The name of the profile whose ``trials`` block ``config`` recorded (``unnamed profile``
    when none matches: a profile file changed since, or one of another checkout)."""
    recorded = ((config or {}).get("profile") or {}).get("trials")
    found = [name for name, trials in sorted(profiles.items()) if trials == recorded]
    return found[0] if found else "unnamed profile"


def scales(experiments, profiles: dict[str, dict]) -> dict[str, dict[tuple, list[str]]]:
    """Profile -> (runs, episodes) -> the experiments (folders) with cells at that scale."""
    out: dict[str, dict[tuple, list[str]]] = defaultdict(lambda: defaultdict(list))
    for exp in experiments:
        for cell in exp.cells.values():
            cfg = cell.config or {}
            at = out[profile_of(cfg, profiles)][(cfg.get("runs"), cfg.get("episodes"))]
            if exp.folder not in at:
                at.append(exp.folder)
    return out


def describe_scales(found: dict[str, dict[tuple, list[str]]]) -> str:
    """``profile `paper`: 100 runs x 500 episodes a cell (fig8, table3); 20 runs x 500 ...``"""
    parts = []
    for name, by_size in sorted(found.items()):
        sizes = "; ".join(
            f"{runs} runs x {episodes} episodes a cell ({', '.join(folders)})"
            for (runs, episodes), folders in sorted(by_size.items(), key=lambda kv: -len(kv[1]))
        )
        parts.append(f"profile `{name}`: {sizes}")
    return "; ".join(parts)


def check_scales(found: dict, runs_dir, allow_mixed: bool) -> None:
    """Records of more than one profile: refused unless ``allow_mixed``."""
    if len(found) > 1 and not allow_mixed:
        raise MixedScalesError(
            f"the records under {runs_dir} are of different scales ({describe_scales(found)}); "
            "run them again at one scale, or build with allow_mixed_scales=true"
        )


def title_and_scale(found: dict, base: str) -> tuple[str, str]:
    """The report's title (``base``, marked when any record is of the smoke profile) and the line
    that states what it was built from."""
    title = f"Smoke-scale test data, not the paper's scale: {base}" if SMOKE in found else base
    line = (
        f"**Built from** records of {describe_scales(found)}."
        if found
        else "**Built from** no experiment records (the accuracy study only)."
    )
    return title, line
