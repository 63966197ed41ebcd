"""View-dependent vertex hierarchy with dependency-free connectivity coding.

Stage entry points: ``build_tree`` (vertex forest of one part), ``encode_hierarchy`` /
``decode_hierarchy`` (versioned blob), ``select_cut`` (Hoppe 1997 view-dependent cut) and
``measure`` (bits per triangle of one coding variant). See ``docs/hierarchy.md``.
"""

from .coding import CAME, PROPOSED, PROPOSED_PLUS, RELATIVE_ID, VARIANTS, Variant, measure
from .format import Hierarchy, blob_length, decode_hierarchy, encode_hierarchy
from .select import Cut, select_cut
from .tree import VertexTree, build_tree, drop_degenerate

__all__ = ["CAME", "PROPOSED", "PROPOSED_PLUS", "RELATIVE_ID", "VARIANTS", "Variant", "measure",
           "Hierarchy", "blob_length", "decode_hierarchy", "encode_hierarchy", "Cut",
           "select_cut", "VertexTree", "build_tree", "drop_degenerate"]
