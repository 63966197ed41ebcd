"""What a cook writes in the streaming layout: its stages and their levels (docs/format.md 14.4).

``streamed(container)`` is ``cook --stream``: the default-layout container rewritten by
``lopcook.lop.stream.to_stream`` with the stages ``assign_stages`` chooses and the levels
``stage_levels`` gives them.

Stages: LOD k of a part is selected for camera distances [t_k, t_{k+1}) (``min_distance_m`` of
it and of the next coarser LOD; ``lopcook.selection``), so a camera at distance d needs exactly the
buffers with t_{k+1} > d. A buffer's key is ``required_level(t_{k+1})``, the level of the farthest
camera that selects it (0 for a coarsest LOD), and stages are the distinct keys in ascending order:
a camera at level B needs the stages up to key B, and a prefix never holds a finer LOD before a
coarser one of the same part. Stage levels: LOD k is drawn from t_k outward, where the half-pixel
criterion asks for ``required_level(t_k)`` bits at most (Meyer et al. 2011, section 4;
``lopcook.viewing``); a shared buffer (placements) takes the most any placement asks for after its
level shift, and the earliest key of its placements.
"""

from __future__ import annotations

import numpy as np

from ..lop.container import Container
from ..lop.stream import to_stream
from ..selection import viewing_of
from ..viewing import required_level

LEVELS = 24


def buffer_level(manifest: dict, i: int, k: int) -> int:
    """The highest level stored buffer (part i, LOD k) is drawn at by a viewer that selects LODs
    by distance (module doc), clamped to ``positions.max_level``."""
    m, max_level = manifest, int(manifest["positions"]["max_level"])
    viewing, extent = viewing_of(m), float(m["grid"]["extent"])
    best = 0
    for j, part in enumerate(m["parts"]):
        pl = part.get("placement")
        if j != i and not (isinstance(pl, dict) and pl["of"] == i):
            continue
        d = part["lods"][k].get("min_distance_m")
        if d is None:
            return max_level
        level = int(np.asarray(required_level(float(d), extent, viewing)))
        shift = int(pl["level_shift"]) if isinstance(pl, dict) else 0
        best = max(best, min(max(level + shift, 1), LEVELS))
    return min(best, max_level)


def stage_keys(manifest: dict) -> dict:
    """{(part, lod): key} of every stored buffer (module doc): ``required_level`` of the next
    coarser LOD's ``min_distance_m`` (0 for the coarsest LOD; 24 where it is not recorded), the
    least over a shared buffer's placements, made non-decreasing from a part's coarsest LOD to
    its finest."""
    m = manifest
    viewing, extent = viewing_of(m), float(m["grid"]["extent"])
    keys: dict = {}
    for j, part in enumerate(m["parts"]):
        pl = part.get("placement")
        owner = int(pl["of"]) if isinstance(pl, dict) else j
        n, key = len(part["lods"]), 0
        for k in range(n - 2, -1, -1):  # coarse to fine
            d = part["lods"][k + 1].get("min_distance_m")
            key = max(key, LEVELS if d is None else int(np.asarray(required_level(float(d), extent, viewing))))
            keys[(owner, k)] = min(keys.get((owner, k), key), key)
        keys[(owner, n - 1)] = 0
    return keys


def stage_levels(manifest: dict, stages: list) -> list[int]:
    """L_s of every stage (``stages``: per stage its (part, lod) buffers): the largest
    ``buffer_level`` over the stage's buffers."""
    return [max(buffer_level(manifest, i, k) for i, k in buffers) for buffers in stages]


def assign_stages(manifest: dict) -> tuple[list, dict]:
    """``(stages, stage_of)``: per stage its stored buffers (part, lod) in manifest order, and the
    stage of each: the rank of its key among the distinct keys (``stage_keys``)."""
    keys = stage_keys(manifest)
    rank = {key: s for s, key in enumerate(sorted(set(keys.values())))}
    stages: list = [[] for _ in rank]
    for (i, k) in sorted(keys):
        stages[rank[keys[(i, k)]]].append((i, k))
    return stages, {b: rank[key] for b, key in keys.items()}


def streamed(c: Container) -> Container:
    """The complete default-layout container ``c`` in the streaming layout (module doc)."""
    order, _ = assign_stages(c.manifest)
    return to_stream(c, order, stage_levels(c.manifest, order))
