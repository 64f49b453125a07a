"""Mesh files: the scripts in meshes/ write files that the cases read back (any meshio format)."""

from pathlib import Path

import numpy as np
import pytest

import material
from femgran.cases import footing, triaxial
from femgran.cases.footing import footing_mesh
from femgran.mesh import box, load_mesh

MESHES = Path(__file__).resolve().parents[2] / "meshes"


def test_make_meshes_round_trip(tmp_path):
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_meshes", MESHES / "make_meshes.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    files = mod.main(["--out", str(tmp_path)])
    assert len(files) == 4
    m = load_mesh(tmp_path / "triaxial_hex_4.vtu")
    ref = box(0.05, 0.05, 0.1, 4, 4, 8)
    np.testing.assert_allclose(m.p, ref.p)
    np.testing.assert_array_equal(m.t, ref.t)  # the hexahedron node order survives the VTK round trip
    f = load_mesh(tmp_path / "footing_quad_3.vtu")
    np.testing.assert_allclose(f.p, footing_mesh(1.0, resolution=3).p)
    assert set(m.boundaries) >= {"left", "right", "front", "back", "bottom", "top"}


@pytest.mark.parametrize("name", ["triaxial_hex_4.vtu", "triaxial_tet_4.vtu"])
def test_triaxial_from_a_mesh_file_matches_the_built_in_mesh(name):
    mat = material.LinearElastic(3e4, 0.3)
    sol = triaxial(mat, 100.0, 0.0, "smooth", mesh=MESHES / name, axial_strain=0.001, steps=1, plots=False)
    # smooth platens, elastic: homogeneous, q = E eps_a
    assert sol.history["q_kPa"][-1] == pytest.approx(3e4 * 0.001, rel=1e-8)


def test_footing_from_a_triangle_mesh_file():
    mat = material.LinearElastic(3e4, 0.3)
    a = footing(mat, 1.0, 0.0, 0.0, True, settlement_m=0.001, steps=1, mesh=MESHES / "footing_tri_3.vtu", plots=False)
    b = footing(mat, 1.0, 0.0, 0.0, True, settlement_m=0.001, steps=1, mesh=MESHES / "footing_quad_3.vtu", plots=False)
    assert a.completed and b.completed
    # the same elastic problem on two discretisations (P2 triangles vs Q2 B-bar quads)
    assert a.history["pressure_kPa"][-1] == pytest.approx(b.history["pressure_kPa"][-1], rel=0.05)
