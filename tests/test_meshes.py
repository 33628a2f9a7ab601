"""Mesh loading, checks, transforms and the inside test (ipsph.geometry.meshes)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import meshio
import numpy as np
import pytest
import pyvista as pv
from pyvista import examples

from ipsph import config as model
from ipsph.errors import MeshError
from ipsph.geometry import inside, meshes

MODELS = Path(__file__).resolve().parents[1] / "meshes"  # shipped with the repository (meshes/PROVENANCE.md)

# Exact geometry (boxes built from 8 corners): float64 round-off only.
EXACT = 1e-12


@pytest.fixture(autouse=True)
def _quiet_pyvista():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", category=DeprecationWarning)
        warnings.filterwarnings("ignore", message=".*extract_surface.*")
        yield


def unit_box():
    return meshes.box_mesh((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))


# ----------------------------------------------------------------------------- loading
@pytest.mark.parametrize("suffix", [".obj", ".stl", ".ply", ".vtk", ".vtu", ".off", ".msh"])
def test_load_formats_roundtrip_a_box(tmp_path, suffix):
    pts, faces = meshes.mesh_arrays(unit_box())
    path = tmp_path / f"box{suffix}"
    fmt = {".msh": "gmsh22"}.get(suffix)
    meshio.write(path, meshio.Mesh(pts, [("triangle", faces)]), file_format=fmt)
    mesh = meshes.load_mesh(path)
    assert mesh.n_cells == 12
    assert meshes.check_closed(mesh) == 0
    assert meshes.signed_volume(mesh) == pytest.approx(1.0, abs=1e-6)  # STL stores float32


def test_load_vtp(tmp_path):
    path = tmp_path / "sphere.vtp"
    examples.load_sphere().save(path)
    mesh = meshes.load_mesh(path)
    assert mesh.is_all_triangles and mesh.n_cells == 840


def test_load_obj_with_uvs_unitbox():
    mesh = meshes.load_mesh(MODELS / "UnitBox.obj")
    assert mesh.n_points == 8 and mesh.n_cells == 12
    assert meshes.signed_volume(mesh) == pytest.approx(1.0, abs=EXACT)


def test_unreadable_missing_unknown_and_empty_files_raise_mesherror(tmp_path):
    garbage = tmp_path / "broken.stl"
    garbage.write_bytes(b"\x00\x01 not an stl at all")
    with pytest.raises(MeshError, match="broken.stl"):
        meshes.load_mesh(garbage)
    with pytest.raises(MeshError, match="not found"):
        meshes.load_mesh(tmp_path / "missing.obj")
    unknown = tmp_path / "points.xyz"
    unknown.write_text("0 0 0\n")
    with pytest.raises(MeshError, match="unknown format"):
        meshes.load_mesh(unknown)
    empty = tmp_path / "empty.obj"
    empty.write_text("# nothing here\n")
    with pytest.raises(MeshError, match="empty.obj") as info:
        meshes.load_mesh(empty)
    assert "\n" not in str(info.value)


# ----------------------------------------------------------------------------- transforms
def test_transform_scale_rotate_translate_on_a_box():
    t = model.Transform(translate=(1.0, 2.0, 3.0), scale=(2.0, 3.0, 4.0), rotate_axis=(0.0, 1.0, 0.0), rotate_deg=90.0)
    mesh = meshes.transform_mesh(unit_box(), t)
    # scaled box [0,2]x[0,3]x[0,4]; +90° about y maps (x, z) -> (z, -x); then translate
    np.testing.assert_allclose(mesh.bounds, (1.0, 5.0, 2.0, 5.0, 1.0, 3.0), atol=EXACT)
    assert meshes.signed_volume(mesh) == pytest.approx(24.0, rel=EXACT)
    back = meshes.inverse_transform_points(np.asarray(mesh.points), t)
    np.testing.assert_allclose(back, unit_box().points, atol=EXACT)


def test_mirroring_scale_keeps_normals_outward():
    mesh = meshes.transform_mesh(unit_box(), model.Transform(scale=(-1.0, 1.0, 1.0)))
    assert meshes.signed_volume(mesh) == pytest.approx(1.0, rel=EXACT)


def test_rotation_matrix_is_rodrigues():
    rot = meshes.rotation_matrix((0.0, 0.0, 2.0), 90.0)
    np.testing.assert_allclose(rot @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=EXACT)
    with pytest.raises(MeshError, match="zero length"):
        meshes.rotation_matrix((0.0, 0.0, 0.0), 10.0)


# ----------------------------------------------------------------------------- checks
def test_box_mesh_is_closed_with_outward_normals():
    box = meshes.box_mesh((-1.0, 0.0, 2.0), (1.0, 3.0, 2.5))
    assert meshes.edge_counts(box) == (0, 0, 0)
    assert meshes.signed_volume(box) == pytest.approx(3.0, rel=EXACT)
    assert meshes.aligned_box(box) is not None


def test_inverted_box_is_detected_and_flipped():
    pts, faces = meshes.mesh_arrays(unit_box())
    inverted = meshes.tri_mesh(pts, faces[:, ::-1])
    assert meshes.signed_volume(inverted) == pytest.approx(-1.0, rel=EXACT)
    mesh, report = meshes.prepare_mesh(inverted, name="inverted")
    assert report.flipped and report.volume == pytest.approx(1.0, rel=EXACT)
    assert meshes.signed_volume(mesh) == pytest.approx(1.0, rel=EXACT)
    assert any("flipped" in note for note in report.notes)


def test_zero_volume_mesh_is_refused():
    # two coincident triangles of opposite orientation: every edge paired, nothing enclosed
    flat = meshes.tri_mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2], [0, 2, 1]]))
    assert meshes.check_closed(flat) == 0
    with pytest.raises(MeshError, match="zero volume"):
        meshes.prepare_mesh(flat, name="flat")
    with pytest.raises(MeshError, match="zero volume"):  # squashed by a tiny scale
        meshes.prepare_mesh(unit_box(), model.Transform(scale=(1.0, 1.0, 1e-12)), name="squashed")


def test_open_mesh_refused_unless_allowed():
    plane = examples.load_airplane()
    with pytest.raises(MeshError, match=r"224 open edges") as info:
        meshes.prepare_mesh(plane, name="airplane", need_closed=True)
    assert "allow_open_mesh" in str(info.value)
    _, report = meshes.prepare_mesh(plane, name="airplane", need_closed=True, allow_open=True)
    assert not report.closed and report.open_edges == 224


def test_dragon_loads_and_is_closed():
    mesh, report = meshes.prepare_mesh(MODELS / "Dragon_50k.obj")
    assert report.n_triangles == 50_000 and report.closed and not report.flipped
    # 16 edges are shared by four triangles (two sheets touching) but pair up in orientation
    assert report.non_manifold_edges == 16 and report.open_edges == 0
    assert report.volume > 0.0
    np.testing.assert_allclose(report.bounds, (-0.625763, 0.625964, 0.0, 0.882636, -0.280047, 0.279827), atol=1e-6)


def test_aligned_box_detection():
    assert meshes.aligned_box(meshes.transform_mesh(unit_box(), model.Transform(scale=(4, 3, 1.5)))) is not None
    rotated = meshes.transform_mesh(unit_box(), model.Transform(rotate_deg=30.0))
    assert meshes.aligned_box(rotated) is None
    assert meshes.aligned_box(examples.load_sphere()) is None


# ----------------------------------------------------------------------------- inside test
def test_winding_number_of_a_box():
    box = unit_box()
    w = inside.winding_number(
        np.array([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5], [0.5, 0.5, 1.0 + 1e-9], [0.9, 0.1, 0.99]]), box
    )
    # inside 1, outside 0, 1e-9 off a face ~0: the face's -2π cancels the other faces' +2π, leaving
    # O(1e-8) cancellation error at that distance; 1e-6 is far below the 0.5 decision threshold
    np.testing.assert_allclose(w, [1.0, 0.0, 0.0, 1.0], atol=1e-6)


def test_winding_number_of_a_sphere_against_distance():
    sphere = pv.Sphere(radius=1.0, theta_resolution=40, phi_resolution=40)
    rng = np.random.default_rng(1)
    p = rng.uniform(-1.5, 1.5, size=(2000, 3))
    rad = np.linalg.norm(p, axis=1)
    clear = np.abs(rad - 1.0) > 0.01  # the facets deviate from the sphere by < 0.01
    w = inside.winding_number(p, sphere)
    np.testing.assert_array_equal(w[clear] > 0.5, rad[clear] < 1.0)


def test_inside_mesh_union_of_overlapping_boxes():
    # one mesh made of two overlapping closed boxes: the voxeliser alone would XOR the overlap
    a = meshes.box_mesh((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    b = meshes.box_mesh((0.5, 0.25, 0.25), (1.5, 0.75, 0.75))
    pa, fa = meshes.mesh_arrays(a)
    pb, fb = meshes.mesh_arrays(b)
    both = meshes.tri_mesh(np.vstack([pa, pb]), np.vstack([fa, fb + len(pa)]))
    g = np.linspace(-0.2 + 1e-3, 1.7 + 1e-3, 39)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    in_a = np.all((p > 0) & (p < 1), axis=1)
    in_b = np.all((p > [0.5, 0.25, 0.25]) & (p < [1.5, 0.75, 0.75]), axis=1)
    got = inside.inside_mesh(p, both, 0.05)
    np.testing.assert_array_equal(got, in_a | in_b)


def test_inside_mesh_matches_winding_number_on_the_ant():
    # the ant's legs overlap its body slightly (w = 2 at a few lattice points)
    ant, report = meshes.prepare_mesh(examples.load_ant())
    rng = np.random.default_rng(2)
    b = np.array(report.bounds).reshape(3, 2)
    p = rng.uniform(b[:, 0], b[:, 1], size=(20_000, 3))
    np.testing.assert_array_equal(inside.inside_mesh(p, ant, 1.0), inside.winding_number(p, ant) > 0.5)


def test_inside_mesh_open_mesh_uses_winding_number():
    hemi = pv.Sphere(radius=1.0, end_phi=90.0).triangulate()  # open bowl
    p = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, -0.5], [3.0, 0.0, 0.0]])
    w = inside.winding_number(p, hemi)
    np.testing.assert_array_equal(inside.inside_mesh(p, hemi, 0.1, closed=False), w > 0.5)
    assert 0.0 < w[0] < 1.0 and math.isfinite(w[1])


def test_stray_lines_and_vertices_are_dropped(tmp_path):
    poly = pv.PolyData(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]]), faces=[3, 0, 1, 2], lines=[2, 2, 3])
    path = tmp_path / "mixed.vtp"
    poly.save(path)
    mesh = meshes.load_mesh(path)
    assert mesh.is_all_triangles and mesh.n_cells == 1 and mesh.n_points == 3


def test_fast_winding_number_matches_exact():
    # 7k triangles: far clusters as dipoles. Tolerance 0.05: 10x below the 0.5 decision margin,
    # and 2x above the largest deviation measured on the dragon (0.025)
    sphere = pv.Sphere(radius=1.0, theta_resolution=60, phi_resolution=60).triangulate()
    rng = np.random.default_rng(6)
    p = np.vstack([rng.uniform(-2, 2, size=(1000, 3)), rng.normal(size=(1000, 3))])
    p[1000:] *= (1.0 + rng.uniform(-0.02, 0.02, size=(1000, 1))) / np.linalg.norm(p[1000:], axis=1)[:, None]
    exact = inside.winding_number(p, sphere)
    fast = inside.fast_winding_number(p, sphere)
    assert sphere.n_cells > 4 * inside.TRIANGLES_PER_CLUSTER
    assert np.abs(fast - exact).max() < 0.05
