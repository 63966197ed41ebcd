"""Copies stored once (``cook --instances``, lopcook.lop.placement, issue 16 item 5): groups found as
designed, world positions equal to the CPU reference (and, through transform feedback, to the
harness vertex shader) at every level, within each placement's guarantee, deterministic bytes,
the chess set's 49 placements over 8 distinct meshes, and bad manifests refused."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from lopcook.lop.container import CLUSTERED_VERSION, VERSION, from_bytes, to_bytes
from lopcook.lop.placement import float32_slack, level_shift, local_level, resident_level, to_world
from lopcook.lop.reader import decode_positions, lod_attributes, owner, part_grid
from lopcook.errors import LopcookError
from tests.support.fixtures import unit_sphere
from lopcook.grid import dx
from lopcook.pipeline import run
from lopcook.settings import Settings, SimplifySettings
from lopcook.simplify.instances import RTOL
from lopcook.types import MeshPart, Scene

INSTANCES = Settings(simplify=SimplifySettings(instances=True))
#: every copy a part of its own on the scene grid (--no-instances; the default before copies were stored once)
SEPARATE = Settings(simplify=SimplifySettings(instances=False))


def _rot(axis, angle):
    x, y, z = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                     [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
                     [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]])


#: name -> (A, t) of each copy of the sphere in the procedural scene
PLACEMENTS = {
    "rep": (np.eye(3), np.zeros(3)),
    "rotated": (_rot([1, 2, 3], 0.7), np.array([0.5, 0.0, 0.0])),
    "scaled": (1.5 * _rot([0, 1, 0], 1.1), np.array([0.0, 0.6, 0.0])),
    "mirrored": (np.diag([-1.0, 1.0, 1.0]), np.array([0.0, 0.0, 0.5])),
    "touching": (np.eye(3), np.array([-0.5, 0.0, 0.0])),
}


def procedural_scene(touching_first: bool = False) -> Scene:
    """Five copies of a 0.1 m sphere (one rotated, one scaled by 1.5, one mirrored) and a plate that
    shares one vertex with the copy "touching" (first with ``touching_first``: then the copy the
    others are found as copies of is the one left out)."""
    sp = unit_sphere(2)[0]
    base = np.asarray(sp.positions, np.float64) * 0.1
    idx = np.asarray(sp.indices, np.uint32)
    parts = []
    names = list(PLACEMENTS)
    if touching_first:
        names = ["touching"] + [n for n in names if n != "touching"]
    for name in names:
        a, t = PLACEMENTS[name]
        n = np.asarray(sp.normals, np.float64) @ np.linalg.inv(a)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        parts.append(MeshPart(name=name, positions=np.ascontiguousarray(base @ a.T + t), indices=idx,
                              normals=n.astype(np.float32), source=name))
    v = base[0] + PLACEMENTS["touching"][1]
    plate = np.array([v, v + [0.05, 0, 0], v + [0, 0.05, 0], v + [0.05, 0.05, 0.0]])
    parts.append(MeshPart(name="plate", positions=plate, indices=np.array([[0, 1, 2], [1, 3, 2]], np.uint32),
                          source="plate"))
    return Scene(parts=tuple(parts), source="procedural", format="obj").validate()


@pytest.fixture(scope="module")
def cooked():
    scene = procedural_scene()
    plain = run(scene, SEPARATE)
    inst = run(scene, INSTANCES)
    return scene, plain, inst


@pytest.fixture(scope="module", params=[False, True], ids=["rep-first", "touching-first"])
def cooked_both(request):
    scene = procedural_scene(touching_first=request.param)
    return scene, run(scene, SEPARATE), run(scene, INSTANCES)


def source_order(c, i: int, part: MeshPart) -> np.ndarray:
    """container vertex j (binned) -> source vertex, from the index buffers (emit keeps triangles)."""
    idx = lod_attributes(c, i, 0)["indices"].astype(np.int64).ravel()
    order = np.zeros(c.manifest["parts"][i]["lods"][0]["vertices"], np.int64)
    order[idx] = np.asarray(part.indices, np.int64).ravel()
    return order


def test_copies_are_grouped_and_the_touching_copy_is_not(cooked):
    scene, _, inst = cooked
    parts = inst.container.manifest["parts"]
    names = [p["name"] for p in parts]
    placed = {p["name"]: p["placement"] for p in parts if "placement" in p}
    assert set(placed) == {"rep", "rotated", "scaled", "mirrored"}
    assert {pl["of"] for pl in placed.values()} == {names.index("rep")}
    assert "grid" not in parts[names.index("touching")] and "grid" not in parts[names.index("plate")]
    # the transforms are the scene's maps (local = rep - lo), rounded to float32
    lo = np.asarray(scene.parts[0].positions).min(axis=0)
    for name, pl in placed.items():
        a, t = PLACEMENTS[name]
        m = np.asarray(pl["transform"]).reshape(3, 4)
        assert np.allclose(m[:, :3], a, atol=1e-6) and np.allclose(m[:, 3], t + a @ lo, atol=1e-6)
        assert np.array_equal(m, m.astype(np.float32).astype(np.float64))
    # the shift: smallest s with 2^s >= sigma E_m / E_w (scaled by 1.5 needs one level more)
    e_m = parts[0]["grid"]["extent"]
    e_w = inst.container.manifest["grid"]["extent"]
    for name, pl in placed.items():
        sig = np.linalg.svd(PLACEMENTS[name][0], compute_uv=False)[0]
        s = pl["level_shift"]
        assert 2.0 ** s >= sig * e_m / e_w * (1 - 1e-9) and 2.0 ** (s - 1) < sig * e_m / e_w
    assert placed["scaled"]["level_shift"] == placed["rep"]["level_shift"] + 1
    head = inst.container.data[:8]  # placements: version 3.0, whether or not a buffer is clustered
    assert (int.from_bytes(head[4:6], "little"), int.from_bytes(head[6:8], "little")) == CLUSTERED_VERSION


def _reference_world(c, i: int, level: int) -> np.ndarray:
    """Independent float32 reference: the mesh-grid decode, then each row's products and sums in
    float32 in the documented order (no fma), written out here."""
    _, widths, local = decode_positions_local(c, i, level)
    m = np.asarray(c.manifest["parts"][i]["placement"]["transform"], np.float64).reshape(3, 4).astype(np.float32)
    out = np.empty_like(local)
    for r in range(3):
        acc = np.float32(m[r, 0]) * local[:, 0]
        acc = (acc + np.float32(m[r, 1]) * local[:, 1]).astype(np.float32)
        acc = (acc + np.float32(m[r, 2]) * local[:, 2]).astype(np.float32)
        out[:, r] = (acc + np.float32(m[r, 3])).astype(np.float32)
    return out


def decode_positions_local(c, i: int, level: int):
    from lopcook.lop.bitplane import decode, reconstruct_float32
    from lopcook.lop.reader import gpu_buffer

    buf = gpu_buffer(c, i, 0, level)
    values, widths = decode(buf.words, buf.vertex_id, buf.bit_id, level)
    origin, extent = part_grid(c, i)
    return values, widths, reconstruct_float32(values, widths, origin, extent / 2.0 ** 24)


def test_world_positions_equal_the_reference_and_keep_each_placements_guarantee(cooked_both):
    scene, plain, inst = cooked_both
    c = inst.container
    placed = [p["name"] for p in c.manifest["parts"] if "placement" in p]
    assert sorted(placed) == ["mirrored", "rep", "rotated", "scaled"]
    e_w = c.manifest["grid"]["extent"]
    assert e_w == plain.container.manifest["grid"]["extent"]
    for i, p in enumerate(c.manifest["parts"]):
        order = source_order(c, i, scene.parts[i])
        src = np.asarray(scene.parts[i].positions)[order]
        m_world = plain.analysis.parts[i].min_level.astype(np.int64)[order]  # the world analysis
        pl = p.get("placement")
        for level in range(1, 25):
            _, widths, pos = decode_positions(c, i, 0, level)
            assert pos.dtype == np.float32
            if pl is None:  # on the scene grid: the same bytes' decode as the plain cook
                assert np.array_equal(pos, decode_positions(plain.container, i, 0, level)[2])
                continue
            assert np.array_equal(pos.view(np.uint32), _reference_world(c, i, level).view(np.uint32))
            # each vertex decodes with at least max(local level, its converted minimum level) bits
            assert np.all(widths >= local_level(np.maximum(level, m_world), pl["level_shift"]))
            # world error within the placement's guarantee dx_w(max(B, m_v)) plus the float32 and
            # affine-fit slack
            slack = float(np.linalg.norm(float32_slack(pl["transform"], part_grid(c, i)[1]))) \
                + RTOL * float(np.linalg.norm(src.max(axis=0) - src.min(axis=0)))
            err = np.linalg.norm(pos.astype(np.float64) - src, axis=1)
            bound = dx(np.maximum(level, m_world), e_w) + slack
            assert np.all(err <= bound), (p["name"], level, float((err - bound).max()))


def test_memory_counts_each_distinct_buffer_once(cooked):
    scene, plain, inst = cooked
    m = inst.container.entries
    groups = {owner(inst.container, i) for i in range(len(scene.parts))}
    assert len(groups) == 3  # the sphere group, "touching", "plate"
    mandatory = len(inst.container.section("positions/mandatory"))
    assert mandatory == sum(4 * m.parts[j].lods[0].mandatory_words for j in groups)
    for level in range(1, 25):
        assert m.cap_bytes(level) < m.cap_bytes_all_copies(level)
        shifts = [m.parts[i].level_shift for i in range(4)]
        want = sum(m.parts[j].lods[0].cap_bytes(level) for j in (4, 5)) + \
            m.parts[0].lods[0].cap_bytes(resident_level(level, shifts))
        assert m.cap_bytes(level) == want
    assert inst.container.manifest["stats"]["placements"] == {
        "parts": 4, "groups": 1, "vertices_all_copies": sum(p.n_vertices for p in scene.parts),
        "triangles_all_copies": sum(p.n_triangles for p in scene.parts)}
    assert m.cap_bytes(12) < plain.container.entries.cap_bytes(12)
    # inspect counts stored buffers: the group's once, plus "touching" and "plate"
    from lopcook.lop.summary import describe_container, format_container

    d = describe_container(inst.container)
    assert d["totals"]["parts"] == 6 and d["totals"]["buffers"] == len(groups) == 3
    assert "6 parts, 3 buffers" in format_container(d) and "of every part vs" in format_container(d)
    assert describe_container(plain.container)["totals"]["buffers"] == 6


def test_bytes_are_deterministic_and_the_default_stores_copies_once(cooked):
    scene, plain, inst = cooked
    assert run(scene, INSTANCES).data == inst.data
    assert run(scene, SEPARATE).data == plain.data
    assert plain.container.manifest["options"]["instances"] is False
    assert int.from_bytes(plain.data[6:8], "little") == VERSION[1]
    assert inst.container.manifest["options"]["instances"] is True
    assert Settings.from_manifest(inst.container.manifest).simplify.instances is True
    assert Settings.from_manifest(plain.container.manifest).simplify.instances is False
    # the default (instances None) stores this scene's copies once: the bytes of instances=True,
    # and its record reads back as True (so a re-cook from the record writes the same bytes)
    assert run(scene, Settings()).data == inst.data


def test_the_default_stores_nothing_once_without_copies_or_where_the_cook_cannot():
    """A scene without copies, or a cook with a hierarchy or a byte budget, takes the default
    cook's bytes of before (no options.instances); forcing instances there is still a usage error."""
    from lopcook.errors import LopcookError
    from lopcook.pipeline import resolve_instances
    from lopcook.settings import TuneSettings

    scene = procedural_scene()
    alone = Scene(parts=scene.parts[-2:], source="procedural", format="obj").validate()  # "touching", "plate"
    default = run(alone, Settings()).container
    assert "instances" not in default.manifest["options"] and Settings.from_manifest(default.manifest) == Settings()
    # the same bytes as instances=False but for its record
    separate = run(alone, SEPARATE).container
    assert separate.manifest["options"].pop("instances") is False
    assert separate.manifest == default.manifest and separate.sections == default.sections
    hier = Settings(simplify=SimplifySettings(hierarchy=True))
    assert resolve_instances(scene, hier).simplify.instances is False
    assert resolve_instances(scene, Settings(tune=TuneSettings(target_bytes="10000"))).simplify.instances is False
    assert resolve_instances(scene, Settings(), budget=True).simplify.instances is False
    assert resolve_instances(scene, Settings()).simplify.instances is True
    assert resolve_instances(alone, Settings()).simplify.instances is False
    with pytest.raises(LopcookError, match="does not combine with --hierarchy"):
        run(scene, Settings(simplify=SimplifySettings(instances=True, hierarchy=True)))


def test_placements_keep_their_guarantee_with_lod_chains():
    from lopcook.settings import parse_lods

    scene = procedural_scene()
    st = Settings(simplify=SimplifySettings(lods=parse_lods("1/2"), instances=True))
    c = run(scene, st).container
    parts = c.manifest["parts"]
    placed = [i for i, p in enumerate(parts) if "placement" in p]
    assert placed
    for i in placed:
        j = parts[i]["placement"]["of"]
        assert len(parts[i]["lods"]) == len(parts[j]["lods"])
        for k in range(len(parts[i]["lods"])):
            a = decode_positions(c, i, k, 24)[2]
            b = decode_positions(c, j, k, 24)[2]
            if i == j:
                continue
            pj = np.asarray(parts[j]["placement"]["transform"], np.float64).reshape(3, 4)
            pi = np.asarray(parts[i]["placement"]["transform"], np.float64).reshape(3, 4)
            # the same local buffer: world_j mapped back and forward gives world_i within slack
            local = (b.astype(np.float64) - pj[:, 3]) @ np.linalg.inv(pj[:, :3]).T
            assert np.allclose(local @ pi[:, :3].T + pi[:, 3], a, atol=1e-5)


def _lie(c, edit):
    m = json.loads(json.dumps(c.manifest))
    edit(m)
    return to_bytes({k: v for k, v in m.items() if k != "sections"},
                    [(s["name"], c.sections[s["name"]]) for s in c.manifest["sections"]])


@pytest.mark.parametrize("edit, message", [
    (lambda m: m["parts"][3]["placement"].update(of=1), "does not own its buffers"),
    (lambda m: m["parts"][1]["placement"].update(of=3), "earlier part"),
    (lambda m: m["parts"][1]["placement"].update(transform=[0.0] * 12), "singular"),
    (lambda m: m["parts"][1]["placement"].update(transform=[1.0] * 11), "12 finite"),
    (lambda m: m["parts"][1]["placement"].update(level_shift=m["parts"][1]["placement"]["level_shift"] + 1),
     "level_shift"),
    (lambda m: m["parts"][1]["grid"].update(origin=[1.0, 0.0, 0.0]), "differs from the grid"),
    (lambda m: m["parts"][1]["lods"][0].update(mandatory_words=[0, 1]), "does not name the buffer"),
    (lambda m: m["parts"][4].update(grid={"origin": [0, 0, 0], "extent": 1.0}), "only allowed with a placement"),
    (lambda m: m["parts"][1]["placement"].pop("level_shift"), "exactly of, transform, level_shift"),
])
def test_bad_placement_records_are_refused(cooked, edit, message):
    _, _, inst = cooked
    with pytest.raises(LopcookError) as exc:
        from_bytes(_lie(inst.container, edit))
    assert message in exc.value.message


def test_instances_with_hierarchy_is_a_usage_error():
    st = Settings(simplify=SimplifySettings(instances=True, hierarchy=True))
    with pytest.raises(LopcookError) as exc:
        run(procedural_scene(), st)
    assert exc.value.stage == "usage" and exc.value.exit_code == 2 and "--hierarchy" in exc.value.message


def test_level_shift_is_exact_at_powers_of_two():
    assert level_shift(1.0, 1.0, 8.0) == -3
    assert level_shift(1.0 + 1e-12, 1.0, 8.0) == -2
    assert level_shift(3.0, 1.0, 1.0) == 2
    assert list(local_level([1, 5, 24], -3)) == [1, 2, 21]
    with pytest.raises(LopcookError):
        level_shift(0.0, 1.0, 1.0)


def test_harness_vertex_shader_applies_the_placement_bit_exactly(cooked, gl):
    """The render harness's decode program (shaders/decode_bitplanes.glsl + VS_MAIN) through transform
    feedback of ``v_pos``: bit-exact with ``placement.to_world`` at several levels."""
    import moderngl

    from lopcook.lop.reader import gpu_buffer
    from lopcook.verify.glsl import vertex_shader_source
    from lopcook.verify.gpu import decode_block

    _, _, inst = cooked
    c = inst.container
    prog = gl.program(vertex_shader=vertex_shader_source(True), varyings=["v_pos"])
    vao = gl.vertex_array(prog, [])
    try:
        for i in (1, 2, 3):
            pl = c.manifest["parts"][i]["placement"]
            rows = np.asarray(pl["transform"], np.float64).reshape(3, 4)
            for r in range(3):
                prog[f"u_place{r}"].value = tuple(float(v) for v in rows[r])
            if "u_mvp" in prog:
                prog["u_mvp"].write(np.eye(4, dtype="<f4").tobytes())
            origin, extent = part_grid(c, i)
            for level in (1, 6, 11, 17, 24):
                buf = gpu_buffer(c, i, 0, level)
                n = int(buf.vertex_id[24])
                ssbo = gl.buffer(np.ascontiguousarray(buf.words, "<u4").tobytes())
                ubo = gl.buffer(decode_block(buf.vertex_id, buf.bit_id, level, origin,
                                             np.float32(extent / 2.0 ** 24 / 2.0), buf.words.size))
                out = gl.buffer(reserve=12 * n)
                ssbo.bind_to_storage_buffer(0)
                ubo.bind_to_uniform_block(0)
                vao.transform(out, mode=moderngl.POINTS, vertices=n)
                got = np.frombuffer(out.read(), "<f4").reshape(n, 3)
                want = decode_positions(c, i, 0, level)[2]
                assert np.array_equal(got.view(np.uint32), want.view(np.uint32)), (i, level)
                for b in (ssbo, ubo, out):
                    b.release()
    finally:
        vao.release()
        prog.release()


def test_harness_builds_each_distinct_buffer_once_and_draws_every_placement_at_its_reference(cooked, gl,
                                                                                            monkeypatch):
    """The render harness builds and uploads one buffer per distinct mesh and level (the placements
    of one owner share it, and its attribute record is decoded once), and each placement still
    draws exactly the reference decode of that buffer mapped by its own transform
    (``decode_positions`` at the resident level)."""
    import lopcook.verify.evaluate as ev
    import lopcook.verify.renderer as rd
    from lopcook.verify.buffers import resident_levels

    scene, _, inst = cooked
    c = inst.container
    built, drawn = [], []
    real_cap, real_draw = ev.cap_buffer, rd.Renderer.draw

    def counting(c_, part, lod, level):
        built.append((owner(c_, part), lod, level))
        return real_cap(c_, part, lod, level)

    def spy(self, items, camera, shading, decoded, **kw):
        if decoded:
            drawn.append([(int(it["part"]), it["ssbo"], np.asarray(it["cover"].positions)) for it in items])
        return real_draw(self, items, camera, shading, decoded, **kw)

    decodes = []
    real_decoded = rd._decoded_positions

    def counted_decode(buf, level, origin, half_cell, place):
        f = real_decoded(buf, level, origin, half_cell, place)

        def positions():
            decodes.append(level)
            return f()

        return positions

    read_records = []
    real_attributes = rd.lod_attributes

    def counted_attributes(c_, part, lod, **kw):
        read_records.append(owner(c_, part))
        return real_attributes(c_, part, lod, **kw)

    monkeypatch.setattr(ev, "cap_buffer", counting)
    monkeypatch.setattr(rd.Renderer, "draw", spy)
    monkeypatch.setattr(rd, "_decoded_positions", counted_decode)
    monkeypatch.setattr(rd, "lod_attributes", counted_attributes)
    levels = [6, 11]
    ev.evaluate(c, scene, levels=levels, views=1, resolution=(64, 48), variants=("cap",))
    n = len(c.manifest["parts"])
    # one build per distinct buffer (owner, LOD) at its resident level, for each scene level drawn
    expected = [(o, k, lv) for level in levels for (o, k), lv in resident_levels(c, [0] * n, level).items()]
    assert sorted(built) == sorted(expected)
    assert len(decodes) == len(built)  # one reference decode per buffer, shared by its placements
    assert sorted(read_records) == sorted(set(read_records))  # each owner's attribute record decoded once
    assert len({o for o, _, _ in built}) < n  # copies exist in this scene: fewer buffers than parts
    for items, level in zip(drawn, levels):
        resident = resident_levels(c, [0] * n, level)
        by_owner: dict = {}
        for part, ssbo, pos in items:
            want = decode_positions(c, part, 0, resident[(owner(c, part), 0)])[2]
            assert np.array_equal(pos.view(np.uint32), want.view(np.uint32)), (part, level)
            by_owner.setdefault(owner(c, part), set()).add(id(ssbo))
        assert all(len(ids) == 1 for ids in by_owner.values())
        assert any(sum(owner(c, p) == o for p, _, _ in items) > 1 for o in by_owner)


def test_decoders_check_each_distinct_buffer_on_its_own_grid(cooked, gl):
    from lopcook.verify.decoders import verify_decoders

    _, _, inst = cooked
    rep = verify_decoders(inst.container, levels=[1, 6, 12, 24], languages=("glsl",), adapt=False)
    assert rep["ok"] and rep["buffers"] == 3
    assert rep["languages"]["glsl"]["float_mismatches"] == 0


@pytest.fixture(scope="module")
def chess(corpus):
    from lopcook import api

    scene = api.load(corpus / "chess_set_flat.usdc")
    return scene, run(scene, INSTANCES)


def test_chess_set_places_49_parts_over_8_distinct_meshes(chess, corpus_meta):
    scene, res = chess
    c = res.container
    parts = c.manifest["parts"]
    assert len(parts) == corpus_meta["chess_set_flat.usdc"]["instances"] == 49
    owners = [owner(c, i) for i in range(len(parts))]
    distinct = sorted(set(owners))
    assert len(distinct) == 8  # board, king, queen, bishop, knight, rook, pawn top, pawn body
    assert sum("placement" in p for p in parts) == 48
    # each distinct mesh stored once: the mandatory section holds exactly the distinct buffers
    m = c.entries
    assert len(c.section("positions/mandatory")) == sum(4 * m.parts[j].lods[0].mandatory_words for j in distinct)
    assert c.manifest["stats"]["vertices"] == sum(parts[j]["lods"][0]["vertices"] for j in distinct)
    assert c.manifest["stats"]["placements"]["vertices_all_copies"] == sum(p.n_vertices for p in scene.parts)
    for level in range(6, 12):
        assert m.cap_bytes(level) < m.cap_bytes_all_copies(level)
    # every placement decodes near its source (level 24: within its guarantee's float32 slack)
    for i in (1, 25, 29, 48):
        order = source_order(c, i, scene.parts[i])
        pos = decode_positions(c, i, 0, 24)[2].astype(np.float64)
        assert np.abs(pos - np.asarray(scene.parts[i].positions)[order]).max() < 1e-6


def test_the_schema_accepts_the_instanced_manifest_and_rejects_a_bad_placement(cooked):
    from jsonschema import Draft202012Validator

    from conftest import REPO

    _, _, inst = cooked
    v = Draft202012Validator(json.loads((REPO / "schema" / "container.schema.json").read_text()))
    v.validate(inst.container.manifest)
    bad = json.loads(json.dumps(inst.container.manifest))
    bad["parts"][1]["placement"]["transform"] = [1.0] * 11
    assert not v.is_valid(bad)


def test_world_normals_of_placements_match_the_source(cooked):
    from lopcook.lop.reader import world_normals

    scene, _, inst = cooked
    c = inst.container
    for i in range(4):
        order = source_order(c, i, scene.parts[i])
        got = world_normals(c, i, lod_attributes(c, i, 0, unit_directions=True)["normals"])
        want = np.asarray(scene.parts[i].normals, np.float64)[order]
        assert np.degrees(np.arccos(np.clip((got * want).sum(axis=1), -1, 1))).max() < 1.0


def test_cli_instances_flag_and_its_usage_error(tmp_path, capsys):
    from conftest import FIXTURES
    from lopcook.cli import main
    from lopcook.lop.container import read

    out = tmp_path / "t.lop"
    assert main(["cook", str(FIXTURES / "two_plates.glb"), "--instances", "-o", str(out), "-q"]) == 0
    c = read(str(out))
    assert c.manifest["options"]["instances"] is True
    assert all("placement" not in p for p in c.manifest["parts"])  # flat plates: their affine map is not determined, no copies
    assert int.from_bytes(c.data[6:8], "little") == VERSION[1]
    assert main(["cook", str(FIXTURES / "two_plates.glb"), "--instances", "--hierarchy", "-o",
                 str(tmp_path / "u.lop"), "-q"]) == 2
    assert "--instances does not combine with --hierarchy" in capsys.readouterr().err
    assert not (tmp_path / "u.lop").exists()


def test_report_of_an_instanced_gltf_says_what_sharing_saves(tmp_path, gl):
    """glTF nodes placing one mesh three times -> cook --instances -> lopcook report: the memory rows
    count the mesh once and carry the all-copies bytes, the HTML states the saving, the JSON passes
    the report schema."""
    from jsonschema import Draft202012Validator

    from conftest import REPO
    from lopcook.cli import main
    from tests.support.fixtures import write_gltf

    sphere = unit_sphere(2)
    nodes = [{"name": "a", "mesh": 0, "translation": [0.0, 0.0, 0.0]},
             {"name": "b", "mesh": 0, "translation": [3.0, 0.0, 0.0], "rotation": [0.0, 0.6, 0.0, 0.8]},
             {"name": "c", "mesh": 0, "translation": [0.0, 6.0, 0.0], "scale": [2.0, 2.0, 2.0]}]
    src = tmp_path / "three.glb"
    write_gltf(sphere, src, binary=True, nodes=nodes)
    lop, html = tmp_path / "three.lop", tmp_path / "three.html"
    assert main(["-q", "cook", str(src), "--instances", "-o", str(lop)]) == 0
    from lopcook.lop.container import read

    c = read(str(lop))
    assert sum("placement" in p for p in c.manifest["parts"]) == 3
    assert main(["-q", "report", str(lop), "--source", str(src), "-o", str(html), "--levels", "6-7", "--views", "2",
                 "--resolution", "160x90"]) == 0
    rep = json.loads(html.with_suffix(".json").read_text())
    Draft202012Validator(json.loads((REPO / "schema" / "report.schema.json").read_text())).validate(rep)
    for row in rep["memory"]:
        assert row["cap_bytes_all_copies"] > row["cap_bytes"] and \
            row["cap_saved_by_sharing_bytes"] == row["cap_bytes_all_copies"] - row["cap_bytes"]
    assert 'id="copies"' in html.read_text()


def test_the_default_writes_the_separate_bytes_where_its_grouping_stores_nothing_once(monkeypatch):
    """The default decides from LOD 0 that copies can be stored once; the cook's grouping (which
    also looks at the LODs and the mesh-grid levels) may still keep every copy on the scene grid.
    Then the default writes what ``instances=False`` writes, with no options.instances record;
    ``instances=True`` records true whatever the grouping found."""
    import lopcook.pipeline as pipeline

    scene = procedural_scene()
    separate = run(scene, SEPARATE).data
    monkeypatch.setattr(pipeline, "placement_groups", lambda *a, **k: [])
    default = run(scene, Settings())
    assert "instances" not in default.container.manifest["options"]
    assert default.container.sections == from_bytes(separate).sections
    forced = run(scene, INSTANCES)
    assert forced.container.manifest["options"]["instances"] is True
    assert forced.container.entries.cap_bytes(12) == default.container.entries.cap_bytes(12)


def test_a_given_analysis_gives_the_same_copies_stored_once():
    """The searches of ``--target-psnr`` hand ``run`` the scene's analysis (a prepared one: the same
    levels as ``analyse``); storing copies once from it writes the bytes of a fresh cook."""
    from lopcook.analyse import analyse
    from lopcook.analyse.prepared import PreparedAnalysis

    scene = procedural_scene()
    for st in (Settings(), INSTANCES):
        fresh = run(scene, st).data
        assert run(scene, st, analysis=analyse(scene, st.analyse)).data == fresh
        prepared = PreparedAnalysis(scene, st.analyse).analyse(st.analyse.eps / 4, st.analyse.edge_eps)
        looser = replace(st, analyse=replace(st.analyse, eps=st.analyse.eps / 4))
        assert run(scene, looser, analysis=prepared).data == run(scene, looser).data


def test_touching_parts_answers_again_only_for_the_same_cells(monkeypatch):
    """``placement.touching_parts`` keeps its last answer for the same grid integers (the probes
    of a search ask again); other cells or owners are sorted again, and the answer handed out is a
    copy the caller may change."""
    import lopcook.lop.placement as P

    a = np.array([[0, 0, 0], [5, 5, 5]], np.uint32)
    b = np.array([[5, 5, 5], [9, 9, 9]], np.uint32)  # shares cell (5, 5, 5) with a
    c = np.array([[7, 7, 7]], np.uint32)
    first = P.touching_parts([a, b, c], [0, 1, 2])
    assert first.tolist() == [True, True, False]
    first[:] = False  # the caller's copy
    calls = []
    real = P._touching
    monkeypatch.setattr(P, "_touching", lambda *x: calls.append(1) or real(*x))
    assert P.touching_parts([a.copy(), b.copy(), c.copy()], [0, 1, 2]).tolist() == [True, True, False]
    assert not calls  # the same cells: no sort
    assert P.touching_parts([a, b, c], [0, 0, 1]).tolist() == [False, False]  # a and b one part now
    assert P.touching_parts([a, c + 1, b], [0, 1, 2]).tolist() == [True, False, True] and len(calls) == 2
