"""View-dependent selection of a cut through the vertex hierarchy, and its triangles.

This work is based on H. Hoppe, "View-Dependent Refinement of Progressive Meshes", SIGGRAPH 1997,
section 4: a node is refined (split) only when its bounding sphere intersects the view frustum,
its normal cone does not face entirely away from the viewer, and its screen-space error exceeds
the tolerance. Selection is top-down from the roots, one vector pass per tree level.

Triangles of a cut are the subtris of the split nodes (the paper's "active nodes"), with every
corner replaced by the cut node above it: the image of the full mesh under the cut's vertex
clustering, degenerate triangles dropped. Because that map is simplicial, the oriented boundary
of the cut equals the image of the input's boundary: the cut of a closed mesh is closed.
Only the records of split nodes are decoded (dependency-free access).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LopcookError
from .decode import decode_records


@dataclass(frozen=True)
class Cut:
    """One view-dependent mesh.

    nodes : (k,) int64 the cut's nodes (preorder IDs), sorted; they are its vertices.
    positions : (k, 3) float64 world positions of those vertices.
    triangles : (t, 3) int64 indices into ``nodes``, counter-clockwise.
    split : (s,) int64 the split nodes whose records were decoded.
    """

    nodes: np.ndarray
    positions: np.ndarray
    triangles: np.ndarray
    split: np.ndarray


def _vec3(x, name):
    a = np.asarray(x, np.float64).reshape(-1)
    if a.shape != (3,) or not np.isfinite(a).all():
        raise LopcookError("usage", None, f"{name} must be three finite numbers, got {x!r}",
                           hint=f"pass {name} as X,Y,Z in scene units")
    return a


def refine_mask(h, nodes, eye, forward, right, up, fov_y, aspect, viewport_h, pixel_error, backface=True):
    """(k,) bool: Hoppe's refinement test for ``nodes`` (frustum, back-face unless
    ``backface=False``, screen error). The back-face test skips nodes whose subtree holds a
    leaf on the part's oriented boundary chain (``Hierarchy.node_open``, when the blob stores
    it): Hoppe's test assumes a closed, consistently oriented surface, whose back-facing regions
    its front hides; at an open edge or a seam a coarsened back-facing region pulls the edge
    away from the surface that continues it, and the gap shows at silhouettes."""
    c = h.origin + (h.node_positions[nodes].astype(np.float64) + 0.5) * h.step
    # the sphere of the region the node's refinement affects (its leaves' incident triangles)
    # when the blob has it, else of its leaves
    extent = h.error if getattr(h, "reach", None) is None else np.maximum(h.reach, h.error)
    r = extent[nodes].astype(np.float64) * h.step + h.step
    d = c - eye
    dist = np.linalg.norm(d, axis=1)
    z = d @ forward
    x = d @ right
    y = d @ up
    ty = np.tan(fov_y / 2)
    tx = ty * aspect
    # frustum: sphere outside a side plane (planes through the eye) or behind the eye
    cy, cx = np.cos(np.arctan(ty)), np.cos(np.arctan(tx))
    inside = z > -r
    inside &= (y - ty * z) * cy < r
    inside &= (-y - ty * z) * cy < r
    inside &= (x - tx * z) * cx < r
    inside &= (-x - tx * z) * cx < r
    # back-facing: every normal of the cone faces away from every point of the sphere
    n = h.cone_axis[nodes].astype(np.float64)
    alpha = h.cone_angle[nodes].astype(np.float64)
    s = np.einsum("ij,ij->i", d, n)
    has = np.linalg.norm(n, axis=1) > 0.5
    back = has & (alpha < np.pi / 2) & (s > r) & ((s - r) ** 2 > dist ** 2 * np.sin(alpha) ** 2) & bool(backface)
    # only where the back-facing region is hidden by the part's own front: not above a leaf on
    # the oriented boundary chain (open edges, seams, orientation flips)
    node_open = getattr(h, "node_open", None)
    if node_open is not None:
        back &= ~node_open[nodes]
    # screen-space error in pixels
    near = np.maximum(dist - r, 1e-9)
    px = h.error[nodes].astype(np.float64) * h.step / near * (viewport_h / (2 * ty))
    return inside & ~back & (px > pixel_error)


def select_cut(h, camera, target, fov: float = 60.0, viewport=(1024, 768), pixel_error: float = 1.0,
               up=(0.0, 1.0, 0.0), max_nodes: int | None = None, backface: bool = True) -> Cut:
    """Select the cut for one camera and decode only its triangles.

    Parameters
    ----------
    h : Hierarchy (from ``decode_hierarchy``)
    camera, target : (3,) world positions of the eye and the point looked at (scene units)
    fov : vertical field of view in degrees, (0, 180)
    viewport : (width, height) in pixels
    pixel_error : tolerated projected error in pixels (> 0)
    up : world up vector
    max_nodes : optional cap on split nodes (coarsest first), None for no cap
    backface : Hoppe's back-face test (a node whose normal cone faces away from the viewer is
        not split). Its coarse triangles can still turn towards the viewer and show at
        silhouettes (docs/hierarchy.md, section 7); False refines back-facing regions as well.
    """
    eye = _vec3(camera, "camera")
    tgt = _vec3(target, "target")
    upv = _vec3(up, "up")
    fwd = tgt - eye
    if np.linalg.norm(fwd) == 0:
        raise LopcookError("usage", None, "camera and target coincide",
                           hint="give a target different from the camera position")
    fwd /= np.linalg.norm(fwd)
    rgt = np.cross(fwd, upv)
    if np.linalg.norm(rgt) < 1e-9:
        rgt = np.cross(fwd, [1.0, 0.0, 0.0] if abs(fwd[0]) < 0.9 else [0.0, 0.0, 1.0])
    rgt /= np.linalg.norm(rgt)
    upo = np.cross(rgt, fwd)
    if not (0 < fov < 180):
        raise LopcookError("usage", None, f"fov {fov} outside (0, 180) degrees", hint="use e.g. 60")
    w, hh = (int(viewport[0]), int(viewport[1]))
    if w <= 0 or hh <= 0 or not pixel_error > 0:
        raise LopcookError("usage", None, f"viewport {viewport} / pixel error {pixel_error} invalid",
                           hint="use a positive WxH and a positive pixel error")
    fov_y = np.radians(fov)
    front = h.roots
    split = []
    budget = max_nodes
    while front.size:
        inner = front[h.left[front] >= 0]
        if not inner.size:
            break
        m = refine_mask(h, inner, eye, fwd, rgt, upo, fov_y, w / hh, hh, pixel_error, backface)
        go = inner[m]
        if budget is not None:
            go = go[:max(budget, 0)]
            budget -= go.size
        if not go.size:
            break
        split.append(go)
        front = np.concatenate([h.left[go], h.right[go]])
    split = np.sort(np.concatenate(split)) if split else np.zeros(0, np.int64)
    return cut_from_split(h, split)


def cut_from_split(h, split: np.ndarray) -> Cut:
    """The cut below an ancestor-closed set of split nodes: its vertices and triangles."""
    split = np.asarray(split, np.int64)
    is_split = np.zeros(h.n_nodes, bool)
    is_split[split] = True
    roots = h.roots
    if split.size:
        par = h.parent[split]
        if not np.all((par < 0) | is_split[np.maximum(par, 0)]):
            raise LopcookError("usage", None, "split nodes are not closed under ancestors",
                               hint="split a node only after its parent")
    kids = np.concatenate([h.left[split], h.right[split], roots])
    cut = np.unique(kids[~is_split[kids]])
    owner, tri = decode_records(h, split.tolist())
    lo_cut = h.lo[cut]
    order = np.argsort(lo_cut, kind="stable")
    lo_sorted = lo_cut[order]
    idx = np.empty_like(tri)
    leafc = tri >= 0
    j = np.searchsorted(lo_sorted, tri[leafc], side="right") - 1
    idx[leafc] = order[j]
    nodec = -tri[~leafc] - 1
    idx[~leafc] = np.searchsorted(cut, nodec)
    if (~leafc).any() and not np.array_equal(cut[idx[~leafc]], nodec):
        raise LopcookError("decode", None, "a cut corner stopped above the cut",
                           hint="the hierarchy data is corrupt; re-encode it")
    pos = h.origin + (h.node_positions[cut].astype(np.float64) + 0.5) * h.step
    return Cut(nodes=cut, positions=pos, triangles=idx, split=split)
