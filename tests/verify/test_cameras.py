"""Cameras of the render harness (lopcook.verify.cameras): icosahedron views, the level distance,
camera placement and the GL matrices. No GL."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lopcook.lop.binning import LEVELS
from lopcook.errors import LopcookError
from lopcook.verify import cameras as C
from lopcook.viewing import Viewing, nearest_box_distance, required_level


def test_twenty_icosahedron_directions_are_unit_and_distinct():
    d = C.icosahedron_directions()
    assert d.shape == (20, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    cos = d @ d.T
    np.fill_diagonal(cos, -1.0)
    assert cos.max() < 0.8  # neighbouring face centres are 41.8 degrees apart
    nearest = np.degrees(np.arccos(cos.max(axis=1)))
    np.testing.assert_allclose(nearest, np.degrees(np.arccos(np.sqrt(5.0) / 3.0)), atol=1e-9)
    np.testing.assert_allclose(d.sum(axis=0), 0.0, atol=1e-12)  # symmetric set
    # turned away from the coordinate planes: no axis-aligned plate is seen exactly edge-on
    assert np.abs(d).min() > np.sin(np.radians(8.9))


def test_select_views():
    assert C.select_views(20) == list(range(20))
    assert C.select_views(4) == [0, 5, 10, 15]
    assert C.select_views([3, 7]) == [3, 7]
    for bad in (0, 21, [20], []):
        with pytest.raises(LopcookError):
            C.select_views(bad)


@pytest.mark.parametrize("extent", [1.0, 0.137, 42.0])
def test_distance_for_level_makes_required_level_select_it(extent):
    viewing = C.render_viewing({"viewing": {"fov_y_deg": 60.0, "pixel_error": 0.5}}, (1280, 720))
    lo, hi = np.zeros(3), np.array([extent, 0.5 * extent, 0.25 * extent])
    for level in range(1, LEVELS):
        d = C.camera_distance(level, extent, viewing)
        assert int(required_level(d, extent, viewing)) == level
        assert int(required_level(d * (1 - 1e-4), extent, viewing)) == level + 1  # d is the threshold
        for view in (0, 7, 19):
            cam = C.make_camera(view, lo, hi, d, viewing)
            assert cam.box_distance == pytest.approx(d, rel=1e-12)
            assert int(required_level(nearest_box_distance(cam.eye, lo, hi), extent, viewing)) == level
            assert 0 < cam.near < cam.far


def test_object_pixels_at_a_level_do_not_depend_on_the_resolution():
    """d_B grows with the viewport height, so the metres per pixel at the object stay the same."""
    for res in ((320, 180), (1280, 720)):
        v = C.render_viewing({}, res)
        d = C.camera_distance(6, 1.0, v)
        assert float(v.pixel_size(d)) == pytest.approx(float(C.render_viewing({}, (640, 360)).pixel_size(
            C.camera_distance(6, 1.0, C.render_viewing({}, (640, 360))))), rel=1e-12)


def test_fixture_rotation_is_the_view_rotation():
    from tests.support import fixtures as F

    np.testing.assert_array_equal(F.GLOSSY_CREASE_ROTATION, C.VIEW_ROTATION)



def test_directions_are_the_rotated_face_centres_of_the_shared_icosahedron():
    from lopcook.mesh import icosahedron

    v, f = icosahedron()
    centres = v[f].mean(axis=1)
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    np.testing.assert_array_equal(C.icosahedron_directions(), (v[f].sum(axis=1) / np.linalg.norm(
        v[f].sum(axis=1), axis=1, keepdims=True)) @ C.VIEW_ROTATION.T)
    np.testing.assert_allclose(C.icosahedron_directions() @ C.VIEW_ROTATION, centres, atol=1e-15)


def test_place_camera_on_the_ray_at_the_box_distance():
    lo, hi = np.array([-1.0, -2.0, 0.0]), np.array([1.0, 2.0, 0.5])
    for d in (1e-3, 0.7, 25.0):
        for u in C.icosahedron_directions()[[0, 3, 11]]:
            eye = C.place_camera(u, lo, hi, d)
            assert nearest_box_distance(eye, lo, hi) == pytest.approx(d, rel=1e-12)
            ray = eye - 0.5 * (lo + hi)
            np.testing.assert_allclose(ray / np.linalg.norm(ray), u, atol=1e-12)


def test_look_at_maps_the_eye_to_the_origin_and_the_target_down_minus_z():
    eye, target = np.array([3.0, 1.0, 2.0]), np.array([0.5, -0.25, 0.0])
    m = C.look_at(eye, target)
    np.testing.assert_allclose(m @ np.append(eye, 1.0), [0, 0, 0, 1], atol=1e-12)
    t = m @ np.append(target, 1.0)
    np.testing.assert_allclose(t[:2], 0.0, atol=1e-12)
    assert t[2] == pytest.approx(-np.linalg.norm(target - eye), rel=1e-12)
    np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-12)  # a rotation
    assert np.linalg.det(m[:3, :3]) == pytest.approx(1.0)
    # looking straight down Y: +Z becomes the up vector, the matrix stays a rotation
    m = C.look_at([0.0, 5.0, 0.0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(m[1, :3], [0.0, 0.0, 1.0], atol=1e-12)


def test_perspective_maps_near_and_far_to_the_clip_range():
    near, far, fov, aspect = 0.5, 40.0, 60.0, 16.0 / 9.0
    p = C.perspective(fov, aspect, near, far)
    for z, ndc in ((-near, -1.0), (-far, 1.0)):
        c = p @ np.array([0.0, 0.0, z, 1.0])
        assert c[2] / c[3] == pytest.approx(ndc, abs=1e-12)
    # a point on the top edge of the field of view lands on y = 1
    y = near * math.tan(math.radians(fov / 2))
    c = p @ np.array([0.0, y, -near, 1.0])
    assert c[1] / c[3] == pytest.approx(1.0, abs=1e-12)
    c = p @ np.array([y * aspect, 0.0, -near, 1.0])
    assert c[0] / c[3] == pytest.approx(1.0, abs=1e-12)


def test_make_camera_sees_the_whole_box_between_near_and_far():
    lo, hi = np.array([-0.3, -0.1, -0.2]), np.array([0.3, 0.1, 0.2])
    viewing = Viewing(viewport=(320, 180))
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    for view in range(C.VIEW_COUNT):
        cam = C.make_camera(view, lo, hi, C.camera_distance(7, 0.6, viewing), viewing)
        clip = corners @ cam.mvp.T
        z = clip[:, 2] / clip[:, 3]
        assert np.all(clip[:, 3] > 0) and np.all(np.abs(z) < 1.0), view  # in front, inside the depth range
        np.testing.assert_array_equal(cam.centre, 0.5 * (lo + hi))
