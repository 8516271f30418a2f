"""Frames and units found from a room's geometry (jaxmotion.scene.level)."""

import dataclasses

import numpy as np
import pytest

from jaxmotion.errors import SceneError
from jaxmotion.scene.level import (
    AXIS_TO_Z,
    detect_unit,
    estimate_normals,
    level_scene,
    rotation_between,
)


@pytest.fixture(scope="module")
def rooms():
    from jaxmotion.scene.rooms import room_to_scene, sample_room

    out = []
    for seed in (9001, 9004, 9007):
        s = room_to_scene(sample_room(seed), 20_000, np.random.default_rng(seed))
        out.append(dataclasses.replace(s, normal=None, objects=()))
    return out


def _turn(axis, angle):
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_rotation_between_takes_a_to_b():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a, b = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
        r = rotation_between(a, b)
        np.testing.assert_allclose(r @ a, b, atol=1e-9)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-9)
        assert np.linalg.det(r) == pytest.approx(1.0)
    np.testing.assert_allclose(rotation_between([0, 0, 1], [0, 0, -1]) @ [0, 0, 1], [0, 0, -1],
                               atol=1e-12)
    for (axis, sign), r in AXIS_TO_Z.items():
        np.testing.assert_allclose(r @ (np.eye(3)[axis] * sign), [0, 0, 1])
        assert np.linalg.det(r) == pytest.approx(1.0)


def test_units_from_the_room_size():
    rng = np.random.default_rng(1)
    room = rng.uniform([0, 0, 0], [5.0, 4.0, 2.6], (2000, 3))  # a 5 x 4 m room, 2.6 m high
    assert detect_unit(room) == (1.0, None)
    for word, scale in (("cm", 0.01), ("mm", 0.001), ("feet", 0.3048)):
        got, note = detect_unit(room / scale)
        assert got == scale and f"read as {word}" in note
    assert detect_unit(room, "cm")[0] == 0.01  # as told
    with pytest.raises(SceneError, match="no unit"):
        detect_unit(room * 1e6)
    with pytest.raises(SceneError, match="unknown unit"):
        detect_unit(room, "furlong")


def test_normals_of_a_plane_and_a_sphere():
    rng = np.random.default_rng(2)
    plane = np.concatenate([rng.uniform(-1, 1, (500, 2)), np.full((500, 1), 0.3)], 1)
    n = estimate_normals(plane)
    np.testing.assert_allclose(n, np.broadcast_to([0, 0, 1], n.shape), atol=1e-6)  # faces up
    d = rng.normal(size=(3000, 3))
    sphere = d / np.linalg.norm(d, axis=1, keepdims=True)
    n = estimate_normals(sphere, k=16)
    assert np.median(np.abs(np.einsum("nc,nc->n", n, sphere))) > 0.99


def test_a_room_in_jaxmotion_s_frame_is_left_as_it_is(rooms):
    for room in rooms:
        out, notes = level_scene(room)
        assert out is room and notes == ()


@pytest.mark.parametrize("case", ["y-up", "x-down", "z-down", "tilted", "floor at 1.5",
                                  "floor at -0.65", "millimetres", "feet"])
def test_frames_and_units_are_found(rooms, case):
    """Every room, moved out of jaxmotion's frame, comes back to it (within 1 cm), with a
    note saying what was done."""
    for room in rooms:
        moved = {
            "y-up": lambda s: s.transformed(AXIS_TO_Z[1, 1].T),
            "x-down": lambda s: s.transformed(AXIS_TO_Z[0, -1].T),
            "z-down": lambda s: s.transformed(AXIS_TO_Z[2, -1].T),
            "tilted": lambda s: s.transformed(_turn(np.array([0.6, 0.8, 0.0]), np.deg2rad(5))),
            "floor at 1.5": lambda s: s.translated([0, 0, 1.5]),
            "floor at -0.65": lambda s: s.translated([0, 0, -0.65]),
            "millimetres": lambda s: dataclasses.replace(s, xyz=s.xyz * 1000.0),
            "feet": lambda s: dataclasses.replace(s, xyz=s.xyz / 0.3048),
        }[case](room)
        out, notes = level_scene(moved, prior="y" if case == "y-up" else "z")
        assert np.abs(out.xyz - room.xyz).max() < 0.01, (case, notes)
        assert notes or case == "y-up", case  # a glTF-style y-up file is the expected frame


def test_a_z_up_gltf_is_not_turned_as_if_y_up(rooms):
    """A glTF authored z-up (prior y): its floor decides, not the format's convention."""
    room = rooms[0]
    out, notes = level_scene(room, prior="y")
    assert np.abs(out.xyz - room.xyz).max() < 1e-6
    assert any("+z-up" in n for n in notes)


def test_a_cluttered_ceiling_is_not_taken_for_the_floor(rooms):
    # a real office scan: a dropped ceiling with lamps and ducts fills the half metre under
    # the ceiling as densely as the furniture fills the half metre above the floor, and the
    # ceiling is only partly scanned; the file is z-up and must stay so
    from jaxmotion.scene.level import find_floor

    for scene in rooms:
        xyz = scene.xyz
        top = np.percentile(xyz[:, 2], 99.5)
        band = (xyz[:, 2] > 0.05) & (xyz[:, 2] < 0.6)
        rng = np.random.default_rng(0)
        hang = xyz[band].copy()
        hang[:, 2] = top - rng.uniform(0.05, 0.6, len(hang))  # as many points, hanging
        ceiling = xyz[:, 2] > top - 0.03
        keep = ~ceiling | (rng.random(len(xyz)) < 0.4)  # 40 % of the ceiling scanned
        floor = find_floor(np.concatenate([xyz[keep], hang]) + [0, 0, -1.45])
        assert (floor.axis, floor.sign) == (2, 1), (floor.axis, floor.sign)
        assert abs(floor.normal @ [0, 0, 1] - 1) < 1e-3 and abs(floor.offset + 1.45) < 0.02
