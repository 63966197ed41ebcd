"""The .lop container format: everything that writes or reads its bytes (docs/format.md).

This work is based on: Meyer, Sussner, Greiner, Stamminger, "Adaptive Level-of-Precision for
GPU-Rendering", VMV 2011, sections 5.3 and 6 (binned adaptive precision buffers, VertexId/BitId);
Purnomo et al. 2005 (the packed attribute record).

Modules, one rule of the format each (docs/format.md section 14 maps rule -> module):

* ``container``: header, CRCs, the section table, ``to_bytes`` (writer) and ``from_bytes`` /
  ``read`` (reader, whole files and prefixes), versions;
* ``validate``: the manifest's run-time checks, one validator per record;
  ``manifest``: its typed view (``Manifest``, ``PartEntry``, ``LodEntry``) and every byte count;
* ``binning`` (bins, VertexId, BitId), ``bitplane`` (packing P, planes, float reconstruction),
  ``clusters`` (clustered buffers), ``placement`` (copies stored once);
* ``codecs`` (one module per attribute codec, ``CODECS``), ``record`` (the packed attribute
  record), ``indices``, ``memo`` (codes kept by content during a search);
* ``reader``: rebuilding P at a level and decoding buffers; ``summary``: what ``inspect`` shows.

Nothing here imports a pipeline stage: emit decides what to write and calls this package;
verify, hierarchy, report, decode and tune read through it.
"""
