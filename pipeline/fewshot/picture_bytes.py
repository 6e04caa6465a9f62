"""The PNG bytes of a rendered dataset's pictures that a trial's records keep (docs/records.md):
the query pictures by picture id and the original support set by category, in the order the
Relation Network's support set holds them, so a replay shows what the recogniser saw."""

from __future__ import annotations

from pathlib import Path

from pipeline.fewshot.data import MANIFEST, load_split, read_manifest


def support_pictures(images_dir: str) -> dict[int, list[bytes]]:
    """PNG bytes of the original support set by category, shot ``k`` of category ``c`` where the
    Relation Network's support set holds it (the order of :func:`pipeline.fewshot.data.load_split`)."""
    # the order and categories; the pixels are read below
    support = load_split(images_dir, "support", 8)
    shots: dict[int, list[bytes]] = {}
    for category, file in zip(support.labels.tolist(), support.files):
        shots.setdefault(category, []).append((Path(images_dir) / file).read_bytes())
    return shots


def query_pictures(images_dir: str) -> dict[int, bytes]:
    """PNG bytes of the query pictures by picture id, from the render stage's manifest (none
    without one)."""
    manifest = Path(images_dir) / MANIFEST
    if not manifest.exists():
        return {}
    df = read_manifest(images_dir)  # a damaged manifest: DataError naming it
    df = df[df["split"] == "query"]
    return {
        int(p): (Path(images_dir) / f).read_bytes() for p, f in zip(df["picture_id"], df["file"])
    }
