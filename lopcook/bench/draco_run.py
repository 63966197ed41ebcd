"""Child process of ``lopcook bench``: encode every part with Draco (DracoPy) and write the buffers.

Usage: ``python -m lopcook.bench.draco_run PARTS.npz OUT.npz BITS [NORMAL_BITS UV_BITS]``

PARTS.npz holds, per part k, ``positions_k`` (n, 3) float32 metres, ``indices_k`` (m, 3) uint32 and,
when present, ``normals_k`` (n, 3) float32 and ``uvs_k`` (n, 2) float32. Each part is one Draco
mesh (as KHR_draco_mesh_compression stores one per primitive): positions at BITS bits over the
part's own bounding cube (Draco's default range), normals at 10 and UVs at 12 bits (the defaults
of glTF-Transform's ``draco`` command), compression level 7 (Draco's default speed 3). OUT.npz
holds ``buffer_k`` (uint8 bytes of each Draco buffer). Only encoding happens here, so the
parent's wall time and peak RSS of this process are the encoder's (plus Python start-up).
"""

from __future__ import annotations

import sys

import numpy as np

NORMAL_BITS = 10
UV_BITS = 12
COMPRESSION_LEVEL = 7


def encode_parts(parts: dict, bits: int, normal_bits: int = NORMAL_BITS, uv_bits: int = UV_BITS) -> dict:
    import DracoPy  # optional (lopcook[bench]): imported where Draco runs

    out = {}
    k = 0
    while f"positions_{k}" in parts:
        kw = {}  # DracoPy 2.2 asserts float64 normals / UVs
        if f"normals_{k}" in parts:
            kw.update(normals=parts[f"normals_{k}"].astype(np.float64), normal_quantization_bits=int(normal_bits))
        if f"uvs_{k}" in parts:
            kw.update(tex_coord=parts[f"uvs_{k}"].astype(np.float64), tex_coord_quantization_bits=int(uv_bits))
        data = DracoPy.encode(parts[f"positions_{k}"], faces=parts[f"indices_{k}"], quantization_bits=int(bits),
                              compression_level=COMPRESSION_LEVEL, **kw)
        out[f"buffer_{k}"] = np.frombuffer(data, np.uint8)
        k += 1
    return out



def write_parts(path, parts) -> None:
    """PARTS.npz (the module doc's layout) of MeshParts ``parts``, at ``path``."""
    arrays = {}
    for k, p in enumerate(parts):
        arrays[f"positions_{k}"] = p.positions.astype(np.float32)
        arrays[f"indices_{k}"] = p.indices.astype(np.uint32)
        if p.normals is not None:
            arrays[f"normals_{k}"] = p.normals.astype(np.float32)
        if p.uvs is not None:
            arrays[f"uvs_{k}"] = p.uvs.astype(np.float32)
    np.savez(path, **arrays)


def decode_buffers(path) -> list[tuple]:
    """The meshes of an OUT.npz written by this module, decoded (DracoPy): per buffer k,
    (positions (n, 3) float64, indices (m, 3) uint32, normals (n, 3) float32 or None, uvs (n, 2)
    float32 or None); an attribute the decoder returns with a count other than n is None."""
    import DracoPy  # optional (lopcook[bench]): imported where Draco runs

    parts = []
    with np.load(path) as z:
        k = 0
        while f"buffer_{k}" in z.files:
            mesh = DracoPy.decode(z[f"buffer_{k}"].tobytes())
            pts = np.asarray(mesh.points, np.float64)
            normals = getattr(mesh, "normals", None)
            uvs = getattr(mesh, "tex_coord", None)
            normals = None if normals is None or len(normals) != len(pts) else np.asarray(normals, np.float32)
            uvs = None if uvs is None or len(uvs) != len(pts) else np.asarray(uvs, np.float32)
            parts.append((pts, np.asarray(mesh.faces, np.uint32).reshape(-1, 3), normals, uvs))
            k += 1
    return parts


def main(argv) -> int:
    src, dst, bits = argv[0], argv[1], int(argv[2])
    nb, ub = (int(argv[3]), int(argv[4])) if len(argv) >= 5 else (NORMAL_BITS, UV_BITS)
    with np.load(src) as z:
        parts = {name: z[name] for name in z.files}
    np.savez(dst, **encode_parts(parts, bits, nb, ub))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
